"""The database of results, jobs and sweeps: SQLite (WAL) by default, PostgreSQL for
several hosts, through one SQLAlchemy code path.

SQLite specifics: WAL journal (readers never block the writer), a 60 s busy timeout,
and write transactions opened with ``BEGIN IMMEDIATE`` so that two writers never
deadlock on a read-to-write lock upgrade.  Reads use plain deferred transactions.

PostgreSQL (``postgresql+psycopg://user:pw@host/db``, extra ``postgres``): one pooled
engine (``RSF_DB_POOL_SIZE``, ``RSF_DB_MAX_OVERFLOW``, ``RSF_DB_POOL_TIMEOUT_S``),
``pool_pre_ping`` (a connection dropped by a server restart is replaced on checkout),
TCP keep-alives, READ COMMITTED isolation (stores that need more take row locks).

Outages: opening a connection is retried with exponential backoff (0.05 s doubling to
1 s) for ``RSF_DB_RETRY_S``; after that :class:`DatabaseUnavailable` is raised and, for
one second, further attempts fail at once (callers answer 503 instead of queueing up).
:func:`diagnose` turns any database exception into a :class:`DbProblem` (what is
wrong, how to recover) for the API's 503 answers, /health and start-up messages.

Schema: created and upgraded by the Alembic revisions of :mod:`rsfapp.db.migrate` at
first use (under a PostgreSQL advisory lock, so processes starting together do not race;
``rsf db upgrade`` does the same by hand); a database at a revision newer than the code
is refused (:class:`SchemaTooNew`).
"""

from __future__ import annotations

import os
import threading
import time
from collections.abc import Callable, Iterator, Mapping, Sequence
from contextlib import contextmanager
from typing import Any, NamedTuple

from sqlalchemy import Connection, Engine, Table, create_engine, event, text
from sqlalchemy import exc as sa_exc
from sqlalchemy.dialects import postgresql, sqlite

from . import migrate
from .migrate import SchemaTooNew

__all__ = [
    "Database",
    "DatabaseUnavailable",
    "DbProblem",
    "SchemaTooNew",
    "database",
    "diagnose",
    "insert_ignore",
    "inserted_keys",
]

_LOCK_ID = 0x72_73_66  # advisory lock key of schema creation ('rsf')


class DatabaseUnavailable(sa_exc.OperationalError):
    """The database could not be reached within the retry window."""

    def __init__(self, reason: str) -> None:
        Exception.__init__(self, reason)
        self.reason = reason
        self.statement, self.params, self.orig = None, None, None  # type: ignore[assignment]

    def __str__(self) -> str:
        return self.reason


class DbProblem(NamedTuple):
    """What is wrong with the database, for people.

    Attributes:
        kind: 'unavailable' (cannot connect / connection lost), 'busy' (locked, pool
            exhausted), 'damaged' (corrupt file or not a database) or 'schema'.
        reason: one line naming the database and the error.
        hint: how to recover.
    """

    kind: str
    reason: str
    hint: str


def _where(url: str) -> str:
    if url.startswith("sqlite"):
        return "SQLite file " + url.split("///", 1)[-1]
    host = url.split("@", 1)[-1]  # never show credentials
    return f"database {url.split('://', 1)[0]}://{host}"


