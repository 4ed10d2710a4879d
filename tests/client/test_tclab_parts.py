"""The parts of ``thermolab.tclab`` and ``thermolab.client`` that need no lab: clock, log, chart."""

from __future__ import annotations

import contextlib
import datetime
import math
import sqlite3
import sys
from pathlib import Path

import matplotlib
import numpy as np
import pytest

from thermolab.client import RunData
from thermolab.tclab import Historian, LabTime, Plotter, clock, labtime, speedup_note

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
    assert ticks == sorted(ticks)
    assert 3 <= len(ticks) <= 6  # 6 on time; a step overslept on a busy machine is skipped
    assert 4.0 <= ticks[-1] < 7.0
    assert 2 <= len(list(clock(6, 2))) <= 4


@pytest.mark.usefixtures("fast_labtime")
def test_a_slow_body_skips_steps_or_fails_beyond_its_tolerance() -> None:
    ticks = []
    for t in clock(20, 1):
        ticks.append(t)
        labtime.sleep(3.5)  # the body takes three and a half steps
    assert 4 <= len(ticks) <= 7  # the loop still ends at 20 lab seconds
    assert ticks[-1] <= 24.0

    def too_slow() -> None:
        for _ in clock(20, 1, tol=0.5):
            labtime.sleep(2.0)

    with pytest.raises(RuntimeError, match="late"):
        too_slow()
    with pytest.raises(ValueError, match="positive"):
        next(clock(5, 0))


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
    assert h.after(1.0, ["T1"]) == [[1.0], [2.0]]
    assert h.t == [0.0, 1.0, 2.0]
    with pytest.raises(KeyError, match="no column 'T2'"):
        h.at(1.0, ["T2"])
    with pytest.raises(ValueError, match="nothing logged"):
        h.at(-1.0)
    h.to_csv(tmp_path / "log.csv")
    assert (tmp_path / "log.csv").read_text().splitlines()[:2] == ["Time,T1,Q1", "0.0,0.0,50.0"]
    with pytest.raises(ValueError, match="has no dbfile"):
        h.get_sessions()
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
    # The file is plain SQL: one value per row and column.
    with contextlib.closing(sqlite3.connect(db)) as plain:
        (count,) = plain.execute("SELECT COUNT(*) FROM log WHERE session = 1").fetchone()
    assert count == 9
    with pytest.raises(ValueError, match=r"no session 7 .*sessions: \[1, 2, 3\]"):
        later.load_session(7)
    # A session of other sources can be read, not logged into by these.
    Historian([("T2", lambda: 1.0)], dbfile=db).update(0.0)
    later.load_session(4)
    assert later.logdict == {"Time": [0.0], "T2": [1.0]}
    with pytest.raises(ValueError, match=r"logs \['Time', 'T2'\]"):
        later.update(1.0)
    later.close()
    with pytest.raises(ValueError, match="was closed"):
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
    for t in range(15):
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


def test_the_speedup_note_says_which_is_in_force_and_why() -> None:
    assert speedup_note(50, 50) is None
    note = speedup_note(1, 200)
    assert note is not None
    assert note.startswith("note: the lab's twin runs at 200x real time, not the real time (1x)")
    assert "a client cannot change it" in note
    assert "a teacher sets each twin's speed-up in the rig's settings" in note
    assert note.endswith("clock() and labtime follow 200x")
