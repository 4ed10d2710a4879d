"""thermolab.records: named channels, written and read back exactly, from any spreadsheet."""

from __future__ import annotations

import io
import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from numpy.testing import assert_allclose

from thermolab import records
from thermolab.errors import InvalidDataError, InvalidParameterError, RecordFormatError
from thermolab.records import (
    REQUIRED,
    RUN_CHANNELS,
    ChannelSpec,
    Dialect,
    RecordWriter,
    read_record,
    reading,
    write_record,
)

SETPOINT = ChannelSpec("r", "V", "setpoint", "set point")


def _write(tmp_path: Path, content: bytes | str, name: str = "rec.csv") -> Path:
    path = tmp_path / name
    if isinstance(content, str):
        content = content.encode()
    path.write_bytes(content)
    return path


@pytest.fixture(params=["fast", "exact"])
def reader(request: pytest.FixtureRequest, monkeypatch: pytest.MonkeyPatch) -> str:
    """Run a test through pyarrow and through the exact reader: both must agree."""
    if request.param == "exact":
        monkeypatch.setattr(reading, "_fast_columns", lambda *args: None)
    return str(request.param)


# --- channels ------------------------------------------------------------------------------


def test_run_channels_are_the_runner_columns() -> None:
    assert records.channel_names(RUN_CHANNELS) == (
        "t", "u", "y", "k", "t_read", "jitter", "lateness",
    )  # fmt: skip
    assert [c.role for c in REQUIRED] == ["time", "input", "output"]
    assert records.KNOWN_CHANNELS["jitter"].unit == "s"


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"name": "U"}, "must start with a lower-case letter"),
        ({"name": ""}, "must start with a lower-case letter"),
        ({"name": "y-2"}, "must start with a lower-case letter"),
        ({"name": "r", "role": "gain"}, "unknown role 'gain'; allowed: time, input"),
        ({"name": "r", "digits": 0}, "digits must be an integer in 1..17"),
    ],
)
def test_bad_channel_specs(kwargs: dict[str, object], message: str) -> None:
    with pytest.raises(InvalidParameterError, match=message):
        ChannelSpec(**kwargs)  # type: ignore[arg-type]


def test_writer_refuses_channels_without_t_u_y_first_or_repeated() -> None:
    with pytest.raises(InvalidParameterError, match="start with t, u, y; got u, t, y"):
        RecordWriter(io.StringIO(), (REQUIRED[1], REQUIRED[0], REQUIRED[2]))
    with pytest.raises(InvalidParameterError, match="channel 'r' appears twice"):
        RecordWriter(io.StringIO(), (*REQUIRED, SETPOINT, SETPOINT))


def test_writer_refuses_a_row_of_the_wrong_width() -> None:
    writer = RecordWriter(io.StringIO(), RUN_CHANNELS)
    with pytest.raises(InvalidParameterError, match=r"has 7 values .*got 3"):
        writer.write_row((0.0, 1.0, 2.0))


# --- writing and reading back --------------------------------------------------------------


def test_the_runner_format_is_unchanged() -> None:
    out = io.StringIO()
    write_record(out, RUN_CHANNELS, [(0.1 * 3, 5.0, 0.25, 3, 0.3000001, 1e-7, 0.0)])
    assert out.getvalue() == "t,u,y,k,t_read,jitter,lateness\n0.3,5.0,0.25,3,0.3000001,1e-07,0.0\n"


finite = st.floats(allow_nan=False, allow_infinity=False, width=64)


@settings(max_examples=40, deadline=None)
@given(
    u=st.lists(finite, min_size=3, max_size=30),
    data=st.data(),
)
def test_written_records_read_back_bit_for_bit(
    tmp_path_factory: pytest.TempPathFactory, u: list[float], data: st.DataObject
) -> None:
    n = len(u)
    y = data.draw(st.lists(finite, min_size=n, max_size=n))
    r = data.draw(st.lists(finite | st.just(math.nan), min_size=n, max_size=n))
    t = np.arange(n) * 0.5
    path = tmp_path_factory.mktemp("rt") / "rec.csv"
    with path.open("w", newline="") as fh:
        write_record(fh, (*REQUIRED, SETPOINT), zip(t, u, y, r, strict=True), comments=["x"])
    rec = read_record(path, known=[SETPOINT])
    assert rec.channels == (*REQUIRED, SETPOINT)
    assert rec.comments == ("x",)
    np.testing.assert_array_equal(rec.u, np.array(u))
    np.testing.assert_array_equal(rec.y, np.array(y))
    np.testing.assert_array_equal(rec["r"], np.array(r))  # NaN == NaN here


