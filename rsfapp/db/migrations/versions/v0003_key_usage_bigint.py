"""``key_usage.points`` as BIGINT: a key's sweep points of one day may exceed 2^31
(a quota above 2^31 - 1, or many sweeps of the 10^8-point maximum).

PostgreSQL: ALTER COLUMN ... TYPE BIGINT (a rewrite of the small usage table, inside the
upgrade's transaction; a no-op on a column already BIGINT).  SQLite's INTEGER already
holds 64-bit values: nothing to do (:func:`rsfapp.db.migrate.compare_type` treats the
two as one there).

Revision ID: 0003
Revises: 0002
Create Date: 2026-11-26
"""

from __future__ import annotations

import sqlalchemy as sa
from alembic import op

__all__ = ["revision", "down_revision", "upgrade", "downgrade"]

revision = "0003"
down_revision = "0002"
branch_labels = None
depends_on = None


def _alter(type_: str) -> None:
    if op.get_bind().dialect.name != "postgresql":
        return
    op.execute(sa.text(f"ALTER TABLE key_usage ALTER COLUMN points TYPE {type_}"))


def upgrade() -> None:
    _alter("BIGINT")


def downgrade() -> None:
    _alter("INTEGER")
