"""Exceptions shared by every layer.

Each subclasses the built-in exception a caller would naturally catch
(``ValueError`` for bad data or parameters, ``RuntimeError`` for a device that
misbehaves), so code that knows nothing of ThermoLab still handles them. The
message always says what was wrong and what is allowed: the command line prints
it as one line, the server returns it as the reason of a 4xx answer.
"""

from __future__ import annotations

from thermolab.errors.base import (
    CONFLICT_CASES,
    AccessDeniedError,
    ChannelNotOnRigError,
    ConfigError,
    ConflictError,
    IdentifierStateError,
    IncompatibleLabError,
    InsufficientExcitationError,
    InvalidDataError,
    InvalidParameterError,
    LoopPairNotOnRigError,
    NotFoundError,
    PairChannelUnknownError,
    PairRoleError,
    RecordFormatError,
    RigError,
    RigFaultError,
    RigStateError,
    RigTimeoutError,
    RunStateError,
    SignalSpecError,
    SubscriberCutError,
    ThermoLabError,
)
from thermolab.errors.bookings import (
    BookingClashError,
    BookingQuotaError,
    BookingSeriesClashError,
    RigBookedError,
    SlotReversedError,
    SlotTimeError,
    SlotTooLongError,
    SlotZoneError,
    TimeZoneError,
)
from thermolab.errors.closed_loop import (
    ChannelInLoopError,
    GainRangeError,
    ModelValueError,
    NoOutputUnitError,
    NoRunError,
    NotClosedLoopError,
    RuleNotApplicableError,
    SetpointNoStepError,
    SetpointRangeError,
)
from thermolab.errors.people import (
    CLASS_LIST_PROBLEMS,
    PASSWORD_PROBLEMS,
    TAKEN_NAMES,
    ClassListError,
    ClassListProblem,
    CourseClosedError,
    CourseNameTakenError,
    HandInRefusedError,
    NameTakenError,
    PasswordChangeRequiredError,
    PasswordRejectedError,
    WrongEnrolCodeError,
)
from thermolab.errors.settings import (
    SettingNotForRigError,
    SettingRangeError,
    SettingsChangedError,
    SpeedupRefusedError,
)
from thermolab.errors.turns import (
    FaultNotClearedError,
    HostOfflineError,
    LabStartingError,
    NobodyControlsError,
    NotControllerError,
    PreviousRunEndingError,
    RigOutOfServiceError,
    RunInProgressError,
    TurnEndedError,
    TurnExtensionRefusedError,
)

__all__ = [
    "CLASS_LIST_PROBLEMS",
    "CONFLICT_CASES",
    "PASSWORD_PROBLEMS",
    "TAKEN_NAMES",
    "AccessDeniedError",
    "BookingClashError",
    "BookingQuotaError",
    "BookingSeriesClashError",
    "ChannelInLoopError",
    "ChannelNotOnRigError",
    "ClassListError",
    "ClassListProblem",
    "ConfigError",
    "ConflictError",
    "CourseClosedError",
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
    "LoopPairNotOnRigError",
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

# The errors are the library's public API under this one name: tracebacks, doctests,
# pickles and ``repr`` show ``thermolab.errors.X``, wherever a family's module declares it.
for _name in __all__:
    _declared = globals()[_name]
    if isinstance(_declared, type):
        _declared.__module__ = __name__
del _name, _declared
