"""Runs with the real online identifiers recover the twin's true Ks and Ts."""

from __future__ import annotations

import numpy as np
import pytest
from numpy.testing import assert_allclose, assert_array_equal

from thermolab.errors import InvalidParameterError
from thermolab.ident import block_least_squares, least_squares, moving_window_least_squares
from thermolab.ident.online import Estimate
from thermolab.rigs import VirtualClock, open_rig
from thermolab.rigs.twin import TwinRig
from thermolab.runner import EndReason, Experiment, RunResult
from thermolab.runner.methods import METHOD_NAMES, build_identifiers, parse_methods
from thermolab.signals import parse_signal


def _run(spec: str, signal: str, methods: str, n: int, seed: int = 0) -> tuple[RunResult, TwinRig]:
    with open_rig(spec, clock=VirtualClock(), seed=seed) as rig:
        assert isinstance(rig, TwinRig)
        identifiers = build_identifiers(parse_methods(methods), 1.0)
        result = Experiment(
            rig, 1.0, n, signal=parse_signal(signal, rig.describe().input_range),
            identifiers=identifiers,
        ).run()  # fmt: skip
    return result, rig


def _latest(result: RunResult, method: str) -> Estimate:
    estimate = result.methods[method].latest
    assert isinstance(estimate, Estimate)
    return estimate


def test_step_test_srm_and_lsm_at_end_recover_the_true_model() -> None:
    # The paper's first panel: SRM and LSM together, a 0 -> 10 V step, 2000 samples.
    result, rig = _run("sim", "step:0:10@10", "srm,lsm", 2000)
    assert result.end_reason is EndReason.COMPLETED
    for method in ("srm", "lsm"):
        # Both appear only at END.
        assert result.methods[method].k.size == 0
        est = _latest(result, method)
        assert est is result.methods[method].final
        assert est.final
        assert est.k == 1999
        assert_allclose(est.K, rig.params.gain, rtol=1e-6)
        assert_allclose(est.tau, rig.params.time_constant, rtol=1e-6)


def test_square_wave_recursive_methods_recover_the_true_model_every_sample() -> None:
    # The paper's MALSM / WLSM panels: a square wave, an estimate at every sample.
    result, rig = _run("sim", "square:0:4:0.1", "blockls,malsm,wlsm", 2000)
    methods = result.methods
    assert_array_equal(methods["blockls"].k, np.arange(99, 2000, 100))  # each full block
    assert_array_equal(methods["malsm"].k, np.arange(99, 2000))  # from the first full window
    assert_array_equal(methods["wlsm"].k, np.arange(2000))  # from the first sample (W0) on
    assert methods["wlsm"].valid[200:].all()
    assert_allclose(methods["wlsm"].K[-100:], 0.14009, rtol=1e-9)
    for method in ("blockls", "malsm", "wlsm"):
        est = _latest(result, method)
        assert_allclose(est.K, rig.params.gain, rtol=1e-9)
        assert_allclose(est.tau, rig.params.time_constant, rtol=1e-9)


# Noisy records fail the residual test of the batch methods (a warning, issue #8).
@pytest.mark.filterwarnings("ignore::thermolab.ident.IdentificationWarning")
def test_online_estimates_equal_the_batch_functions_on_the_recorded_data() -> None:
    # The runner feeds the identifiers exactly the (u, y) it records.
    with open_rig("sim:paper-practical", clock=VirtualClock(), seed=7) as rig:
        identifiers = build_identifiers(["lsm", "blockls", "malsm"], 1.0)
        result = Experiment(
            rig, 1.0, 1000, signal=parse_signal("square:4:6:0.1"), identifiers=identifiers
        ).run()
    assert tuple(least_squares(result.u, result.y, 1.0).W.tolist()) == _latest(result, "lsm").W
    blocks = block_least_squares(result.u, result.y, 1.0, block=100)
    online_blocks = result.methods["blockls"]
    assert_allclose(online_blocks.K, blocks.K[online_blocks.k], rtol=1e-12)
    window = moving_window_least_squares(result.u, result.y, 1.0, window=100)
    assert_array_equal(identifiers["malsm"].trajectory().W, window.W)
    online = result.methods["malsm"]
    assert_allclose(online.tau, window.tau[online.k], rtol=1e-12)
    assert_array_equal(online.valid, window.valid[online.k])


def test_noisy_twin_long_record_methods_stay_close_to_the_reference() -> None:
    # Table II's lesson: with noise and jitter, SRM and LSM(1) still land near the model.
    result, rig = _run("sim:paper-practical", "step:0:10@10", "srm,lsm", 2000, seed=2)
    for method in ("srm", "lsm"):
        est = _latest(result, method)
        assert est.valid
        assert_allclose(est.K, rig.params.gain, rtol=0.02)
        assert_allclose(est.tau, rig.params.time_constant, rtol=0.03)


def test_settings_that_no_chosen_method_uses_are_refused() -> None:
    with pytest.raises(InvalidParameterError, match="gamma is a setting of wlsm"):
        build_identifiers(["srm", "lsm"], 1.0, gamma=0.9)
    with pytest.raises(InvalidParameterError, match="options given for malsm"):
        build_identifiers(["srm"], 1.0, options={"malsm": {"window": 10}})
    with pytest.raises(InvalidParameterError, match="window"):
        build_identifiers(["malsm"], 1.0, window=0)


def test_method_lists() -> None:
    assert parse_methods("all") == METHOD_NAMES == ("srm", "lsm", "blockls", "malsm", "wlsm", "oe")
    assert parse_methods(["wlsm", "srm", "wlsm"]) == ("wlsm", "srm")
    with pytest.raises(InvalidParameterError, match="no method given"):
        parse_methods(" , ")


def test_warm_up_leaves_the_identifiers_untouched() -> None:
    identifiers = build_identifiers(METHOD_NAMES, 1.0)
    for ident in identifiers.values():
        assert ident.n_samples == 0
        assert not ident.finished
