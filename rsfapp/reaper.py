"""Chunk leases and the reaper: a lost worker host costs seconds, not a restart.

* :class:`Lease`: while a worker process computes a chunk, the process's renewal thread
  renews the chunk's lease (its ``heartbeat``) every ``RSF_LEASE_S / 3`` seconds.
* :class:`Reaper`: a thread in every worker's main process.  Every
  :func:`scan_interval` seconds it refreshes this worker's row in the worker registry
  (for /health), requeues the running chunks whose lease expired (their worker died,
  lost its host, or lost the database), closes sweeps whose chunks are all done
  (self-repair), and sends again queued chunks whose message the broker lost (its
  queue empty for a whole lease while they wait).  Several reapers may run at once:
  a chunk is taken back by one atomic conditional update, so it is requeued once.

Worst case from a worker's death to its chunk being sent again: ``RSF_LEASE_S`` (the
last renewal happened before the death) plus one scan interval; the chunk then takes
one chunk's time on another worker.  Redelivered messages are harmless: storage is
exactly-once per point.
"""

from __future__ import annotations

import contextlib
import logging
import os
import threading
import time
from collections.abc import Callable
from types import TracebackType
from typing import NamedTuple

from sqlalchemy import select

from .config import Settings
from .db.tables import chunks, sweeps
from .health import check_broker, register_worker, unregister_worker
from .metrics import LEASE_EXPIRIES, REQUEUES, Requeue
from .store import stores_for

__all__ = ["Lease", "Reaper", "TickResult", "scan_interval"]
log = logging.getLogger("rsf.reaper")


def scan_interval(lease_s: float) -> float:
    """Seconds between two scans of a reaper: lease / 10, clamped to [0.2, 2] s."""
    return max(0.2, min(lease_s / 10.0, 2.0))


class _Renewer:
    """One daemon thread per process that renews every :class:`Lease` entered in it,
    each ``every`` seconds after the last renewal.  Started at the first lease (again
    after a fork: the child has none of its parent's threads) and kept: entering and
    leaving a lease only touches a dict under a lock, where a thread per lease cost a
    start and a join, each waiting for the OS to schedule it (5-10 ms per chunk on a
    loaded machine)."""

    #: Longest sleep of the thread [s]: a lease due later than its planned wake-up needs
    #: no notification (which would make the thread take the GIL from the computing
    #: thread at once: ~one switch interval, 5 ms, per chunk).
    IDLE_S = 1.0

    def __init__(self) -> None:
        self._cv = threading.Condition()
        self._due: dict[int, tuple[float, Lease]] = {}
        self._pid = -1
        self._wake = 0.0

    def add(self, lease: Lease) -> None:
        with self._cv:
            if self._pid != os.getpid():
                self._pid = os.getpid()
                self._due.clear()
                self._wake = 0.0
                threading.Thread(target=self._run, name="rsf-lease", daemon=True).start()
            due = time.monotonic() + lease.every
            self._due[id(lease)] = (due, lease)
            if due < self._wake:
                self._cv.notify()

    def remove(self, lease: Lease) -> None:
        with self._cv:
            self._due.pop(id(lease), None)

    def _run(self) -> None:
        while True:
            with self._cv:
                now = time.monotonic()
                due = [ls for t, ls in self._due.values() if t <= now]
                for ls in due:
                    self._due[id(ls)] = (now + ls.every, ls)
                if not due:
                    nxt = min((t for t, _ in self._due.values()), default=now + self.IDLE_S)
                    self._wake = min(nxt, now + self.IDLE_S)
                    self._cv.wait(max(0.0, self._wake - now))
                    continue
            for ls in due:  # outside the lock: a renewal is a database transaction
                ls.renew_once()


_RENEWER = _Renewer()


class Lease:
    """Context manager renewing a lease while a chunk runs (from the process's one
    renewal thread, :class:`_Renewer`).

    Args:
        renew: called every ``every`` seconds; returns False once the lease is lost
            (another worker took the chunk), which sets :attr:`lost`.
        every: renewal interval [s], > 0.
    """

    def __init__(self, renew: Callable[[], bool], every: float) -> None:
        self.renew, self.every = renew, every
        self.lost = False

    def renew_once(self) -> None:
        """One renewal (called by the renewal thread); a lost lease is not renewed again."""
        try:
            if not self.renew():
                self.lost = True
                _RENEWER.remove(self)
        except Exception as exc:  # noqa: BLE001 - database down: try again next time
            log.warning("lease renewal failed: %s", str(exc).splitlines()[0])

    def __enter__(self) -> Lease:
        _RENEWER.add(self)
        return self

    def __exit__(
        self, _t: type[BaseException] | None, _e: BaseException | None, _tb: TracebackType | None
    ) -> None:
        _RENEWER.remove(self)


