"""The CSV recorder: header, exact floats, rows visible at once, errors."""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np
import pytest

from thermolab.errors import InvalidParameterError
from thermolab.records import REQUIRED, RUN_CHANNELS, ChannelSpec, channel_names, read_record
from thermolab.runner import CSV_COLUMNS, CsvRecorder, Experiment, SampleEvent

from .conftest import HookedTwin


def test_columns_start_with_t_u_y() -> None:
    assert CSV_COLUMNS[:3] == ("t", "u", "y")


@pytest.mark.parametrize("fsync", [False, True])
def test_every_row_is_readable_before_close_and_floats_round_trip(
    tmp_path: Path, fsync: bool
) -> None:
    path = tmp_path / "run.csv"
    rec = CsvRecorder(path, fsync=fsync)
    rec.open()
    rng = np.random.default_rng(1)
    values = rng.normal(size=(50, 3))
    for k, (u, y, j) in enumerate(values):
        # NumPy scalars must be written as plain numbers.
        rec.write(k, k * 0.1, np.float64(u), float(y), k * 0.1 + j, float(j), 0.0)
        with path.open(newline="") as f:
            rows = list(csv.reader(f))
        assert rows[0] == list(CSV_COLUMNS)
        assert len(rows) == k + 2
    rec.close()
    rec.close()  # idempotent
    with path.open(newline="") as f:
        rows = list(csv.DictReader(f))
    assert [float(r["u"]) for r in rows] == values[:, 0].tolist()
    assert [float(r["y"]) for r in rows] == values[:, 1].tolist()
    assert rows[3]["t"] == "0.3"  # k * dt is written rounded, not 0.30000000000000004
    assert rec.rows == 50


def test_unwritable_path_is_a_clear_error(tmp_path: Path) -> None:
    rec = CsvRecorder(tmp_path / "missing" / "run.csv")
    with pytest.raises(InvalidParameterError, match="cannot write the record"):
        rec.open()


def test_write_before_open_is_refused(tmp_path: Path) -> None:
    with pytest.raises(RuntimeError, match="not open"):
        CsvRecorder(tmp_path / "x.csv").write(0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0)


# --- named channels ------------------------------------------------------------------------

SETPOINT = ChannelSpec("r", "V", "setpoint", "set point")
ERROR = ChannelSpec("e", "V", "error", "set point minus output")


def test_extra_channels_reach_the_record_the_events_and_the_result(
    twin: HookedTwin, tmp_path: Path
) -> None:
    path = tmp_path / "run.csv"

    def setpoint(t: float, u: float, y: float) -> float:
        return 1.0 if t < 50 else 1.2

    def error(t: float, u: float, y: float) -> float:
        return setpoint(t, u, y) - y

    recorder = CsvRecorder(path, channels=(*RUN_CHANNELS, SETPOINT, ERROR), comments=["rig: twin"])
    exp = Experiment(
        twin,
        1.0,
        100,
        set_point=10.0,
        sources=[(SETPOINT, setpoint), (ERROR, error)],
        recorder=recorder,
    )
    sub = exp.events.subscribe(maxsize=10_000)
    result = exp.run()
    samples = [e for e in sub.drain() if isinstance(e, SampleEvent)]
    assert list(samples[60].channels())[7:] == ["r", "e"]
    assert samples[60].extra == {"r": 1.2, "e": 1.2 - samples[60].y}
    assert samples[60].to_dict()["extra"] == {"r": 1.2, "e": 1.2 - samples[60].y}
    assert tuple(samples[0].channels()) == channel_names(exp.channels)
    np.testing.assert_array_equal(result.extra["e"], np.where(result.t < 50, 1.0, 1.2) - result.y)
    assert [c["name"] for c in result.to_dict()["channels"]][7:] == ["r", "e"]
    back = read_record(path, known=[SETPOINT, ERROR])
    assert back.channels == exp.channels
    assert back.comments == ("rig: twin",)
    np.testing.assert_array_equal(back.y, result.y)
    np.testing.assert_array_equal(back["e"], result.extra["e"])
    np.testing.assert_array_equal(back["k"], np.arange(100))


def test_a_recorder_must_declare_the_runs_channels(twin: HookedTwin, tmp_path: Path) -> None:
    with pytest.raises(InvalidParameterError, match="give the recorder channels="):
        Experiment(
            twin,
            1.0,
            10,
            set_point=1.0,
            sources=[(SETPOINT, lambda t, u, y: 1.0)],
            recorder=CsvRecorder(tmp_path / "x.csv"),
        )


@pytest.mark.parametrize("name", ["y", "jitter", "r"])
def test_extra_channel_names_are_unique(twin: HookedTwin, name: str) -> None:
    spec = ChannelSpec(name)
    with pytest.raises(InvalidParameterError, match=f"extra channel '{name}' is taken"):
        Experiment(
            twin,
            1.0,
            10,
            set_point=1.0,
            sources=[(spec, lambda t, u, y: 1.0), (SETPOINT, lambda t, u, y: 1.0)],
        )


def test_a_recorder_refuses_channels_that_do_not_start_with_the_runs() -> None:
    with pytest.raises(InvalidParameterError, match="starts with the channels t,u,y,k"):
        CsvRecorder("x.csv", channels=(*REQUIRED, SETPOINT))
