"""The CSV files' spreadsheet form: what Excel or LibreOffice in pt-BR opens as columns.

The grades of a real twin run are read back by pandas as a pt-BR spreadsheet
reads them (``sep=";"``, ``decimal=","``, ``encoding="utf-8-sig"``): columns,
accents, numbers and local times right; the machine form is unchanged beside
it. The laws (Hypothesis): a number written for people reads back as the
number to ten significant digits, never in scientific notation; any name with
accents comes back intact through an import (Windows-1252 or UTF-8) and the
grades' export.
"""

from __future__ import annotations

import csv
import io
import math
import shutil
import subprocess
import xml.etree.ElementTree as ET
from datetime import UTC, datetime, timedelta
from pathlib import Path
from typing import Any
from zoneinfo import ZoneInfo

import pandas as pd
import pytest
from fastapi.testclient import TestClient
from hypothesis import given, settings
from hypothesis import strategies as st

from thermolab.lab.assignments.grades import GRADE_COLUMNS, GradeRow, grades_csv
from thermolab.lab.audit.log import AuditLog, AuditRecord
from thermolab.lab.classes.class_list import read_class_list
from thermolab.lab.clock import ManualClock
from thermolab.lab.spreadsheets import SheetDialect, plain_number, sheet_dialect
from thermolab.records import read_record

# ``school``: the assignments' fixture (a twin lab, teacher tina, student ana in ctrl1).
from .test_assignments import _assignment, _run, school  # noqa: F401
from .test_class_list import IBERIAN

SAO_PAULO = "America/Sao_Paulo"
PT_BR_GRADES = [
    "Disciplina",
    "Nº da atividade",
    "Atividade",
    "Nome de login",
    "Nome",
    "Situação",
    "Nota",
    "Nota máxima",
    "Atrasada",
    f"Entregue em ({SAO_PAULO})",
    f"Corrigida em ({SAO_PAULO})",
    "Ensaio",
    "Resposta Ks",
    "Resposta Ts",
    "Resposta θ",
    "Conclusão",
    "Nota automática",
    "Comentário do professor",
]


def read_pt_br(content: bytes) -> pd.DataFrame:
    """A CSV as a pt-BR spreadsheet opens it."""
    return pd.read_csv(io.BytesIO(content), sep=";", decimal=",", encoding="utf-8-sig")


def test_the_grades_open_in_a_pt_br_spreadsheet_as_columns_with_accents_and_numbers(
    school: Any,  # noqa: F811 - the imported fixture
) -> None:
    clock: ManualClock = school["clock"]
    tina: TestClient = school["tina"]
    # The class list as a Brazilian Excel saves it: Portuguese headings, Windows-1252.
    roster = "Matrícula;Nome completo\r\nana;-Ana\r\njoao;João Gonçalves\r\n".encode("cp1252")
    imported = tina.put("/api/courses/ctrl1/roster", content=roster)
    assert imported.json()["encoding"] == "Windows-1252"
    deadline = (clock.now() + timedelta(hours=1)).isoformat()
    made = tina.post(
        "/api/courses/ctrl1/assignments",
        json=_assignment(title="Degrau da caixa", deadline=deadline, methods=["lsm"], settings={}),
    ).json()
    run_id = _run(school["lab"], school["ana_p"])
    handed = school["ana"].post(
        f"/api/assignments/{made['id']}/submissions",
        json={"runId": run_id, "K": 0.14009, "tau": 250.126233, "theta": 0.0, "conclusion": "ok"},
    )
    assert handed.json()["mark"] == 10.0
    at = clock.now()

    machine = tina.get("/api/courses/ctrl1/grades.csv")
    answer = tina.get("/api/courses/ctrl1/grades.csv", params={"dialect": "pt-BR", "tz": SAO_PAULO})
    assert answer.status_code == 200, answer.text
    assert answer.headers["content-type"] == "text/csv; charset=utf-8"
    assert answer.content.startswith(b"\xef\xbb\xbf")  # the BOM: Excel reads UTF-8
    table = read_pt_br(answer.content)
    assert list(table.columns) == PT_BR_GRADES
    ana, joao = (table[table["Nome de login"] == who].iloc[0] for who in ("ana", "joao"))
    assert (ana["Nome"], ana["Situação"], ana["Atrasada"]) == ("'-Ana", "corrigida", "não")
    assert (ana["Nota"], ana["Nota máxima"]) == (10, 10)
    assert (ana["Resposta Ks"], ana["Resposta Ts"]) == (0.14009, 250.126233)
    handed_at = datetime.strptime(ana[f"Entregue em ({SAO_PAULO})"], "%d/%m/%Y %H:%M:%S")
    local = at.astimezone(ZoneInfo(SAO_PAULO)).replace(tzinfo=None, microsecond=0)
    assert abs(handed_at - local) <= timedelta(seconds=1)
    assert (joao["Nome"], joao["Situação"]) == ("João Gonçalves", "não entregue")
    assert math.isnan(joao["Nota"])
    # The cells as written: marks as the page shows them, decimal commas, no float noise.
    line = next(row for row in answer.text.splitlines() if ";ana;" in row)
    assert ";corrigida;10;10;não;" in line
    assert ";0,14009;250,126233;0;ok" in line
    # The machine form beside it is as it was.
    assert machine.text.splitlines()[0] == ",".join(GRADE_COLUMNS)
    assert not machine.content.startswith(b"\xef\xbb\xbf")
    assert ",marked,10.0,10.0,no," in machine.text

    spanish = tina.get("/api/courses/ctrl1/grades.csv", params={"dialect": "es"}).text
    assert spanish.splitlines()[0].startswith("\ufeffCurso;N.º de tarea;Tarea;")
    assert ";corregida;10;10;no;" in spanish
    assert ";no entregada;" in spanish
    english = tina.get("/api/courses/ctrl1/grades.csv", params={"dialect": "en"}).text
    assert english.splitlines()[0].startswith("\ufeffCourse,Assignment no.,Assignment,")
    assert "Handed in at (UTC)" in english

    for bad in ({"dialect": "fr"}, {"dialect": "pt-BR", "tz": "Mars/Olympus_Mons"}):
        refused = tina.get("/api/courses/ctrl1/grades.csv", params=bad)
        assert refused.status_code == 422, bad
        assert refused.json()["code"] in ("invalid_request", "invalid_parameter")