class TickResult(NamedTuple):
    """What one reaper scan did: chunks sent (lease expired or dispatch repaired),
    sweeps closed."""

    requeued: int
    closed: int


class Reaper(threading.Thread):
    """The reaper thread of one worker (see the module docstring).

    Args:
        settings: this process's settings (database, lease).
        name: this worker's unique name in the registry (e.g. the Celery node name).
        concurrency: its processes (reported by /health).
        send: enqueues chunk ``idx`` of sweep ``sweep_id``.
    """

    def __init__(
        self, settings: Settings, name: str, concurrency: int, send: Callable[[str, int], None]
    ) -> None:
        super().__init__(name="rsf-reaper", daemon=True)
        self.settings, self.worker_name, self.concurrency, self.send = (
            settings,
            name,
            concurrency,
            send,
        )
        #: set by :meth:`stop` (not ``_stop``: Thread.join calls a method of that name)
        self._halt = threading.Event()
        self._failing = False
        self._queued_since: dict[tuple[str, int], float] = {}

    def tick(self) -> TickResult:
        """One scan (raises on database errors)."""
        s = self.settings
        st = stores_for(s)
        register_worker(
            st.db,
            self.worker_name,
            s.node,
            os.getpid(),
            self.concurrency,
            stale_after_s=10 * s.lease_s,
        )
        expired = st.sweeps.reap_expired(s.lease_s)
        for sweep_id, idx in expired:
            self.send(sweep_id, idx)
        LEASE_EXPIRIES.inc(len(expired))
        REQUEUES.labels(Requeue.lease_expired).inc(len(expired))
        if expired:
            log.warning(
                "requeued %d chunk(s) whose lease expired: %s",
                len(expired),
                ", ".join(f"{a[:8]}/{b}" for a, b in expired[:10]),
            )
        closed, nxt = st.sweeps.close_finished(s.sweep_window, s.lease_s)
        for sweep_id, idx in nxt:
            self.send(sweep_id, idx)
        REQUEUES.labels(Requeue.repair).inc(len(nxt))
        if closed or nxt:
            log.warning(
                "self-repair: closed %d finished sweep(s), dispatched %d chunk(s)", closed, len(nxt)
            )
        lost = self._lost_messages()
        for sweep_id, idx in lost:
            self.send(sweep_id, idx)
        REQUEUES.labels(Requeue.lost_message).inc(len(lost))
        if lost:
            log.warning(
                "broker queue empty but %d chunk(s) queued for a lease: sent again", len(lost)
            )
        return TickResult(len(expired) + len(nxt) + len(lost), closed)

    def _lost_messages(self) -> list[tuple[str, int]]:
        """Queued chunks whose message the broker lost (e.g. Redis restarted without its
        last writes): the broker's queue has been empty while they stayed ``queued`` for
        a whole lease.  A message merely reserved by a live worker is started well within
        a lease, and a duplicate is harmless (exactly-once storage)."""
        s = self.settings
        if check_broker(s).get("queue_length") != 0:
            self._queued_since.clear()
            return []
        with stores_for(s).db.read() as conn:
            rows = conn.execute(
                select(chunks.c.sweep_id, chunks.c.idx)
                .join(sweeps, sweeps.c.id == chunks.c.sweep_id)
                .where(sweeps.c.status.in_(("queued", "running")), chunks.c.status == "queued")
            ).all()
        now = time.monotonic()
        queued = {(str(a), int(b)) for a, b in rows}
        self._queued_since = {p: self._queued_since.get(p, now) for p in queued}
        lost = sorted(p for p, t in self._queued_since.items() if now - t >= s.lease_s)
        for p in lost:
            self._queued_since[p] = now
        return lost

    def run(self) -> None:
        dt = scan_interval(self.settings.lease_s)
        while True:
            try:
                self.tick()
                if self._failing:
                    log.warning("reaper: database and broker reachable again")
                self._failing = False
            except Exception as exc:  # noqa: BLE001 - keep scanning; log once per outage
                if not self._failing:
                    log.warning(
                        "reaper scan failed (retrying every %.1f s): %s",
                        dt,
                        str(exc).splitlines()[0] if str(exc) else type(exc).__name__,
                    )
                self._failing = True
            if self._halt.wait(dt):
                return

    def stop(self) -> None:
        """End the thread (joined within 5 s: a scan blocked on the database may hold it
        longer; it is a daemon thread) and remove this worker from the registry."""
        self._halt.set()
        self.join(timeout=5)
        with contextlib.suppress(Exception):  # the row expires anyway
            unregister_worker(stores_for(self.settings).db, self.worker_name)
