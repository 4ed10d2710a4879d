"""Exceptions shared by every layer.

Each subclasses the built-in exception a caller would naturally catch
(``ValueError`` for bad data or parameters, ``RuntimeError`` for a device that
misbehaves), so code that knows nothing of ThermoLab still handles them. The
message always says what was wrong and what is allowed: the command line prints
it as one line, the server returns it as the reason of a 4xx answer.
"""

from __future__ import annotations

__all__ = [
    "AccessDeniedError",
    "BookingClashError",
    "ClassListError",
    "ConfigError",
    "ConflictError",
    "GainRangeError",
    "IdentifierStateError",
    "IncompatibleLabError",
    "InsufficientExcitationError",
    "InvalidDataError",
    "InvalidParameterError",
    "NoOutputUnitError",
    "NoRunError",
    "NotClosedLoopError",
    "NotFoundError",
    "PasswordChangeRequiredError",
    "PreviousRunEndingError",
    "RecordFormatError",
    "RigBookedError",
    "RigError",
    "RigFaultError",
    "RigStateError",
    "RigTimeoutError",
    "RunInProgressError",
    "RunStateError",
    "SetpointRangeError",
    "SettingNotForRigError",
    "SettingRangeError",
    "SettingsChangedError",
    "SignalSpecError",
    "SubscriberCutError",
    "ThermoLabError",
    "TurnEndedError",
    "TurnExtensionRefusedError",
    "WrongEnrolCodeError",
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


class ConflictError(ThermoLabError, RuntimeError):
    """The request clashes with the current state (duplicate user, rig out of service)."""


class TurnEndedError(ConflictError):
    """The turn at the controls ended while the request was being decided (it lost the race)."""


class RunInProgressError(ConflictError):
    """A run of the caller's own turn is already going on the rig (END it first)."""


class PreviousRunEndingError(ConflictError):
    """Right after a hand-over, the previous turn's run is still ENDing and storing its data."""


class TurnExtensionRefusedError(ConflictError):
    """A controller may not extend the turn now (someone waits, too early, or no room left)."""


class AccessDeniedError(ThermoLabError, PermissionError):
    """The caller is known but not allowed to do this (a student acting on another's control)."""


class IncompatibleLabError(ThermoLabError, RuntimeError):
    """A client and a lab speak different versions of the API (see ``thermolab.api_version``)."""


# -- the closed loop (issue #11) ----------------------------------------------------------


class GainRangeError(InvalidParameterError):
    """A PID gain or loop parameter not finite or outside its published range."""


class SetpointRangeError(InvalidParameterError):
    """A set point outside the rig's output range (its output limit and interlocks)."""


class NoOutputUnitError(InvalidParameterError):
    """PID control asked of a rig that has no measured output (no output unit)."""


class NoRunError(ConflictError):
    """A run command (switch, set point, gains, fan) with no run going on the rig."""


class NotClosedLoopError(ConflictError):
    """A control command to a run started without a controller (an open-loop run)."""


# -- courses and people (issue #10) -------------------------------------------------------


class ClassListError(InvalidParameterError):
    """A class list (CSV) with bad lines; ``problems`` holds ``(line, reason)`` for each.

    The message lists every bad line, so the CLI's one line and the API's
    ``detail`` say the same; nothing was changed.
    """

    def __init__(self, problems: list[tuple[int, str]]) -> None:
        self.problems = list(problems)
        listed = "; ".join(f"line {line}: {reason}" for line, reason in self.problems[:20])
        more = len(self.problems) - 20
        tail = f"; and {more} more" if more > 0 else ""
        super().__init__(f"the class list was not imported (nothing changed): {listed}{tail}")


class WrongEnrolCodeError(AccessDeniedError):
    """No course has this enrolment code (mistyped, or rotated by the teacher)."""


class PasswordChangeRequiredError(AccessDeniedError):
    """The account holds a temporary password: it must be changed before anything else."""


# -- teacher settings (issue #10) --------------------------------------------------------


class SettingRangeError(InvalidParameterError):
    """A teacher setting outside its allowed range (the message names the range).

    ``setting`` is its name, ``minimum``/``maximum`` the range in force for the rig.
    """

    def __init__(self, setting: str, message: str, minimum: float, maximum: float) -> None:
        self.setting = setting
        self.minimum = minimum
        self.maximum = maximum
        super().__init__(message)


class SettingNotForRigError(InvalidParameterError):
    """A teacher setting this rig does not have (the twin speed-up of a hardware rig).

    ``setting`` is its name.
    """

    def __init__(self, setting: str, message: str) -> None:
        self.setting = setting
        super().__init__(message)


class SettingsChangedError(ConflictError):
    """Someone saved a rig's settings since the version the change was based on."""


# -- bookings (issue #10, item 5) ----------------------------------------------------------


class BookingClashError(ConflictError):
    """A booking overlaps another on a rig they share; ``slot`` names the other one.

    ``slot`` holds ``id``, ``course``, ``startsAt``, ``endsAt`` (ISO 8601, UTC)
    and the shared ``rigs``, so a page can say which slot is in the way.
    """

    def __init__(self, message: str, slot: dict[str, object]) -> None:
        super().__init__(message)
        self.slot = slot


class RigBookedError(ConflictError):
    """A rig is booked for another course's slot now; ``slot`` holds its start and end."""

    def __init__(self, message: str, slot: dict[str, object]) -> None:
        super().__init__(message)
        self.slot = slot