# --- records from anywhere -----------------------------------------------------------------


@pytest.mark.parametrize(
    ("content", "dialect"),
    [
        ("t,u,y\n0,0,1\n1,5,1.5\n2,5,2\n", Dialect(",", ".", "utf-8")),
        ("t;u;y\r\n0;0;1\r\n1;5;1,5\r\n2;5;2\r\n", Dialect(";", ",", "utf-8")),
        ("t\tu\ty\n0\t0\t1\n1\t5\t1.5\n2\t5\t2\n", Dialect("\t", ".", "utf-8")),
        ("t\tu\ty\n0\t0\t1\n1\t5\t1,5\n2\t5\t2\n", Dialect("\t", ",", "utf-8")),
        ("\ufefft,u,y\n0,0,1\n1,5,1.5\n2,5,2\n", Dialect(",", ".", "utf-8-sig")),
        (" T ; U ;Y\n0;0;1\n1;5;1,5\n2;5;2\n", Dialect(";", ",", "utf-8")),
        ("t;u;y\n0;0;1\n1;5;1.5\n2;5;2\n", Dialect(";", ".", "utf-8")),
        ('"t","u","y"\n"0","0","1"\n"1","5","1.5"\n"2","5","2"\n', Dialect(",", ".", "utf-8")),
    ],
)
def test_dialects(tmp_path: Path, reader: str, content: str, dialect: Dialect) -> None:
    rec = read_record(_write(tmp_path, content))
    assert rec.dialect == dialect
    np.testing.assert_array_equal(rec.t, [0.0, 1.0, 2.0])
    np.testing.assert_array_equal(rec.u, [0.0, 5.0, 5.0])
    np.testing.assert_array_equal(rec.y, [1.0, 1.5, 2.0])


def test_latin1_header_and_extra_columns(tmp_path: Path, reader: str) -> None:
    content = "# ensaio de aquecimento\nt;u;y;observa\xe7\xe3o\n0;0;1;a\n1;5;1,5;b\n2;5;2;c\n"
    rec = read_record(_write(tmp_path, content.encode("latin-1")), channels=())
    assert rec.dialect == Dialect(";", ",", "latin-1")
    assert rec.comments == ("ensaio de aquecimento",)
    np.testing.assert_array_equal(rec.y, [1.0, 1.5, 2.0])


def test_comments_and_blank_lines_between_samples(tmp_path: Path, reader: str) -> None:
    rec = read_record(_write(tmp_path, "# a\nt,u,y\n0,0,1\n# pause\n\n1,5,1.5\n2,5,2\n"))
    np.testing.assert_array_equal(rec.y, [1.0, 1.5, 2.0])


def test_a_decimal_comma_first_seen_late(tmp_path: Path, reader: str) -> None:
    rows = "".join(f"{k};0;1\n" for k in range(200)) + "200;5;1,5\n"
    rec = read_record(_write(tmp_path, "t;u;y\n" + rows))
    assert rec.dialect.decimal == ","
    assert rec.y[-1] == 1.5


def test_other_channels_by_name_with_empty_cells_as_nan(tmp_path: Path, reader: str) -> None:
    rec = read_record(_write(tmp_path, "t,u,y,r,k\n0,0,1,,0\n1,5,1.5,2,1\n2,5,2,2,2\n"))
    assert [c.name for c in rec.channels] == ["t", "u", "y", "r", "k"]
    assert rec.channels[4] == records.INDEX
    assert rec.channels[3] == ChannelSpec("r")
    np.testing.assert_array_equal(rec["r"], [math.nan, 2.0, 2.0])
    only = read_record(
        _write(tmp_path, "t,u,y,r,k\n0,0,1,,0\n1,5,1.5,2,1\n2,5,2,2,2\n"), channels=["k"]
    )
    assert list(only.columns) == ["t", "u", "y", "k"]


