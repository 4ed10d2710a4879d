"""Server errors in the reader's language: every code has a sentence in every language."""

from __future__ import annotations

import io
import re
from collections.abc import Callable
from pathlib import Path

import pytest
from babel.messages.extract import extract_from_dir, extract_from_file
from babel.messages.pofile import read_po
from fastapi.testclient import TestClient

import thermolab.cli
from thermolab.cli import main
from thermolab.cli._words import ARGPARSE_WORDS, in_language
from thermolab.errors import (
    CLASS_LIST_PROBLEMS,
    CONFLICT_CASES,
    PASSWORD_PROBLEMS,
    TAKEN_NAMES,
    ConflictError,
)
from thermolab.lab import error_messages
from thermolab.lab.access.views import TURN_END_WORDS
from thermolab.lab.accounts.users import Principal
from thermolab.lab.classes.reminders import REMINDER_WORDS
from thermolab.lab.error_messages import (
    ERROR_SENTENCES,
    LANGUAGES,
    error_message,
    language_from_environment,
    negotiate_language,
)
from thermolab.lab.http.errors import all_error_codes
from thermolab.lab.rigs.camera import CAMERA_WORDS
from thermolab.lab.service import Lab
from thermolab.lab.spreadsheets import SHEET_WORDS
from thermolab.reproduction import _results

from .conftest import FAST_HASHER, PASSWORD

Client = Callable[..., TestClient]
TRANSLATED = [language for language in LANGUAGES if language != "en"]


def cli_msgids() -> set[str]:
    """Every msgid of the command line (Babel's extractor): its ``_()``, argparse's words
    and the reproduced Table I's words (``Table1Result.format``'s ``say()``)."""
    root = Path(thermolab.cli.__file__).parent
    found = extract_from_dir(root, method_map=[("**.py", "python")], keywords={"_": None})
    table = extract_from_file("python", _results.__file__, keywords={"say": None})
    return (
        {str(message) for _file, _line, message, _comments, _context in found}
        | {str(message) for _line, message, _comments, _context in table}
        | set(ARGPARSE_WORDS)
    )


#: Every msgid the server's catalogue holds: error sentences, class-list problems,
#: the spreadsheet forms' words, a password's refusals, the camera picture's words,
#: the booking reminders' words, how a turn ended, the command line's own words and
#: its prefix.
SERVER_WORDS = [
    *CLASS_LIST_PROBLEMS.values(),
    *SHEET_WORDS,
    *PASSWORD_PROBLEMS.values(),
    *CAMERA_WORDS.values(),
    *REMINDER_WORDS,
    *TAKEN_NAMES.values(),
    *TURN_END_WORDS,
    *sorted(cli_msgids()),
]
MSGIDS = {*ERROR_SENTENCES.values(), *SERVER_WORDS, "error"}
#: Words the same in a language by chance (checked one by one).
SAME_BY_CHANCE = {("es", "no"), ("es", "error")}


@pytest.fixture
def database_url(sqlite_url: str) -> str:
    return sqlite_url


def _catalogue(language: str) -> dict[str, str]:
    path = Path(error_messages.__file__).with_name("locale")
    path = path / language.replace("-", "_") / "LC_MESSAGES" / "thermolab.po"
    with path.open("rb") as source:
        catalog = read_po(source)
    return {str(m.id): str(m.string) for m in catalog if m.id and not m.fuzzy}


def test_every_error_code_has_a_sentence() -> None:
    assert all_error_codes() <= set(ERROR_SENTENCES), all_error_codes() - set(ERROR_SENTENCES)


@pytest.mark.parametrize("language", TRANSLATED)
def test_every_sentence_is_translated_in_every_language(language: str) -> None:
    catalogue = _catalogue(language)
    for code, sentence in ERROR_SENTENCES.items():
        assert catalogue.get(sentence), f"{language}: {code} ({sentence!r}) is not translated"
        assert catalogue[sentence] != sentence, f"{language}: {code} is still English"
        assert error_message(code, language) == catalogue[sentence]
    assert set(catalogue) <= MSGIDS, "stale entries"


