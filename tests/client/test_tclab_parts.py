"""The parts of ``thermolab.tclab`` and ``thermolab.client`` that need no lab: clock, log, chart."""

from __future__ import annotations

import contextlib
import datetime
import itertools
import math
import sqlite3
import sys
import time
from pathlib import Path

import matplotlib
import numpy as np
import pytest

from thermolab.client import RunData
from thermolab.tclab import (
    Historian,
    LabTime,
    NoDatabaseError,
    Plotter,
    clock,
    labtime,
)

matplotlib.use("Agg")


@pytest.fixture
def fast_labtime() -> object:
    before = labtime.rate
    labtime.set_rate(50.0)  # a lab second is 20 ms
    yield labtime
    labtime.set_rate(before)


@pytest.mark.usefixtures("fast_labtime")
def test_clock_yields_every_step_up_to_the_period() -> None:
    ticks = list(clock(5))
    assert ticks[0] == 0.0
    # Never one time twice (the CBE 30338 PID chapters divide by t - t_prev), never early.
    assert all(b > a for a, b in itertools.pairwise(ticks))
    assert all(t >= k - 0.01 for k, t in enumerate(ticks)), ticks
    assert ticks[-1] <= 5.5
    # Adaptive (the default, as in tclab): a step woken late (a lab second is 20 ms here,
    # which a loaded machine can miss) is skipped, then lab time slows; a wake past the
    # period ends the loop, as in tclab (a CI machine stalled ~3 lab s: 0, 1, 2, then done).
    assert len(ticks) >= 2, ticks
    long_steps = list(clock(6, 2))
    assert long_steps[0] == 0.0
    assert all(b > a for a, b in itertools.pairwise(long_steps))
    assert all(t >= 2 * k - 0.01 for k, t in enumerate(long_steps)), long_steps
    assert len(long_steps) >= 2, long_steps


@pytest.mark.usefixtures("fast_labtime")
def test_a_slow_body_slows_lab_time_or_fails_beyond_its_tolerance() -> None:
    ticks = []
    for t in clock(8, 1):
        ticks.append(t)
        time.sleep(0.07)  # 3.5 lab seconds at 50x: the body takes three and a half steps
    # tclab's adaptive clock: the first overrun skips to the next step; lab time then slows
    # (to 80 % of what the body allows), so no later step is lost.
    # (A loaded machine may wake the body later still: a later first step, never a repeat.)
    rounded = [round(t) for t in ticks]
    assert rounded[0] == 0
    assert rounded[1] >= 4, ticks
    assert all(b > a for a, b in itertools.pairwise(ticks))
    assert rounded[-1] in (7, 8), ticks
    assert labtime.get_rate() < 50.0 * 0.8 / 3.5 * 1.25 + 1e-9

    def too_slow() -> None:
        for _ in clock(20, 1, tol=0.5, adaptive=False):
            labtime.sleep(2.0)

    with pytest.raises(RuntimeError, match=r"step is 1 s but 2\.\d\d s passed .*tol = 0\.5 s"):
        too_slow()
    # Not adaptive: steps missed by the body are skipped, the loop ends at the period.
    skipped = []
    for t in clock(12, 1, adaptive=False):
        skipped.append(t)
        labtime.sleep(2.5)
    assert 4 <= len(skipped) <= 6
    assert round(skipped[-1]) <= 12
    with pytest.raises(ValueError, match="positive"):
        next(clock(5, 0))


@pytest.mark.usefixtures("fast_labtime")
def test_the_clock_never_yields_one_time_twice(monkeypatch: pytest.MonkeyPatch) -> None:
    # A timer that wakes a hair early (a loaded machine) must not give a step again: a PID
    # dividing by t - t_prev would divide by zero (tclab's own clock does that).
    real = labtime.sleep
    monkeypatch.setattr(labtime, "sleep", lambda delay: real(max(delay - 0.004, 0.0)))
    ticks = list(clock(6, 1))
    assert ticks == sorted(set(ticks))  # never one time twice, never back
    assert ticks[0] == 0.0
    # No step early, however early the timer wakes. (Late is allowed: at 50x a lab second
    # is 20 ms, and a busy CI machine woke one 0.6 lab s late, which rounds to the next.)
    assert all(t >= k - 0.01 for k, t in enumerate(ticks[:6]))


