"""Alembic's environment: runs the revisions on the connection that
:mod:`rsfapp.db.migrate` passes in ``config.attributes["connection"]`` (inside its
transaction, under its lock).  ``target_metadata`` is the code's tables, for
autogenerate (``rsf db revision``)."""

from __future__ import annotations

from alembic import context

from rsfapp.db import ops  # noqa: F401  (registers the rsf_* tables on the metadata)
from rsfapp.db.migrate import compare_type
from rsfapp.db.tables import metadata

__all__: list[str] = []

_conn = context.config.attributes.get("connection")
if _conn is None:
    raise RuntimeError("run migrations through rsfapp.db.migrate (`rsf db upgrade`)")
context.configure(
    connection=_conn,
    target_metadata=metadata,
    render_as_batch=_conn.dialect.name == "sqlite",  # SQLite alters tables by copying
    compare_type=compare_type,
)
with context.begin_transaction():
    context.run_migrations()