def diagnose(exc: BaseException, url: str = "") -> DbProblem | None:
    """A :class:`DbProblem` for a database exception, or None if ``exc`` is not one."""
    where = _where(url) if url else "the database"
    msg = (
        str(getattr(exc, "orig", None) or exc).strip().splitlines()[0]
        if str(exc)
        else type(exc).__name__
    )
    low = msg.lower()
    if isinstance(exc, SchemaTooNew):
        return DbProblem(
            "schema",
            f"{where}: {exc}",
            "upgrade rsf on this machine to the version the other processes run "
            "(pip install -U 'rsf-stability[service]'), or point RSF_CACHE_URL at "
            "another database",
        )
    if isinstance(exc, DatabaseUnavailable):
        return DbProblem(
            "unavailable",
            f"{where} unavailable: {msg}",
            "check that the database server is running and reachable "
            "(RSF_CACHE_URL); requests are answered 503 until it is back",
        )
    if not isinstance(exc, sa_exc.SQLAlchemyError):
        import sqlite3

        if not isinstance(exc, sqlite3.Error):
            return None
    damaged = ("malformed", "not a database", "file is encrypted", "disk i/o error", "corrupt")
    if any(d in low for d in damaged):
        hint = (
            (
                "stop every rsf process using it, then move the file aside (results are a "
                "cache and are recomputed; unfinished sweeps must be resubmitted): "
                f"mv {url.split('///', 1)[-1]} {url.split('///', 1)[-1]}.damaged; "
                "or salvage it with `sqlite3 FILE .recover | sqlite3 NEW` and move NEW in "
                "its place"
            )
            if url.startswith("sqlite")
            else "restore the database from a backup; see the server's log"
        )
        return DbProblem("damaged", f"{where} is damaged: {msg}", hint)
    if "locked" in low or "queuepool limit" in low or "busy" in low:
        return DbProblem("busy", f"{where} busy: {msg}", "retry later")
    if isinstance(exc, (sa_exc.OperationalError, sa_exc.InterfaceError)) or getattr(
        exc, "connection_invalidated", False
    ):
        return DbProblem(
            "unavailable",
            f"{where} unavailable: {msg}",
            "check that the database server is running and reachable "
            "(RSF_CACHE_URL); requests are answered 503 until it is back",
        )
    if isinstance(exc, sa_exc.DBAPIError):
        return DbProblem("unavailable", f"{where} error: {msg}", "retry later")
    return None


def _sqlite_engine(url: str, begin: str) -> Engine:
    eng = create_engine(
        url, connect_args={"timeout": 60, "check_same_thread": False}, pool_size=8, max_overflow=16
    )

    @event.listens_for(eng, "connect")
    def _on_connect(dbapi_conn: Any, _record: Any) -> None:
        dbapi_conn.isolation_level = None  # we issue BEGIN ourselves
        cur = dbapi_conn.cursor()
        # free pages can be handed back by ``PRAGMA incremental_vacuum`` (takes effect on
        # a new file; an older one is converted by its first :meth:`Database.reclaim`)
        cur.execute("PRAGMA auto_vacuum=INCREMENTAL")
        cur.execute("PRAGMA journal_mode=WAL")
        cur.execute("PRAGMA synchronous=NORMAL")
        cur.execute("PRAGMA busy_timeout=60000")
        cur.execute("PRAGMA foreign_keys=ON")
        cur.close()

    @event.listens_for(eng, "begin")
    def _on_begin(conn: Connection) -> None:
        conn.exec_driver_sql(begin)

    return eng


class _Backoff:
    """Connection attempts with exponential backoff for ``window`` seconds, then fail
    fast for ``cool`` seconds (a caller gets its 503 at once while the server is down)."""

    def __init__(self, window: float, cool: float = 1.0) -> None:
        self.window, self.cool = window, cool
        self.down_until = 0.0
        self.last_error = ""

    def connect(self, fn: Callable[[], Any]) -> Any:
        now = time.monotonic()
        if now < self.down_until:
            raise DatabaseUnavailable(self.last_error or "database unavailable")
        deadline, delay = now + self.window, 0.05
        while True:
            try:
                conn = fn()
            except Exception as exc:  # noqa: BLE001 - driver-specific connect errors
                self.last_error = (
                    str(exc).strip().splitlines()[0] if str(exc) else type(exc).__name__
                )
                if time.monotonic() + delay > deadline:
                    self.down_until = time.monotonic() + self.cool
                    raise DatabaseUnavailable(self.last_error) from exc
                time.sleep(delay)
                delay = min(delay * 2, 1.0)
                continue
            self.down_until = 0.0
            return conn


def _server_engine(url: str, opts: Mapping[str, Any], backoff: _Backoff) -> Engine:
    connect_args: dict[str, Any] = {}
    if url.startswith("postgresql"):
        connect_args = {
            "connect_timeout": max(1, int(opts.get("connect_timeout", 5))),
            "keepalives": 1,
            "keepalives_idle": 10,
            "keepalives_interval": 5,
            "keepalives_count": 3,
            "application_name": "rsf",
        }
    eng = create_engine(
        url,
        pool_pre_ping=True,
        pool_size=int(opts.get("pool_size", 5)),
        max_overflow=int(opts.get("max_overflow", 10)),
        pool_timeout=float(opts.get("pool_timeout", 10.0)),
        pool_recycle=1800,
        connect_args=connect_args,
    )

    @event.listens_for(eng, "do_connect")
    def _connect(dialect: Any, _rec: Any, cargs: Any, cparams: Any) -> Any:
        return backoff.connect(lambda: dialect.connect(*cargs, **cparams))

    return eng


