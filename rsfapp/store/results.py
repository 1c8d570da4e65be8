"""Result cache: every computed answer keyed by its canonical request.

Key = sha256 of (kind, canonical JSON of the validated request including tolerances,
rsfcore.NUMERICS_VERSION) (:func:`rsfapp.keys.cache_key`).  Inserts are idempotent (the
first writer wins, later identical writes are no-ops), so concurrent processes may race
freely.
"""

from __future__ import annotations

import json
import threading
import time
from typing import Any

from sqlalchemy import func, select

from ..db.engine import Database, insert_ignore
from ..db.tables import results
from ..keys import canonical
from ..metrics import CACHE_LOOKUPS

__all__ = ["ResultStore"]


class ResultStore:
    """Cached results in ``db``; counts this process's hits and misses."""

    def __init__(self, db: Database) -> None:
        self.db = db
        self._lock = threading.Lock()
        self._hits = 0
        self._misses = 0

    def get_text(self, key: str) -> str | None:
        """The cached result JSON text for ``key`` or None (counts a hit or a miss)."""
        with self.db.read() as conn:
            row = conn.execute(select(results.c.result).where(results.c.key == key)).first()
        with self._lock:
            if row is None:
                self._misses += 1
            else:
                self._hits += 1
        CACHE_LOOKUPS.labels("miss" if row is None else "hit").inc()
        return None if row is None else str(row[0])

    def get(self, key: str) -> dict[str, Any] | None:
        """The cached result for ``key`` or None."""
        text = self.get_text(key)
        return None if text is None else dict(json.loads(text))

    def put(
        self,
        key: str,
        kind: str,
        numerics_version: str,
        request: dict[str, Any],
        result: dict[str, Any],
    ) -> bool:
        """Store a result unless the key exists; True if this call inserted it."""
        row = {
            "key": key,
            "kind": kind,
            "numerics_version": numerics_version,
            "request": canonical(request),
            "result": canonical(result),
            "created_at": time.time(),
        }
        with self.db.write() as conn:
            return insert_ignore(conn, results, row) == 1

    def stats(self) -> dict[str, Any]:
        """Entries per kind, total, and this process's hit/miss counters."""
        with self.db.read() as conn:
            rows = conn.execute(select(results.c.kind, func.count()).group_by(results.c.kind)).all()
        by_kind = {str(k): int(n) for k, n in rows}
        with self._lock:
            hits, misses = self._hits, self._misses
        return {
            "entries": sum(by_kind.values()),
            "by_kind": by_kind,
            "hits": hits,
            "misses": misses,
            "hit_ratio": hits / (hits + misses) if hits + misses else None,
        }
