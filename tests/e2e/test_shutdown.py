"""A worker stopped by SIGTERM or SIGINT shuts down cleanly: its reaper thread stops and is
joined, it leaves the worker registry, and its log holds no traceback.  The same for an
API process (uvicorn) that has just answered a computed query.

A real Celery worker (prefork pool, one child: the pool's own threads and processes
are stopped too) on the filesystem broker and SQLite; the signal goes to the main
process only, as ``docker stop`` and systemd send it.  The reaper scans every 0.2 s
here (lease 2 s), so it is registered within a second of the worker being ready.
"""

from __future__ import annotations

import os
import signal
import subprocess
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest

from tests.conftest import Server, Worker

pytestmark = pytest.mark.timeout(180)

#: Lines a clean shutdown never writes: a Python traceback, a signal handler that raised
#: (Celery logs "Signal handler <...> raised: ..."), an exception in a thread or at exit.
FORBIDDEN = (
    "Traceback (most recent call last)",
    "raised:",
    "Exception in thread",
    "Exception ignored",
)


def wait_for(pred: Callable[[], Any], timeout: float, what: str) -> Any:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        v = pred()
        if v:
            return v
        time.sleep(0.1)
    raise AssertionError(f"timed out after {timeout} s waiting for {what}")


def _registered(data_dir: Path) -> list[str]:
    """Names in the worker registry (empty until the reaper's first scan made the table)."""
    from sqlalchemy import create_engine, inspect, select

    from rsfapp.db.ops import workers

    eng = create_engine(f"sqlite:///{data_dir / 'cache.sqlite3'}")
    try:
        with eng.connect() as conn:
            if not inspect(conn).has_table(workers.name):
                return []
            return [str(r[0]) for r in conn.execute(select(workers.c.name))]
    finally:
        eng.dispose()


@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGINT], ids=["SIGTERM", "SIGINT"])
def test_worker_stops_cleanly(sig: signal.Signals, tmp_path: Path) -> None:
    w = Worker(tmp_path, pool="prefork", concurrency=1, RSF_LEASE_S="2")
    try:
        names = wait_for(lambda: _registered(tmp_path), 30, "the reaper to register the worker")
        assert len(names) == 1
        time.sleep(0.5)  # a few reaper scans
        os.kill(w.pid, sig)
        try:
            w.p.wait(60)
        except subprocess.TimeoutExpired:
            raise AssertionError(f"still running 60 s after {sig.name}:\n{w.tail()}") from None
        log = w.log.read_text(errors="replace")
        assert "Warm shutdown" in log, log[-3000:]  # the signal was received as a stop
        for bad in FORBIDDEN:
            assert bad not in log, f"{bad!r} in the log after {sig.name}:\n{log[-6000:]}"
        assert _registered(tmp_path) == [], "the reaper did not leave the worker registry"
    finally:
        w.stop()


@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGINT], ids=["SIGTERM", "SIGINT"])
def test_api_stops_cleanly(sig: signal.Signals, tmp_path: Path) -> None:
    import httpx

    srv = Server(tmp_path, RSF_AUTH="auto")
    try:
        body = {"ba": 2.0, "kappa": 2.0, "eps": 0.25, "size": 1.0}
        r = httpx.post(srv.url + "/v1/classify", json=body, timeout=60)
        assert r.status_code == 200, r.text
        os.kill(srv.pid, sig)
        try:
            srv.p.wait(30)
        except subprocess.TimeoutExpired:
            raise AssertionError(f"still running 30 s after {sig.name}:\n{srv.tail()}") from None
        # uvicorn re-raises the signal after its graceful shutdown: -SIGTERM, or 0 after SIGINT
        assert srv.p.returncode in (0, -sig), srv.p.returncode
        log = srv.log.read_text(errors="replace")
        for bad in FORBIDDEN:
            assert bad not in log, f"{bad!r} in the log after {sig.name}:\n{log[-6000:]}"
    finally:
        srv.stop()