# --- bad input: one line naming the cause --------------------------------------------------


@pytest.mark.parametrize(
    ("content", "message"),
    [
        (b"", "empty file; expected a header with the columns t,u,y"),
        (b"# only a comment\n\n", "empty file"),
        (b"\xff\xfet\x00,\x00u\x00", "it is UTF-16 text (save it as UTF-8 or Latin-1 CSV)"),
        (b"\x89PNG\r\n\x1a\n\x00\x00", "not a CSV text file (binary data: a NUL byte at byte 8)"),
        (b"a,b,c\n1,2,3\n", "lacks the columns t, u, y"),
        (b"t;u,y\n0;1,2\n", "line 1: the header 't;u,y' holds both comma and semicolon"),
        (b"t,u,y,t\n0,0,0,0\n", "names the column 't' 2 times"),
        (b"t,u,y,R-2\n0,0,0,0\n", "has the column 'r-2'; a channel name starts with a letter"),
        (b"t,u,y\n0,0,0\n1,1,0\n", "too few rows: 2 samples, at least 3"),
        (
            b"t,u,y\n0,0,0\n1,1,5,1\n2,1,0\n",
            "line 3 (sample 1) has 4 cells, the header has 3 (decimal commas need a ';' or tab",
        ),
        (b"t;u;y\n0;0,5;1.5\n1;1;0\n2;1;0\n", "ambiguous decimal mark: line 2, column u has '0,5'"),
        (b"t;u;y\n0;1.000,5;1\n1;1;0\n2;1;0\n", "line 2, column u: '1.000,5' mixes '.' and ','"),
        (b"t;u;y\n0;0;0\n1;1;0\n2;1;0\n3;1,5;0\n4;1.5;0\n", "line 6, column u has '1.5'"),
        (b"t,u,y\n0,0,0\n1,,0\n2,1,0\n", "line 3 (sample 1), column u: empty; t, u and y need"),
        (b"t,u,y\n0,0,0\n1,1_0,0\n2,1,0\n", "line 3 (sample 1), column u: '1_0' is not a number"),
        (b"t,u,y\n0,0,0\n1,1,inf\n2,1,0\n", "column y: 'inf' is not finite (NaN or inf)"),
        (b"t,u,y\n0,0,0\n1,1,0\n0.5,1,0\n", "line 4 (sample 2): t = 0.5 does not increase"),
    ],
)
def test_bad_files(tmp_path: Path, reader: str, content: bytes, message: str) -> None:
    path = _write(tmp_path, content)
    with pytest.raises(RecordFormatError) as info:
        read_record(path)
    text = str(info.value)
    assert message in text
    assert text.startswith(f"{path}: ")
    assert "\n" not in text
    assert isinstance(info.value, InvalidDataError)


def test_a_requested_channel_that_is_missing(tmp_path: Path) -> None:
    with pytest.raises(RecordFormatError, match=r"line 1\) lacks the column r$"):
        read_record(_write(tmp_path, "t,u,y\n0,0,0\n1,1,0\n2,1,0\n"), channels=["r"])


def test_missing_file_and_folder(tmp_path: Path) -> None:
    with pytest.raises(RecordFormatError, match="no such file"):
        read_record(tmp_path / "nope.csv")
    with pytest.raises(RecordFormatError, match="is a directory"):
        read_record(tmp_path)


