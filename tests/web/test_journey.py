"""The class's journey in a real Chromium (#10): teacher and student, end to end, in 3 languages.

Against ``thermolab serve`` with the paper's twin at the e2e speed-up, in pt-BR on
PostgreSQL (skipped, saying why, where the server is unreachable), in es and en on
SQLite: each language and each database once (:data:`JOURNEYS`), not every pair, as
nothing a page says depends on the database (issue #20):

1. the teacher creates a course and uploads a class list;
2. writes a guide page (the steps of panel 1);
2a. books the rig for the course on the calendar, from now for an hour;
3. sets an assignment (rig, LSM, deadline, tolerances);
4. a student of the list logs in with the one-time password and chooses their own;
5. reads the guide beside panel 1;
6. runs the experiment on the twin inside the course's slot (the rig page says so):
   a step of the set point, 0 to 10 V;
7. hands in the run with the Ks, Ts and θ the page showed, and reads the mark and feedback;
8. the teacher sees the hand-in and downloads the grades: the CSV has the student's row;
9. the audit log (the teacher is the lab's administrator) lists the teacher's privileged
   actions: the course made, its class list, its assignment.

In pt-BR and es every step ends by reading both pages as a person meets them
(tests/web/test_no_english.py's reader): no English word on them (#24).

The steps are functions in :data:`STEPS`, in order, sharing one
:class:`Journey`: a new step goes in the list where it belongs.
"""

from __future__ import annotations

import csv
import io
import os
import uuid
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import pytest

from .axe import serious_violations
from .conftest import audited
from .guide_drawer import open_panel_guide
from .test_language_pages import visible_text
from .test_messages import catalogue
from .test_no_english import ENGLISH, MACHINE_NAMES, english_words, words

pytestmark = pytest.mark.browser

WORDS = {
    "pt-BR": {"locale": "pt-BR", "mark": "Nota: 10 de 10", "state": "corrigida", "theta": "2,5"},
    "es": {"locale": "es-MX", "mark": "Nota: 10 sobre 10", "state": "corregida", "theta": "2,5"},
    "en": {"locale": "en-GB", "mark": "Mark: 10 out of 10", "state": "marked", "theta": "2.5"},
}
RIGS = {"pt-BR": "caixa-1", "es": "caja-2", "en": "tclab-3"}
#: What the teacher types, in the class's language.
TYPED = {
    "pt-BR": (
        "Degrau de 0 a 10 V; dê Ks, Ts e θ.",
        "O sistema é de primeira ordem.",
        "Um degrau de $u$ de 0 a 10 V.",
    ),
    "es": (
        "Escalón de 0 a 10 V; dé Ks, Ts y θ.",
        "El sistema es de primer orden.",
        "Un escalón de $u$ de 0 a 10 V.",
    ),
    "en": (
        "Step 0 → 10 V; give Ks, Ts and θ.",
        "The system is first order.",
        "A step of $u$ from 0 to 10 V.",
    ),
}
CONFIG = """\
title = "ThermoLab journey"
{database}
[[rigs]]
id = "caixa-1"
title = "Gêmeo digital da caixa"
spec = "sim"

[[rigs]]
id = "caja-2"
title = "Gemelo digital de la caja"
spec = "sim"

[[rigs]]
id = "tclab-3"
title = "TCLab 3"
spec = "sim"
"""
POSTGRES = os.environ["THERMOLAB_TEST_POSTGRES_URL"]  # the test run's own (tests/conftest.py)


@dataclass
class Journey:
    """What the steps share: the lab, the browser pages, and what one step tells the next."""

    lab: Any
    browser: Any
    language: str
    artifacts: Path
    teacher: Any = None
    student: Any = None
    course: str = ""
    login: str = ""
    one_time: str = ""
    assignment: int = 0
    run_text: dict[str, str] = field(default_factory=dict)

    @property
    def words(self) -> dict[str, str]:
        return WORDS[self.language]

    @property
    def course_title(self) -> str:
        return f"Controle I ({self.language})"

    @property
    def rig(self) -> str:
        return RIGS[self.language]

    @property
    def suffix(self) -> str:
        return self.language.lower().replace("-", "")


