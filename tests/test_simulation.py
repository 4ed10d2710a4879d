"""The exact simulation of eq. 4 and of general ARX models."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from numpy.testing import assert_allclose

from thermolab.errors import InvalidDataError, InvalidParameterError
from thermolab.simulation import (
    PAPER_W0,
    REFERENCE_MODEL,
    FirstOrderPlant,
    simulate_arx,
    simulate_first_order,
)


def _loop_first_order(u: np.ndarray, K: float, tau: float, dt: float, y0: float, c: float):
    a = math.exp(-dt / tau)
    b = (1.0 - a) * K
    y = np.empty(u.size)
    y[0] = y0
    for k in range(u.size - 1):
        y[k + 1] = c + a * (y[k] - c) + b * u[k]
    return y


def test_reference_model_is_the_papers() -> None:
    assert REFERENCE_MODEL.K == 0.140090
    assert REFERENCE_MODEL.tau == 250.126233
    assert REFERENCE_MODEL.dt == 1.0
    assert PAPER_W0 == (0.96329, 9.9082e-4)
    a, b = REFERENCE_MODEL.w
    assert_allclose(a, math.exp(-1.0 / 250.126233), rtol=1e-15)
    assert_allclose(b / (1.0 - a), 0.140090, rtol=1e-12)


def test_step_matches_closed_form() -> None:
    k = np.arange(2001)
    y = simulate_first_order(np.full(k.size, 10.0), 0.140090, 250.126233, 1.0)
    expected = 10.0 * 0.140090 * -np.expm1(-k / 250.126233)
    assert_allclose(y, expected, rtol=1e-12, atol=1e-15)


@settings(max_examples=40, deadline=None)
@given(
    K=st.floats(-5, 5).filter(lambda v: abs(v) > 1e-3),
    tau=st.floats(0.05, 1e4),
    dt=st.floats(0.01, 10.0),
    y0=st.floats(-10, 10),
    ambient=st.floats(-10, 10),
    seed=st.integers(0, 2**16),
)
def test_equals_the_recursion(
    K: float, tau: float, dt: float, y0: float, ambient: float, seed: int
) -> None:
    u = np.random.default_rng(seed).uniform(-10, 10, size=200)
    y = simulate_first_order(u, K, tau, dt, y0=y0, ambient=ambient)
    assert_allclose(y, _loop_first_order(u, K, tau, dt, y0, ambient), rtol=1e-10, atol=1e-10)


def test_default_start_is_rest_at_ambient() -> None:
    y = simulate_first_order(np.zeros(50), 0.14, 250.0, 1.0, ambient=3.0)
    assert_allclose(y, 3.0, rtol=0, atol=0)
    y = simulate_first_order(np.zeros(3), 1.0, 1.0, 1.0, y0=1.0)
    assert_allclose(y, [1.0, math.exp(-1), math.exp(-2)], rtol=1e-14)


def test_output_length_and_last_input_unused() -> None:
    y1 = simulate_first_order([1.0, 2.0, 3.0], 1.0, 5.0, 1.0)
    y2 = simulate_first_order([1.0, 2.0, -7.0], 1.0, 5.0, 1.0)
    assert y1.shape == (3,)
    assert_allclose(y1, y2, rtol=0, atol=0)
    assert simulate_first_order([4.0], 1.0, 5.0, 1.0, y0=0.5).tolist() == [0.5]


def test_plant_simulate_delegates() -> None:
    u = np.linspace(0, 10, 30)
    plant = FirstOrderPlant(K=0.5, tau=7.0, dt=0.5)
    assert_allclose(
        plant.simulate(u, ambient=1.0), simulate_first_order(u, 0.5, 7.0, 0.5, ambient=1.0)
    )


@settings(max_examples=30, deadline=None)
@given(
    K=st.floats(0.01, 5),
    tau=st.floats(0.5, 500),
    y0=st.floats(-5, 5),
    ambient=st.floats(-5, 5),
    seed=st.integers(0, 1000),
)
def test_arx_first_order_equals_eq4(
    K: float, tau: float, y0: float, ambient: float, seed: int
) -> None:
    u = np.random.default_rng(seed).uniform(-10, 10, size=120)
    plant = FirstOrderPlant(K=K, tau=tau, dt=1.0)
    assert_allclose(
        simulate_arx(u, [plant.a], [plant.b], y0=y0, ambient=ambient),
        plant.simulate(u, y0=y0, ambient=ambient),
        rtol=1e-10,
        atol=1e-10,
    )


def test_arx_general_order_against_loop() -> None:
    rng = np.random.default_rng(7)
    u = rng.uniform(-1, 1, size=60)
    a, b, delay, y0, c = [1.2, -0.35], [0.5, 0.25, -0.1], 3, 0.7, 0.2
    y = np.full(u.size + 10, y0 - c)  # index shift 10 holds the history y[k<=0]
    for k in range(1, u.size):
        acc = sum(a[i] * y[10 + k - 1 - i] for i in range(2))
        acc += sum(b[j] * (u[k - delay - j] if k - delay - j >= 0 else 0.0) for j in range(3))
        y[10 + k] = acc
    expected = y[10:] + c
    # `delay` counts the dead time beyond the natural one-sample delay of the loop above.
    assert_allclose(simulate_arx(u, a, b, delay=delay - 1, y0=y0, ambient=c), expected, rtol=1e-12)


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"K": 0.0}, "K .*non-zero"),
        ({"K": math.nan}, "K must be finite"),
        ({"tau": 0.0}, "tau .*> 0"),
        ({"tau": -3.0}, "tau .*> 0"),
        ({"dt": 0.0}, "dt .*> 0"),
        ({"dt": math.inf}, "dt must be finite"),
        ({"y0": math.nan}, "y0 must be finite"),
        ({"ambient": math.inf}, "ambient must be finite"),
    ],
)
def test_bad_parameters(kwargs: dict[str, float], match: str) -> None:
    args = {"K": 1.0, "tau": 10.0, "dt": 1.0} | kwargs
    y0 = args.pop("y0", None)
    ambient = args.pop("ambient", 0.0)
    with pytest.raises(InvalidParameterError, match=match):
        simulate_first_order([1.0, 2.0], args["K"], args["tau"], args["dt"], y0=y0, ambient=ambient)


@pytest.mark.parametrize(
    ("u", "match"),
    [
        ([], "empty"),
        ([[1.0, 2.0]], "one-dimensional"),
        ([1.0, math.nan], r"u\[1\] is nan"),
        (["a", "b"], "array of numbers"),
    ],
)
def test_bad_input(u: object, match: str) -> None:
    with pytest.raises(InvalidDataError, match=match):
        simulate_first_order(u, 1.0, 10.0, 1.0)  # type: ignore[arg-type]


def test_arx_bad_parameters() -> None:
    with pytest.raises(InvalidParameterError, match="delay must be an integer >= 0"):
        simulate_arx([1.0], [0.5], [1.0], delay=-1)
    with pytest.raises(InvalidParameterError, match="at least one input coefficient"):
        simulate_arx([1.0], [0.5], [])
    with pytest.raises(InvalidParameterError, match=r"a\[1\] must be finite"):
        simulate_arx([1.0], [0.5, math.nan], [1.0])


def test_plant_validates() -> None:
    with pytest.raises(InvalidParameterError, match="tau"):
        FirstOrderPlant(K=1.0, tau=-1.0, dt=1.0)
