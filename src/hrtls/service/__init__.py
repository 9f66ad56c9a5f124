"""The supervisor: ``hrtls serve``, a live service that tracks the whole team (docs/service-api.md).

FastAPI + uvicorn on SQLAlchemy 2 (SQLite in WAL mode or PostgreSQL), schema migrations with
Alembic, one restorable tracker per agent. Import :func:`hrtls.service.app.create_app` to build
the application; nothing here is imported by ``hrtls --help``.
"""
