"""The release notes name every migration the package ships, and no other."""

from __future__ import annotations

import re
from pathlib import Path

from thermolab.lab.db import MIGRATIONS_DIR
from thermolab.lab.operations.backup import known_revisions

NOTES = Path(__file__).parents[2] / "docs" / "release-notes.md"
HEADING = re.compile(r"^### (\d{4}) — .+ \(`(v\d{4}_\w+)`\)$", re.MULTILINE)


def _shipped() -> dict[str, str]:
    """Migration file (without ``.py``) -> its Alembic revision, from the files themselves."""
    files = {}
    for path in sorted((MIGRATIONS_DIR / "versions").glob("v*.py")):
        found = re.search(r'^revision: str = "(\w+)"$', path.read_text(), re.MULTILINE)
        assert found is not None, f"{path.name} declares no revision"
        files[path.stem] = found.group(1)
    return files


def test_every_migration_is_in_the_release_notes_under_its_revision() -> None:
    shipped = _shipped()
    named = {stem: revision for revision, stem in HEADING.findall(NOTES.read_text())}
    missing = sorted(set(shipped) - set(named))
    assert not missing, (
        f"docs/release-notes.md does not name {', '.join(missing)}: add a '### REVISION — what "
        f"(`FILE`)' heading and say what it changes"
    )
    stale = sorted(set(named) - set(shipped))
    assert not stale, f"docs/release-notes.md names migrations that do not exist: {stale}"
    assert named == shipped  # each under its own revision


def test_the_notes_list_the_migrations_in_the_order_they_run() -> None:
    order = [revision for revision, _ in HEADING.findall(NOTES.read_text())]
    assert order == known_revisions()
