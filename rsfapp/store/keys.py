"""API keys in the application database: hashed, scoped, revocable, with quotas.

A key is ``rsf_`` followed by 43 URL-safe characters (``secrets.token_urlsafe(32)``,
256 random bits).  It is shown once, when created; the database keeps only its
SHA-256, so a copy of the database does not hold usable keys.  A presented key is
hashed, looked up by that hash, and the stored hash compared with
:func:`hmac.compare_digest` (constant time); an attacker controls neither hash, so
timing reveals nothing about any key.

Scopes are ordered: ``read`` < ``submit`` < ``admin`` (see :class:`Scope`).  Per-key
quota overrides are stored as a JSON object; missing entries fall back to the
``RSF_QUOTA_*`` settings.  ``key_usage`` counts sweep points per key and UTC day;
``sweep_owners`` records which key submitted a sweep.

Verification reads the database on every request that carries a key, so a key revoked
by any process (``rsf keys revoke``, another API process or host) is refused from the
next request on.  The read is one indexed ``SELECT`` by ``key_hash`` in its own read
transaction, sent as plain SQL on a driver connection (:meth:`KeyStore.verify`, ~10 us
on SQLite against ~150 us through a SQLAlchemy ``Connection`` with its ``BEGIN``), and on
SQLite the API may even run it on its event loop (:meth:`KeyStore.verify_inline`, ~5 us,
no thread hop), on a connection of its own that never waits for a lock.
"""

from __future__ import annotations

import contextlib
import enum
import hashlib
import hmac
import json
import os
import re
import secrets
import sqlite3
import threading
import time
import urllib.parse
from dataclasses import dataclass, fields, replace
from typing import Any

from sqlalchemy import and_, case, func, select, update
from sqlalchemy.pool import Pool

from ..db.engine import Database, insert_ignore
from ..db.tables import api_keys, key_usage, sweep_owners, sweeps

__all__ = [
    "ApiKey",
    "KEY_PREFIX",
    "KeyStore",
    "KeyStoreError",
    "NAME_PATTERN",
    "Quotas",
    "Scope",
    "WouldBlock",
    "hash_key",
    "new_key",
    "utc_day",
    "validate_quota",
]

#: Every key starts with this prefix (lets secret scanners recognise leaked keys).
KEY_PREFIX = "rsf_"
#: Valid key names: 1-64 of letters, digits, '.', '_', '-', starting with a letter/digit.
NAME_PATTERN = r"^[A-Za-z0-9][A-Za-z0-9._-]{0,63}$"


class Scope(enum.StrEnum):
    """What a key may do; each scope includes the ones below it."""

    read = "read"
    submit = "submit"
    admin = "admin"

    @property
    def rank(self) -> int:
        """0 read, 1 submit, 2 admin."""
        return _RANK[self]

    def allows(self, needed: Scope) -> bool:
        """True if this scope includes ``needed``."""
        return self.rank >= needed.rank


_RANK = {Scope.read: 0, Scope.submit: 1, Scope.admin: 2}


@dataclass(frozen=True)
class Quotas:
    """Limits of one key (defaults from the ``RSF_QUOTA_*`` settings).

    Attributes:
        concurrent_sweeps: sweeps of this key queued or running at once, >= 0.
        points_per_day: sweep points this key may submit per UTC day, >= 0.
        fresh_per_s: fresh (not cached) computations per second, > 0 (burst: the same
            number, at least 1).
        concurrent_requests: computing requests of this key in flight at once, >= 1.
        trajectory_points: largest ``n_points`` of one trajectory request, >= 2.
        step_budget: most integrator steps one single query of this key may use, in the
            API process or through the queue, >= 10 (a query needing more is refused).
    """

    concurrent_sweeps: int = 4
    points_per_day: int = 1_000_000
    fresh_per_s: float = 10.0
    concurrent_requests: int = 8
    trajectory_points: int = 100_000
    step_budget: int = 10_000_000

    @classmethod
    def names(cls) -> list[str]:
        """The quota names."""
        return [f.name for f in fields(cls)]

    def with_overrides(self, overrides: dict[str, Any]) -> Quotas:
        """These quotas with the known entries of ``overrides`` replaced."""
        known = {k: v for k, v in overrides.items() if k in self.names()}
        return replace(self, **known)


def validate_quota(name: str, value: str) -> int | float:
    """Parse one ``NAME=VALUE`` quota override; ValueError naming the quota if invalid."""
    if name not in Quotas.names():
        raise ValueError(f"unknown quota {name!r}; valid: {', '.join(Quotas.names())}")
    try:
        v: int | float = float(value) if name == "fresh_per_s" else int(value)
    except ValueError:
        raise ValueError(f"quota {name}: {value!r} is not a number") from None
    low = {"fresh_per_s": 1e-3, "concurrent_requests": 1, "trajectory_points": 2}.get(name, 0)
    if not (v >= low) or v > 1e12:
        raise ValueError(f"quota {name}: {value} out of range (valid range: [{low}, 1e12])")
    return v


