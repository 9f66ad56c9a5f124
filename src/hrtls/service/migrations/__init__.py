"""Alembic migrations of the service schema, run by :func:`hrtls.service.db.migrate`."""
