"""Class lists as schools save them: Portuguese and Spanish headers, Windows-1252, BOMs.

The laws (Hypothesis): a name written with the letters of Portuguese and
Spanish names comes back intact whatever the encoding a spreadsheet saved it
in, and every header word of the synonyms' table is recognised in any case,
with or without its accents.
"""

from __future__ import annotations

import json
import unicodedata
from collections.abc import Callable
from pathlib import Path

import pytest
from fastapi.testclient import TestClient
from hypothesis import given, settings
from hypothesis import strategies as st

from thermolab.errors import CLASS_LIST_PROBLEMS, ClassListError
from thermolab.lab.classes.class_list import (
    HEADER_SYNONYMS,
    decode_class_list,
    header_column,
    read_class_list,
)
from thermolab.lab.classes.courses import temporary_password
from thermolab.lab.service import Lab
from thermolab.web import STATIC_DIR

from .conftest import FAST_HASHER, PASSWORD
from .test_cli import run

Clients = Callable[..., TestClient]

#: The letters of Portuguese and Spanish names beyond ASCII. In Windows-1252 each is one
#: byte from 0xC0 up, which UTF-8 never has before another such byte: a file of these
#: names in Windows-1252 is never mistaken for UTF-8.
IBERIAN = "áàâãéêíóôõúüçñÁÀÂÃÉÊÍÓÔÕÚÜÇÑ"
ENCODINGS = {
    "utf-8": "UTF-8",
    "utf-8-sig": "UTF-8 with BOM",
    "utf-16": "UTF-16",
    "cp1252": "Windows-1252",
    "latin-1": "Windows-1252",
}
#: Headers as schools write them (accents, case, spaces), and the columns they name.
WRITTEN_HEADERS = [
    ("matrícula;nome", "Windows-1252"),
    ("Usuário;Nome Completo", "UTF-8 with BOM"),
    ("usuario;nombre completo", "Windows-1252"),
    ("Correo electrónico\tNombre y apellido", "UTF-16"),
    ("RA,Nome do aluno", "UTF-8"),
]


@pytest.fixture
def database_url(sqlite_url: str) -> str:
    return sqlite_url


@pytest.fixture
def teacher(lab: Lab, app_client: Clients) -> TestClient:
    lab.users.add("tina", PASSWORD, "teacher")
    client = app_client("tina")
    assert client.post("/api/courses", json={"name": "c1", "title": "C"}).status_code == 201
    return client


_CODECS = {"Windows-1252": "cp1252", "UTF-8 with BOM": "utf-8-sig", "UTF-16": "utf-16"}


@pytest.mark.parametrize(("header", "encoding"), WRITTEN_HEADERS)
def test_a_brazilian_or_spanish_list_imports_with_its_accents(
    lab: Lab, teacher: TestClient, header: str, encoding: str
) -> None:
    separator = ";" if ";" in header else "\t" if "\t" in header else ","
    text = f"{header}\r\nJoão.Gonçalves{separator}João Gonçalves\r\n"
    text += f"ines{separator}Inês Muñoz D'Ávila\r\n"
    data = text.encode(_CODECS.get(encoding, "utf-8"))
    answer = teacher.put("/api/courses/c1/roster", content=data)
    assert answer.status_code == 200, answer.text
    assert answer.json()["encoding"] == encoding
    assert sorted(answer.json()["created"]) == ["ines", "joao.goncalves"]
    members = teacher.get("/api/courses/c1").json()["members"]
    assert {m["username"]: m["displayName"] for m in members if m["role"] == "student"} == {
        "ines": "Inês Muñoz D'Ávila",
        "joao.goncalves": "João Gonçalves",
    }
    # The same list again in another encoding: nobody twice, nothing changed.
    again = teacher.put("/api/courses/c1/roster", content=text.encode("utf-8"))
    assert sorted(again.json()["unchanged"]) == ["ines", "joao.goncalves"]
    assert len(lab.users.list()) == 3


def test_class_list_problems_reach_the_page_in_its_language(teacher: TestClient) -> None:
    bad = b"login;turma\nana;A\n"
    answer = teacher.put("/api/courses/c1/roster", content=bad, headers={"Accept-Language": "es"})
    problem = answer.json()["errors"][0]
    assert (answer.status_code, problem["type"]) == (422, "class_list.header")
    assert problem["params"]["columns"] == "'login', 'turma'"
    assert problem["message"].startswith("el encabezado tiene las columnas 'login', 'turma'")
    assert problem["msg"].startswith("the header has columns 'login', 'turma'")


