"""Exceptions shared by every layer.

Each subclasses the built-in exception a caller would naturally catch
(``ValueError`` for bad data or parameters, ``RuntimeError`` for a device that
misbehaves), so code that knows nothing of ThermoLab still handles them. The
message always says what was wrong and what is allowed: the command line prints
it as one line, the server returns it as the reason of a 4xx answer.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, field

__all__ = [
    "CLASS_LIST_PROBLEMS",
    "CONFLICT_CASES",
    "PASSWORD_PROBLEMS",
    "TAKEN_NAMES",
    "AccessDeniedError",
    "BookingClashError",
    "BookingQuotaError",
    "BookingSeriesClashError",
    "ChannelNotOnRigError",
    "ClassListError",
    "ClassListProblem",
    "ConfigError",
    "ConflictError",
    "CourseNameTakenError",
    "FaultNotClearedError",
    "GainRangeError",
    "HandInRefusedError",
    "HostOfflineError",
    "IdentifierStateError",
    "IncompatibleLabError",
    "InsufficientExcitationError",
    "InvalidDataError",
    "InvalidParameterError",
    "LabStartingError",
    "ModelValueError",
    "NameTakenError",
    "NoOutputUnitError",
    "NoRunError",
    "NobodyControlsError",
    "NotClosedLoopError",
    "NotControllerError",
    "NotFoundError",
    "PairChannelUnknownError",
    "PairRoleError",
    "PasswordChangeRequiredError",
    "PasswordRejectedError",
    "PreviousRunEndingError",
    "RecordFormatError",
    "RigBookedError",
    "RigError",
    "RigFaultError",
    "RigOutOfServiceError",
    "RigStateError",
    "RigTimeoutError",
    "RuleNotApplicableError",
    "RunInProgressError",
    "RunStateError",
    "SetpointNoStepError",
    "SetpointRangeError",
    "SettingNotForRigError",
    "SettingRangeError",
    "SettingsChangedError",
    "SignalSpecError",
    "SlotReversedError",
    "SlotTimeError",
    "SlotTooLongError",
    "SlotZoneError",
    "SpeedupRefusedError",
    "SubscriberCutError",
    "ThermoLabError",
    "TimeZoneError",
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


class ChannelNotOnRigError(InvalidParameterError):
    """A further input or output the rig does not declare (``q2`` on a one-heater rig)."""


class PairChannelUnknownError(InvalidParameterError):
    """A run's input/output pair names a channel the rig does not declare (``q3``)."""


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


#: A name already taken, by stable code: an English sentence with ``{name}``, the
#: gettext msgid that ``lab/locale`` translates (the command line's detail).
TAKEN_NAMES: Mapping[str, str] = {
    "taken.user": "user {name} already exists",
    "taken.user_choose": "user {name} already exists; choose another login name",
    "taken.course": "course {name} already exists",
    "taken.course_choose": "course {name} already exists; choose another name",
}


class _TakenError(ConflictError):
    """A name already taken: ``sentence`` (a key of ``TAKEN_NAMES``) and the ``name``."""

    def __init__(self, sentence: str, name: str) -> None:
        if sentence not in TAKEN_NAMES:
            raise KeyError(sentence)
        self.sentence = sentence
        self.name = name
        super().__init__(self.describe())

    def __reduce__(self) -> tuple[type[_TakenError], tuple[str, str]]:
        return type(self), (self.sentence, self.name)

    def describe(self, translate: Callable[[str], str] = str) -> str:
        """The refusal with its sentence passed through ``translate`` (a gettext function)."""
        return translate(TAKEN_NAMES[self.sentence]).format(name=repr(self.name))


class NameTakenError(_TakenError):
    """A login name that someone already has.

    Examples
    --------
    >>> str(NameTakenError("taken.user", "ana"))
    "user 'ana' already exists"
    """


class CourseNameTakenError(_TakenError):
    """A course name that another course already has."""


class TurnEndedError(ConflictError):
    """The turn at the controls ended while the request was being decided (it lost the race)."""


class RunInProgressError(ConflictError):
    """A run of the caller's own turn is already going on the rig (END it first)."""


class PreviousRunEndingError(ConflictError):
    """Right after a hand-over, the previous turn's run is still ENDing and storing its data."""


class TurnExtensionRefusedError(ConflictError):
    """A controller may not extend the turn now (someone waits, too early, or no room left)."""


class CourseClosedError(ConflictError):
    """The course is closed for the term: it is read and exported, never changed."""


class AccessDeniedError(ThermoLabError, PermissionError):
    """The caller is known but not allowed to do this (a student acting on another's control)."""


class IncompatibleLabError(ThermoLabError, RuntimeError):
    """A client and a lab speak different versions of the API (see ``thermolab.api_version``)."""


# -- the closed loop (issue #11) ----------------------------------------------------------


