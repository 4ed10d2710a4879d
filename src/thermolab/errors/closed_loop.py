"""The closed loop's refusals (issue #11): gains, tuning rules, set points, run commands.

The parameter errors carry a word code (``thermolab.control.words.LOOP_WORDS``)
so a page says them in its reader's language.
"""

from __future__ import annotations

from collections.abc import Mapping

from thermolab.errors.base import ConflictError, InvalidParameterError

__all__ = [
    "ChannelInLoopError",
    "GainRangeError",
    "ModelValueError",
    "NoOutputUnitError",
    "NoRunError",
    "NotClosedLoopError",
    "RuleNotApplicableError",
    "SetpointNoStepError",
    "SetpointRangeError",
]


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


class ChannelInLoopError(ConflictError):
    """A hand setting of the heater a closed loop drives: the loop's PID sets it."""


class NoRunError(ConflictError):
    """A run command (switch, set point, gains, fan) with no run going on the rig."""


class NotClosedLoopError(ConflictError):
    """A control command to a run started without a controller (an open-loop run)."""
