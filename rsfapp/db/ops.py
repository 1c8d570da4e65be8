"""Operational tables of the application database (on the shared ``metadata``).

* ``rsf_schema``: one row, the hand-migrated schema version of releases before Alembic
  (1 or 2); :data:`rsfapp.db.migrate.LEGACY_MARK` once Alembic manages the database, so
  those releases refuse it;
* ``rsf_workers``: one row per running worker process (node, host, pid), its
  heartbeat renewed by the reaper thread; /health counts the live ones.
"""

from __future__ import annotations

from sqlalchemy import Column, Float, Integer, String, Table

from .tables import metadata

__all__ = ["schema", "workers"]

schema = Table(
    "rsf_schema",
    metadata,
    Column("id", Integer, primary_key=True),  # always 1
    Column("version", Integer, nullable=False),
    Column("updated_at", Float, nullable=False),
)

workers = Table(
    "rsf_workers",
    metadata,
    Column("name", String(200), primary_key=True),  # node:pid (unique per process)
    Column("node", String(100), nullable=False),
    Column("pid", Integer, nullable=False),
    Column("concurrency", Integer, nullable=False),
    Column("started_at", Float, nullable=False),
    Column("heartbeat", Float, nullable=False),
)
