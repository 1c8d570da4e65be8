"""`rsf serve`: the API (uvicorn) plus one embedded Celery worker subprocess.

The worker uses the filesystem broker and the SQLite cache under ``data_dir`` unless
``RSF_BROKER_URL`` / ``RSF_CACHE_URL`` say otherwise.  The worker is restarted if it
dies; on exit (Ctrl-C / SIGTERM) uvicorn stops first, then the worker gets a warm
shutdown (finishes its current chunk; unfinished chunks are requeued at next start).
"""
from __future__ import annotations

import os
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

__all__ = ["serve", "worker_command"]


def worker_command(concurrency: int | None = None, pool: str = "prefork",
                   name: str = "rsf-embedded") -> list[str]:
    """Command line of a Celery worker for this project."""
    from rsfapp.config import get_settings
    conc = concurrency or max(1, os.cpu_count() or 1)
    return [sys.executable, "-m", "celery", "-A", "worker.celery_app:app", "worker",
            "-Q", get_settings().queue, f"--pool={pool}", f"--concurrency={conc}",
            "--loglevel=INFO", "--without-gossip", "--without-mingle", "--without-heartbeat",
            "-n", f"{name}-{os.getpid()}@%h"]


def _die_with_parent() -> None:
    """In the child (Linux): get SIGTERM if `rsf serve` dies, even by SIGKILL."""
    try:
        import ctypes
        ctypes.CDLL("libc.so.6", use_errno=True).prctl(1, signal.SIGTERM)  # PR_SET_PDEATHSIG
    except (OSError, AttributeError):
        pass


class _Supervisor(threading.Thread):
    """Keeps one worker subprocess alive until :meth:`stop`."""

    def __init__(self, cmd: list[str], env: dict[str, str], log_path: Path) -> None:
        super().__init__(daemon=True, name="rsf-worker-supervisor")
        self.cmd, self.env, self.log_path = cmd, env, log_path
        self.proc: subprocess.Popen[bytes] | None = None
        self._stop = threading.Event()
        self._lock = threading.Lock()

    def _start(self) -> None:
        log = open(self.log_path, "ab")  # noqa: SIM115 - owned by the child
        self.proc = subprocess.Popen(self.cmd, env=self.env, stdout=log, stderr=log,
                                     start_new_session=True, preexec_fn=_die_with_parent)
        log.close()

    def run(self) -> None:
        backoff = 1.0
        while not self._stop.is_set():
            with self._lock:
                if self._stop.is_set():
                    return
                self._start()
            started = time.monotonic()
            rc = self.proc.wait()
            if self._stop.is_set():
                return
            print(f"[rsf serve] worker exited with {rc}; restarting", file=sys.stderr)
            backoff = 1.0 if time.monotonic() - started > 30 else min(backoff * 2, 30.0)
            self._stop.wait(backoff)

    def stop(self, timeout: float = 60.0) -> None:
        """Warm shutdown (SIGTERM), then SIGKILL of the worker's process group."""
        with self._lock:
            self._stop.set()
            p = self.proc
        if p is None or p.poll() is not None:
            return
        p.send_signal(signal.SIGTERM)
        try:
            p.wait(timeout)
        except subprocess.TimeoutExpired:
            os.killpg(p.pid, signal.SIGKILL)
            p.wait()


def _note(signum: int, _frame: object) -> None:
    print(f"[rsf serve] signal {signum}: stopping", file=sys.stderr)


def serve(host: str = "127.0.0.1", port: int = 8000, data_dir: str | Path = "rsf-data",
          concurrency: int | None = None) -> None:
    """Run the API on host:port and an embedded worker; returns when the API stops.

    Args:
        host: interface to bind (127.0.0.1 = loopback only).
        port: TCP port, 1..65535 (0 = any free port).
        data_dir: directory for cache.sqlite3, the broker queues and worker.log.
        concurrency: worker processes (default: CPU count).
    """
    import uvicorn

    data = Path(data_dir).expanduser().resolve()
    data.mkdir(parents=True, exist_ok=True)
    os.environ["RSF_DATA_DIR"] = str(data)
    env = dict(os.environ)
    sup = _Supervisor(worker_command(concurrency), env, data / "worker.log")
    sup.start()
    print(f"[rsf serve] data in {data}; worker log {data / 'worker.log'}", file=sys.stderr)
    # uvicorn re-raises SIGTERM/SIGINT after its graceful shutdown; with these handlers
    # that ends in the `finally` below (stopping the worker) instead of killing us.
    prev = {sig: signal.signal(sig, _note) for sig in (signal.SIGTERM, signal.SIGINT)}
    try:
        uvicorn.run("service.app:app", host=host, port=port, log_level="info")
    finally:
        sup.stop()
        for sig, h in prev.items():
            signal.signal(sig, h)