class _WordedParameterError(InvalidParameterError):
    """An error whose sentence is declared by code (``thermolab.control.words.LOOP_WORDS``).

    ``word_code`` and ``word_params`` name it and its values, so a page can say
    it in its reader's language; the message is the English sentence.
    """

    def __init__(
        self,
        message: str,
        *,
        word_code: str | None = None,
        word_params: Mapping[str, float | str] | None = None,
    ) -> None:
        super().__init__(message)
        self.word_code = word_code
        self.word_params: Mapping[str, float | str] = dict(word_params or {})


class GainRangeError(_WordedParameterError):
    """A PID gain or loop parameter not finite or outside its published range."""


class RuleNotApplicableError(_WordedParameterError):
    """A tuning rule that cannot tune this model (one needing a dead time, on a model without)."""


class ModelValueError(_WordedParameterError):
    """A first-order model no rule tunes: a zero gain, a tau not positive, a negative theta."""


class SetpointRangeError(InvalidParameterError):
    """A set point outside the rig's output range (its output limit and interlocks)."""


class SetpointNoStepError(SetpointRangeError):
    """A tuning step to the output the loop starts from: there is no step to tune for."""


class NoOutputUnitError(InvalidParameterError):
    """PID control asked of a rig that has no measured output (no output unit)."""


class NoRunError(ConflictError):
    """A run command (switch, set point, gains, fan) with no run going on the rig."""


# Why a rig takes no turn now: each its own stable code, so a page says which.
class RigOutOfServiceError(ConflictError):
    """A rig a teacher took out of service."""


class FaultNotClearedError(ConflictError):
    """A rig whose fault a teacher has not cleared yet."""


class LabStartingError(ConflictError):
    """A rig asked for before the lab has read its state at start-up."""


class HostOfflineError(ConflictError):
    """A rig whose host (the computer its kit hangs on) is not connected."""


class NotControllerError(ConflictError):
    """A controller's action by someone who does not control the rig."""


class NobodyControlsError(ConflictError):
    """A teacher's action on the controller of a rig nobody controls."""


class HandInRefusedError(ConflictError):
    """A run that cannot be handed in for an assignment; ``case`` (``handin_*``) says why."""

    def __init__(self, message: str, case: str) -> None:
        if not case.startswith("handin_"):
            raise ValueError(f"no hand-in refusal {case!r}")
        super().__init__(message, case=case)


class NotClosedLoopError(ConflictError):
    """A control command to a run started without a controller (an open-loop run)."""


# -- courses and people (issue #10) -------------------------------------------------------


#: What can be wrong with a class list, by stable code: an English sentence with
#: named ``{placeholders}``, the gettext msgid that ``lab/locale`` translates, so a
#: problem reaches the page (``error.<code>`` in the browser's catalogue) and the
#: command line in the reader's language. ``class_list.line`` frames one problem
#: and ``class_list.not_imported`` the whole list.
CLASS_LIST_PROBLEMS: Mapping[str, str] = {
    "class_list.not_imported": "the class list was not imported (nothing changed): {problems}",
    "class_list.line": "line {line}: {reason}",
    "class_list.more": "and {count} more",
    "class_list.too_large": "the file is larger than {limit} bytes",
    "class_list.workbook": (
        "the file is a spreadsheet workbook, not CSV text; in the spreadsheet choose "
        "'Save as' > 'CSV' and upload that file"
    ),
    "class_list.not_text": (
        "the file is not text in UTF-8 or Windows-1252 (byte {byte} of the line); save it as "
        "'CSV UTF-8' and upload it again"
    ),
    "class_list.empty": "the file is empty; the first line must be the header",
    "class_list.not_csv": "not readable as CSV ({reason})",
    "class_list.header": (
        "the header has columns {columns}; it must have one login column ({logins}) and "
        "one name column ({names})"
    ),
    "class_list.too_many": "more than {limit} students in one list",
    "class_list.cells": "{cells} cells where the header has {columns}",
    "class_list.username": (
        "user name {value} is not valid: use 1 to {limit} letters, digits, '.', '_', '@' or '-', "
        "starting with a letter or digit (no spaces; a full name with spaces is a display name)"
    ),
    "class_list.display_name": (
        "display name {value} is not valid: use 1 to {limit} letters, digits, spaces and ' . , -"
    ),
    "class_list.duplicate": "login name {value} is already on line {first}",
    "class_list.no_student": "the list has a header but no student",
    "class_list.teacher": "{value} is a teacher's account, not a student's",
}


