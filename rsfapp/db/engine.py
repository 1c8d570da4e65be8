"""The database of results, jobs and sweeps: SQLite (WAL) by default, PostgreSQL for
several hosts, through one SQLAlchemy code path.

SQLite specifics: WAL journal (readers never block the writer), a 60 s busy timeout,
and write transactions opened with ``BEGIN IMMEDIATE`` so that two writers never
deadlock on a read-to-write lock upgrade.  Reads use plain deferred transactions.
Any other SQLAlchemy URL (PostgreSQL for multi-host workers) is used as is, with
``pool_pre_ping`` so a dropped connection is replaced.
"""
from __future__ import annotations

import os
import threading
from collections.abc import Iterator, Mapping, Sequence
from contextlib import contextmanager
from typing import Any

from sqlalchemy import Connection, Engine, Table, create_engine, event
from sqlalchemy.dialects import postgresql, sqlite

from .tables import metadata

__all__ = ["Database", "database", "insert_ignore"]


def _sqlite_engine(url: str, begin: str) -> Engine:
    eng = create_engine(url, connect_args={"timeout": 60, "check_same_thread": False},
                        pool_size=8, max_overflow=16)

    @event.listens_for(eng, "connect")
    def _on_connect(dbapi_conn: Any, _record: Any) -> None:
        dbapi_conn.isolation_level = None  # we issue BEGIN ourselves
        cur = dbapi_conn.cursor()
        cur.execute("PRAGMA journal_mode=WAL")
        cur.execute("PRAGMA synchronous=NORMAL")
        cur.execute("PRAGMA busy_timeout=60000")
        cur.execute("PRAGMA foreign_keys=ON")
        cur.close()

    @event.listens_for(eng, "begin")
    def _on_begin(conn: Connection) -> None:
        conn.exec_driver_sql(begin)

    return eng


class Database:
    """A read engine and a write engine on one URL; the tables are created on first use.

    Args:
        url: SQLAlchemy URL (``sqlite:///path`` or ``postgresql+psycopg://...``).
    """

    def __init__(self, url: str) -> None:
        self.url = url
        if url.startswith("sqlite"):
            self.reader = _sqlite_engine(url, "BEGIN")
            self.writer = _sqlite_engine(url, "BEGIN IMMEDIATE")
        else:
            eng = create_engine(url, pool_pre_ping=True)
            self.reader = self.writer = eng
        with self.writer.begin() as conn:
            metadata.create_all(conn)

    @property
    def dialect(self) -> str:
        """'sqlite' or 'postgresql'."""
        return self.writer.dialect.name

    @contextmanager
    def read(self) -> Iterator[Connection]:
        """A read transaction."""
        with self.reader.connect() as conn:
            yield conn

    @contextmanager
    def write(self) -> Iterator[Connection]:
        """A write transaction (committed on exit, rolled back on error)."""
        with self.writer.begin() as conn:
            yield conn

    def dispose(self) -> None:
        """Close every pooled connection."""
        self.reader.dispose()
        if self.writer is not self.reader:
            self.writer.dispose()


_lock = threading.Lock()
_databases: dict[tuple[int, str], Database] = {}


def database(url: str) -> Database:
    """The :class:`Database` of ``url`` in this process (never shared across fork)."""
    key = (os.getpid(), url)
    with _lock:
        db = _databases.get(key)
        if db is None:
            db = _databases[key] = Database(url)
    return db


def insert_ignore(conn: Connection, table: Table,
                  rows: Sequence[Mapping[str, Any]] | Mapping[str, Any]) -> int:
    """INSERT rows, silently skipping those whose primary key exists; returns rows added."""
    if not rows:
        return 0
    mod: Any = postgresql if conn.dialect.name == "postgresql" else sqlite
    stmt = mod.insert(table).on_conflict_do_nothing()
    res = conn.execute(stmt, list(rows) if isinstance(rows, Sequence) else [rows])
    return max(res.rowcount or 0, 0)
