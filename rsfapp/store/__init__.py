"""The stores of the application database, bundled per database URL and process."""

from __future__ import annotations

from dataclasses import dataclass

from ..config import Settings
from ..db.engine import Database, database
from .jobs import JobState, JobStatus, JobStore
from .results import ResultStore
from .sweeps import SweepStore

__all__ = ["JobState", "JobStatus", "JobStore", "ResultStore", "Stores", "SweepStore", "stores_for"]


@dataclass(frozen=True)
class Stores:
    """Every store on one :class:`~rsfapp.db.engine.Database`."""

    db: Database
    results: ResultStore
    jobs: JobStore
    sweeps: SweepStore

    @classmethod
    def on(cls, db: Database) -> Stores:
        """The stores of ``db``."""
        return cls(db, ResultStore(db), JobStore(db), SweepStore(db))


_by_db: dict[int, Stores] = {}


def stores_for(settings: Settings) -> Stores:
    """The stores of this process for the database URL of ``settings``."""
    db = database(settings.effective_cache_url)
    st = _by_db.get(id(db))
    if st is None or st.db is not db:
        st = _by_db[id(db)] = Stores.on(db)
    return st
