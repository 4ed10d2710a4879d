"""Alembic migrations of the lab's schema (run by :meth:`thermolab.lab.db.Database.upgrade`)."""
