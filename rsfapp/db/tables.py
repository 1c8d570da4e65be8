"""Every table of the application database, in one place.

* ``results``: every computed answer, keyed by sha256 of (kind, canonical request,
  numerics version) (:mod:`rsfapp.store.results`);
* ``jobs``: long single queries sent to the queue (:mod:`rsfapp.store.jobs`);
* ``sweeps``, ``sweep_chunks``, ``sweep_points``: sweep bookkeeping and results
  (:mod:`rsfapp.store.sweeps`);
* ``sweep_blocks``, ``sweep_inputs``: sweep results as compressed arrays, one row per
  chunk (``sweep_points`` is the pre-array layout, no longer written), and the scattered
  points of a sweep (:mod:`rsfapp.store.sweeps`);
* ``api_keys``, ``key_usage``, ``sweep_owners``: hashed API keys, their daily usage and
  the key that submitted each sweep (:mod:`rsfapp.store.keys`);
* ``rate_buckets``: the fresh-computation token bucket of each API key, shared by every
  API process and host (:mod:`rsfapp.store.ratelimits`);
* ``inflight_leases``: one row per computing request of an API key in flight, on any
  API process or host (its ``concurrent_requests`` quota; :mod:`rsfapp.store.inflight`).

Flat point indices, point counts and chunk numbers of sweeps are BIGINT (64-bit): a sweep
may hold more than 2^31 points (Alembic revision 0002, :mod:`rsfapp.db.migrate`), and so
may the sweep points a key submits in a day (``key_usage.points``, revision 0003).  A
sweep's progress is kept in counters of its row (chunks done, points stored and failed)
and its chunks are indexed by status (revision 0004).
"""

from __future__ import annotations

from sqlalchemy import (
    BigInteger,
    Column,
    Float,
    ForeignKey,
    Index,
    Integer,
    LargeBinary,
    MetaData,
    String,
    Table,
    Text,
)

__all__ = [
    "metadata",
    "results",
    "jobs",
    "sweeps",
    "chunks",
    "points",
    "api_keys",
    "key_usage",
    "sweep_owners",
    "sweep_blocks",
    "sweep_inputs",
    "rate_buckets",
    "inflight_leases",
]

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
    Column("n_total", BigInteger, nullable=False),
    Column("n_chunks", BigInteger, nullable=False),
    Column("numerics_version", String(32), nullable=False),
    Column("created_at", Float, nullable=False),
    Column("started_at", Float),
    Column("finished_at", Float),
    # progress counters, updated in the transaction that stores a block or marks a chunk
    # done (revision 0004): completion and status are O(1), not a count over the chunks
    Column("chunks_done", BigInteger, nullable=False, server_default="0"),
    Column("points_done", BigInteger, nullable=False, server_default="0"),
    Column("points_failed", BigInteger, nullable=False, server_default="0"),
)

chunks = Table(
    "sweep_chunks",
    metadata,
    Column("sweep_id", String(64), ForeignKey("sweeps.id"), primary_key=True),
    Column("idx", BigInteger, primary_key=True),
    Column("i0", BigInteger, nullable=False),
    Column("i1", BigInteger, nullable=False),
    Column("status", String(16), nullable=False),  # queued|running|done|cancelled
    Column("owner", String(128)),
    Column("heartbeat", Float),
    Column("attempts", Integer, nullable=False, default=0),
)
# a sweep's chunks by status in index order (revision 0004): the next pending chunk and
# the chunks in flight are found without reading the sweep's other chunks
Index("ix_sweep_chunks_status", chunks.c.sweep_id, chunks.c.status, chunks.c.idx)

points = Table(
    "sweep_points",
    metadata,
    Column("sweep_id", String(64), ForeignKey("sweeps.id"), primary_key=True),
    Column("idx", BigInteger, primary_key=True),
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
    Column("points", BigInteger, nullable=False, default=0),  # sweep points; > 2^31 fit (0003)
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
    Column("idx", BigInteger, primary_key=True),
    Column("i0", BigInteger, nullable=False),
    Column("i1", BigInteger, nullable=False),
    Column("n_failed", BigInteger, nullable=False),
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
