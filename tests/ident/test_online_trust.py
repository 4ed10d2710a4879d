"""Online identifiers take the batch functions' defaults (offset "auto", the dead time search)."""

from __future__ import annotations

import json
import warnings

import numpy as np
import pytest

from thermolab.ident import (
    block_least_squares,
    least_squares,
    make_identifier,
    moving_window_least_squares,
    output_error,
    weighted_least_squares,
)
from thermolab.ident.online import OnlineIdentifier
from thermolab.simulation import REFERENCE_MODEL, simulate_first_order

K, TAU = REFERENCE_MODEL.K, REFERENCE_MODEL.tau


def _feed(ident: OnlineIdentifier, u: np.ndarray, y: np.ndarray) -> list[object]:
    return [ident.update(float(a), float(b)) for a, b in zip(u, y, strict=True)]


def _settled() -> tuple[np.ndarray, np.ndarray]:
    """Settled under 5 V (ambient 1 V), then a step to 8 V at sample 200."""
    u = np.where(np.arange(600) < 200, 5.0, 8.0)
    return u, REFERENCE_MODEL.simulate(u, y0=1.0 + K * 5.0, ambient=1.0)


def test_online_lsm_searches_the_dead_time_and_decides_the_operating_point_like_batch() -> None:
    u = np.where(np.arange(1500) < 100, 2.0, 6.0)
    y = simulate_first_order(u, 0.6, 140.0, 1.0, theta=12.0, ambient=21.0, y0=21.0 + 1.2)
    ident = make_identifier("lsm", 1.0)
    assert ident.params["order"] is None  # searched at END
    _feed(ident, u, y)
    est = ident.finish()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        batch = least_squares(u, y, 1.0)
    assert est is not None
    assert est.valid
    assert (est.K, est.tau) == (batch.K, batch.tau)
    assert est.extras["theta"] == pytest.approx(12.0)
    assert est.extras["operating_point"]["handling"] == "fit"
    assert est.extras["trusted"] is batch.trusted
    d = est.to_dict()
    assert json.loads(json.dumps(d, allow_nan=False)) == d
    assert ident.trajectory().order.delay == 12


@pytest.mark.parametrize(
    ("method", "batch"),
    [("malsm", moving_window_least_squares), ("wlsm", weighted_least_squares)],
)
def test_recursive_auto_fits_the_constant_from_the_first_input_change(
    method: str, batch: object
) -> None:
    u, y = _settled()
    ident = make_identifier(method, 1.0)
    live = _feed(ident, u, y)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        fitted = batch(u, y, 1.0, offset="fit")  # type: ignore[operator]
        auto = batch(u, y, 1.0)  # type: ignore[operator]
    assert auto.offset == "fit"
    # From the input change on, the live estimates are the constant-term ones.
    after = live[250]
    assert after is not None
    assert len(after.W) == 3
    np.testing.assert_array_equal(np.asarray(after.W), fitted.W[250])
    est = ident.finish()
    assert est is not None
    # MALSM's last windows hold a constant input, which cannot separate the
    # constant term from the gain: not excited, in batch as online.
    assert est.valid is auto.final.valid is (method == "wlsm")
    if est.valid:
        assert pytest.approx(K, rel=1e-6) == est.K
        assert est.tau == pytest.approx(TAU, rel=1e-6)
    assert est.extras["operating_point"]["handling"] == "fit"
    assert est.extras["offset"] == "fit"
    np.testing.assert_array_equal(ident.trajectory().W, auto.W)


@pytest.mark.parametrize("method", ["malsm", "wlsm", "blockls"])
def test_a_record_from_rest_keeps_the_papers_handling_and_equals_batch(method: str) -> None:
    u = np.where((np.arange(1000) // 5) % 2 == 0, 4.0, 0.0)
    y = REFERENCE_MODEL.simulate(u)
    batch = {
        "malsm": moving_window_least_squares,
        "wlsm": weighted_least_squares,
        "blockls": block_least_squares,
    }[method]
    ident = make_identifier(method, 1.0)
    _feed(ident, u, y)
    before_end = ident.trajectory()
    est = ident.finish()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        auto = batch(u, y, 1.0)
    assert auto.offset == "initial"
    np.testing.assert_array_equal(before_end.W, auto.W)
    assert est is not None
    assert est.extras["trusted"] is True
    assert est.extras["warnings"] == []


def test_an_estimate_not_to_be_trusted_says_so() -> None:
    u = np.where((np.arange(1000) // 50) % 2 == 0, 4.0, 0.0)
    y = REFERENCE_MODEL.simulate(u)
    for method in ("lsm", "blockls", "malsm", "wlsm", "oe"):
        ident = make_identifier(method, 1.0, expected_sign=-1)
        _feed(ident, u, y)
        est = ident.finish()
        assert est is not None
        assert est.extras["trusted"] is False, method
        assert any("implausible gain" in w for w in est.extras["warnings"]), method


def test_online_oe_equals_the_batch_fit() -> None:
    u = np.where(np.arange(800) < 50, 0.0, 40.0)
    y = simulate_first_order(u, 0.6, 140.0, 1.0, theta=15.5, ambient=21.0)
    ident = make_identifier("oe", 1.0)
    assert _feed(ident, u, y)[-1] is None  # at END only
    est = ident.finish()
    batch = output_error(u, y, 1.0)
    assert est is not None
    assert (est.K, est.tau, est.extras["theta"]) == (batch.K, batch.tau, batch.theta)
    assert est.extras["theta"] == pytest.approx(15.5, rel=0.02)
    assert est.extras["trusted"] is batch.trusted


def test_no_public_name_is_shadowed_by_a_submodule() -> None:
    import importlib
    import pkgutil
    import types

    import thermolab.ident as package

    for info in pkgutil.iter_modules(package.__path__):
        importlib.import_module(f"thermolab.ident.{info.name}")
    for name in package.__all__:
        assert not isinstance(getattr(package, name), types.ModuleType), name
