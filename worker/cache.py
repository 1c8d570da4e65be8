"""Result cache: every computed answer keyed by its canonical request.

Key = sha256 of (kind, canonical JSON of the validated request including tolerances,
rsfcore.NUMERICS_VERSION).  Inserts are idempotent (the first writer wins, later
identical writes are no-ops), so concurrent processes may race freely.
"""
from __future__ import annotations

import hashlib
import json
import threading
import time
from typing import Any

from sqlalchemy import Column, Float, String, Table, Text, func, select

from . import db

__all__ = ["cache_key", "canonical", "get", "put", "stats", "results"]

results = Table(
    "results", db.metadata,
    Column("key", String(64), primary_key=True),
    Column("kind", String(32), nullable=False, index=True),
    Column("numerics_version", String(32), nullable=False),
    Column("request", Text, nullable=False),
    Column("result", Text, nullable=False),
    Column("created_at", Float, nullable=False),
)

_counts_lock = threading.Lock()
_counts = {"hits": 0, "misses": 0}


def canonical(obj: Any) -> str:
    """Canonical JSON: sorted keys, no spaces, floats in repr form."""
    return json.dumps(obj, sort_keys=True, separators=(",", ":"), allow_nan=False)


def cache_key(kind: str, request: dict[str, Any], numerics_version: str) -> str:
    """Hex sha256 identifying (kind, request, numerics version)."""
    return hashlib.sha256(canonical([kind, request, numerics_version]).encode()).hexdigest()


def get(key: str) -> dict[str, Any] | None:
    """The cached result for ``key`` or None (counts a hit or a miss)."""
    with db.read() as conn:
        row = conn.execute(select(results.c.result).where(results.c.key == key)).first()
    with _counts_lock:
        _counts["hits" if row else "misses"] += 1
    return None if row is None else json.loads(row[0])


def put(key: str, kind: str, numerics_version: str, request: dict[str, Any],
        result: dict[str, Any]) -> bool:
    """Store a result unless the key exists; True if this call inserted it."""
    row = {"key": key, "kind": kind, "numerics_version": numerics_version,
           "request": canonical(request), "result": canonical(result), "created_at": time.time()}
    with db.write() as conn:
        return db.insert_ignore(conn, results, row) == 1


def stats() -> dict[str, Any]:
    """Entries per kind, total, and this process's hit/miss counters."""
    with db.read() as conn:
        rows = conn.execute(select(results.c.kind, func.count()).group_by(results.c.kind)).all()
    by_kind = {k: int(n) for k, n in rows}
    with _counts_lock:
        hits, misses = _counts["hits"], _counts["misses"]
    return {"entries": sum(by_kind.values()), "by_kind": by_kind,
            "hits": hits, "misses": misses,
            "hit_ratio": hits / (hits + misses) if hits + misses else None}
