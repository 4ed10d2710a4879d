"""The documentation's Python examples run as tests, so the site cannot lie.

Every ```` ```python ```` block of the pages below is executed by Sybil, in page
order, in one namespace per page; a block written as a ``>>>`` session is a
doctest, so the figures it prints are checked (the examples round them: Sybil runs
the standard library's doctest, without pytest's ``NUMBER``). A block that needs a running
lab server is preceded by ``<!-- skip: next -->`` (Sybil's skip directive).

The student's guides (English and pt-BR) must also quote the interface's buttons
and pages as the browser's message catalogues have them (INICIAR, ENCERRAR...).
"""

from __future__ import annotations

import doctest
import re
from pathlib import Path

import pytest
from sybil import Sybil
from sybil.parsers.markdown import PythonCodeBlockParser, SkipParser

ROOT = Path(__file__).resolve().parent.parent
DOCS = ROOT / "docs"

#: The pages whose examples run: the README and every Markdown page of the site
#: (the reference pages aside: they are generated from the code).
PAGES = [
    ROOT / "README.md",
    *sorted(p for p in DOCS.rglob("*.md") if "reference" not in p.relative_to(DOCS).parts),
]

FLAGS = doctest.NORMALIZE_WHITESPACE | doctest.ELLIPSIS

SYBIL = Sybil(parsers=[PythonCodeBlockParser(doctest_optionflags=FLAGS), SkipParser()])


def test_pages_have_examples() -> None:
    """The user guides' identification examples are among the pages tested."""
    sources = "\n".join(p.read_text(encoding="utf-8") for p in PAGES)
    for name in ("step_response", "least_squares", "moving_window_least_squares", "parse_signal"):
        assert name in sources, name


@pytest.mark.parametrize("page", PAGES, ids=[str(p.relative_to(ROOT)) for p in PAGES])
def test_page_examples(page: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Every example of ``page`` runs (in a temporary folder) and prints what it says."""
    monkeypatch.chdir(tmp_path)  # examples that write a CSV write it here
    document = SYBIL.parse(page)
    for example in document.examples():
        example.evaluate()


MESSAGES = ROOT / "src" / "thermolab" / "web" / "static" / "js" / "messages"

#: The interface's labels a student's guide names: each guide must quote them as
#: its language's catalogue has them, so a renamed button shows up here.
STUDENT_LABELS = (
    "access.ask",
    "access.release",
    "turn.extend",
    "panel.start",
    "panel.end",
    "guide.open",
    "loop.use",
    "nav.rigs",
    "nav.runs",
    "nav.assignments",
    "nav.bookings",
    "nav.account",
)


def catalogue(language: str) -> dict[str, str]:
    """The browser's message catalogue of ``language`` (its plain string values)."""
    text = (MESSAGES / f"{language}.js").read_text(encoding="utf-8")
    return dict(re.findall(r'^  "([^"]+)": "((?:[^"\\]|\\.)*)",?$', text, re.MULTILINE))


@pytest.mark.parametrize(
    ("page", "language"), [("student.md", "en"), ("pt-BR/estudante.md", "pt-BR")]
)
def test_student_guide_quotes_the_interface(page: str, language: str) -> None:
    """The student's guide names the buttons and pages as the interface shows them."""
    text = " ".join((DOCS / page).read_text(encoding="utf-8").split())  # lines wrapped
    labels = catalogue(language)
    missing = [f"{key} = {labels[key]!r}" for key in STUDENT_LABELS if labels[key] not in text]
    assert not missing, f"{page} does not quote: {missing}"
