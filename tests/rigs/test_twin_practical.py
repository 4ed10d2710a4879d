"""The paper-practical twin shows the lessons of the paper's Table II.

On the real rig (NOTES.md §4) the 100-sample estimates scattered widely
(LSM(2) Ts from 15.7 s to 907 s, MALSM Ts 224-597 s), WLSM did not converge,
and only the long-record methods (SRM, LSM(1)) stayed close to the reference.
The same experiments on the ``paper-practical`` twin must show the same, and on
the noise-free ``paper`` twin must not: the difference is the realism.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt
import pytest
from numpy.testing import assert_allclose

from thermolab.rigs.clock import VirtualClock
from thermolab.rigs.twin import TwinRig

ident = pytest.importorskip("thermolab.ident")

KS, TS = 0.140090, 250.126233
FloatArray = npt.NDArray[np.float64]


def _record(preset: str, u: FloatArray, seed: int = 2024) -> tuple[FloatArray, FloatArray]:
    """Sample the twin once a second as the runner does: read y[k], then apply u[k]."""
    clock = VirtualClock()
    rig = TwinRig(preset, clock=clock, seed=seed)
    rig.power_on()
    y = np.empty(u.size)
    for k in range(u.size):
        clock.sleep_until(float(k))
        y[k] = rig.read().value
        rig.apply(float(u[k]))
    rig.close()
    return np.arange(u.size, dtype=float), y


def _step(n: int = 2000) -> FloatArray:
    return np.where(np.arange(n) >= 1, 10.0, 0.0)


def _square(low: float, high: float, n: int) -> FloatArray:
    return np.where((np.arange(n) // 5) % 2 == 0, high, low)


@pytest.fixture(scope="module")
def step_practical() -> tuple[FloatArray, FloatArray, FloatArray]:
    u = _step()
    t, y = _record("paper-practical", u)
    return t, u, y


# Noisy records fail the residual test of the batch methods (a warning, issue #8).
@pytest.mark.filterwarnings("ignore::thermolab.ident.IdentificationWarning")
def test_long_record_methods_stay_close_to_the_reference(
    step_practical: tuple[FloatArray, FloatArray, FloatArray],
) -> None:
    t, u, y = step_practical
    lsm = ident.least_squares(u, y, 1.0)
    assert_allclose([lsm.model.K, lsm.model.tau], [KS, TS], rtol=0.05)
    srm = ident.step_response(t, u, y, u_initial=0.0)
    assert_allclose([srm.model.K, srm.model.tau], [KS, TS], rtol=0.05)


# The last block, on the step's settled tail, is rightly flagged as not excited.
@pytest.mark.filterwarnings("ignore:final estimate not excited")
def test_hundred_sample_blocks_scatter_from_seconds_to_hundreds_of_seconds(
    step_practical: tuple[FloatArray, FloatArray, FloatArray],
) -> None:
    _, u, y = step_practical
    tau = ident.block_least_squares(u, y, 1.0, block=100).tau
    tau = tau[np.isfinite(tau)]
    assert tau.size >= 15  # most blocks still give a first-order model ...
    assert tau.min() < 50.0  # ... but some say tens of seconds or less
    assert tau.max() > 200.0  # ... and others hundreds
    assert tau.max() / tau.min() > 10.0


def test_the_same_blocks_on_the_noise_free_twin_agree() -> None:
    u = _step()
    _, y = _record("paper", u)
    tau = ident.block_least_squares(u, y, 1.0, block=100).tau
    tau = tau[np.isfinite(tau)]
    assert tau.size == 20
    np.testing.assert_allclose(tau, TS, rtol=1e-3)


def test_moving_window_scatters() -> None:
    u = _square(4.0, 6.0, 3000)
    _, y = _record("paper-practical", u)
    tr = ident.moving_window_least_squares(u, y, 1.0, window=100)
    tau = tr.tau[-2000:]
    tau = tau[np.isfinite(tau)]
    low, high = np.percentile(tau, [5, 95])
    assert high / low > 1.4  # the paper's real rig: 224-597 s
    assert low < 0.9 * TS
    assert high > 1.1 * TS


def test_wlsm_never_settles_within_one_percent() -> None:
    u = _square(0.0, 4.0, 3000)
    _, y = _record("paper-practical", u)
    tr = ident.weighted_least_squares(
        u, y, 1.0, gamma=0.96, pmax=1e4, w0=[0.96329, 9.9082e-4], form="paper"
    )
    converged = tr.converged_at(tol=0.01, last=2000)
    assert converged["tau"] is None
    tau = tr.tau[-2000:]
    assert np.nanmax(tau) / np.nanmin(tau) > 1.5