@dataclass(frozen=True, slots=True)
class ClassListProblem:
    """One bad line of a class list: where, which problem (a key of ``CLASS_LIST_PROBLEMS``), and
    the values its sentence names.

    Examples
    --------
    >>> ClassListProblem.of(3, "class_list.duplicate", value="'ana'", first=2).reason
    "login name 'ana' is already on line 2"
    """

    line: int
    code: str
    params: Mapping[str, str | int] = field(default_factory=dict)

    @classmethod
    def of(cls, line: int, code: str, **params: str | int) -> ClassListProblem:
        """The problem ``code`` on ``line``, with its sentence's values."""
        if code not in CLASS_LIST_PROBLEMS:
            raise KeyError(code)
        return cls(line, code, params)

    def sentence(self, translate: Callable[[str], str] = str) -> str:
        """The problem in words, each sentence passed through ``translate`` (English by default)."""
        return translate(CLASS_LIST_PROBLEMS[self.code]).format(**self.params)

    @property
    def reason(self) -> str:
        """The problem in English."""
        return self.sentence()


class ClassListError(InvalidParameterError):
    """A class list (CSV) with bad lines; ``problems`` holds a :class:`ClassListProblem` for each.

    The message lists every bad line, so the CLI's one line and the API's
    ``detail`` say the same; nothing was changed. :meth:`describe` says it in
    another language.
    """

    def __init__(self, problems: Iterable[ClassListProblem]) -> None:
        self.problems = list(problems)
        super().__init__(self.describe())

    def describe(self, translate: Callable[[str], str] = str) -> str:
        """The message with every sentence passed through ``translate`` (a gettext function)."""

        def say(code: str, **params: str | int) -> str:
            return translate(CLASS_LIST_PROBLEMS[code]).format(**params)

        listed = [
            say("class_list.line", line=p.line, reason=p.sentence(translate))
            for p in self.problems[:20]
        ]
        if len(self.problems) > 20:
            listed.append(say("class_list.more", count=len(self.problems) - 20))
        return say("class_list.not_imported", problems="; ".join(listed))


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


class SpeedupRefusedError(InvalidParameterError):
    """A speed-up a rig does not allow for a turn (the message names the rig and what it allows)."""


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


#: Why a new password is refused, by stable code: an English sentence with named
#: ``{placeholders}``, the gettext msgid ``lab/locale`` translates, so the refusal
#: reaches the command line and the page in the reader's language.
PASSWORD_PROBLEMS: Mapping[str, str] = {
    "password.too_short": "password too short: at least {limit} characters are needed",
    "password.too_long": "password too long: at most {limit} characters are allowed",
    "password.blank": "the password may not be only whitespace",
    "password.user_name": "the password may not be the user name or a variant of it",
    "password.breached": "this password is in a list of breached passwords; choose another",
    "password.guessable": (
        "this password is too easy to guess (a keyboard row, a sequence, a repeated "
        "character or the lab's name, with little else); choose another"
    ),
}


class PasswordRejectedError(InvalidParameterError):
    """A new password the lab refuses: ``problem`` (a key of ``PASSWORD_PROBLEMS``) and its values.

    Examples
    --------
    >>> str(PasswordRejectedError("password.too_short", limit=12))
    'password too short: at least 12 characters are needed'
    """

    def __init__(self, problem: str, **params: str | int) -> None:
        if problem not in PASSWORD_PROBLEMS:
            raise KeyError(problem)
        self.problem = problem
        self.params: Mapping[str, str | int] = dict(params)
        super().__init__(self.describe())

    def describe(self, translate: Callable[[str], str] = str) -> str:
        """The refusal with its sentence passed through ``translate`` (a gettext function)."""
        return translate(PASSWORD_PROBLEMS[self.problem]).format(**self.params)


# -- slot times and booking tools (issue #24, item 7) --------------------------------------


class SlotTimeError(InvalidParameterError):
    """A slot's times are not a slot: see the subclasses (each has its stable code)."""


class SlotReversedError(SlotTimeError):
    """A slot that ends at or before it starts (start and end swapped, say)."""


class SlotTooLongError(SlotTimeError):
    """A slot longer than a day that was not said to be longer, or longer than the longest."""


class SlotZoneError(SlotTimeError):
    """A slot's time given without its time zone (a naive date and time)."""


class TimeZoneError(InvalidParameterError):
    """A time zone name that is not an IANA zone the lab knows (``Mars/Olympus``, ``GMT+25``)."""


class BookingQuotaError(ConflictError):
    """A student's own booking past their course's weekly quota; ``quota`` says how much is left.

    ``quota`` holds ``minutesPerWeek``, ``usedMinutes`` (in that week, before this
    booking) and ``weekStartsAt`` (ISO 8601, UTC).
    """

    def __init__(self, message: str, quota: dict[str, object]) -> None:
        super().__init__(message)
        self.quota = quota


class BookingSeriesClashError(ConflictError):
    """Occurrences of a weekly series overlap other bookings; ``clashes`` lists each one.

    Each item holds the occurrence's ``startsAt``, ``endsAt`` and the ``slot`` in
    the way (as :class:`BookingClashError`'s). Nothing was booked.
    """

    def __init__(self, message: str, clashes: list[dict[str, object]]) -> None:
        super().__init__(message)
        self.clashes = clashes