def test_a_lab_twins_clock_never_runs_ahead_of_the_twin(monkeypatch: pytest.MonkeyPatch) -> None:
    labtime.hold(50.0, "rig 'kit' of the lab at http://lab runs at 50x")
    try:
        real = labtime.sleep
        monkeypatch.setattr(labtime, "sleep", lambda delay: real(max(delay - 0.3, 0.0)))
        start = labtime.time()
        seen = [(t, labtime.time() - start) for t in clock(5, 1)]
    finally:
        labtime.hold(1.0, None)
        labtime.set_rate(1.0)
    assert len(seen) == 6
    assert all(now >= k for k, (_, now) in enumerate(seen))  # a step waits for its time
    assert all(abs(t - now) < 0.5 for t, now in seen)  # and gives the twin's time


def test_labtime_pauses_and_refuses_a_bad_rate() -> None:
    lab = LabTime()
    lab.stop()
    frozen = lab.time()
    assert lab.time() == frozen
    assert not lab.running
    lab.start()
    lab.reset(100.0)
    assert 100.0 <= lab.time() < 101.0
    with pytest.raises(ValueError, match="positive finite"):
        lab.set_rate(0.0)


def test_historian_logs_named_sources_and_writes_csv(tmp_path: Path) -> None:
    values = iter(range(100))
    h = Historian([("T1", lambda: next(values)), ("Q1", lambda: 50.0)])
    for t in (0.0, 1.0, 2.0):
        h.update(t)
    assert h.logdict == {"Time": [0.0, 1.0, 2.0], "T1": [0.0, 1.0, 2.0], "Q1": [50.0] * 3}
    assert h.after(1.0, ["T1"]) == [[1.0, 2.0]]  # columns, as tclab's after()
    assert h.after(1.5) == [[1.0, 2.0], [1.0, 2.0], [50.0, 50.0]]  # from the row in force
    assert h.t == [0.0, 1.0, 2.0]
    with pytest.raises(KeyError, match="no column 'T2'"):
        h.at(1.0, ["T2"])
    assert h.at(-1.0) == [0.0, 0.0, 50.0]  # before the start: the first row, as in tclab
    assert Historian([("T1", lambda: 1.0)]).get_sessions()[0][::2] == (1, 0)  # in memory
    with pytest.raises(ValueError, match="nothing logged yet"):
        Historian([("T1", lambda: 1.0)]).at(0.0)
    h.to_csv(tmp_path / "log.csv")
    # Values as the sources give them (an int stays an int), as in tclab.
    assert (tmp_path / "log.csv").read_text().splitlines()[:2] == ["Time,T1,Q1", "0.0,0,50.0"]
    with pytest.raises(NoDatabaseError, match="has no database"):
        Historian([("T1", lambda: 1.0)], dbfile=None).get_sessions()
    with pytest.raises(ValueError, match="distinct"):
        Historian([("T1", lambda: 0.0), ("T1", lambda: 1.0)])