def _postgres_schema() -> Iterator[str]:
    from sqlalchemy import create_engine, text
    from sqlalchemy.engine import make_url
    from sqlalchemy.exc import OperationalError

    admin = create_engine(
        POSTGRES, isolation_level="AUTOCOMMIT", connect_args={"connect_timeout": 3}
    )
    schema = f"thermolab_journey_{uuid.uuid4().hex[:12]}"
    try:
        with admin.connect() as connection:
            connection.execute(text(f'CREATE SCHEMA "{schema}"'))
    except OperationalError as exc:
        admin.dispose()
        pytest.skip(
            f"PostgreSQL at {make_url(POSTGRES).render_as_string()} unreachable: {exc.orig}"
        )
    url = make_url(POSTGRES).update_query_dict({"options": f"-csearch_path={schema}"})
    try:
        yield url.render_as_string(hide_password=False)
    finally:
        with admin.connect() as connection:
            connection.execute(text(f'DROP SCHEMA "{schema}" CASCADE'))
        admin.dispose()


#: (database, language) of each journey: every language once, every database once.
JOURNEYS = [
    pytest.param("postgres", "pt-BR", marks=pytest.mark.postgres, id="postgres-pt-BR"),
    pytest.param("sqlite", "es", id="sqlite-es"),
    pytest.param("sqlite", "en", id="sqlite-en"),
]


def pytest_generate_tests(metafunc: pytest.Metafunc) -> None:
    # The lab is the module's, one per database (indirect, module scope); the language
    # is the test's: parametrized together so the pairs are JOURNEYS, not their product.
    if "journey_lab" in metafunc.fixturenames and "language" in metafunc.fixturenames:
        metafunc.parametrize(
            ("journey_lab", "language"), JOURNEYS, indirect=["journey_lab"], scope="module"
        )


@pytest.fixture(scope="module")
def journey_lab(
    request: pytest.FixtureRequest, tmp_path_factory: pytest.TempPathFactory, start_lab: Any
) -> Iterator[Any]:
    """A lab with one teacher (tess), on SQLite or PostgreSQL, for the module's journeys."""
    database = ""
    schemas: Iterator[str] | None = None
    if request.param == "postgres":
        schemas = _postgres_schema()
        database = f'database_url = "{next(schemas)}"\n'
    folder = tmp_path_factory.mktemp(f"journey-{request.param}")
    try:
        with start_lab(folder, {"tess": "teacher"}, config=CONFIG.format(database=database)) as lab:
            yield lab
    finally:
        if schemas is not None:
            for _ in schemas:  # drop the schema
                pass


# -- the steps ------------------------------------------------------------------------


def teacher_uploads_a_class_list(j: Journey) -> None:
    page = j.teacher
    page.goto(f"{j.lab.url}/#/courses")
    page.wait_for_selector("#course-form")
    page.fill("#course-name", j.course)
    page.fill("#course-title", j.course_title)
    page.click("#course-form button[type=submit]")
    page.wait_for_selector("#course-code")
    j.login = f"joao.{j.suffix}"
    # As a Brazilian spreadsheet saves it in pt-BR (Portuguese headings, Windows-1252).
    data = (
        f"Matrícula;Nome completo\nJoão.{j.suffix};João Gonçalves\n".encode("cp1252")
        if j.language == "pt-BR"
        else f"username;name\nJoão.{j.suffix};João Gonçalves\n".encode()
    )
    page.set_input_files(
        "#roster-file", files=[{"name": "turma.csv", "mimeType": "text/csv", "buffer": data}]
    )
    page.click("#roster-upload")
    page.wait_for_selector("#roster-passwords")
    cells = page.locator("#roster-passwords tbody tr").all_inner_texts()
    created = dict(cell.split("\t") for cell in cells)
    assert list(created) == [j.login]
    j.one_time = created[j.login]