class WouldBlock(Exception):
    """:meth:`KeyStore.verify_inline` cannot answer without waiting (a server database, a
    busy or not yet created SQLite file, or its connection in use): call
    :meth:`KeyStore.verify` in a thread instead."""


#: The one statement of a key verification (the ``key_hash`` column is UNIQUE, so indexed).
_SELECT_KEY = (
    "SELECT name, scope, quotas, created_at, revoked_at, key_hash FROM api_keys WHERE key_hash = "
)
_PLACEHOLDER = {"qmark": "?", "format": "%s", "pyformat": "%s"}


class KeyStoreError(ValueError):
    """A key operation that cannot be done (duplicate or unknown name, bad name)."""


@dataclass(frozen=True)
class ApiKey:
    """A stored key (never the key itself).

    Attributes:
        name: unique name given at creation.
        scope: what the key may do.
        quotas: per-key overrides (JSON object; empty = the defaults).
        created_at: Unix time [s].
        revoked_at: Unix time [s] of revocation, None while valid.
    """

    name: str
    scope: Scope
    quotas: dict[str, Any]
    created_at: float
    revoked_at: float | None

    @property
    def active(self) -> bool:
        """Not revoked."""
        return self.revoked_at is None


def new_key() -> str:
    """A fresh random key: ``rsf_`` + 256 random bits, URL-safe base64."""
    return KEY_PREFIX + secrets.token_urlsafe(32)


def hash_key(key: str) -> str:
    """Hex SHA-256 of a key (what the database stores)."""
    return hashlib.sha256(key.encode("utf-8", "surrogatepass")).hexdigest()