@pytest.mark.parametrize("language", TRANSLATED)
def test_class_list_problems_and_spreadsheet_words_are_translated(language: str) -> None:
    catalogue = _catalogue(language)
    for msgid in SERVER_WORDS:
        assert catalogue.get(msgid), f"{language}: {msgid!r} is not translated"
        if (language, msgid) not in SAME_BY_CHANCE:
            assert catalogue[msgid] != msgid, f"{language}: {msgid!r} is still English"
        # A translation fills the same values.
        assert set(re.findall(r"\{(\w+)\}", catalogue[msgid])) == set(
            re.findall(r"\{(\w+)\}", msgid)
        ), msgid


def test_the_english_catalogue_is_the_template() -> None:
    assert set(_catalogue("en")) == MSGIDS
    assert error_message("not_found", "en") == ERROR_SENTENCES["not_found"]


def test_languages_are_negotiated_like_the_browser() -> None:
    assert negotiate_language("pt-PT,en;q=0.5") == "pt-BR"
    assert negotiate_language("fr;q=0.9, es-AR;q=0.8") == "es"
    assert negotiate_language("en;q=0.2, pt;q=0.9") == "pt-BR"
    assert negotiate_language("de, fr") == "en"
    assert negotiate_language("es;q=0") == "en"
    assert negotiate_language("es", chosen="xx") == "es"
    assert language_from_environment({"LANG": "pt_BR.UTF-8"}) == "pt-BR"
    assert language_from_environment({"LANGUAGE": "es:en", "LANG": "pt_BR.UTF-8"}) == "es"
    assert language_from_environment({"LC_ALL": "C", "LANG": "pt_BR.UTF-8"}) == "en"
    assert language_from_environment({}) == "en"


def test_api_errors_speak_the_readers_language(lab: Lab, app_client: Client) -> None:
    lab.users.add("ana", PASSWORD, "student")
    ana = app_client("ana")
    answer = ana.get("/api/rigs/nope", headers={"Accept-Language": "pt-BR,pt;q=0.9"})
    body = answer.json()
    assert answer.status_code == 404
    assert (body["code"], body["message"]) == ("not_found", "Nada foi encontrado ali.")
    assert body["detail"] == "no rig called 'nope'; the lab has: twin, other"
    assert answer.headers["content-language"] == "pt-BR"
    # The reader's choice (cookie) wins over the browser's preference.
    ana.cookies.set("thermolab_lang", "es")
    answer = ana.put("/api/rigs/twin/input", json={"u": "x"}, headers={"Accept-Language": "en"})
    assert answer.status_code == 422
    assert answer.json()["message"] == "La solicitud no es válida."
    assert answer.headers["content-language"] == "es"
    ana.cookies.delete("thermolab_lang")
    answer = ana.get("/api/rigs/twin/input", headers={"Accept-Language": "es"})
    assert (answer.status_code, answer.json()["code"]) == (405, "method_not_allowed")
    assert answer.json()["message"] == "Esta acción no está permitida aquí."
    big = b'{"u": 1, "pad": "' + b"x" * 70_000 + b'"}'
    answer = ana.put(
        "/api/rigs/twin/input",
        content=big,
        headers={"content-type": "application/json", "Accept-Language": "pt-BR"},
    )
    assert (answer.status_code, answer.json()["message"]) == (413, "O pedido é grande demais.")
    answer = ana.delete(
        "/api/rigs/twin/control",
        headers={"Origin": "https://evil.example", "Accept-Language": "pt-BR"},
    )
    assert answer.status_code == 403
    assert answer.json()["message"] == error_message("cross_origin", "pt-BR")
    stranger = app_client()
    answer = stranger.get("/api/rigs", headers={"Accept-Language": "en"})
    assert answer.json()["message"] == ERROR_SENTENCES["not_authenticated"]


