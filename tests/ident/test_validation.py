"""The shared input checks: each error names the problem and what is allowed."""

from __future__ import annotations

import math

import numpy as np
import pytest
from numpy.testing import assert_array_equal

from thermolab.errors import InvalidDataError, InvalidParameterError
from thermolab.ident import ArxOrder
from thermolab.ident import _validation as v


def test_time_axis_must_be_strictly_increasing() -> None:
    assert_array_equal(v.check_time([0.0, 1.0, 2.5], 3), [0.0, 1.0, 2.5])
    with pytest.raises(InvalidDataError, match=r"strictly increasing: t\[2\] = 1.0 follows t\[1\]"):
        v.check_time([0.0, 1.0, 1.0])
    with pytest.raises(InvalidDataError, match=r"strictly increasing: t\[1\] = -1.0"):
        v.check_time([0.0, -1.0])
    with pytest.raises(InvalidDataError, match="one time per sample"):
        v.check_time([0.0, 1.0], 3)
    with pytest.raises(InvalidDataError, match="t must be finite"):
        v.check_time([0.0, math.nan])


def test_signals_report_the_first_bad_sample_and_the_count() -> None:
    with pytest.raises(InvalidDataError, match=r"y\[1\] is nan \(2 bad samples\)"):
        v.as_signal("y", [0.0, math.nan, math.inf])
    with pytest.raises(InvalidDataError, match="one-dimensional"):
        v.as_signal("u", np.zeros((2, 2)))


@pytest.mark.parametrize("dt", [0, -0.5, math.inf, math.nan, True, "1"])
def test_sample_period(dt: object) -> None:
    with pytest.raises(InvalidParameterError, match="dt"):
        v.check_dt(dt)


def test_order_forms() -> None:
    assert v.check_order(None) == ArxOrder()
    assert v.check_order((2, 1, 3)) == ArxOrder(2, 1, 3)
    assert v.check_order({"na": 2}) == ArxOrder(2, 1, 0)
    with pytest.raises(InvalidParameterError, match="order must be"):
        v.check_order("first")


def test_offset_forms() -> None:
    assert v.check_offset("fit") == "fit"
    assert v.check_offset(2) == 2.0
    with pytest.raises(InvalidParameterError, match="'initial', 'fit', 'none' or a number"):
        v.check_offset("zero")
    with pytest.raises(InvalidParameterError, match="real number"):
        v.check_offset(True)


def test_integers_and_unknown_parameters() -> None:
    assert v.integer("window", np.int64(5), 3, "x") == 5
    with pytest.raises(InvalidParameterError, match=r"window must be >= 3 \(why\), got 2"):
        v.integer("window", 2, 3, "why")
    with pytest.raises(InvalidParameterError, match="allowed: a, b"):
        v.check_known("m", {"c": 1}, ("a", "b"))
