"""The lab's database: tables (:mod:`.models`), engine and transactions, migrations.

``migrations/`` holds the Alembic revisions; :meth:`Database.upgrade` runs them.
"""

from thermolab.lab.db.engine import MIGRATIONS_DIR, Database, normalize_database_url

__all__ = ["MIGRATIONS_DIR", "Database", "normalize_database_url"]