def test_the_command_line_says_a_class_lists_problems_in_portuguese(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(
        "thermolab.lab.accounts.security.default_password_hasher", lambda: FAST_HASHER
    )
    for name in ("LANGUAGE", "LC_ALL", "LC_MESSAGES"):
        monkeypatch.delenv(name, raising=False)
    monkeypatch.setenv("LANG", "pt_BR.UTF-8")
    base = ["--data-dir", str(tmp_path / "data")]
    add = [*base, "user", "add", "tina", "--role", "teacher", "--password-stdin"]
    assert run(add, capsys, monkeypatch, PASSWORD + "\n")[0] == 0
    create = [*base, "course", "create", "c1", "--title", "C", "--teacher", "tina"]
    assert run(create, capsys, monkeypatch)[0] == 0
    roster = tmp_path / "turma.csv"
    roster.write_bytes("matrícula;nome\n1;Ana\n1;Bia\n".encode("cp1252"))
    status, out, err = run([*base, "course", "import", "c1", str(roster)], capsys, monkeypatch)
    assert (status, out, err.count("\n")) == (1, "", 1), err
    assert err.startswith("erro: A lista da turma tem linhas com erro; nada foi alterado. (")
    assert "a lista da turma não foi importada (nada mudou): linha 3: o nome de login '1'" in err
    roster.write_bytes("matrícula;nome\n1;Conceição\n".encode("cp1252"))
    status, out, err = run([*base, "course", "import", "c1", str(roster)], capsys, monkeypatch)
    assert status == 0
    assert "(lido como Windows-1252)" in err
    assert out.splitlines()[0] == "username,password"
    # The one-time passwords for a Brazilian spreadsheet.
    roster.write_bytes("matrícula;nome\n2;Zé\n".encode("cp1252"))
    command = [*base, "course", "import", "c1", str(roster), "--dialect", "pt-BR"]
    status, out, err = run(command, capsys, monkeypatch)
    assert status == 0
    lines = out.splitlines()
    assert lines[0] == "\ufeffNome de login;Senha provisória"
    assert lines[1].startswith("2;")
    assert lines[1][2].isalnum()  # never a leading "-" that a spreadsheet takes for a formula


iberian_names = st.lists(
    st.text(alphabet=IBERIAN + "abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ", min_size=1),
    min_size=1,
    max_size=4,
).map(lambda words: " ".join(words)[:128])


@settings(max_examples=200, deadline=None)
@given(
    names=st.lists(iberian_names, min_size=1, max_size=5),
    codec=st.sampled_from(sorted(ENCODINGS)),
    separator=st.sampled_from([";", ",", "\t"]),
)
def test_any_iberian_name_comes_back_intact_in_any_encoding(
    names: list[str], codec: str, separator: str
) -> None:
    text = f"matrícula{separator}nome completo\r\n"
    text += "".join(f"s{i}{separator}{name}\r\n" for i, name in enumerate(names))
    read = read_class_list(text.encode(codec))
    assert read.encoding == ENCODINGS[codec] or (
        # Plain ASCII is UTF-8 and Windows-1252 alike.
        text.isascii() and read.encoding == "UTF-8"
    )
    assert [e.display_name for e in read.entries] == [
        " ".join(unicodedata.normalize("NFC", n).split()) for n in names
    ]


def _respell(word: str, data: st.DataObject) -> str:
    spaced = word.replace("_", data.draw(st.sampled_from(["_", " ", "-"])))
    return "".join(c.upper() if data.draw(st.booleans()) else c for c in spaced)


ACCENTED = {"usuario": "usuário", "matricula": "matrícula", "codigo_do_aluno": "código do aluno"}


@settings(max_examples=200, deadline=None)
@given(data=st.data())
def test_every_header_synonym_is_recognised_in_any_case_and_accents(data: st.DataObject) -> None:
    column = data.draw(st.sampled_from(sorted(HEADER_SYNONYMS)))
    word = data.draw(st.sampled_from(HEADER_SYNONYMS[column]))
    if word in ACCENTED and data.draw(st.booleans()):
        word = ACCENTED[word]
    assert header_column(f" {_respell(word, data)} ") == column


def test_files_that_are_not_text_are_named_as_such() -> None:
    with pytest.raises(ClassListError, match="line 2: the file is not text in UTF-8") as raised:
        decode_class_list(b"usuario;nome\nana;A\x81na\n")
    assert raised.value.problems[0].params == {"byte": 6}
    with pytest.raises(ClassListError, match="spreadsheet workbook"):
        decode_class_list(b"\xd0\xcf\x11\xe0\xa1\xb1\x1a\xe1")  # an .xls
    with pytest.raises(ClassListError, match="not text"):
        decode_class_list("usuario;nome\n".encode("utf-16-le"))  # UTF-16 without its BOM


def test_the_pages_catalogue_words_each_problem_as_the_server_does() -> None:
    # The browser words a problem from its code ("error.class_list.header"); in English
    # that sentence is the server's, placeholder for placeholder.
    text = (STATIC_DIR / "js" / "messages" / "en.js").read_text(encoding="utf-8")
    body = json.loads(
        text[text.index("{", text.index("export const messages")) : text.rindex("}") + 1]
    )
    frames = {"class_list.not_imported", "class_list.line", "class_list.more"}
    for code, sentence in CLASS_LIST_PROBLEMS.items():
        if code not in frames:
            assert body[f"error.{code}"] == sentence, code


def test_a_one_time_password_never_starts_as_a_formula() -> None:
    assert all(temporary_password()[0].isalnum() for _ in range(300))
