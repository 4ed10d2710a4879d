"""The adaptive tuner: only valid estimates retune, within the rate and the bounds."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from thermolab.control import AdaptiveTuner, GainBounds, PIDGains, tune
from thermolab.errors import InvalidParameterError
from thermolab.ident import make_identifier
from thermolab.simulation import REFERENCE_MODEL


@dataclass
class Est:
    K: float
    tau: float
    valid: bool = True
    theta: float | None = None


class Scripted:
    """An identifier that returns the estimates it is given, one per sample."""

    def __init__(self, *estimates: Est | None) -> None:
        self.estimates = list(estimates)

    def update(self, u: float, y: float) -> Est | None:
        return self.estimates.pop(0) if self.estimates else None


def test_only_valid_estimates_retune() -> None:
    tuner = AdaptiveTuner(Scripted(Est(1.0, 10.0, valid=False), None), every=1, theta=1.0)
    g = PIDGains(1.0, 10.0)
    assert tuner.update(0.0, 0.0, g) is None
    assert tuner.last_reason == "no valid estimate yet"
    assert tuner.update(0.0, 0.0, g) is None  # the invalid one is still the latest
    assert (tuner.retunes, tuner.skipped) == (0, 2)


def test_a_gain_of_the_wrong_sign_does_not_retune() -> None:
    tuner = AdaptiveTuner(Scripted(Est(-1.0, 10.0)), every=1, theta=1.0)
    assert tuner.update(0.0, 0.0, PIDGains(1.0, 10.0)) is None
    assert "wrong sign" in tuner.last_reason


def test_an_estimate_no_rule_tunes_holds_with_the_declared_reason() -> None:
    """Why, by code (a page says it in its reader's language), never the bare English."""
    g = PIDGains(1.0, 10.0)
    tuner = AdaptiveTuner(Scripted(Est(1.0, 10.0, theta=-2.0)), every=1)
    assert tuner.update(0.0, 0.0, g) is None
    assert tuner.to_dict()["last_word"] == {
        "code": "model_theta_invalid", "params": {"value": -2.0},
    }  # fmt: skip
    assert tuner.last_reason == "the model's theta must be a number >= 0, got -2.0"
    zn = AdaptiveTuner(Scripted(Est(1.0, 10.0, theta=0.0)), "zn", every=1)
    assert zn.update(0.0, 0.0, g) is None
    assert zn.last_word is not None
    assert (zn.last_word.code, zn.last_word.params) == ("needs_dead_time", {"rule": "zn"})


def test_retunes_every_n_samples_with_the_estimates_theta() -> None:
    est = Est(1.0, 10.0, theta=2.0)
    tuner = AdaptiveTuner(Scripted(*[est] * 10), "simc", every=5, tau_c=2.0, max_change=10.0)
    g = PIDGains(2.5, 10.0)
    results = [tuner.update(0.0, 0.0, g) for _ in range(10)]
    assert [r is not None for r in results] == [False] * 4 + [True] + [False] * 4 + [True]
    assert results[4] == tune((1.0, 10.0, 2.0), "simc", tau_c=2.0).gains


@settings(max_examples=80, deadline=None)
@given(
    kp=st.floats(0.01, 100.0),
    ti=st.floats(1.0, 1000.0),
    K=st.floats(0.01, 10.0),
    tau=st.floats(1.0, 1000.0),
    c=st.floats(0.01, 1.0),
)
def test_gains_move_at_most_max_change_and_stay_in_bounds(
    kp: float, ti: float, K: float, tau: float, c: float
) -> None:
    bounds = GainBounds(kp=(0.05, 50.0), ti=(2.0, 500.0))
    tuner = AdaptiveTuner(
        Scripted(Est(K, tau)), "imc", form="pi", every=1, tau_c=10.0, max_change=c,
        bounds=bounds,
    )  # fmt: skip
    new = tuner.update(0.0, 0.0, PIDGains(kp, ti))
    assert new is not None
    assert 0.05 <= new.Kp <= 50.0
    assert 2.0 <= new.Ti <= 500.0
    for old, now, (lo, hi) in ((kp, new.Kp, bounds.kp), (ti, new.Ti, bounds.ti)):
        # Within the rate limit, unless the bounds pulled it back in.
        assert now <= max(old * (1 + c), lo) * (1 + 1e-12)
        assert now >= min(old / (1 + c), hi) * (1 - 1e-12)


def test_wlsm_on_the_reference_model_converges_to_its_imc_tuning() -> None:
    u = np.where((np.arange(3000) // 50) % 2 == 0, 6.0, 4.0)
    y = REFERENCE_MODEL.simulate(u)
    tuner = AdaptiveTuner(make_identifier("wlsm", 1.0), "imc", form="pi", every=50, tau_c=100.0)
    g = PIDGains(5.0, 50.0)
    for uk, yk in zip(u, y, strict=True):
        g = tuner.update(float(uk), float(yk), g) or g
    target = tune((0.140090, 250.126233), "imc", form="pi", tau_c=100.0).gains
    assert g.Kp == pytest.approx(target.Kp, rel=1e-3)
    assert g.Ti == pytest.approx(target.Ti, rel=1e-3)


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"every": 0}, "every must be"),
        ({"max_change": 0.0}, "max_change"),
        ({"rule": "magic"}, "unknown tuning rule"),
        ({"theta": -1.0}, "theta"),
    ],
)
def test_bad_settings(kwargs: dict[str, object], match: str) -> None:
    with pytest.raises(InvalidParameterError, match=match):
        AdaptiveTuner(Scripted(), **kwargs)  # type: ignore[arg-type]
    with pytest.raises(InvalidParameterError, match="bounds of kp"):
        GainBounds(kp=(10.0, 1.0))