class Database:
    """A read engine and a write engine on one URL; the schema is ensured on first use.

    Args:
        url: SQLAlchemy URL (``sqlite:///path`` or ``postgresql+psycopg://...``).
        pool_size, max_overflow, pool_timeout, connect_timeout: pool settings of a
            server database (ignored for SQLite).
        retry_s: how long opening a connection is retried [s] before
            :class:`DatabaseUnavailable`.
    """

    def __init__(
        self,
        url: str,
        *,
        pool_size: int = 5,
        max_overflow: int = 10,
        pool_timeout: float = 10.0,
        connect_timeout: float = 5.0,
        retry_s: float = 2.0,
    ) -> None:
        self.url = url
        self._backoff = _Backoff(retry_s)
        if url.startswith("sqlite"):
            self.reader = _sqlite_engine(url, "BEGIN")
            self.writer = _sqlite_engine(url, "BEGIN IMMEDIATE")
        else:
            eng = _server_engine(
                url,
                {
                    "pool_size": pool_size,
                    "max_overflow": max_overflow,
                    "pool_timeout": pool_timeout,
                    "connect_timeout": connect_timeout,
                },
                self._backoff,
            )
            self.reader = self.writer = eng
        self._ready = False
        self._ready_lock = threading.Lock()

    @property
    def dialect(self) -> str:
        """'sqlite' or 'postgresql'."""
        return self.writer.dialect.name

    def ensure_schema(self) -> str | None:
        """Create or upgrade the schema to :func:`~rsfapp.db.migrate.head` with the
        Alembic revisions; returns the revision found before (None = new database or
        one made by release 0.1.0).  Raises :class:`SchemaTooNew`, changing nothing."""
        with self._ready_lock:
            with self.writer.begin() as conn:
                if self.dialect == "postgresql":
                    conn.execute(text("SELECT pg_advisory_xact_lock(:k)"), {"k": _LOCK_ID})
                before = migrate.upgrade(conn)
            self._ready = True
            return before

    def _ensure(self) -> None:
        if not self._ready:
            self.ensure_schema()

    @contextmanager
    def read(self) -> Iterator[Connection]:
        """A read transaction."""
        self._ensure()
        with self.reader.connect() as conn:
            yield conn

    @contextmanager
    def write(self) -> Iterator[Connection]:
        """A write transaction (committed on exit, rolled back on error)."""
        self._ensure()
        with self.writer.begin() as conn:
            yield conn

    def ping(self) -> None:
        """One round trip (``SELECT 1``); raises the database's error if it fails."""
        with self.reader.connect() as conn:
            conn.execute(text("SELECT 1"))

    def schema_version(self) -> str | None:
        """The Alembic revision of the database (None if it has none yet)."""
        with self.reader.connect() as conn:
            return migrate.current(conn)

    def quick_check(self, budget_s: float) -> str | None:
        """SQLite only: ``PRAGMA quick_check`` within ``budget_s`` seconds.

        Returns None when the file is sound (or the check ran out of time, or the
        database is not SQLite), else SQLite's first complaint.  Raises on errors
        opening the file (e.g. a damaged header)."""
        if self.dialect != "sqlite" or budget_s <= 0:
            return None
        raw = self.reader.raw_connection()
        try:
            dbapi = raw.driver_connection
            assert dbapi is not None
            deadline = time.monotonic() + budget_s
            dbapi.set_progress_handler(lambda: int(time.monotonic() > deadline), 10_000)
            try:
                rows = dbapi.execute("PRAGMA quick_check(5)").fetchall()
            except Exception as exc:  # noqa: BLE001
                if "interrupted" in str(exc):
                    return None
                raise
            finally:
                dbapi.set_progress_handler(None, 0)
        finally:
            raw.close()
        msgs = [str(r[0]) for r in rows]
        return None if msgs == ["ok"] else "; ".join(msgs)

    def reclaim(self, tables: Sequence[str]) -> None:
        """Give the disk space of deleted rows back (after a purge).

        SQLite: ``PRAGMA incremental_vacuum`` (a file created before incremental
        auto-vacuum is converted once by a full ``VACUUM``), then ``PRAGMA
        wal_checkpoint(TRUNCATE)`` empties the WAL file.  PostgreSQL: plain ``VACUUM`` of
        ``tables`` (not FULL: it takes no exclusive lock): the space of deleted rows is
        reusable at once and empty pages at the end of each table (and its TOAST table)
        go back to the operating system; ``VACUUM FULL`` by an operator returns the rest.
        Errors are the caller's to log: the rows are deleted either way."""
        if self.dialect == "sqlite":
            raw = self.writer.raw_connection()
            try:
                dbapi = raw.driver_connection
                assert dbapi is not None
                mode = dbapi.execute("PRAGMA auto_vacuum").fetchone()[0]
                if int(mode) != 2:  # NONE or FULL: convert once
                    dbapi.execute("PRAGMA auto_vacuum=INCREMENTAL")
                    dbapi.execute("VACUUM")
                else:
                    # executescript steps the pragma to its end (execute() frees one page)
                    dbapi.executescript("PRAGMA incremental_vacuum;")
                dbapi.execute("PRAGMA wal_checkpoint(TRUNCATE)").fetchall()
            finally:
                raw.close()
            return
        with self.writer.connect().execution_options(isolation_level="AUTOCOMMIT") as conn:
            for t in tables:
                if not t.replace("_", "").isalnum():  # table names only, never user text
                    raise ValueError(f"not a table name: {t!r}")
                conn.exec_driver_sql(f"VACUUM {t}")

    def dispose(self) -> None:
        """Close every pooled connection."""
        self.reader.dispose()
        if self.writer is not self.reader:
            self.writer.dispose()


