"""Database access: one :class:`~rsfapp.db.engine.Database` per URL and process, and the
tables (:mod:`rsfapp.db.tables`)."""

from .engine import Database, database, insert_ignore
from .tables import metadata

__all__ = ["Database", "database", "insert_ignore", "metadata"]
