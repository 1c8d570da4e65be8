"""One SQLAlchemy engine per process for the cache database (SQLite WAL by default).

SQLite specifics: WAL journal (readers never block the writer), a 60 s busy timeout,
and write transactions opened with ``BEGIN IMMEDIATE`` so that two writers never
deadlock on a read-to-write lock upgrade.  Reads use plain deferred transactions.
Any other SQLAlchemy URL (PostgreSQL for multi-host workers) is used as is.
"""
from __future__ import annotations

import os
import threading
from contextlib import contextmanager
from typing import Iterator

from sqlalchemy import Connection, Engine, MetaData, Table, create_engine, event
from sqlalchemy.dialects import postgresql, sqlite

from service.settings import get_settings

__all__ = ["metadata", "engines", "read", "write", "insert_ignore"]

metadata = MetaData()
_lock = threading.Lock()
_engines: dict[tuple[int, str], tuple[Engine, Engine]] = {}


def _sqlite_engine(url: str, begin: str) -> Engine:
    eng = create_engine(url, connect_args={"timeout": 60, "check_same_thread": False},
                        pool_size=8, max_overflow=16)

    @event.listens_for(eng, "connect")
    def _on_connect(dbapi_conn, _record) -> None:  # noqa: ANN001
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


def engines(url: str | None = None) -> tuple[Engine, Engine]:
    """(read_engine, write_engine) for ``url`` (default: the cache URL setting).

    Engines are per process (never shared across fork) and create the tables once.
    """
    url = url or get_settings().effective_cache_url
    key = (os.getpid(), url)
    with _lock:
        pair = _engines.get(key)
        if pair is None:
            if url.startswith("sqlite"):
                pair = (_sqlite_engine(url, "BEGIN"), _sqlite_engine(url, "BEGIN IMMEDIATE"))
            else:
                eng = create_engine(url, pool_pre_ping=True)
                pair = (eng, eng)
            with pair[1].begin() as conn:
                metadata.create_all(conn)
            _engines[key] = pair
    return pair


@contextmanager
def read() -> Iterator[Connection]:
    """A read transaction on the cache database."""
    with engines()[0].connect() as conn:
        yield conn


@contextmanager
def write() -> Iterator[Connection]:
    """A write transaction (committed on exit, rolled back on error)."""
    with engines()[1].begin() as conn:
        yield conn


def insert_ignore(conn: Connection, table: Table, rows: list[dict] | dict) -> int:
    """INSERT rows, silently skipping those whose primary key exists; returns rows added."""
    if not rows:
        return 0
    mod = postgresql if conn.dialect.name == "postgresql" else sqlite
    stmt = mod.insert(table).on_conflict_do_nothing()
    res = conn.execute(stmt, rows if isinstance(rows, list) else [rows])
    return max(res.rowcount or 0, 0)