def test_why_a_rig_takes_no_turn_is_said_by_its_own_code(lab: Lab, app_client: Client) -> None:
    """Not the generic "conflict": each reason its code and sentence, in the reader's language."""
    lab.users.add("ana", PASSWORD, "student")
    teacher = lab.users.add("tess", PASSWORD, "teacher")
    ana = app_client("ana")
    pt = {"Accept-Language": "pt-BR"}
    # Asking for more time without the rig's control.
    answer = ana.post("/api/rigs/twin/control/more-time", headers=pt)
    assert (answer.status_code, answer.json()["code"]) == (409, "not_controller")
    assert answer.json()["message"] == "Você não controla esta bancada agora."
    # A teacher kicks the controller of a rig nobody controls.
    tess = app_client("tess")
    answer = tess.post("/api/rigs/twin/control/kick", json={}, headers={"Accept-Language": "es"})
    assert (answer.status_code, answer.json()["code"]) == (409, "nobody_controls")
    assert answer.json()["message"] == "Nadie controla este equipo ahora."
    # ... or someone who neither controls it nor waits: a precise case of a conflict.
    answer = tess.post("/api/rigs/twin/control/kick", json={"username": "ana"}, headers=pt)
    assert (answer.status_code, answer.json()["code"]) == (409, "not_in_line")
    assert answer.json()["message"] == "Esta pessoa não controla esta bancada nem espera por ela."
    # A rig out of service takes no turn.
    lab.access.set_service("twin", Principal(teacher.id, teacher.username, teacher.role), False)
    answer = ana.post("/api/rigs/twin/control", headers=pt)
    assert (answer.status_code, answer.json()["code"]) == (409, "rig_out_of_service")
    assert answer.json()["message"] == error_message("rig_out_of_service", "pt-BR")
    assert "out of service" in answer.json()["detail"]  # the precise English beside it


def test_a_conflict_names_only_a_declared_case() -> None:
    assert ConflictError("x", case="course_open").case == "course_open"
    assert ConflictError("x").case is None
    with pytest.raises(ValueError, match="no conflict case"):
        ConflictError("x", case="something_new")
    assert set(CONFLICT_CASES) <= all_error_codes()