def teacher_writes_a_guide_page(j: Journey) -> None:
    page = j.teacher
    page.goto(f"{j.lab.url}/#/rig/{j.rig}")
    open_panel_guide(page)
    page.locator("[data-testid=guide-text] h1").wait_for()  # the default text
    page.click("[data-testid=guide-edit]")
    page.fill("[data-testid=guide-source]", f"## {j.course}\n\n{TYPED[j.language][2]}")
    page.locator(".guide-editor button").first.click()  # preview, rendered by the server
    page.locator("[data-testid=guide-preview] h2").wait_for()
    page.locator(".guide-editor button.primary").click()  # save
    page.locator("[data-testid=guide-text] h2").wait_for()
    assert j.course in page.inner_text("[data-testid=guide-text]")


def teacher_books_a_slot_for_the_course(j: Journey) -> None:
    """The rig is the course's from this minute for an hour, typed in the browser's own time."""
    page = j.teacher
    page.goto(f"{j.lab.url}/#/bookings")
    page.wait_for_selector(f"#booking-rig-{j.rig}")
    assert page.inner_text("h1") == catalogue(j.language)["calendar.title"]
    date, start, end = page.evaluate(
        """() => {
          const two = (n) => String(n).padStart(2, "0");
          const now = new Date();
          const later = new Date(now.getTime() + 3600e3);
          const hm = (d) => `${two(d.getHours())}:${two(d.getMinutes())}`;
          const day = `${now.getFullYear()}-${two(now.getMonth() + 1)}-${two(now.getDate())}`;
          return [day, hm(now), later.getDate() === now.getDate() ? hm(later) : "23:59"];
        }"""
    )
    page.select_option("#booking-course", j.course)
    page.check(f"#booking-rig-{j.rig}")
    page.fill("#booking-date", date)
    page.fill("#booking-start", start)
    page.fill("#booking-end", end)
    page.click("#booking-submit")
    slot = page.locator("[data-testid=slot]", has_text=j.course_title)
    slot.first.wait_for()
    assert j.rig in slot.first.inner_text()
    assert serious_violations(page) == []


def teacher_sets_an_assignment(j: Journey) -> None:
    page = j.teacher
    page.goto(f"{j.lab.url}/#/assignments")
    page.wait_for_selector("#assign-form")
    page.select_option("#assign-course", j.course)
    page.fill("#assign-title", f"Degrau {j.suffix}")
    page.fill("#assign-instructions", TYPED[j.language][0])
    page.select_option("#assign-rig", j.rig)
    page.fill("#assign-deadline", "2099-12-31T23:00")
    page.fill("#assign-tol-k", "5")
    page.fill("#assign-tol-tau", "5")
    page.fill("#assign-tol-theta", j.words["theta"])  # the language's decimal mark
    assert page.is_checked("input[name=method][value=lsm]")
    assert serious_violations(page) == []
    page.click("#assign-form button[type=submit]")
    page.wait_for_selector("#assign-details")
    j.assignment = int(page.evaluate("() => location.hash.split('/').pop()"))
    page.wait_for_selector("#submissions p")  # nobody has handed in yet


def student_logs_in_from_the_class_list(j: Journey) -> None:
    page = j.student
    page.goto(f"{j.lab.url}/")
    page.fill("#login-username", j.login)
    page.fill("#login-password", j.one_time)
    page.click("form button[type=submit]")
    page.wait_for_selector("#password-new")
    page.fill("#password-current", j.one_time)
    page.fill("#password-new", "joao's own long secret")
    page.click("form button[type=submit]")
    page.wait_for_function("() => !location.hash.includes('password')")
    page.wait_for_selector("#nav:not([hidden])")


def student_reads_the_guide(j: Journey) -> None:
    page = j.student
    page.goto(f"{j.lab.url}/#/rig/{j.rig}")
    open_panel_guide(page)
    shown = page.locator("[data-testid=guide-text]")
    shown.locator("h2").wait_for()
    assert j.course in shown.inner_text()
    assert page.locator("[data-testid=guide-edit]").count() == 0
    page.click("[data-testid=guide] .guide-head button")  # close it: back to the panel


