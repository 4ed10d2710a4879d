"""Closing the loop: the PID law, tuning from an FOPDT model, predicted closed loop, adaptive PID.

Numerics only (no threads, clocks, rigs or I/O); the runner drives them
(:class:`thermolab.runner.ControlLoop`).

* :mod:`~thermolab.control.pid` — :class:`PID` (output limits, back-calculation
  anti-windup, filtered derivative on the measurement, bumpless transfer) and
  :class:`PIDGains` with the published :data:`GAIN_LIMITS`;
* :mod:`~thermolab.control.tuning` — :func:`tune` by IMC/lambda, SIMC,
  Ziegler–Nichols (open loop) and Cohen–Coon;
* :mod:`~thermolab.control.response` — :func:`predict_closed_loop`,
  :func:`step_metrics` and :func:`predict_record_step` (overshoot, 2 % settling time, IAE);
* :mod:`~thermolab.control.adaptive` — :class:`AdaptiveTuner`;
* :mod:`~thermolab.control.parameters` — every parameter of the loop declared
  once (:data:`PARAMETERS`, :func:`control_json` for the lab and the page);
* :mod:`~thermolab.control.convert` — :func:`to_control` (python-control,
  imported lazily).
"""

from typing import TYPE_CHECKING, Any

from thermolab.control.adaptive import AdaptiveTuner, GainBounds
from thermolab.control.convert import to_control
from thermolab.control.parameters import PARAMETERS, ControlParameter, control_json
from thermolab.control.pid import GAIN_LIMITS, PID, PIDGains
from thermolab.control.tuning import (
    FOPDT,
    RULE_FORMS,
    RULES,
    SPEED_RULES,
    STEP_FRACTION,
    Tuning,
    as_fopdt,
    step_setpoint,
    tune,
)
from thermolab.control.words import LOOP_WORDS, LoopWord, word_of

if TYPE_CHECKING:
    from thermolab.control.response import (
        ClosedLoopResponse,
        StepMetrics,
        predict_closed_loop,
        predict_record_step,
        rest_warning,
        rest_word,
        settling_warning,
        settling_word,
        step_metrics,
    )

# The response module needs NumPy; the rest is plain Python, so that the command
# line can list the rules without loading NumPy (tests/ident/test_registry.py).
_LAZY = {
    "ClosedLoopResponse",
    "StepMetrics",
    "predict_closed_loop",
    "predict_record_step",
    "rest_warning",
    "rest_word",
    "settling_warning",
    "settling_word",
    "step_metrics",
}


def __getattr__(name: str) -> Any:
    if name in _LAZY:
        from thermolab.control import response

        return getattr(response, name)
    raise AttributeError(f"module 'thermolab.control' has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted(set(globals()) | _LAZY)


__all__ = [
    "FOPDT",
    "GAIN_LIMITS",
    "LOOP_WORDS",
    "PARAMETERS",
    "PID",
    "RULES",
    "RULE_FORMS",
    "SPEED_RULES",
    "STEP_FRACTION",
    "AdaptiveTuner",
    "ClosedLoopResponse",
    "ControlParameter",
    "GainBounds",
    "LoopWord",
    "PIDGains",
    "StepMetrics",
    "Tuning",
    "as_fopdt",
    "control_json",
    "predict_closed_loop",
    "predict_record_step",
    "rest_warning",
    "rest_word",
    "settling_warning",
    "settling_word",
    "step_metrics",
    "step_setpoint",
    "to_control",
    "tune",
    "word_of",
]