def utc_day(t: float | None = None) -> int:
    """UTC day number (days since 1970-01-01) of Unix time ``t`` (default: now)."""
    return int((time.time() if t is None else t) // 86400)


def _row(r: Any) -> ApiKey:
    return ApiKey(r.name, Scope(r.scope), json.loads(r.quotas or "{}"), r.created_at, r.revoked_at)


def _checked(rows: list[Any], h: str) -> ApiKey | None:
    """The active key among ``rows`` (tuples in :data:`_SELECT_KEY`'s column order)
    whose hash is ``h``, compared in constant time; None if there is none."""
    if len(rows) != 1:
        return None
    name, scope, quotas, created_at, revoked_at, stored = rows[0]
    if not hmac.compare_digest(str(stored), h) or revoked_at is not None:
        return None
    return ApiKey(name, Scope(scope), json.loads(quotas or "{}"), created_at, revoked_at)


class KeyStore:
    """API keys, their usage counters and sweep owners in ``db``.

    ``KeyStore.changes`` counts the keys created, stored or revoked in this process, so a
    cache of "is any key active" can be dropped at once.
    """

    changes: int = 0

    def __init__(self, db: Database) -> None:
        self.db = db
        dialect = db.reader.dialect
        mark = _PLACEHOLDER.get(str(dialect.paramstyle))
        #: the verification statement in the driver's parameter style (None: unknown style)
        self._sql = None if mark is None else _SELECT_KEY + mark
        url = db.reader.url
        file = url.database if dialect.name == "sqlite" else None
        #: SQLite file read on the event loop (None: not SQLite, in memory, or URI options)
        self._file = file if file and file != ":memory:" and not url.query else None
        self._inline: sqlite3.Connection | None = None
        self._inline_of: tuple[int, Pool] | None = None  # (process, reader pool) it belongs to
        self._inline_lock = threading.Lock()

    # ------------------------------------------------------------------ keys
    def create(
        self, name: str, scope: Scope = Scope.read, quotas: dict[str, Any] | None = None
    ) -> str:
        """Create key ``name``; returns the key (the only time it is available).

        Raises:
            KeyStoreError: invalid name, or a key (even revoked) with that name exists.
        """
        if not re.match(NAME_PATTERN, name):
            raise KeyStoreError(
                f"name {name!r}: 1-64 letters, digits, '.', '_' or '-', "
                "starting with a letter or digit"
            )
        key = new_key()
        row = {
            "name": name,
            "key_hash": hash_key(key),
            "scope": Scope(scope).value,
            "quotas": json.dumps(quotas or {}, sort_keys=True),
            "created_at": time.time(),
            "revoked_at": None,
        }
        with self.db.write() as conn:
            if not insert_ignore(conn, api_keys, row):
                raise KeyStoreError(
                    f"a key named {name!r} exists already (names are never "
                    "reused, even after revocation)"
                )
        KeyStore.changes += 1
        return key

    def put(self, name: str, key: str, scope: Scope = Scope.read) -> bool:
        """Store a key chosen by the operator (e.g. from the environment of a container)
        under ``name``: created, or the existing entry replaced (new hash and scope,
        revocation cleared), so the previous key of that name stops working.  Returns
        True if anything changed.

        Raises:
            KeyStoreError: invalid name, or a key shorter than 32 characters.
        """
        if not re.match(NAME_PATTERN, name):
            raise KeyStoreError(
                f"name {name!r}: 1-64 letters, digits, '.', '_' or '-', "
                "starting with a letter or digit"
            )
        if len(key) < 32 or len(key) > 512 or not key.isprintable() or " " in key:
            raise KeyStoreError(
                "the key must be 32-512 printable characters without spaces "
                "(e.g. 'rsf_' + `openssl rand -base64 32`)"
            )
        h, sc = hash_key(key), Scope(scope).value
        KeyStore.changes += 1
        with self.db.write() as conn:
            r = conn.execute(select(api_keys).where(api_keys.c.name == name)).first()
            if r is None:
                insert_ignore(
                    conn,
                    api_keys,
                    {
                        "name": name,
                        "key_hash": h,
                        "scope": sc,
                        "quotas": "{}",
                        "created_at": time.time(),
                        "revoked_at": None,
                    },
                )
                return True
            if r.key_hash == h and r.scope == sc and r.revoked_at is None:
                return False
            conn.execute(
                update(api_keys)
                .where(api_keys.c.name == name)
                .values(key_hash=h, scope=sc, revoked_at=None)
            )
        return True

    def revoke(self, name: str) -> bool:
        """Revoke key ``name`` (effective for the next request); False if already revoked.

        Raises:
            KeyStoreError: no key with that name.
        """
        KeyStore.changes += 1
        with self.db.write() as conn:
            r = conn.execute(
                update(api_keys)
                .where(and_(api_keys.c.name == name, api_keys.c.revoked_at.is_(None)))
                .values(revoked_at=time.time())
            )
            if r.rowcount:
                return True
            exists = conn.execute(select(api_keys.c.name).where(api_keys.c.name == name)).first()
        if exists is None:
            raise KeyStoreError(f"no key named {name!r}")
        return False

    def list_keys(self) -> list[ApiKey]:
        """Every key (active and revoked), oldest first."""
        with self.db.read() as conn:
            rows = conn.execute(select(api_keys).order_by(api_keys.c.created_at)).all()
        return [_row(r) for r in rows]

    def any_active(self) -> bool:
        """True if at least one key is not revoked."""
        with self.db.read() as conn:
            return (
                conn.execute(
                    select(api_keys.c.name).where(api_keys.c.revoked_at.is_(None)).limit(1)
                ).first()
                is not None
            )

    def verify(self, key: str) -> ApiKey | None:
        """The active key matching ``key``, else None (unknown, malformed or revoked).

        The lookup is by SHA-256 of the presented key (one indexed ``SELECT`` on a pooled
        driver connection, its own read transaction, so a revocation committed by any
        process is seen); the stored hash is then compared in constant time.  Unknown and
        revoked keys are indistinguishable to the caller.  A driver error (e.g. no schema
        yet) retries once through SQLAlchemy, which creates the schema or raises the
        error the API answers 503.
        """
        if not key or len(key) > 512:
            return None
        h = hash_key(key)
        if self._sql is not None:
            rows = self._pooled_rows(h)
            if rows is not None:
                return _checked(rows, h)
        with self.db.read() as conn:
            r = conn.execute(select(api_keys).where(api_keys.c.key_hash == h)).first()
        if r is None or not hmac.compare_digest(r.key_hash, h) or r.revoked_at is not None:
            return None
        return _row(r)

    def _pooled_rows(self, h: str) -> list[Any] | None:
        """Rows of the verification statement on a pooled driver connection; None after a
        driver error (the connection is discarded).  Connection failures (the database
        is down) propagate as SQLAlchemy errors."""
        assert self._sql is not None
        dbapi_error = self.db.reader.dialect.loaded_dbapi.Error
        rc = self.db.reader.raw_connection()
        try:
            cur = rc.cursor()
            try:
                cur.execute(self._sql, (h,))
                rows = list(cur.fetchall())  # all rows: the statement and its read end here
            finally:
                cur.close()
        except dbapi_error:
            rc.invalidate()
            return None
        finally:
            rc.close()  # back to the pool (rolled back: no transaction is left open)
        return rows

    def verify_inline(self, key: str) -> ApiKey | None:
        """:meth:`verify` without leaving the calling thread, for the API's event loop:
        on a SQLite file, one indexed ``SELECT`` (~5 us) in its own read transaction on a
        connection of this store and process (so a revocation committed by any process
        is seen by the next call), with no busy wait.

        Raises:
            WouldBlock: the answer may need waiting (a server database, a busy or missing
                SQLite file or table, or the connection in use by another thread); call
                :meth:`verify` in a thread.
        """
        if not key or len(key) > 512:
            return None
        if self._file is None or not self._inline_lock.acquire(blocking=False):
            raise WouldBlock
        try:
            h = hash_key(key)
            conn = self._inline_conn()
            try:
                rows = conn.execute(_SELECT_KEY + "?", (h,)).fetchall()  # ends the read
            except sqlite3.Error:
                self._drop_inline()
                raise WouldBlock from None
            return _checked(rows, h)
        finally:
            self._inline_lock.release()

    def _inline_conn(self) -> sqlite3.Connection:
        """The event-loop connection of this process and reader pool (a new pool, after
        ``dispose``, or a forked child opens a new one).  Autocommit (each statement its
        own read transaction), ``busy_timeout`` 0, never creates the file."""
        owner = (os.getpid(), self.db.reader.pool)
        if (
            self._inline is None
            or self._inline_of is None
            or self._inline_of[0] != owner[0]
            or self._inline_of[1] is not owner[1]
        ):
            self._drop_inline()
            assert self._file is not None
            try:
                conn = sqlite3.connect(
                    f"file:{urllib.parse.quote(self._file)}?mode=rw",
                    uri=True,
                    isolation_level=None,
                    check_same_thread=False,
                    cached_statements=8,
                )
                conn.execute("PRAGMA busy_timeout=0")
            except sqlite3.Error:
                raise WouldBlock from None
            self._inline, self._inline_of = conn, owner
        return self._inline

    def _drop_inline(self) -> None:
        conn, self._inline, self._inline_of = self._inline, None, None
        if conn is not None:
            with contextlib.suppress(sqlite3.Error):
                conn.close()

    # ------------------------------------------------------------------ usage
    def reserve_points(self, name: str, n: int, limit: int, day: int | None = None) -> int:
        """Add ``n`` sweep points to today's usage of ``name`` if that stays <= ``limit``.

        Returns the points left today after the reservation, or -1 (nothing added) if it
        would exceed the limit.  Atomic (one write transaction).
        """
        d = utc_day() if day is None else day
        with self.db.write() as conn:
            used = conn.execute(
                select(key_usage.c.points).where(
                    and_(key_usage.c.name == name, key_usage.c.day == d)
                )
            ).scalar()
            used = int(used or 0)
            if used + n > limit:
                return -1
            if not insert_ignore(conn, key_usage, {"name": name, "day": d, "points": n}):
                conn.execute(
                    update(key_usage)
                    .where(and_(key_usage.c.name == name, key_usage.c.day == d))
                    .values(points=key_usage.c.points + n)
                )
        return limit - used - n

    def refund_points(self, name: str, n: int, day: int | None = None) -> None:
        """Give back ``n`` points reserved today (e.g. the sweep existed already)."""
        d = utc_day() if day is None else day
        with self.db.write() as conn:
            conn.execute(
                update(key_usage)
                .where(and_(key_usage.c.name == name, key_usage.c.day == d))
                .values(points=case((key_usage.c.points > n, key_usage.c.points - n), else_=0))
            )

    def points_used(self, name: str, day: int | None = None) -> int:
        """Sweep points submitted by ``name`` on UTC day ``day`` (default today)."""
        d = utc_day() if day is None else day
        with self.db.read() as conn:
            v = conn.execute(
                select(key_usage.c.points).where(
                    and_(key_usage.c.name == name, key_usage.c.day == d)
                )
            ).scalar()
        return int(v or 0)

    # ------------------------------------------------------------------ sweep owners
    def set_owner(self, sweep_id: str, owner: str) -> None:
        """Record ``owner`` as the submitter of ``sweep_id`` (the first owner stays)."""
        with self.db.write() as conn:
            insert_ignore(conn, sweep_owners, {"sweep_id": sweep_id, "owner": owner})

    def owner(self, sweep_id: str) -> str | None:
        """The key name that submitted ``sweep_id`` (None: anonymous or unknown)."""
        with self.db.read() as conn:
            return conn.execute(
                select(sweep_owners.c.owner).where(sweep_owners.c.sweep_id == sweep_id)
            ).scalar()

    def active_sweeps(self, owner: str) -> int:
        """Sweeps of ``owner`` that are queued or running."""
        with self.db.read() as conn:
            return int(
                conn.execute(
                    select(func.count())
                    .select_from(sweep_owners.join(sweeps, sweeps.c.id == sweep_owners.c.sweep_id))
                    .where(
                        and_(
                            sweep_owners.c.owner == owner,
                            sweeps.c.status.in_(("queued", "running")),
                        )
                    )
                ).scalar()
                or 0
            )