def student_runs_the_experiment(j: Journey) -> None:
    page = j.student
    page.goto(f"{j.lab.url}/#/rig/{j.rig}")
    page.wait_for_selector("button[data-action=ask]")
    # Inside the course's slot: the page says the rig is the course's, and control is granted.
    own = catalogue(j.language)["chance.ownNow"].split("{")[0]
    page.wait_for_function(
        "(m) => document.querySelector('[data-testid=chance-now]')?.textContent.startsWith(m)",
        arg=own,
    )
    assert j.course_title in page.inner_text("[data-testid=chance-now]")
    page.click("button[data-action=ask]")
    page.wait_for_function(
        "() => document.querySelector('[data-testid=access-role]')?.dataset.role === 'controller'"
    )
    page.click("[role=tab][data-panel=srm-lsm]")
    page.fill("#srm-lsm-dt", "1")
    page.fill("#srm-lsm-n", "1500")
    page.fill("#srm-lsm-setpoint", "0")
    page.click("[data-panel-view=srm-lsm] button[data-action=start]")
    page.wait_for_function("() => +document.querySelector('[data-readout=k]').textContent > 20")
    page.fill("[data-run-form=srm-lsm] input[name=setpoint-live]", "10")
    page.click("[data-run-form=srm-lsm] button[data-action=setpoint]")
    row = "[data-testid=results-srm-lsm] [data-method=lsm]"
    words = catalogue(j.language)
    page.wait_for_function(
        """([sel, finished]) => document.querySelector(sel)?.textContent.includes(finished)""",
        arg=["[data-testid=run-status-srm-lsm]", words["runStatus.finished"]],
        timeout=90_000,
    )
    page.wait_for_function(
        """([sel, final]) => document.querySelector(sel)?.textContent.includes(final)""",
        arg=[f"{row} [data-field=status]", words["estimate.final"]],
    )
    j.run_text = {
        "K": page.inner_text(f"{row} [data-field=K]").splitlines()[0],
        "tau": page.inner_text(f"{row} [data-field=tau]").splitlines()[0],
    }
    page.click("button[data-action=release]")


def student_hands_in_and_reads_the_mark(j: Journey) -> None:
    page = j.student
    page.click("#nav a[data-nav=assignments]")
    page.locator(f"a[data-assignment='{j.assignment}']").click()
    page.wait_for_selector("#handin-form")
    page.wait_for_selector("#handin-run option", state="attached")
    page.fill("#handin-k", j.run_text["K"])
    page.fill("#handin-tau", j.run_text["tau"])
    page.fill("#handin-theta", "0")
    page.fill("#handin-conclusion", TYPED[j.language][1])
    page.click("#handin-form button[type=submit]")
    page.wait_for_selector("[data-testid=mark]")
    assert page.inner_text("[data-testid=mark]") == j.words["mark"]
    verdicts = page.eval_on_selector_all(
        "#feedback tr[data-check]", "rows => rows.map(r => r.dataset.verdict)"
    )
    assert verdicts == ["pass"] * 6  # Ks, Ts, θ against the twin and against the run
    theta = page.inner_text("#feedback tr[data-check=theta-reference]")
    assert f"±{j.words['theta']} s" in theta
    assert page.locator("[data-testid=late]").count() == 0
    assert serious_violations(page) == []
    page.screenshot(path=str(j.artifacts / f"journey-handin-{j.suffix}.png"), full_page=True)


def teacher_sees_the_hand_in_and_exports_grades(j: Journey) -> None:
    page = j.teacher
    page.goto(f"{j.lab.url}/#/assignments/{j.assignment}")
    page.reload()  # the page set the assignment: read its hand-ins again
    row = page.locator(f"#submissions tr[data-student='{j.login}']")
    row.wait_for()
    assert j.words["state"] in row.inner_text()
    assert serious_violations(page) == []
    with page.expect_download() as download:
        page.click("#grades-link")
    text = Path(download.value.path()).read_text(encoding="utf-8")
    rows = list(csv.DictReader(io.StringIO(text)))
    mine = [r for r in rows if r["student"] == j.login]
    assert len(mine) == 1
    assert mine[0]["display_name"] == "João Gonçalves"
    assert (mine[0]["state"], mine[0]["mark"], mine[0]["max"]) == ("marked", "10.0", "10.0")
    assert mine[0]["late"] == "no"
    assert mine[0]["course"] == j.course
    # Beside it, the grades as a spreadsheet in the page's language opens them.
    with page.expect_download() as download:
        page.click("#grades-sheet-link")
    sheet = Path(download.value.path()).read_text(encoding="utf-8-sig")
    separator, no = {"pt-BR": (";", "não"), "es": (";", "no"), "en": (",", "no")}[j.language]
    table = list(csv.reader(io.StringIO(sheet), delimiter=separator))
    (line,) = [r for r in table[1:] if r[3] == j.login]
    assert line[4:9] == ["João Gonçalves", j.words["state"], "10", "10", no]


