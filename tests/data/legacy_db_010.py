"""The database code path of release 0.1.0 (commit c8e3207), frozen for the upgrade test
of tests/app/test_migrations.py: its tables (rsfapp/db/tables.py and ops.py as they were)
and its schema creation (``create_all``, then ``rsf_schema`` version 1, exactly as
``Database.ensure_schema`` of that release did on a new database)."""

from __future__ import annotations

import time

from sqlalchemy import (
    Column,
    Connection,
    Float,
    ForeignKey,
    Integer,
    LargeBinary,
    MetaData,
    String,
    Table,
    Text,
)

metadata = MetaData()

results = Table(
    "results",
    metadata,
    Column("key", String(64), primary_key=True),
    Column("kind", String(32), nullable=False, index=True),
    Column("numerics_version", String(32), nullable=False),
    Column("request", Text, nullable=False),
    Column("result", Text, nullable=False),
    Column("created_at", Float, nullable=False),
)

jobs = Table(
    "jobs",
    metadata,
    Column("key", String(64), primary_key=True),
    Column("kind", String(32), nullable=False),
    Column("state", String(16), nullable=False),  # queued | failed
    Column("message", Text, nullable=False, default=""),
    Column("updated_at", Float, nullable=False),
)

sweeps = Table(
    "sweeps",
    metadata,
    Column("id", String(64), primary_key=True),
    Column("spec", Text, nullable=False),
    Column("status", String(16), nullable=False),  # queued|running|done|cancelled
    Column("n_total", Integer, nullable=False),
    Column("n_chunks", Integer, nullable=False),
    Column("numerics_version", String(32), nullable=False),
    Column("created_at", Float, nullable=False),
    Column("started_at", Float),
    Column("finished_at", Float),
)

chunks = Table(
    "sweep_chunks",
    metadata,
    Column("sweep_id", String(64), ForeignKey("sweeps.id"), primary_key=True),
    Column("idx", Integer, primary_key=True),
    Column("i0", Integer, nullable=False),
    Column("i1", Integer, nullable=False),
    Column("status", String(16), nullable=False),  # queued|running|done|cancelled
    Column("owner", String(128)),
    Column("heartbeat", Float),
    Column("attempts", Integer, nullable=False, default=0),
)

points = Table(
    "sweep_points",
    metadata,
    Column("sweep_id", String(64), ForeignKey("sweeps.id"), primary_key=True),
    Column("idx", Integer, primary_key=True),
    Column("i", Integer, nullable=False),
    Column("j", Integer, nullable=False),
    Column("x", Float, nullable=False),
    Column("y", Float, nullable=False),
    Column("kind", String(16)),
    Column("critical_size", Float),
    Column("outcome", String(16)),
    Column("rel_accuracy", Float),
    Column("error", Text),
    Column("created_at", Float, nullable=False),
)

# API keys: only the sha256 of a key is stored; ``quotas`` is a JSON object of per-key
# overrides of the RSF_QUOTA_* defaults.
api_keys = Table(
    "api_keys",
    metadata,
    Column("name", String(64), primary_key=True),
    Column("key_hash", String(64), nullable=False, unique=True),
    Column("scope", String(8), nullable=False),  # read | submit | admin
    Column("quotas", Text, nullable=False, default="{}"),
    Column("created_at", Float, nullable=False),
    Column("revoked_at", Float),
)

key_usage = Table(
    "key_usage",
    metadata,
    Column("name", String(64), primary_key=True),
    Column("day", Integer, primary_key=True),  # UTC days since 1970-01-01
    Column("points", Integer, nullable=False, default=0),
)

# A side table (not a column of ``sweeps``) so that existing databases gain it on start.
sweep_owners = Table(
    "sweep_owners",
    metadata,
    Column("sweep_id", String(64), primary_key=True),
    Column("owner", String(64), nullable=False, index=True),
)

# Sweep results: one row per finished chunk, its points [i0, i1) as compressed numpy
# arrays (``data``, an .npz), ``errors`` a JSON object {offset in chunk: message} of the
# failed points.  Written once (primary key), so a chunk computed twice is stored once.
sweep_blocks = Table(
    "sweep_blocks",
    metadata,
    Column("sweep_id", String(64), ForeignKey("sweeps.id"), primary_key=True),
    Column("idx", Integer, primary_key=True),
    Column("i0", Integer, nullable=False),
    Column("i1", Integer, nullable=False),
    Column("n_failed", Integer, nullable=False),
    Column("data", LargeBinary, nullable=False),
    Column("errors", Text),
    Column("created_at", Float, nullable=False),
)

# The scattered points of a sweep (compressed .npz of one float64 array per parameter).
sweep_inputs = Table(
    "sweep_inputs",
    metadata,
    Column("sweep_id", String(64), ForeignKey("sweeps.id"), primary_key=True),
    Column("data", LargeBinary, nullable=False),
)

# Fresh-computation token buckets, one row per API key (its SHA-256), updated by single
# atomic statements (:mod:`rsfapp.store.ratelimits`).  A new table: ``create_all`` adds
# it to an existing database at start, so no migration (and no schema version bump).
rate_buckets = Table(
    "rate_buckets",
    metadata,
    Column("key_id", String(64), primary_key=True),
    Column("tokens", Float, nullable=False),  # level at ``stamp`` (may be negative)
    Column("stamp", Float, nullable=False),  # wall clock of ``tokens`` [s since 1970]
    Column("rate", Float, nullable=False),  # refill [tokens/s] of the last update
    Column("capacity", Float, nullable=False),  # burst [tokens] of the last update
)

# Leases of computing requests in flight, one row per request (:mod:`rsfapp.store.inflight`);
# a new table too, added by ``create_all`` at start.
inflight_leases = Table(
    "inflight_leases",
    metadata,
    Column("lease_id", String(32), primary_key=True),
    Column("key_id", String(64), nullable=False, index=True),  # SHA-256 of the API key
    Column("expires_at", Float, nullable=False, index=True),  # wall clock [s since 1970]
)
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


def create_010(conn: Connection) -> None:
    """What release 0.1.0 did on first use of a new database (inside its transaction)."""
    metadata.create_all(conn)
    conn.execute(schema.insert().values(id=1, version=1, updated_at=time.time()))
