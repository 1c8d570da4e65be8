"""Sweep indices and counts as BIGINT (sweeps beyond 2^31 points; was rsf_schema 2).

PostgreSQL: ALTER COLUMN ... TYPE BIGINT (a table rewrite, inside the upgrade's
transaction and lock; a no-op on a column already BIGINT, as in a database migrated by
hand to rsf_schema 2).  SQLite's INTEGER already holds 64-bit values: nothing to do (the
declared type stays INTEGER; :func:`rsfapp.db.migrate.compare_type` treats the two as one
there).

Revision ID: 0002
Revises: 0001
Create Date: 2026-11-26
"""

from __future__ import annotations

import sqlalchemy as sa
from alembic import op

__all__ = ["BIGINT_COLUMNS", "revision", "down_revision", "upgrade", "downgrade"]

revision = "0002"
down_revision = "0001"
branch_labels = None
depends_on = None

#: {table: columns} widened to BIGINT.
BIGINT_COLUMNS: dict[str, tuple[str, ...]] = {
    "sweeps": ("n_total", "n_chunks"),
    "sweep_chunks": ("idx", "i0", "i1"),
    "sweep_blocks": ("idx", "i0", "i1", "n_failed"),
    "sweep_points": ("idx",),
}


def _alter(type_: str) -> None:
    if op.get_bind().dialect.name != "postgresql":
        return
    for table, cols in BIGINT_COLUMNS.items():
        alters = ", ".join(f"ALTER COLUMN {c} TYPE {type_}" for c in cols)
        op.execute(sa.text(f"ALTER TABLE {table} {alters}"))


def upgrade() -> None:
    _alter("BIGINT")


def downgrade() -> None:
    _alter("INTEGER")
