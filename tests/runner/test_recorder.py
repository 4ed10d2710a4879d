"""The CSV recorder: header, exact floats, rows visible at once, errors."""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np
import pytest

from thermolab.errors import InvalidParameterError
from thermolab.runner import CSV_COLUMNS, CsvRecorder


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