_ODF = {
    "office": "urn:oasis:names:tc:opendocument:xmlns:office:1.0",
    "table": "urn:oasis:names:tc:opendocument:xmlns:table:1.0",
}


def _calc_cells(csv_file: Path, work: Path) -> list[list[tuple[str | None, str]]]:
    """The cells LibreOffice Calc makes of ``csv_file`` as a Brazilian user opens it.

    The import options a pt-BR Calc offers: separator ``;``, UTF-8, language
    pt-BR (1046, which reads ``0,14`` and ``24/11/2026`` as a number and a date).
    Each cell is (value type, value): ``("float", "0.14009")``, ``("date", ...)``,
    ``("string", "João")``, ``(None, "")`` for an empty one.
    """
    subprocess.run(
        [
            "soffice",
            f"-env:UserInstallation={(work / 'profile').as_uri()}",
            "--headless",
            "--infilter=CSV:59,34,76,1,,1046",
            "--convert-to",
            "fods",
            "--outdir",
            str(work),
            str(csv_file),
        ],
        check=True,
        capture_output=True,
        timeout=120,
    )
    root = ET.parse(work / f"{csv_file.stem}.fods").getroot()
    office, table = (f"{{{_ODF[p]}}}" for p in ("office", "table"))
    rows = []
    for row in root.iter(f"{table}table-row"):
        cells: list[tuple[str | None, str]] = []
        for cell in row.iter(f"{table}table-cell"):
            repeated = int(cell.get(f"{table}number-columns-repeated", "1"))
            if repeated > 100:  # the sheet's empty tail
                break
            kind = cell.get(f"{office}value-type")
            value = cell.get(f"{office}value") or cell.get(f"{office}date-value")
            cells += [(kind, value or "".join(cell.itertext()).strip())] * repeated
        rows.append(cells)
    return rows


@pytest.mark.skipif(
    shutil.which("soffice") is None, reason="LibreOffice (soffice) is not installed"
)
def test_libreoffice_calc_in_pt_br_opens_the_grades_as_typed_columns(tmp_path: Path) -> None:
    at = datetime(2026, 11, 24, 17, 5, 9, 123456, tzinfo=UTC)
    row = GradeRow(
        *("ctrl1", 1, "Degrau", "joao", "João Gonçalves", "marked", 10.0, 10.0, at, at, False, 3),
        *(0.14009, 250.126233, 0.0, "Ks ≈ 0,14; ação ok"),
    )
    people = tmp_path / "notas.csv"
    people.write_text(grades_csv([row], SheetDialect("pt-BR", SAO_PAULO)), encoding="utf-8")
    header, cells = _calc_cells(people, tmp_path)
    assert [value for _, value in header] == PT_BR_GRADES
    assert cells[4:9] == [
        ("string", "João Gonçalves"),
        ("string", "corrigida"),
        ("float", "10"),
        ("float", "10"),
        ("string", "não"),
    ]
    assert cells[9] == ("date", "2026-11-24T14:05:09")
    assert cells[12:16] == [
        ("float", "0.14009"),
        ("float", "250.126233"),
        ("float", "0"),
        ("string", "Ks ≈ 0,14; ação ok"),
    ]
    # The machine form, opened the same way, is text in a column or two (split at the
    # conclusion's ";"), no number or date: why the spreadsheet links exist.
    machine = tmp_path / "grades.csv"
    machine.write_text(grades_csv([row]), encoding="utf-8")
    garbled = _calc_cells(machine, tmp_path)
    assert garbled[0][0] == ("string", ",".join(GRADE_COLUMNS))
    assert {kind for r in garbled for kind, _ in r} <= {"string", None}


