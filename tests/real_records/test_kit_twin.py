"""The two-heater twin: fitted to real kits, equal to ``tclab``'s model on the published constants.

* On the held-out real records the fitted constants (:data:`KIT_FIT`) follow
  each sensor within :data:`HELD_OUT_RMS` and, over the held-out records, within
  :data:`PEER_RATIO` of the published constants' error (data-driven: a new
  fit that generalises worse fails here).
* With the published constants, :func:`simulate_kit` is the ``tclab``
  package's ``TCLabModel`` within :data:`TCLAB_TOL` over a scripted
  two-heater sequence (``tclab`` steps Euler 0.2 s; we step exactly).
* A reading lies on the kit's converter grid.
"""

from __future__ import annotations

import contextlib
import io
import math
import random
import sys
from pathlib import Path

import numpy as np
import pytest
import tclab

sys.path.insert(0, str(Path(__file__).parent))

import kit_records

from thermolab.kit_physics import KIT_FIT, KitConstants, KitPhysics, simulate_kit
from thermolab.tclab import TCLabModel

HELD_OUT_RMS = 7.0
"""°C: the fitted twin's RMS error on each sensor of each held-out record (measured:
2.2 and 4.0 on ``kantor_step01``, 6.1 and 2.7 on ``apm_hybrid_mimo_data``)."""
PEER_RATIO = 1.25
"""The fitted twin's RMS over the held-out records at most this times the published
constants' (measured: 1.06 on T1, 1.10 on T2; the kits differ more than the constants)."""
TCLAB_TOL = 0.03
"""°C: our exact steps against ``tclab``'s Euler steps of 0.2 s (measured: 0.015 at most,
on T1 after heater 1's step to 80 %)."""

needs_records = pytest.mark.skipif(
    not kit_records.SHARED.is_dir(),
    reason=f"the real-record corpus is absent ({kit_records.SHARED}; CI checks out ../shared)",
)


def _tclab_run(t: np.ndarray, q1: np.ndarray, q2: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``tclab.TCLabModel`` on its own clock (``synced=False``): each row, update, read, write."""
    with contextlib.redirect_stdout(io.StringIO()):
        lab = tclab.TCLabModel(synced=False)
    T1, T2 = np.empty(t.size), np.empty(t.size)
    for i, now in enumerate(t):
        lab.update(float(now))
        T1[i], T2[i] = lab._T1, lab._T2  # before the converter: the physics alone
        lab.Q1(float(q1[i]))
        lab.Q2(float(q2[i]))
    return T1, T2


def _script() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """20 minutes of both heaters stepping, with a notebook's 1 s sampling and its jitter."""
    rng = np.random.default_rng(5)
    t = np.cumsum(np.r_[0.0, 1.0 + rng.uniform(-0.05, 0.3, 1199)])
    q1 = np.select([t < 10, t < 400, t < 800], [0.0, 80.0, 20.0], 0.0)
    q2 = np.select([t < 200, t < 600, t < 1000], [0.0, 60.0, 100.0], 0.0)
    return t, q1, q2


@needs_records
def test_the_fitted_twin_follows_the_held_out_real_records() -> None:
    held_out = kit_records.records(held_out=True)
    assert {r.heaters for r in held_out} == {1, 2}  # one record of each kind
    ours, peer = [], []
    for record in held_out:
        fitted = kit_records.score(record, KIT_FIT)
        published = kit_records.score(record, KitConstants())
        assert fitted.T1 <= HELD_OUT_RMS, record.spec.name
        assert fitted.T2 <= HELD_OUT_RMS, record.spec.name
        ours.append((fitted.T1, fitted.T2))
        peer.append((published.T1, published.T2))
    rms = np.sqrt(np.mean(np.square(ours), axis=0))
    rms_peer = np.sqrt(np.mean(np.square(peer), axis=0))
    assert np.all(rms <= PEER_RATIO * rms_peer), (rms, rms_peer)


@needs_records
def test_the_fitted_constants_fit_the_fitting_records_better_than_the_published() -> None:
    fitting = kit_records.records(held_out=False)
    assert {r.heaters for r in fitting} == {1, 2}
    assert kit_records.cost(fitting, KIT_FIT) < 0.6 * kit_records.cost(fitting, KitConstants())


def test_the_published_constants_are_tclabs_model_over_two_heaters_steps() -> None:
    t, q1, q2 = _script()
    T1, T2 = simulate_kit(t, q1, q2, KitConstants(), ambient=21.0)
    theirs = _tclab_run(t, q1, q2)
    assert np.max(np.abs(T1 - theirs[0])) < TCLAB_TOL
    assert np.max(np.abs(T2 - theirs[1])) < TCLAB_TOL
    assert T1.max() > 50  # both heaters heated, well off the ambient
    assert T2.max() > 40


def test_the_twin_is_our_tclab_model_on_its_constants_and_steps_exactly() -> None:
    t, q1, q2 = _script()
    for constants in (KIT_FIT, KitConstants()):
        T1, T2 = simulate_kit(t, q1, q2, constants, ambient=constants.ambient)
        with contextlib.redirect_stdout(io.StringIO()):
            lab = TCLabModel(synced=False, constants=constants)
        kit = KitPhysics(constants)
        for k in range(300):  # the first 5 minutes: both heaters step in them
            assert kit.temperatures is not None
            assert kit.temperatures[2:] == pytest.approx((T1[k], T2[k]), abs=1e-9)
            lab.update(t[k])
            assert (lab._kit.temperatures or ())[2:] == pytest.approx((T1[k], T2[k]), abs=1e-9)
            lab.Q1(q1[k])
            lab.Q2(q2[k])
            kit.advance(t[k + 1] - t[k], q1=q1[k], q2=q2[k], p1=constants.p1, p2=constants.p2)
        lab.close()
    with pytest.raises(ValueError, match="never decrease"):
        simulate_kit([0.0, 2.0, 1.0], [0, 0, 0], [0, 0, 0])
    with pytest.raises(ValueError, match="one length"):
        simulate_kit([0.0, 1.0], [0.0], [0.0, 0.0])


def test_a_reading_lies_on_the_kits_converter_grid() -> None:
    t, q1, q2 = _script()
    quiet = simulate_kit(t, q1, q2)
    T1, T2 = simulate_kit(t, q1, q2, readings=True, seed=2)
    for read, true in ((T1, quiet[0]), (T2, quiet[1])):
        counts = read / KIT_FIT.quantum
        np.testing.assert_allclose(counts, np.round(counts), atol=1e-3)
        # Truncation to the count below: within one count under, and the noise's 5 sigma over.
        assert np.all(read - true <= 5 * KIT_FIT.noise + 1e-9)
        assert np.all(true - read <= KIT_FIT.quantum + 5 * KIT_FIT.noise)
    assert KIT_FIT.quantum == pytest.approx(3300 / 1024 / 10, abs=1e-4)  # 10 bits, 3.3 V, TMP36
    again = simulate_kit(t, q1, q2, readings=True, seed=2)
    np.testing.assert_array_equal(again[0], T1)
    assert math.isclose(KIT_FIT.noise, KitConstants().noise)
    assert random.Random(0).random() == random.Random(0).random()
