"""W <-> (K, tau): the first-order model, ARX models and the vectorised conversion."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from numpy.testing import assert_allclose

from thermolab.errors import InvalidParameterError
from thermolab.ident import (
    INVALID_REASONS,
    ArxModel,
    ArxOrder,
    FirstOrderModel,
    discrete_to_first_order,
)


def test_round_trip_of_the_reference_model() -> None:
    a, b = FirstOrderModel(0.140090, 250.126233).to_discrete(1.0)
    assert_allclose(a, math.exp(-1 / 250.126233), rtol=1e-15)
    back = FirstOrderModel.from_discrete(a, b, 1.0)
    assert back.valid
    assert_allclose([back.K, back.tau], [0.140090, 250.126233], rtol=1e-12)


@pytest.mark.parametrize(
    ("a", "fragment"),
    [
        (1.003, "a = 1.003 >= 1: the identified model is unstable or integrating"),
        (1.0, "a = 1 >= 1"),
        (0.0, "a = 0 <= 0"),
        (-0.4, "a = -0.4 <= 0"),
        (math.nan, "not finite"),
        (math.inf, "not finite"),
    ],
)
def test_from_discrete_says_why_there_is_no_time_constant(a: float, fragment: str) -> None:
    m = FirstOrderModel.from_discrete(a, 0.01, 1.0)
    assert not m.valid
    assert math.isnan(m.K)
    assert math.isnan(m.tau)
    assert m.reason is not None
    assert fragment in m.reason
    with pytest.raises(InvalidParameterError, match="no discretisation"):
        m.to_discrete(1.0)
    assert m.to_dict()["K"] is None


@pytest.mark.parametrize(
    ("kwargs", "fragment"),
    [
        ({"K": 1.0, "tau": 0.0}, "tau"),
        ({"K": 1.0, "tau": -2.0}, "tau"),
        ({"K": math.inf, "tau": 2.0}, "K"),
        ({"K": "1", "tau": 2.0}, "real number"),
    ],
)
def test_first_order_model_refuses_bad_parameters(kwargs: dict[str, object], fragment: str) -> None:
    with pytest.raises(InvalidParameterError, match=fragment):
        FirstOrderModel(**kwargs)  # type: ignore[arg-type]


@pytest.mark.parametrize("dt", [0.0, -1.0, math.nan, math.inf])
def test_conversions_refuse_a_bad_sample_period(dt: float) -> None:
    with pytest.raises(InvalidParameterError, match="dt"):
        FirstOrderModel(1.0, 10.0).to_discrete(dt)
    with pytest.raises(InvalidParameterError, match="dt"):
        FirstOrderModel.from_discrete(0.9, 0.1, dt)
    with pytest.raises(InvalidParameterError, match="dt"):
        discrete_to_first_order([[0.9, 0.1]], dt)


@pytest.mark.parametrize(
    ("args", "fragment"), [((0, 1, 0), "na"), ((1, 0, 0), "nb"), ((1, 1, -1), "delay")]
)
def test_arx_order_validation(args: tuple[int, int, int], fragment: str) -> None:
    with pytest.raises(InvalidParameterError, match=fragment):
        ArxOrder(*args)


def test_arx_order_lag_and_names() -> None:
    assert ArxOrder().lag == 0
    assert ArxOrder().is_first_order
    assert ArxOrder(3, 1, 0).lag == 2
    assert ArxOrder(1, 2, 2).lag == 3
    assert ArxOrder(2, 1).param_names(constant=True) == ("a1", "a2", "b1", "c")


def test_arx_model_dc_gain_dominant_pole_and_ambient() -> None:
    # (z - 0.8)(z - 0.3) = z^2 - 1.1 z + 0.24
    m = ArxModel(a=(1.1, -0.24), b=(0.05, 0.02), dt=0.5, c=0.14)
    assert_allclose(m.poles, [0.8, 0.3], rtol=1e-12)
    assert_allclose(m.K, 0.07 / 0.14, rtol=1e-12)
    assert_allclose(m.tau, -0.5 / math.log(0.8), rtol=1e-12)
    assert_allclose(m.ambient, 1.0, rtol=1e-12)


@pytest.mark.parametrize(
    ("a", "fragment"),
    [
        ((1.2, -0.1), "unstable"),  # poles 1.11, 0.09
        ((0.0, -0.25), "complex"),
        ((-0.5, 0.14), "<= 0"),  # poles -0.7, 0.2
    ],
)
def test_arx_model_without_a_time_constant(a: tuple[float, float], fragment: str) -> None:
    fo = ArxModel(a=a, b=(0.1,), dt=1.0).first_order()
    assert not fo.valid
    assert fo.reason is not None
    assert fragment in fo.reason


def test_vectorised_conversion_codes() -> None:
    W = np.array(
        [[0.9, 0.2], [1.0, 0.1], [1.5, 0.1], [-0.3, 0.1], [0.0, 0.1], [np.nan, np.nan], [np.inf, 1]]
    )
    K, tau, code = discrete_to_first_order(W, 1.0)
    assert code.tolist() == [0, 3, 3, 4, 4, 1, 6]
    assert_allclose(K[0], 2.0, rtol=1e-15)
    assert np.isnan(K[1:]).all()
    assert np.isnan(tau[1:]).all()
    assert INVALID_REASONS[0] is None
    assert all(isinstance(r, str) for r in INVALID_REASONS[1:])


@settings(max_examples=60, deadline=None)
@given(
    a=st.floats(-2.0, 2.0, allow_nan=False),
    b=st.floats(-5.0, 5.0, allow_nan=False),
    dt=st.floats(0.01, 100.0),
)
def test_vectorised_conversion_agrees_with_the_scalar_one(a: float, b: float, dt: float) -> None:
    m = FirstOrderModel.from_discrete(a, b, dt)
    K, tau, code = discrete_to_first_order([[a, b]], dt)
    assert (code[0] == 0) == m.valid
    if m.valid:
        assert_allclose([K[0], tau[0]], [m.K, m.tau], rtol=1e-14)


@settings(max_examples=40, deadline=None)
@given(
    p1=st.floats(0.05, 0.98),
    p2=st.floats(-0.9, 0.9),
    g=st.floats(0.1, 5.0),
)
def test_second_order_conversion_matches_the_model(p1: float, p2: float, g: float) -> None:
    """For a second-order W, the vectorised path equals ArxModel's (eigenvalues vs roots)."""
    a = (p1 + p2, -p1 * p2)
    b = (g * (1 - a[0] - a[1]), 0.0)
    fo = ArxModel(a=a, b=b, dt=1.0).first_order()
    K, tau, code = discrete_to_first_order([[*a, *b]], 1.0, ArxOrder(2, 2))
    assert (code[0] == 0) == fo.valid
    if fo.valid:
        assert_allclose([K[0], tau[0]], [fo.K, fo.tau], rtol=1e-9)
        assert_allclose(K[0], g, rtol=1e-9)
