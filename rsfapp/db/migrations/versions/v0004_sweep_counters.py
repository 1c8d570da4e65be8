"""Sweep progress counters and chunks indexed by status (O(1) chunk completion).

``sweeps`` gains ``chunks_done``, ``points_done`` and ``points_failed`` (BIGINT, 0 by
default), filled here from the rows already stored: the chunks marked done, the points
and failed points of the stored blocks.  ``sweep_chunks`` gains the index
``ix_sweep_chunks_status`` on (sweep_id, status, idx): a worker finds a sweep's next
pending chunk and counts its chunks in flight without reading its other chunks.  Both
dialects (ADD COLUMN with a server default; CREATE INDEX).

Revision ID: 0004
Revises: 0003
Create Date: 2026-11-26
"""

from __future__ import annotations

import sqlalchemy as sa
from alembic import op

__all__ = ["COUNTERS", "INDEX", "revision", "down_revision", "upgrade", "downgrade"]

revision = "0004"
down_revision = "0003"
branch_labels = None
depends_on = None

#: The new columns of ``sweeps``.
COUNTERS = ("chunks_done", "points_done", "points_failed")
#: The new index of ``sweep_chunks``.
INDEX = "ix_sweep_chunks_status"


def upgrade() -> None:
    for name in COUNTERS:
        op.add_column(
            "sweeps", sa.Column(name, sa.BigInteger(), nullable=False, server_default="0")
        )
    op.create_index(INDEX, "sweep_chunks", ["sweep_id", "status", "idx"])
    op.execute(
        sa.text(
            "UPDATE sweeps SET "
            "chunks_done = (SELECT count(*) FROM sweep_chunks c "
            "WHERE c.sweep_id = sweeps.id AND c.status = 'done'), "
            "points_done = (SELECT coalesce(sum(b.i1 - b.i0), 0) FROM sweep_blocks b "
            "WHERE b.sweep_id = sweeps.id), "
            "points_failed = (SELECT coalesce(sum(b.n_failed), 0) FROM sweep_blocks b "
            "WHERE b.sweep_id = sweeps.id)"
        )
    )


def downgrade() -> None:
    op.drop_index(INDEX, "sweep_chunks")
    with op.batch_alter_table("sweeps") as batch:
        for name in COUNTERS:
            batch.drop_column(name)
