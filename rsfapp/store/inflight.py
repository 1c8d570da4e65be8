"""Computing requests of API keys in flight, shared through the database (the
``concurrent_requests`` quota of a key, on every API process and host).

A request that computes holds a *lease*: one row of ``inflight_leases`` (a random id,
the SHA-256 of the key, an expiry time).  :meth:`InflightStore.acquire` inserts one only
if the key holds fewer unexpired leases than its quota; the request deletes it when it
ends (:meth:`InflightStore.release`, in a ``finally``) and renews it while it runs
(:meth:`InflightStore.renew`), so only a process that died (or lost the database for a
whole lease) leaves a lease behind, and that lease stops counting when it expires and is
deleted by the next acquisition for its key (:meth:`InflightStore.purge` deletes every
expired one).

Race freedom: the purge of the key's expired leases, the count of its leases and the
insert run in one write transaction, serialised per key.  On SQLite, write transactions
start with ``BEGIN IMMEDIATE`` (:class:`rsfapp.db.engine.Database`): one writer at a time
in the whole file.  On PostgreSQL (READ COMMITTED), the transaction first takes a
transaction-level advisory lock on the key (``pg_advisory_xact_lock(namespace,
hashtext(key_id))``, released at commit); every later statement of the transaction reads
a snapshot taken after the lock was granted, so it sees every lease committed by the
previous holder.  (A bare ``INSERT ... SELECT ... WHERE (SELECT count(*) ...) < quota``
would not do under READ COMMITTED: two transactions would both count the same committed
rows and both insert.)  Distinct keys never wait for each other on PostgreSQL (two keys
share a lock only on a 32-bit hash collision, which merely serialises them).

Time is the wall clock (``time.time``): expiry times must mean the same on every host,
whose clocks should be synchronised (NTP); a host whose clock is off by ``d`` seconds
sees leases expire ``d`` seconds early or late, so leases should be much longer than the
clock error.
"""

from __future__ import annotations

import logging
import time
import uuid
from collections.abc import Callable
from typing import NamedTuple

from sqlalchemy import delete, func, insert, select, text, update

from ..db.engine import Database
from ..db.tables import inflight_leases

__all__ = ["InflightStore", "Lease", "LOCK_NAMESPACE"]
log = logging.getLogger("rsf.store")

#: First key of the PostgreSQL advisory locks of this module (the second is the hash of
#: the API key); the two-key lock space does not overlap the one-key space of the
#: schema lock (:mod:`rsfapp.db.engine`).
LOCK_NAMESPACE = 0x72_73_69  # 'rsi'


class Lease(NamedTuple):
    """Outcome of :meth:`InflightStore.acquire`.

    Attributes:
        admitted: True if a lease was taken.
        lease_id: its id (hex), None if refused.
        held: unexpired leases of the key after the call (including the new one).
    """

    admitted: bool
    lease_id: str | None
    held: int


class InflightStore:
    """Leases of computing requests in flight in ``db``.

    Args:
        db: the application database.
        clock: wall clock [s since 1970] (a parameter for tests).
        purge_every_s: interval of the purge of every key's expired leases [s].
    """

    def __init__(
        self, db: Database, clock: Callable[[], float] = time.time, purge_every_s: float = 60.0
    ) -> None:
        self.db, self.clock, self.purge_every_s = db, clock, purge_every_s
        self._next_purge = 0.0

    def acquire(self, key_id: str, quota: int, lease_s: float) -> Lease:
        """Take a lease for a request of ``key_id`` if the key holds fewer than ``quota``
        unexpired leases (one transaction, serialised per key; see the module docstring).
        Expired leases of the key are deleted on the way, and those of every key at
        most once per ``purge_every_s`` of this store (:meth:`purge`).

        Args:
            key_id: SHA-256 (hex) of the API key.
            quota: the key's ``concurrent_requests``, >= 1.
            lease_s: lease length [s], > 0 (renew it before it runs out).

        Returns:
            :class:`Lease`; a refused acquisition adds nothing.
        """
        if not quota >= 1:
            raise ValueError(f"quota: {quota!r} must be >= 1 [requests]")
        if not lease_s > 0:
            raise ValueError(f"lease_s: {lease_s!r} must be > 0 [s]")
        t = inflight_leases
        now = self.clock()
        lease_id = uuid.uuid4().hex
        with self.db.write() as conn:
            if conn.dialect.name == "postgresql":
                conn.execute(
                    text("SELECT pg_advisory_xact_lock(CAST(:ns AS integer), hashtext(:k))"),
                    {"ns": LOCK_NAMESPACE, "k": key_id},
                )
            conn.execute(delete(t).where(t.c.key_id == key_id, t.c.expires_at <= now))
            held = int(
                conn.execute(
                    select(func.count()).select_from(t).where(t.c.key_id == key_id)
                ).scalar_one()
            )
            if held >= quota:
                return Lease(False, None, held)
            conn.execute(
                insert(t).values(lease_id=lease_id, key_id=key_id, expires_at=now + lease_s)
            )
        if time.monotonic() >= self._next_purge:
            self._next_purge = time.monotonic() + self.purge_every_s
            try:
                self.purge()
            except Exception:  # noqa: BLE001 - the lease is taken; purge next time
                log.warning("could not purge expired leases", exc_info=True)
        return Lease(True, lease_id, held + 1)

    def renew(self, lease_id: str, lease_s: float) -> bool:
        """Extend an unexpired lease to ``lease_s`` seconds from now; False if it is gone
        or already expired (an expired lease is not revived: its place may be taken)."""
        t = inflight_leases
        now = self.clock()
        with self.db.write() as conn:
            n = conn.execute(
                update(t)
                .where(t.c.lease_id == lease_id, t.c.expires_at > now)
                .values(expires_at=now + lease_s)
                .returning(t.c.lease_id)
            ).all()
        return bool(n)

    def release(self, lease_id: str) -> None:
        """Delete a lease (nothing if it is gone)."""
        with self.db.write() as conn:
            conn.execute(delete(inflight_leases).where(inflight_leases.c.lease_id == lease_id))

    def held(self, key_id: str) -> int:
        """Unexpired leases of ``key_id`` now.  Reads only."""
        t = inflight_leases
        with self.db.read() as conn:
            return int(
                conn.execute(
                    select(func.count())
                    .select_from(t)
                    .where(t.c.key_id == key_id, t.c.expires_at > self.clock())
                ).scalar_one()
            )

    def purge(self) -> int:
        """Delete every expired lease (of every key); the number deleted.  On PostgreSQL
        it skips rows locked by a concurrent transaction (``FOR UPDATE SKIP LOCKED``),
        so it never waits for, nor deadlocks with, an acquisition."""
        t = inflight_leases
        expired = (
            select(t.c.lease_id)
            .where(t.c.expires_at <= self.clock())
            .with_for_update(skip_locked=True)
        )
        with self.db.write() as conn:
            rows = conn.execute(
                delete(t).where(t.c.lease_id.in_(expired)).returning(t.c.lease_id)
            ).all()
        return len(rows)