def test_historian_logs_sessions_to_an_sqlite_file(tmp_path: Path) -> None:
    db = tmp_path / "log.db"
    values = iter([20.0, 21.0, 22.5, math.nan, 30.0])
    sources = [("T1", lambda: next(values)), ("Q1", lambda: 50.0)]
    first = Historian(sources, dbfile=db)
    for t in (0.0, 1.0, 2.0):
        first.update(t)
    first.new_session()  # a new session starts empty
    assert first.log == []
    first.update(0.0)
    first.close()
    # Another historian on the file (a later notebook) is a third session and sees them all.
    later = Historian(sources, dbfile=str(db))
    sessions = later.get_sessions()
    assert [(i, n) for i, _, n in sessions] == [(1, 3), (2, 1), (3, 0)]
    started = datetime.datetime.fromisoformat(sessions[0][1])
    assert abs(datetime.datetime.now(datetime.UTC) - started) < datetime.timedelta(minutes=5)
    later.load_session(1)
    assert later.logdict == {"Time": [0.0, 1.0, 2.0], "T1": [20.0, 21.0, 22.5], "Q1": [50.0] * 3}
    later.load_session(2)
    assert later.columns == ["Time", "T1", "Q1"]
    assert math.isnan(later.log[0][1])  # NaN comes back as NaN
    later.update(1.0)  # logging goes on into the loaded session
    assert later.get_sessions()[1][2] == 2
    # The file is plain SQL: one value per time and tag (Time is the key, not a tag).
    with contextlib.closing(sqlite3.connect(db)) as plain:
        (count,) = plain.execute("SELECT COUNT(*) FROM log WHERE session = 1").fetchone()
        names = plain.execute("SELECT DISTINCT name FROM log ORDER BY name").fetchall()
    assert count == 6
    assert names == [("Q1",), ("T1",)]
    with pytest.raises(ValueError, match=r"no session 7 .*sessions: \[1, 2, 3\]"):
        later.load_session(7)
    # A session of other sources can be read, not logged into by these.
    Historian([("T2", lambda: 1.0)], dbfile=db).update(0.0)
    later.load_session(4)
    assert later.logdict == {"Time": [0.0], "T2": [1.0]}
    with pytest.raises(ValueError, match=r"logs \['Time', 'T2'\]"):
        later.update(1.0)
    later.close()
    with pytest.raises(NotImplementedError, match="closed its database"):
        later.get_sessions()
    with pytest.raises(ValueError, match="cannot log to"):
        Historian(sources, dbfile=tmp_path / "missing" / "log.db")


def test_historian_in_an_sqlite_database_in_memory() -> None:
    h = Historian([("T1", lambda: 21.0)], dbfile=":memory:")
    h.update(0.0)
    assert h.get_sessions()[0][::2] == (1, 1)


def test_plotter_updates_its_historian_and_draws_the_window() -> None:
    h = Historian([("T1", lambda: 21.0), ("Q1", lambda: 40.0)])
    p = Plotter(h, twindow=10, layout=[("T1",), ("Q1",)])
    p.fps = 1e-3  # a loaded machine draws slowly: no redraw after the first in this test
    for t in range(3):
        p.update(float(t))
    # A redraw at most fps times a real second (3, as tclab's): quick rows wait in the log.
    assert p.axes[0].get_xlim() == (0.0, 10.0)
    assert len(p.lines["Q1"].get_ydata()) == 1
    p.fps = math.inf
    for t in range(3, 15):
        p.update(float(t))
    assert len(h.log) == 15
    assert p.axes[0].get_xlim() == (4.0, 14.0)
    assert list(p.lines["Q1"].get_ydata()) == [40.0] * 15


def test_run_data_without_pandas_says_how_to_get_it(monkeypatch: pytest.MonkeyPatch) -> None:
    data = RunData.from_export(
        {
            "run": {"id": 3},
            "channels": [{"name": n, "unit": u} for n, u in (("t", "s"), ("u", "V"), ("y", "V"))],
            "samples": {"t": [0, 1], "u": [0, 5], "y": [0.0, None]},
            "methods": {},
        }
    )
    assert np.isnan(data.y[1])
    assert data.units == {"t": "s", "u": "V", "y": "V"}
    with pytest.raises(KeyError, match="has no channel 'r'"):
        data["r"]
    monkeypatch.setitem(sys.modules, "pandas", None)
    with pytest.raises(ImportError, match="pip install pandas"):
        data.to_pandas()