def test_the_command_line_says_errors_in_the_users_language(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    record = tmp_path / "bad.csv"
    record.write_text("x\n")
    for name in ("LANGUAGE", "LC_ALL", "LC_MESSAGES"):
        monkeypatch.delenv(name, raising=False)
    monkeypatch.setenv("LANG", "pt_BR.UTF-8")
    assert main(["identify", str(record), "--method", "lsm"]) == 1
    line = capsys.readouterr().err.strip()
    assert line.startswith("erro: Um valor não é permitido. (")
    assert "lacks the columns t, u, y" in line
    assert "\n" not in line
    monkeypatch.setenv("LANG", "en_US.UTF-8")
    assert main(["identify", str(record), "--method", "lsm"]) == 1
    assert capsys.readouterr().err.startswith("error: ")


def test_a_refused_password_is_said_in_the_users_language(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    # The teacher who met "erro: Um valor não é permitido. (password too short ...)".
    for name in ("LANGUAGE", "LC_ALL", "LC_MESSAGES"):
        monkeypatch.delenv(name, raising=False)
    monkeypatch.setenv("LANG", "pt_BR.UTF-8")
    monkeypatch.setattr("sys.stdin", io.StringIO("curta\n"))
    command = ["--data-dir", str(tmp_path), "user", "add", "bia", "--role", "student"]
    assert main([*command, "--password-stdin"]) == 1
    line = capsys.readouterr().err.strip()
    assert line == (
        "erro: Um valor não é permitido. "
        "(senha curta demais: são necessários pelo menos 12 caracteres)"
    )


def test_a_taken_name_is_said_in_the_users_language(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    # Issue #24: "erro: Isto conflita com ... (user 'bia' already exists)" was half English.
    for name in ("LANGUAGE", "LC_ALL", "LC_MESSAGES"):
        monkeypatch.delenv(name, raising=False)
    monkeypatch.setenv("LANG", "pt_BR.UTF-8")
    command = ["--data-dir", str(tmp_path), "user", "add", "bia", "--role", "student"]
    for status in (0, 1):
        monkeypatch.setattr("sys.stdin", io.StringIO(PASSWORD + "\n"))
        assert main([*command, "--password-stdin"]) == status
    line = capsys.readouterr().err.strip()
    assert line == "erro: Este nome de usuário já está em uso. (o usuário 'bia' já existe)"
    monkeypatch.setenv("LANG", "es_ES.UTF-8")
    teacher = ["--data-dir", str(tmp_path), "user", "add", "tina", "--role", "teacher"]
    monkeypatch.setattr("sys.stdin", io.StringIO(PASSWORD + "\n"))
    assert main([*teacher, "--password-stdin"]) == 0
    course = ["--data-dir", str(tmp_path), "course", "create", "ctrl", "--title", "Controle"]
    for status in (0, 1):
        assert main([*course, "--teacher", "tina"]) == status
    line = capsys.readouterr().err.strip()
    assert line == "error: Otro curso ya tiene este nombre: elige otro. (el curso 'ctrl' ya existe)"


def test_the_api_says_why_a_password_is_refused_in_the_readers_language(
    lab: Lab, app_client: Client
) -> None:
    lab.users.add("ana", PASSWORD, "student")
    ana = app_client("ana")
    answer = ana.put(
        "/api/users/ana/password",
        json={"currentPassword": PASSWORD, "password": "password1234"},
        headers={"Accept-Language": "es"},
    )
    assert answer.status_code == 422, answer.text
    body = answer.json()
    assert body["message"] == (
        "esta contraseña está en una lista de contraseñas filtradas; elige otra"
    )
    assert body["errors"][0]["type"] == "password.breached"
    assert body["detail"] == "this password is in a list of breached passwords; choose another"


def test_a_teachers_first_commands_speak_the_users_language(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    # Issue #24: the command line answered a Portuguese teacher in English but for errors.
    for name in ("LANGUAGE", "LC_ALL", "LC_MESSAGES"):
        monkeypatch.delenv(name, raising=False)
    monkeypatch.setattr(
        "thermolab.lab.accounts.security.default_password_hasher", lambda: FAST_HASHER
    )
    monkeypatch.setenv("LANG", "pt_BR.UTF-8")
    lab = ["--data-dir", str(tmp_path)]

    def said(*words: str, stdin: str = "") -> tuple[str, str]:
        monkeypatch.setattr("sys.stdin", io.StringIO(stdin))
        assert main([*lab, *words]) == 0
        out, err = capsys.readouterr()
        return out.strip(), err.strip()

    assert said("user", "list")[0].startswith("ainda não há contas; crie a conta de admin")
    out, _ = said("user", "add", "tina", "--role", "teacher", "--password-stdin", stdin=PASSWORD)
    assert out == "conta criada: docente 'tina'"
    out, _ = said("course", "create", "ctrl1", "--title", "Controle I", "--teacher", "tina")
    assert out.startswith("disciplina 'ctrl1' criada (Controle I); código de inscrição ")
    (tmp_path / "turma.csv").write_text("username,display_name\nana,Ana Souza\n")
    out, err = said("course", "import", "ctrl1", str(tmp_path / "turma.csv"))
    assert err.splitlines() == [
        "ctrl1: 1 contas criadas, 0 atualizadas, 0 sem mudança (lido como UTF-8)",
        "senhas de uso único (mostradas uma só vez; cada uma deve ser trocada no primeiro acesso):",
    ]
    assert out.splitlines()[0] == "username,password"  # a file's header: never translated
    out, _ = said("user", "list")
    assert out.splitlines()[0].split() == ["usuário", "papel", "criada", "(UTC)"]
    assert {line.split()[1] for line in out.splitlines()[1:]} == {"docente", "estudante"}
    monkeypatch.setenv("LANG", "es_ES.UTF-8")
    assert said("user", "remove", "ana")[0] == "cuenta eliminada: estudiante 'ana'"
    monkeypatch.setattr("sys.stdin", io.StringIO("x\n"))
    assert main([*lab, "user", "add", "bia", "--role", "student"]) == 1  # not a terminal
    refusal = capsys.readouterr().err.strip()
    assert refusal.startswith("error: la entrada estándar no es una terminal")
    assert refusal.endswith("--password-stdin")
    # argparse's own words too.
    assert main([*lab, "user", "add"]) == 2
    assert "los siguientes argumentos son obligatorios: NAME, --role" in capsys.readouterr().err
    assert in_language("usage: ", "pt-BR") == "uso: "


def test_every_word_of_the_command_line_is_seen_by_the_extractor() -> None:
    # `_()` around an f-string or a variable, or inside an f-string's braces, holds a
    # msgid Babel cannot see: it would never be translated.
    for path in Path(thermolab.cli.__file__).parent.glob("*.py"):
        if path.name == "_words.py":  # where _() is written
            continue
        source = path.read_text(encoding="utf-8")
        hidden = re.findall(r"(?<![\w.])_\((?!\s*[\"'])[^)]{0,40}", source)
        assert hidden == [], f"{path.name}: {hidden}"
        assert not re.search(r"\{_\(", source), f"{path.name}: _() inside an f-string"
