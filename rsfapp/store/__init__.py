"""The stores of the application database, one bundle per database and process.

:class:`Stores` holds every store on one :class:`~rsfapp.db.engine.Database`: results,
jobs and sweeps (the computations), API keys, token buckets and in-flight leases (who
may ask).  :func:`stores_for` is the one cache of this process: the same settings give
the same bundle, so a store that keeps per-process state (the result store's hit counter,
the key store's SQLite connection read on the event loop) exists once per database.
"""

from __future__ import annotations

import threading
from dataclasses import dataclass

from ..config import Settings
from ..db.engine import Database, database
from .inflight import InflightStore
from .jobs import JobState, JobStatus, JobStore
from .keys import KeyStore
from .ratelimits import RateLimitStore
from .results import ResultStore
from .sweeps import SweepStore

__all__ = [
    "InflightStore",
    "JobState",
    "JobStatus",
    "JobStore",
    "KeyStore",
    "RateLimitStore",
    "ResultStore",
    "Stores",
    "SweepStore",
    "stores_for",
]


@dataclass(frozen=True)
class Stores:
    """Every store on one :class:`~rsfapp.db.engine.Database`.

    Attributes:
        db: the database.
        results: cached results (:mod:`rsfapp.store.results`).
        jobs: deferred single queries and fits (:mod:`rsfapp.store.jobs`).
        sweeps: sweeps and their chunks (:mod:`rsfapp.store.sweeps`).
        keys: API keys, their usage and sweep owners (:mod:`rsfapp.store.keys`).
        rates: the keys' fresh-computation token buckets (:mod:`rsfapp.store.ratelimits`).
        leases: the keys' requests in flight (:mod:`rsfapp.store.inflight`).
    """

    db: Database
    results: ResultStore
    jobs: JobStore
    sweeps: SweepStore
    keys: KeyStore
    rates: RateLimitStore
    leases: InflightStore

    @classmethod
    def on(cls, db: Database) -> Stores:
        """The stores of ``db`` (a new bundle: use :func:`stores_for` to share one)."""
        return cls(
            db,
            ResultStore(db),
            JobStore(db),
            SweepStore(db),
            KeyStore(db),
            RateLimitStore(db),
            InflightStore(db),
        )


_by_db: dict[int, Stores] = {}
_lock = threading.Lock()


def stores_for(settings: Settings) -> Stores:
    """This process's bundle of stores for the database URL of ``settings``."""
    db = database(settings.effective_cache_url)
    st = _by_db.get(id(db))
    if st is None or st.db is not db:
        with _lock:
            st = _by_db.get(id(db))
            if st is None or st.db is not db:
                st = _by_db[id(db)] = Stores.on(db)
    return st
