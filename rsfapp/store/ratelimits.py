"""Fresh-computation token buckets of API keys, shared through the database.

One row per key (``rate_buckets``: the SHA-256 of the key, its token level at a wall-clock
``stamp``, the rate and capacity of the last update), so every API process of a host
(``rsf api --workers N``) and every API host on the same database see one bucket per
key.  A bucket refills at ``rate`` tokens per second up to ``capacity = max(1, rate)``
tokens (the burst); a new key starts full.

Every change is one atomic SQL statement, on SQLite and PostgreSQL alike: an
``INSERT ... ON CONFLICT (key_id) DO UPDATE`` whose update refills the level from the
elapsed time and subtracts the charge in the same statement (for :meth:`take`, only
``WHERE`` the refilled level holds enough tokens).  PostgreSQL re-evaluates that
condition on the newest row version after waiting for a concurrent update of the row
(READ COMMITTED), and SQLite serialises writers (``BEGIN IMMEDIATE``), so two processes
can never both take the last token.

Time is the wall clock (``time.time``), as stamps must mean the same on every host: the
hosts' clocks should be synchronised (NTP).  A stamp never moves backwards and a negative
elapsed time refills nothing, so a host whose clock lags delays refills by its lag and
never creates tokens.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any, NamedTuple

from sqlalchemy import ColumnElement, case, literal, select
from sqlalchemy.dialects import postgresql, sqlite

from ..db.engine import Database
from ..db.tables import rate_buckets

__all__ = ["Admission", "RateLimitStore", "capacity_of"]


def capacity_of(rate: float) -> float:
    """Burst of a bucket refilled at ``rate`` [tokens/s], > 0: ``max(1, rate)`` tokens."""
    return max(1.0, float(rate))


def _wait(level: float, rate: float, n: float) -> float:
    """Seconds until a bucket at ``level`` refilled at ``rate`` holds ``n`` tokens."""
    return 0.0 if level >= n else (n - level) / rate


class Admission(NamedTuple):
    """Outcome of :meth:`RateLimitStore.take`.

    Attributes:
        admitted: True if the tokens were taken.
        tokens: the level after taking them (admitted), or the level now (refused).
        wait_s: 0 if admitted, else seconds until enough tokens are back [s].
    """

    admitted: bool
    tokens: float
    wait_s: float


class RateLimitStore:
    """Token buckets of API keys in ``db``.

    Args:
        db: the application database.
        clock: wall clock [s since 1970] (a parameter for tests).
    """

    def __init__(self, db: Database, clock: Callable[[], float] = time.time) -> None:
        self.db, self.clock = db, clock

    def _upsert(
        self, key_id: str, rate: float, n: float, now: float, conditional: bool
    ) -> float | None:
        """The single statement of :meth:`take` (``conditional``) and :meth:`charge`:
        the new level, or None when a conditional take found too few tokens."""
        if not rate > 0:
            raise ValueError(f"rate: {rate!r} must be > 0 [tokens/s]")
        cap = capacity_of(rate)
        t = rate_buckets
        now_ = literal(now)
        elapsed = case((t.c.stamp < now_, now_ - t.c.stamp), else_=literal(0.0))
        refill: ColumnElement[Any] = t.c.tokens + literal(rate) * elapsed
        level = case((refill > literal(cap), literal(cap)), else_=refill)
        with self.db.write() as conn:
            mod: Any = postgresql if conn.dialect.name == "postgresql" else sqlite
            stmt = (
                mod.insert(t)
                .values(key_id=key_id, tokens=cap - n, stamp=now, rate=rate, capacity=cap)
                .on_conflict_do_update(
                    index_elements=[t.c.key_id],
                    set_={
                        "tokens": level - literal(n),
                        "stamp": case((t.c.stamp > now_, t.c.stamp), else_=now_),
                        "rate": rate,
                        "capacity": cap,
                    },
                    where=(level >= literal(n)) if conditional else None,
                )
                .returning(t.c.tokens)
            )
            row = conn.execute(stmt).first()
        return None if row is None else float(row[0])

    def take(self, key_id: str, rate: float, n: float = 1.0) -> Admission:
        """Take ``n`` tokens from the bucket of ``key_id`` if it holds them now.

        Args:
            key_id: SHA-256 (hex) of the API key.
            rate: the key's refill rate [tokens/s], > 0 (its current quota; the capacity
                follows from it).
            n: tokens to take, 0 < n <= capacity.

        Returns:
            :class:`Admission`; a refused take changes nothing.
        """
        now = self.clock()
        after = self._upsert(key_id, rate, n, now, conditional=True)
        if after is not None:
            return Admission(True, after, 0.0)
        level = self.level(key_id, rate, now)
        return Admission(False, level, _wait(level, rate, n))

    def charge(self, key_id: str, rate: float, n: float = 1.0) -> float:
        """Take ``n`` tokens whatever the level (it may go negative: a charge made after
        the work, e.g. of an endpoint that cannot tell before computing); the new level."""
        after = self._upsert(key_id, rate, n, self.clock(), conditional=False)
        assert after is not None
        return after

    def level(self, key_id: str, rate: float, now: float | None = None) -> float:
        """Tokens in the bucket of ``key_id`` now, refilled at ``rate`` [tokens/s] since
        its last update (a key never seen: full).  Reads only."""
        t = now if now is not None else self.clock()
        cap = capacity_of(rate)
        with self.db.read() as conn:
            row = conn.execute(
                select(rate_buckets.c.tokens, rate_buckets.c.stamp).where(
                    rate_buckets.c.key_id == key_id
                )
            ).first()
        if row is None:
            return cap
        tokens, stamp = float(row[0]), float(row[1])
        return min(cap, tokens + rate * max(0.0, t - stamp))

    def wait_s(self, key_id: str, rate: float, n: float = 1.0) -> float:
        """Seconds until the bucket of ``key_id`` holds ``n`` tokens (0: now).  Reads only."""
        return _wait(self.level(key_id, rate), rate, n)
