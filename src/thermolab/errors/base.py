"""The families every error belongs to, and the errors of data, parameters, rigs and runs.

:class:`ThermoLabError` and its built-in bases (``ValueError``, ``RuntimeError``,
``LookupError``, ``PermissionError``); :class:`ConflictError` with its precise
cases. The lab's refusals in :mod:`.turns`, :mod:`.closed_loop`,
:mod:`.settings`, :mod:`.people` and :mod:`.bookings` subclass these.
"""

from __future__ import annotations

__all__ = [
    "CONFLICT_CASES",
    "AccessDeniedError",
    "ChannelNotOnRigError",
    "ConfigError",
    "ConflictError",
    "IdentifierStateError",
    "IncompatibleLabError",
    "InsufficientExcitationError",
    "InvalidDataError",
    "InvalidParameterError",
    "LoopPairNotOnRigError",
    "ModelPairError",
    "NotFoundError",
    "PairChannelUnknownError",
    "PairRoleError",
    "RecordFormatError",
    "RigError",
    "RigFaultError",
    "RigStateError",
    "RigTimeoutError",
    "RunStateError",
    "SignalSpecError",
    "SubscriberCutError",
    "ThermoLabError",
]


class ThermoLabError(Exception):
    """Base class of every error ThermoLab raises on purpose."""


class InvalidDataError(ThermoLabError, ValueError):
    """A record cannot be used: NaN/inf, mismatched lengths, too few samples, bad time axis."""


class RecordFormatError(InvalidDataError):
    """A record file cannot be read: not CSV text, ambiguous separators or decimal marks, bad cells.

    The message names the file and, for a bad cell, its line, sample and column.
    """


class InsufficientExcitationError(InvalidDataError):
    """The data do not determine the parameters (input held constant, output settled)."""


class InvalidParameterError(ThermoLabError, ValueError):
    """A method or signal parameter is outside its allowed range."""


class ChannelNotOnRigError(InvalidParameterError):
    """A further input or output the rig does not declare (``q2`` on a one-heater rig)."""


class LoopPairNotOnRigError(ChannelNotOnRigError):
    """A closed loop on a heater and sensor the rig does not pair (``q2/t2`` on one heater)."""


class PairChannelUnknownError(InvalidParameterError):
    """A run's input/output pair names a channel the rig does not declare (``q3``)."""


class ModelPairError(InvalidParameterError):
    """A tuning table asked for a loop whose heater and sensor are not the model's pair
    (a Q2 -> T2 model for the Q1/T1 loop)."""


class PairRoleError(InvalidParameterError):
    """A run's pair whose input is not an input the run records, or whose output is no sensor."""


class IdentifierStateError(ThermoLabError, RuntimeError):
    """An online identifier was used out of order (a sample after ``finish()``)."""


class SignalSpecError(InvalidParameterError):
    """A signal specification string (``square:4:6:0.1`` ...) cannot be parsed."""


class RigError(ThermoLabError, RuntimeError):
    """A rig could not do what was asked."""


class RigFaultError(RigError):
    """A rig reported a fault (over-temperature, garbage from the device, unplugged)."""


class RigStateError(RigError):
    """A rig operation is not allowed in the rig's current lifecycle state (closed, faulted...)."""


class RigTimeoutError(RigFaultError):
    """A rig did not answer within its timeout."""


class RunStateError(ThermoLabError, RuntimeError):
    """An experiment run was asked for a transition its state does not allow (END before START)."""


class SubscriberCutError(ThermoLabError, RuntimeError):
    """An event subscriber fell too far behind a run and was disconnected from it."""


class ConfigError(InvalidParameterError):
    """A lab configuration (TOML) is malformed or has a bad value; the message names the key."""


class NotFoundError(ThermoLabError, LookupError):
    """A named thing (user, rig, run) does not exist."""


#: The precise reasons a request clashes with the lab's state, by stable code (each code's
#: sentence in every language: lab/error_messages.py). A ConflictError given one answers with
#: it, so a page says which clash; without one, with the generic ``conflict``.
CONFLICT_CASES = (
    # Why a run cannot be handed in (HandInRefusedError).
    "handin_wrong_rig",
    "handin_unfinished",
    "handin_too_short",
    # A teacher's and an administrator's clashes.
    "group_name_taken",
    "already_in_group",
    "course_open",
    "leavers_changed",
    "class_list_changed",
    "platform_registered",
    "member_has_other_role",
    "token_limit",
    "person_at_rig",
    "pace_fixed_during_run",
    "not_in_line",
    "rig_no_device",
    "nothing_handed_in",
    "stored_meanwhile",
)


class ConflictError(ThermoLabError, RuntimeError):
    """The request clashes with the current state (duplicate user, rig out of service).

    ``case`` (of :data:`CONFLICT_CASES`) names the clash precisely, or is None.
    """

    def __init__(self, *args: object, case: str | None = None) -> None:
        if case is not None and case not in CONFLICT_CASES:
            raise ValueError(f"no conflict case {case!r}")  # a mistake in the lab's code
        super().__init__(*args)
        self.case = case


class AccessDeniedError(ThermoLabError, PermissionError):
    """The caller is known but not allowed to do this (a student acting on another's control)."""


class IncompatibleLabError(ThermoLabError, RuntimeError):
    """A client and a lab speak different versions of the API (see ``thermolab.api_version``)."""