def teacher_finds_the_journey_in_the_audit_log(j: Journey) -> None:
    done = {(a, target) for a, target in audited(j.teacher, "tess") if target.startswith(j.course)}
    assert done == {
        ("course.created", j.course),
        ("course.roster", j.course),
        ("assignment.changed", f"{j.course} #{j.assignment}"),
    }


#: The journey, in order (the booking after the guide, before the run inside the slot).
STEPS: list[Callable[[Journey], None]] = [
    teacher_uploads_a_class_list,
    teacher_writes_a_guide_page,
    teacher_books_a_slot_for_the_course,
    teacher_sets_an_assignment,
    student_logs_in_from_the_class_list,
    student_reads_the_guide,
    student_runs_the_experiment,
    student_hands_in_and_reads_the_mark,
    teacher_sees_the_hand_in_and_exports_grades,
    teacher_finds_the_journey_in_the_audit_log,
]


def test_a_teacher_and_a_student_go_from_class_list_to_grades(
    language: str, browser: Any, journey_lab: Any, artifacts: Path
) -> None:
    words = WORDS[language]
    options = {
        "locale": words["locale"],
        "bypass_csp": True,
        "viewport": {"width": 1280, "height": 900},
    }
    # Logged in through the form (not a cached cookie: each database has its own lab).
    teacher = browser.new_context(accept_downloads=True, **options)
    student = browser.new_context(accept_downloads=True, **options)
    errors: list[str] = []
    try:
        j = Journey(journey_lab, browser, language, artifacts)
        j.teacher = teacher.new_page()
        j.student = student.new_page()
        for page in (j.teacher, j.student):
            page.on("pageerror", lambda exc: errors.append(str(exc)))
        j.course = f"journey-{j.suffix}"
        j.teacher.goto(f"{journey_lab.url}/")
        j.teacher.fill("#login-username", "tess")
        j.teacher.fill("#login-password", journey_lab.password("tess"))
        j.teacher.click("form button[type=submit]")
        j.teacher.wait_for_selector("#nav:not([hidden])")
        english = ENGLISH if language == "pt-BR" else english_words(language) | MACHINE_NAMES
        met: list[str] = []
        for step in STEPS:
            try:
                step(j)
                if language != "en":
                    for who, page in (("teacher", j.teacher), ("student", j.student)):
                        met += _english_on(page, english, f"{step.__name__}, {who}")
            except Exception:
                for who, page in (("teacher", j.teacher), ("student", j.student)):
                    shot = artifacts / f"journey-failed-{step.__name__}-{who}-{j.suffix}.png"
                    page.screenshot(path=str(shot), full_page=True)
                raise
        assert errors == []
        assert met == [], "\n".join(met)
    finally:
        student.close()
        teacher.close()


def _english_on(page: Any, english: set[str], where: str) -> list[str]:
    """The English words a reader of ``page`` meets (none on a page not yet opened)."""
    if page.url in ("", "about:blank"):
        return []
    page.wait_for_load_state("networkidle")
    text = visible_text(page)
    found = sorted(words(text) & english)
    lines = [line for line in text.splitlines() if words(line) & set(found)]
    # The server's English the page declares (lang="en"): none is left either (#24).
    marked = page.evaluate(
        """() => [...document.body.querySelectorAll('span[lang=en]')]
          .filter((el) => el.getClientRects().length > 0).map((el) => el.textContent)"""
    )
    return ([f"{where}: {found} in {lines[:6]}"] if found else []) + (
        [f"{where}: marked English {marked[:6]}"] if marked else []
    )
