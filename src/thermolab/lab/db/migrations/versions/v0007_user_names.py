"""Login names in their normal form, and display names.

Revision ID: 0007
Revises: 0005
Create Date: 2026-11-24

Login names become NFKC, case folded, accents stripped
(``thermolab.lab.accounts.names.username_form``), so that two accounts never differ
only by case or accent; ``users.display_name`` keeps a name as written. Rows
stored earlier are rewritten to the normal form (the history of turns and
commands, which keeps names as text, too). If two existing accounts have the
same normal form the upgrade refuses, naming them, and changes nothing: a
person must remove or rename one (``thermolab user remove``) first; the
error (``ConfigError``) is the one line ``thermolab serve`` prints.
"""

from __future__ import annotations

import unicodedata
from collections import defaultdict

import sqlalchemy as sa
from alembic import op

from thermolab.errors import ConfigError

revision: str = "0007"
down_revision: str | None = "0006"
branch_labels: str | None = None
depends_on: str | None = None

# Tables that keep a user's name as text (the account may be gone).
_NAME_COLUMNS = (
    ("control_sessions", "username"),
    ("control_sessions", "ended_by"),
    ("commands", "username"),
)


def _form(username: str) -> str:
    # Self-contained (a migration must not change when the library does): the rule
    # of thermolab.lab.accounts.names.username_form at this revision.
    folded = unicodedata.normalize("NFKC", username).casefold()
    decomposed = unicodedata.normalize("NFD", folded)
    bare = "".join(ch for ch in decomposed if not unicodedata.combining(ch))
    return unicodedata.normalize("NFC", bare).strip()


def upgrade() -> None:
    bind = op.get_bind()
    users = sa.table("users", sa.column("id", sa.Integer), sa.column("username", sa.String))
    rows = bind.execute(sa.select(users.c.id, users.c.username)).all()
    by_form: dict[str, list[str]] = defaultdict(list)
    for _, name in rows:
        by_form[_form(name)].append(name)
    clashes = {form: names for form, names in by_form.items() if len(names) > 1}
    if clashes:
        listed = "; ".join(
            f"{', '.join(repr(n) for n in sorted(names))} -> {form!r}"
            for form, names in sorted(clashes.items())
        )
        raise ConfigError(
            "migration 0007 refused: these accounts differ only by case or accent and would "
            f"share one login name: {listed}; remove or rename all but one of each, then "
            "start again (nothing was changed)"
        )
    columns = {c["name"] for c in sa.inspect(bind).get_columns("users")}
    if "display_name" not in columns:
        with op.batch_alter_table("users") as batch:
            batch.add_column(sa.Column("display_name", sa.String(128), nullable=True))
    renamed = {name: _form(name) for _, name in rows if _form(name) != name}
    present = set(sa.inspect(bind).get_table_names())
    for old, new in renamed.items():
        bind.execute(sa.update(users).where(users.c.username == old).values(username=new))
        for table, column in _NAME_COLUMNS:
            if table not in present:
                continue
            named = sa.table(table, sa.column(column, sa.String))
            bind.execute(sa.update(named).where(named.c[column] == old).values({column: new}))


def downgrade() -> None:
    with op.batch_alter_table("users") as batch:
        batch.drop_column("display_name")