def test_untrusted_unsettled_or_unexcited_estimates_hold_the_gains() -> None:
    g = PIDGains(1.0, 10.0)
    # The caller's trust check (the runner's: plausibility and the estimate's warnings).
    tuner = AdaptiveTuner(
        Scripted(Est(1.0, 10.0)), every=1, theta=1.0, excitation=0,
        trust=lambda est: "implausible time constant",
    )  # fmt: skip
    assert tuner.update(0.0, 0.0, g) is None
    assert tuner.last_reason == "estimate not trusted: implausible time constant"
    # ... and by code, for a page in another language (issue #24).
    assert tuner.to_dict()["last_word"] == {
        "code": "hold.not_trusted", "params": {"warning": "implausible time constant"},
    }  # fmt: skip
    # Not settled: tau jumped by half within the interval.
    tuner = AdaptiveTuner(Scripted(Est(1.0, 10.0), Est(1.0, 15.0)), every=2, theta=1.0,
                          excitation=0)  # fmt: skip
    assert tuner.update(0.0, 0.0, g) is None
    assert tuner.update(0.0, 0.0, g) is None
    assert tuner.last_reason.startswith("estimate not settled: tau moved from 10 to 15")
    assert tuner.last_word is not None
    assert tuner.last_word.code == "hold.unsettled_moved"
    assert tuner.last_word.params["name"] == "tau"
    assert (tuner.last_word.params["low"], tuner.last_word.params["high"]) == (10.0, 15.0)
    # Not excited: the input stayed within 5 % of its range.
    tuner = AdaptiveTuner(Scripted(Est(1.0, 10.0), Est(1.0, 10.0)), every=2, theta=1.0)
    tuner.set_input_range(0.0, 100.0)
    tuner.update(20.0, 0.0, g)
    assert tuner.update(24.0, 0.0, g) is None
    assert tuner.last_reason.startswith("too little excitation: the input moved 4")
    assert tuner.skipped == 1
    assert tuner.retunes == 0
    # The same, settled and excited, retunes; the next interval starts from the input in
    # force, so a step right after a retune counts.
    tuner = AdaptiveTuner(Scripted(*[Est(1.0, 10.0)] * 4), every=2, theta=1.0)
    tuner.set_input_range(0.0, 100.0)
    tuner.update(20.0, 0.0, g)
    assert tuner.update(30.0, 0.0, g) is not None
    tuner.update(50.0, 0.0, g)
    assert tuner.update(50.0, 0.0, g) is not None, tuner.last_reason
    assert tuner.to_dict()["last_reason"] == ""
    assert tuner.to_dict()["last_word"] is None
