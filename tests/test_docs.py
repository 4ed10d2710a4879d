"""The documentation's Python examples run as tests, so the site cannot lie.

Every ```` ```python ```` block of the pages below is executed by Sybil, in page
order, in one namespace per page; a block written as a ``>>>`` session is a
doctest, so the figures it prints are checked (the examples round them: Sybil runs
the standard library's doctest, without pytest's ``NUMBER``). A block that needs a running
lab server is preceded by ``<!-- skip: next -->`` (Sybil's skip directive).
"""

from __future__ import annotations

import doctest
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
