"""Base: the schema of release 0.1.0 (the last one migrated by hand, rsf_schema 1).

Each table is created only where it is missing: a database made by 0.1.0 (every table
present, ``rsf_schema.version`` = 1) upgrades in place with its data, and so does one
made by an older 0.1 build that lacks the tables added later by ``create_all``
(``rate_buckets``, ``inflight_leases``).  The definitions are frozen here (never import
the live tables into a revision).

Revision ID: 0001
Revises:
Create Date: 2026-11-26
"""

from __future__ import annotations

from typing import Any

import sqlalchemy as sa
from alembic import op

__all__ = ["revision", "down_revision", "upgrade", "downgrade"]

revision = "0001"
down_revision = None
branch_labels = None
depends_on = None

_F, _I, _S, _T, _B = sa.Float, sa.Integer, sa.String, sa.Text, sa.LargeBinary


def _col(name: str, type_: Any, *args: Any, **kw: Any) -> sa.Column[Any]:
    return sa.Column(name, type_, *args, **kw)


def _tables() -> list[tuple[str, list[sa.Column[Any]]]]:
    pk, nn = {"primary_key": True}, {"nullable": False}
    sweep_fk = sa.ForeignKey("sweeps.id")
    return [
        (
            "results",
            [
                _col("key", _S(64), **pk),
                _col("kind", _S(32), index=True, **nn),
                _col("numerics_version", _S(32), **nn),
                _col("request", _T, **nn),
                _col("result", _T, **nn),
                _col("created_at", _F, **nn),
            ],
        ),
        (
            "jobs",
            [
                _col("key", _S(64), **pk),
                _col("kind", _S(32), **nn),
                _col("state", _S(16), **nn),
                _col("message", _T, **nn),
                _col("updated_at", _F, **nn),
            ],
        ),
        (
            "sweeps",
            [
                _col("id", _S(64), **pk),
                _col("spec", _T, **nn),
                _col("status", _S(16), **nn),
                _col("n_total", _I, **nn),
                _col("n_chunks", _I, **nn),
                _col("numerics_version", _S(32), **nn),
                _col("created_at", _F, **nn),
                _col("started_at", _F),
                _col("finished_at", _F),
            ],
        ),
        (
            "sweep_chunks",
            [
                _col("sweep_id", _S(64), sweep_fk, **pk),
                _col("idx", _I, **pk),
                _col("i0", _I, **nn),
                _col("i1", _I, **nn),
                _col("status", _S(16), **nn),
                _col("owner", _S(128)),
                _col("heartbeat", _F),
                _col("attempts", _I, **nn),
            ],
        ),
        (
            "sweep_points",
            [
                _col("sweep_id", _S(64), sa.ForeignKey("sweeps.id"), **pk),
                _col("idx", _I, **pk),
                _col("i", _I, **nn),
                _col("j", _I, **nn),
                _col("x", _F, **nn),
                _col("y", _F, **nn),
                _col("kind", _S(16)),
                _col("critical_size", _F),
                _col("outcome", _S(16)),
                _col("rel_accuracy", _F),
                _col("error", _T),
                _col("created_at", _F, **nn),
            ],
        ),
        (
            "api_keys",
            [
                _col("name", _S(64), **pk),
                _col("key_hash", _S(64), unique=True, **nn),
                _col("scope", _S(8), **nn),
                _col("quotas", _T, **nn),
                _col("created_at", _F, **nn),
                _col("revoked_at", _F),
            ],
        ),
        (
            "key_usage",
            [
                _col("name", _S(64), **pk),
                _col("day", _I, **pk),
                _col("points", _I, **nn),
            ],
        ),
        (
            "sweep_owners",
            [
                _col("sweep_id", _S(64), **pk),
                _col("owner", _S(64), index=True, **nn),
            ],
        ),
        (
            "sweep_blocks",
            [
                _col("sweep_id", _S(64), sa.ForeignKey("sweeps.id"), **pk),
                _col("idx", _I, **pk),
                _col("i0", _I, **nn),
                _col("i1", _I, **nn),
                _col("n_failed", _I, **nn),
                _col("data", _B, **nn),
                _col("errors", _T),
                _col("created_at", _F, **nn),
            ],
        ),
        (
            "sweep_inputs",
            [
                _col("sweep_id", _S(64), sa.ForeignKey("sweeps.id"), **pk),
                _col("data", _B, **nn),
            ],
        ),
        (
            "rate_buckets",
            [
                _col("key_id", _S(64), **pk),
                _col("tokens", _F, **nn),
                _col("stamp", _F, **nn),
                _col("rate", _F, **nn),
                _col("capacity", _F, **nn),
            ],
        ),
        (
            "inflight_leases",
            [
                _col("lease_id", _S(32), **pk),
                _col("key_id", _S(64), index=True, **nn),
                _col("expires_at", _F, index=True, **nn),
            ],
        ),
        (
            "rsf_schema",
            [
                _col("id", _I, **pk),
                _col("version", _I, **nn),
                _col("updated_at", _F, **nn),
            ],
        ),
        (
            "rsf_workers",
            [
                _col("name", _S(200), **pk),
                _col("node", _S(100), **nn),
                _col("pid", _I, **nn),
                _col("concurrency", _I, **nn),
                _col("started_at", _F, **nn),
                _col("heartbeat", _F, **nn),
            ],
        ),
    ]


def upgrade() -> None:
    have = set(sa.inspect(op.get_bind()).get_table_names())
    for name, cols in _tables():
        if name not in have:
            op.create_table(name, *cols)


def downgrade() -> None:
    for name, _cols in reversed(_tables()):
        op.drop_table(name)