def test_a_runs_samples_in_a_pt_br_spreadsheet_read_back_as_the_same_record(
    school: Any,  # noqa: F811 - the imported fixture
    tmp_path: Path,
) -> None:
    run_id = _run(school["lab"], school["ana_p"], samples=300)
    ana: TestClient = school["ana"]
    machine = ana.get(f"/api/runs/{run_id}/samples.csv")
    sheet = ana.get(f"/api/runs/{run_id}/samples.csv", params={"dialect": "pt-BR"})
    assert sheet.status_code == 200
    table = read_pt_br(sheet.content)
    assert list(table.columns[:4]) == ["t (s)", "u (V)", "y (V)", "k"]
    assert table["k"].tolist() == list(range(300))
    (tmp_path / "machine.csv").write_bytes(machine.content)
    (tmp_path / "sheet.csv").write_bytes(sheet.content)
    # The library reads the spreadsheet form too (';', decimal comma, BOM, units).
    plain, people = read_record(tmp_path / "machine.csv"), read_record(tmp_path / "sheet.csv")
    for name in ("t", "u", "y"):
        assert people[name] == pytest.approx(plain[name], rel=1e-9, abs=1e-12)
    assert people.units["y"] == "V"


def test_the_audit_log_in_a_spanish_spreadsheet() -> None:
    at = datetime(2026, 11, 24, 17, 5, 9, 123456, tzinfo=UTC)
    record = AuditRecord(7, at, "tina", "course.roster", "ctrl1", None, {"created": ["joão"]})
    text = AuditLog.to_csv([record], SheetDialect("es", "America/Argentina/Buenos_Aires"))
    rows = list(csv.reader(io.StringIO(text.removeprefix("\ufeff")), delimiter=";"))
    assert rows[0][:3] == ["N.º", "Cuándo (America/Argentina/Buenos_Aires)", "Quién"]
    # Local time to the second; the actions keep the stable names the audit page shows.
    assert rows[1][:6] == ["7", "24/11/2026 14:05:09", "tina", "course.roster", "ctrl1", ""]
    assert rows[1][6] == "created=['joão']"
    # The machine form is as it was: ISO UTC with microseconds, commas.
    assert (
        AuditLog.to_csv([record])
        .splitlines()[1]
        .startswith("7,2026-11-24T17:05:09.123456+00:00,tina,")
    )


@settings(max_examples=500, deadline=None)
# Up to 1e300: rounding the largest floats to ten digits would overflow to infinity.
@given(value=st.floats(-1e300, 1e300), decimal=st.sampled_from(",."))
def test_a_number_for_people_reads_back_to_ten_significant_digits(
    value: float, decimal: str
) -> None:
    text = plain_number(value, decimal)
    assert "e" not in text.lower()  # never scientific notation
    assert not text.endswith(f"{decimal}0")  # no float noise, no ".0"
    assert "." not in text.replace(decimal, "")  # no thousands separator
    back = float(text.replace(decimal, "."))
    assert back == pytest.approx(value, rel=5e-10, abs=0.0)


iberian_names = st.text(alphabet=IBERIAN + "abcdefghijklmnopqrstuvwxyz", min_size=1, max_size=20)


@settings(max_examples=100, deadline=None)
@given(
    names=st.lists(iberian_names, min_size=1, max_size=4, unique=True),
    codec=st.sampled_from(["cp1252", "utf-8", "utf-8-sig"]),
    language=st.sampled_from(["pt-BR", "es", "en"]),
)
def test_any_name_with_accents_round_trips_through_an_import_and_the_grades(
    names: list[str], codec: str, language: str
) -> None:
    # In: a class list saved by a spreadsheet in ``codec``. Out: the grades in
    # ``language``'s spreadsheet form, read as a spreadsheet of that language reads it.
    listed = "nome;matrícula\r\n" + "".join(f"{n};s{i}\r\n" for i, n in enumerate(names))
    entries = read_class_list(listed.encode(codec)).entries
    assert [e.display_name for e in entries] == names
    rows = [
        GradeRow(
            "c", 1, "T", e.username, e.display_name, "missing", None, 10.0, None, None, False, None
        )
        for e in entries
    ]
    dialect = sheet_dialect(language)
    assert dialect is not None
    text = grades_csv(rows, dialect)
    assert text.startswith("\ufeff")
    read = list(
        csv.reader(
            io.StringIO(text.encode("utf-8").decode("utf-8-sig")), delimiter=dialect.delimiter
        )
    )
    assert [row[4] for row in read[1:]] == names
