"""Interlock settings and the watchdog thread."""

from __future__ import annotations

import math
import threading
import time

import pytest

from thermolab.errors import InvalidParameterError
from thermolab.rigs import RigInfo
from thermolab.runner import Interlocks, Watchdog

INFO = RigInfo("box", "twin", -10.0, 10.0, "V", "V", 0.0, None)


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"output_max": math.nan}, "output_max must be a finite number"),
        ({"output_min": math.inf}, "output_min must be a finite number"),
        ({"output_min": 5.0, "output_max": 5.0}, "must be below output_max"),
        ({"watchdog": 0.0}, "watchdog must be a positive number"),
        ({"watchdog": -1.0}, "watchdog must be a positive number"),
    ],
)
def test_invalid_settings_are_refused(kwargs: dict[str, float], match: str) -> None:
    with pytest.raises(InvalidParameterError, match=match):
        Interlocks(**kwargs)


@pytest.mark.parametrize(
    ("y", "expected"),
    [
        (1.0, None),
        (5.0, None),
        (5.01, "output 5.01 V is above the limit of 5 V"),
        (-2.5, "output -2.5 V is below the limit of -2 V"),
        (math.nan, "the sensor returned nan, not a number"),
        (math.inf, "the sensor returned inf, not a number"),
    ],
)
def test_output_window(y: float, expected: str | None) -> None:
    assert Interlocks(output_max=5.0, output_min=-2.0).check_output(y, "V") == expected


@pytest.mark.parametrize(
    ("u", "ok"), [(-10.0, True), (10.0, True), (10.000001, False), (math.nan, False)]
)
def test_input_range(u: float, ok: bool) -> None:
    problem = Interlocks.check_input(u, INFO)
    assert (problem is None) == ok
    if not ok:
        assert "outside the range of 'box': [-10, 10] V" in (problem or "")


def test_watchdog_trips_once_on_a_stall() -> None:
    trips: list[float] = []
    dog = Watchdog(0.05, trips.append)
    dog.start()
    assert dog.wait_tripped(5.0)
    time.sleep(0.1)
    dog.stop()
    assert len(trips) == 1
    assert trips[0] > 0.05


def test_watchdog_stays_quiet_while_beating_or_paused() -> None:
    tripped = threading.Event()
    dog = Watchdog(0.1, lambda stalled: tripped.set())
    dog.start()
    end = time.monotonic() + 0.4
    while time.monotonic() < end:  # beating well inside the timeout
        dog.beat()
        time.sleep(0.01)
    dog.pause()  # an intended wait longer than the timeout
    time.sleep(0.3)
    dog.resume()
    dog.stop()
    assert not tripped.is_set()