_lock = threading.Lock()
_databases: dict[tuple[int, str], Database] = {}


def database(url: str) -> Database:
    """The :class:`Database` of ``url`` in this process (never shared across fork),
    with the pool and retry settings of this process (:mod:`rsfapp.config`)."""
    key = (os.getpid(), url)
    with _lock:
        db = _databases.get(key)
        if db is None:
            from ..config import get_settings

            s = get_settings()
            db = _databases[key] = Database(
                url,
                pool_size=s.db_pool_size,
                max_overflow=s.db_max_overflow,
                pool_timeout=s.db_pool_timeout_s,
                connect_timeout=s.db_connect_timeout_s,
                retry_s=s.db_retry_s,
            )
    return db


#: The INSERT ... ON CONFLICT DO NOTHING RETURNING statement of each (dialect, table),
#: built once: SQLAlchemy keeps the cache key of a statement object, so a statement
#: reused costs no construction and no key (~0.2-0.4 ms of CPU each time otherwise).
_INSERT_IGNORE: dict[tuple[str, Table, str], Any] = {}


def insert_ignore(
    conn: Connection, table: Table, rows: Sequence[Mapping[str, Any]] | Mapping[str, Any]
) -> int:
    """INSERT rows, silently skipping those whose primary key exists; returns rows added."""
    return len(inserted_keys(conn, table, rows, list(table.primary_key.columns)[0].name))


def inserted_keys(
    conn: Connection,
    table: Table,
    rows: Sequence[Mapping[str, Any]] | Mapping[str, Any],
    column: str,
) -> list[Any]:
    """INSERT rows, silently skipping those whose primary key exists (one statement,
    several rows in one round trip); returns ``column`` of each row added."""
    if not rows:
        return []
    key = (conn.dialect.name, table, column)
    stmt = _INSERT_IGNORE.get(key)
    if stmt is None:
        mod: Any = postgresql if conn.dialect.name == "postgresql" else sqlite
        # RETURNING tells the inserted rows on every driver (psycopg reports rowcount -1
        # for these statements).
        stmt = _INSERT_IGNORE[key] = (
            mod.insert(table).on_conflict_do_nothing().returning(table.c[column])
        )
    res = conn.execute(stmt, list(rows) if isinstance(rows, Sequence) else rows)
    return list(res.scalars())
