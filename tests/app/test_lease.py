"""rsfapp.reaper.Lease: renewals while entered, none after, a lost lease stops renewing,
and one renewal thread per process however many leases (no thread start/join per
chunk)."""

from __future__ import annotations

import threading
import time

from rsfapp.reaper import Lease


def _lease_threads() -> int:
    return sum(t.name == "rsf-lease" and t.is_alive() for t in threading.enumerate())


def test_a_lease_is_renewed_while_entered_and_not_after() -> None:
    calls: list[float] = []
    third = threading.Event()

    def renew() -> bool:
        calls.append(time.monotonic())
        if len(calls) >= 3:
            third.set()
        return True

    with Lease(renew, 0.02) as lease:
        assert third.wait(30.0), "three renewals of a 20 ms lease within 30 s"
    n = len(calls)
    time.sleep(0.2)  # ten more intervals: at most one renewal already under way
    assert len(calls) <= n + 1 and not lease.lost
    assert all(b > a for a, b in zip(calls, calls[1:], strict=False))


def test_a_lost_lease_stops_renewing() -> None:
    calls = 0
    lost = threading.Event()

    def renew() -> bool:
        nonlocal calls
        calls += 1
        lost.set()
        return False  # another worker took the chunk

    with Lease(renew, 0.01) as lease:
        assert lost.wait(30.0)
        time.sleep(0.1)
        assert lease.lost and calls == 1


def test_one_renewal_thread_serves_every_lease() -> None:
    for _ in range(50):
        with Lease(lambda: True, 5.0):
            pass
    with Lease(lambda: True, 5.0), Lease(lambda: True, 5.0):
        assert _lease_threads() == 1
