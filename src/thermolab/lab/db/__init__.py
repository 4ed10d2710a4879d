"""The lab's database: tables (:mod:`.models`), engine and transactions, migrations.

``migrations/`` holds the Alembic revisions; :meth:`Database.upgrade` runs them.
Tables of later features are declared in modules of their own (``*_models``)
and imported here, so that ``Base.metadata`` is complete wherever the database
is used (the migrations' environment, the schema test).
"""

from thermolab.lab.db import (  # noqa: F401
    agent_models,
    assignment_models,
    audit_models,
    booking_models,
    booking_tool_models,
    course_settings_models,
    grading_models,
    guide_image_models,
    guide_models,
    login_models,
    lti_models,
    power_models,
    settings_models,
)
from thermolab.lab.db.engine import MIGRATIONS_DIR, Database, normalize_database_url

__all__ = ["MIGRATIONS_DIR", "Database", "normalize_database_url"]
