"""Why a tuning rule cannot tune a model, and why a closed-loop prediction may not hold.

Each sentence is declared once here by a stable code, an English sentence
with named ``{placeholders}``: the command line and the API's ``error`` and
``note`` say the English, and the API sends the code with its values beside
it, so a page says the sentence in its reader's language with numbers
written for that reader (js/loopwords.js, the catalogues' ``loopWord.<code>``;
tests/web/test_loopwords.py keeps them equal to :data:`LOOP_WORDS`).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field

from thermolab.errors import GainRangeError, ModelValueError, RuleNotApplicableError

__all__ = ["LOOP_WORDS", "LoopWord", "word_of"]

#: The sentences by code. A placeholder's name is letters and digits only (the
#: browser's catalogues take no other), and its value a number or a word.
LOOP_WORDS: Mapping[str, str] = {
    "needs_dead_time": (
        "rule {rule!r} needs a dead time theta > 0; use imc or simc for a model without"
    ),
    "gain_out_of_range": "{gain} must be finite with {gain} in [{low:g}, {high:g}], got {value!r}",
    "gain_size_out_of_range": (
        "{gain} must be finite with |{gain}| in [{low:g}, {high:g}], got {value!r}"
    ),
    "no_setpoint_recorded": "not a closed-loop run (no set point recorded), or too few samples",
    "no_measured_step": (
        "no set-point step to measure: the set point never moves away from the output, "
        "or the last step leaves fewer than 2 samples"
    ),
    "no_model": "the run was started without the model its gains came from",
    "record_not_finite": "t, r and y must be finite (no NaN or inf)",
    # A first-order model no rule tunes (control.tuning.FOPDT).
    "model_gain_invalid": "the model's gain K must be finite and non-zero, got {value!r}",
    "model_tau_invalid": "the model's tau must be a positive number, got {value!r}",
    "model_theta_invalid": "the model's theta must be a number >= 0, got {value!r}",
    "output_drifted": (
        "the output drifted at {slope:+.3g}/s in the model's dead time ({theta:g} s) after "
        "the step, before the controller could act: the box was about {away:+.3g} from rest "
        "(still warm from an earlier run?), so the prediction, which starts it settled, does "
        "not describe this run; start from a box at rest"
    ),
    # Why the adaptive tuner holds the gains (AdaptiveTuner.last_reason).
    "hold.no_estimate": "no valid estimate yet",
    "hold.not_trusted": "estimate not trusted: {warning}",
    "hold.not_tunable": "estimate not tunable: {reason}",
    "hold.wrong_sign": "the estimate's gain has the wrong sign",
    "hold.unsettled_invalid": (
        "estimate not settled: some estimates of the last {every} samples are invalid"
    ),
    "hold.unsettled_moved": (
        "estimate not settled: {name} moved from {low:.4g} to {high:.4g} over the last {every} "
        "samples (more than ±{tolerance:g} % of {value:.4g})"
    ),
    "hold.little_excitation": (
        "too little excitation: the input moved {moved:.3g} over the last {every} samples (less "
        "than {share:g} % of its range); a set-point step gives the estimator something to "
        "learn from"
    ),
    "settling_near_band": (
        "the overshoot ({measured:.1f} % measured, {predicted:.1f} % predicted) is near the "
        "{band:g} % settling band, where the settling time jumps between reaching the band "
        "and leaving the peak: compare the overshoot and the IAE instead"
    ),
}


@dataclass(frozen=True, slots=True)
class LoopWord:
    """One sentence of :data:`LOOP_WORDS`: its code and the values it names.

    Examples
    --------
    >>> w = LoopWord.of("needs_dead_time", rule="zn")
    >>> w.text
    "rule 'zn' needs a dead time theta > 0; use imc or simc for a model without"
    >>> w.to_dict()
    {'code': 'needs_dead_time', 'params': {'rule': 'zn'}}
    """

    code: str
    params: Mapping[str, float | str] = field(default_factory=dict)

    @classmethod
    def of(cls, code: str, **params: float | str) -> LoopWord:
        """The sentence ``code`` with its values (a ``KeyError`` for a code not declared)."""
        if code not in LOOP_WORDS:
            raise KeyError(code)
        return cls(code, params)

    @property
    def text(self) -> str:
        """The sentence in English."""
        return LOOP_WORDS[self.code].format(**self.params)

    def to_dict(self) -> dict[str, object]:
        """``{"code", "params"}``, JSON-ready (a value that is not finite is ``None``)."""
        params = {
            name: None if isinstance(v, float) and not math.isfinite(v) else v
            for name, v in self.params.items()
        }
        return {"code": self.code, "params": params}


def word_of(exc: BaseException) -> LoopWord | None:
    """The declared sentence an error of the closed loop says, if it says one."""
    if isinstance(exc, (GainRangeError, ModelValueError, RuleNotApplicableError)) and exc.word_code:
        return LoopWord.of(exc.word_code, **exc.word_params)
    return None