def test_a_large_file_is_read_by_the_fast_reader(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    n = 50_000
    rng = np.random.default_rng(7)
    u, y = rng.normal(size=n), rng.normal(size=n)
    path = tmp_path / "big.csv"
    with path.open("w", newline="") as fh:
        write_record(fh, REQUIRED, zip(np.arange(n) * 0.1, u, y, strict=True))

    def refuse(*args: object) -> object:
        raise AssertionError("the exact reader was used on a clean file")

    monkeypatch.setattr(reading, "exact_columns", refuse)
    rec = read_record(path)
    np.testing.assert_array_equal(rec.u, u)
    np.testing.assert_array_equal(rec.y, y)


DIALECTS = [
    Dialect(",", ".", "utf-8"),
    Dialect(";", ",", "utf-8-sig"),
    Dialect("\t", ",", "latin-1"),
    Dialect(";", ".", "utf-8"),
    Dialect("\t", ".", "utf-8-sig"),
]


@settings(max_examples=60, deadline=None)
@given(
    dialect=st.sampled_from(DIALECTS),
    values=st.lists(st.tuples(finite, finite), min_size=3, max_size=40),
    exact=st.booleans(),
)
def test_any_dialect_reads_back_the_same_numbers(
    tmp_path_factory: pytest.TempPathFactory,
    dialect: Dialect,
    values: list[tuple[float, float]],
    exact: bool,
) -> None:
    # A spreadsheet's export of the same numbers, through either reader.
    lines = ["# ensaio: a\u00e7\u00e3o", dialect.delimiter.join(["t", "u", "y", "nota"])]
    for k, (u, y) in enumerate(values):
        cells = [repr(float(k)), repr(u), repr(y), "ok"]
        lines.append(dialect.delimiter.join(c.replace(".", dialect.decimal) for c in cells))
    text = "\r\n".join(lines) + "\r\n"
    path = tmp_path_factory.mktemp("dialect") / "rec.csv"
    path.write_bytes(text.encode(dialect.encoding))
    original = reading._fast_columns
    if exact:
        reading._fast_columns = lambda *args: None  # type: ignore[assignment]
    try:
        rec = read_record(path, channels=())
    finally:
        reading._fast_columns = original
    assert rec.dialect == dialect
    np.testing.assert_array_equal(rec.u, [u for u, _ in values])
    np.testing.assert_array_equal(rec.y, [y for _, y in values])


def test_no_header_in_the_first_64_kib(tmp_path: Path) -> None:
    path = _write(tmp_path, "# a comment line of some length\n" * 3000 + "t,u,y\n0,0,0\n")
    with pytest.raises(RecordFormatError, match="no header in the first 65536 bytes"):
        read_record(path)


def test_equal_times_are_refused_or_merged_into_the_last(tmp_path: Path) -> None:
    """A second reading at one time stamp (issue #21): refused by default, or the last kept."""
    path = tmp_path / "dup.csv"
    path.write_text("t,u,y\n0,0,1\n1,0,1\n1,5,1.5\n2,5,2\n3,5,2.5\n")
    with pytest.raises(RecordFormatError, match="does not increase"):
        read_record(path)
    r = read_record(path, equal_times="last")
    assert_allclose(r.t, [0.0, 1.0, 2.0, 3.0], rtol=0, atol=0)
    assert_allclose(r.u, [0.0, 5.0, 5.0, 5.0], rtol=0, atol=0)
    assert r.merged_times == (1, 1.0)
    path.write_text("t,u,y\n0,0,1\n2,0,1\n1,5,1.5\n")
    with pytest.raises(RecordFormatError, match="does not increase"):
        read_record(path, equal_times="last")


@pytest.mark.parametrize(
    ("text", "options", "units"),
    [
        ("Time (s);Q1 (%);T1 (degC)\n0;0;20,5\n1;50;20,5\n2;50;21\n",
         {"columns": "t=Time,u=Q1,y=T1"}, ("s", "%", "°C")),
        ("0,0,299.5\n1,150,299.5\n2,150,300\n", {"columns": {"t": 1, "u": 2, "y": 3},
         "units": "u=PWM,y=K"}, ("s", "PWM", "K")),
        ("Time,T1,T2,Q1,Q2\n0,20,20,0,0\n1,20,20,50,0\n2,20.3,20,50,0\n", {}, ("s", "%", "°C")),
        ("t,u,y\n0,0,0\n1,1,0\n2,1,0.1\n", {}, ("s", "V", "V")),
    ],
)  # fmt: skip
def test_columns_and_units_as_the_user_has_them(
    tmp_path: Path, text: str, options: dict[str, Any], units: tuple[str, str, str]
) -> None:
    path = tmp_path / "record.csv"
    path.write_text(text, encoding="utf-8")
    r = read_record(path, channels=(), **options)
    assert (r.units["t"], r.units["u"], r.units["y"]) == units
    assert r.n == 3
    assert r.u[1] > r.u[0]
