"""`rsf serve`, `rsf api`, `rsf worker`: the processes of a deployment.

* ``rsf serve``: the API (uvicorn) plus one embedded Celery worker subprocess (one
  machine, nothing to install: filesystem broker and SQLite under ``data_dir``).
* ``rsf api [--workers N]``: HTTP only, N uvicorn processes; they share nothing but
  the database and the broker.
* ``rsf worker [--concurrency N]``: a Celery worker; needs only ``RSF_BROKER_URL`` and
  ``RSF_CACHE_URL`` (no disk shared with the API or other workers).

Every process reads the same ``RSF_*`` settings.  Before starting, each command opens
the database (creating or migrating its schema) and, if that fails, says what is wrong
and how to recover, without a traceback: a damaged or too-new database stops it at once
(exit status 1); an unreachable one is waited for up to ``--wait-db`` seconds first.

In ``rsf serve`` the worker is restarted if it dies; on exit (Ctrl-C / SIGTERM)
uvicorn stops first, then the worker gets a warm shutdown (finishes its current chunk;
a chunk left unfinished is requeued by a reaper when its lease expires).

Metrics (docs/operations.md): each command points ``PROMETHEUS_MULTIPROC_DIR`` at a
private empty directory (unless set) before any of its processes starts, so the counters
of all of them add up at a scrape (``rsf serve``: the API's ``/metrics`` includes the
embedded worker's); with ``RSF_METRICS_PORT`` each also serves ``/metrics`` on that port
without a key (``rsf serve``: the API's only).
"""

from __future__ import annotations

import atexit
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

import typer

from .keys import check_bind

__all__ = [
    "StartupError",
    "api",
    "app",
    "check_database",
    "serve",
    "worker",
    "worker_command",
]


class StartupError(SystemExit):
    """Start-up refused: the message says what is wrong and how to recover."""


def _metrics_dir(who: str, remove_at_exit: bool = True) -> None:
    """Point PROMETHEUS_MULTIPROC_DIR at a new empty directory unless it is set (before
    prometheus-client is imported here or in any child)."""
    if os.environ.get("PROMETHEUS_MULTIPROC_DIR"):
        return
    d = tempfile.mkdtemp(prefix=f"rsf-metrics-{who}-")
    os.environ["PROMETHEUS_MULTIPROC_DIR"] = d
    if remove_at_exit:
        atexit.register(shutil.rmtree, d, True)


def _metrics_port() -> None:
    """With RSF_METRICS_PORT: serve /metrics (every process of this command, and the
    deployment's state) on that port from this process, no key."""
    from rsfapp.config import get_settings

    s = get_settings()
    if not s.metrics_port:
        return
    from prometheus_client import start_http_server

    from rsfapp import metrics
    from rsfapp.metrics_state import StateCollector

    reg = metrics.registry(StateCollector(s))
    start_http_server(s.metrics_port, s.metrics_host, registry=reg)
    print(f"[rsf] metrics on http://{s.metrics_host}:{s.metrics_port}/metrics", file=sys.stderr)


def check_database(wait_s: float = 60.0, who: str = "rsf") -> None:
    """Open the configured database and ensure its schema, or raise
    :class:`StartupError` with a message (no traceback).

    Args:
        wait_s: how long an unreachable database server is waited for [s], >= 0.
        who: the command, for messages.
    """
    from rsfapp.config import get_settings
    from rsfapp.db.engine import database, diagnose

    s = get_settings()
    url = s.effective_cache_url
    deadline = time.monotonic() + wait_s
    said = False
    while True:
        try:
            database(url).ensure_schema()
            if said:
                print(f"[{who}] database is back", file=sys.stderr)
            return
        except Exception as exc:  # noqa: BLE001 - turned into a message below
            p = diagnose(exc, url)
            if p is None:
                raise
            if p.kind in ("damaged", "schema") or time.monotonic() >= deadline:
                msg = f"[{who}] cannot start: {p.reason}\n[{who}] how to recover: {p.hint}"
                raise StartupError(msg) from None
            if not said:
                print(
                    f"[{who}] waiting up to {wait_s:g} s for the database: {p.reason}",
                    file=sys.stderr,
                )
                said = True
            time.sleep(1.0)


def worker_command(
    concurrency: int | None = None,
    pool: str = "prefork",
    name: str = "rsf-embedded",
    loglevel: str = "INFO",
) -> list[str]:
    """Command line of a Celery worker for this project.

    The node name is ``{name}-{pid}@{RSF_NODE}`` (RSF_NODE defaults to the host name),
    unique per process and naming its host."""
    from rsfapp.config import get_settings

    s = get_settings()
    conc = concurrency or max(1, os.cpu_count() or 1)
    return [
        sys.executable,
        "-m",
        "celery",
        "-A",
        "worker.celery_app:app",
        "worker",
        "-Q",
        s.queue,
        f"--pool={pool}",
        f"--concurrency={conc}",
        f"--loglevel={loglevel}",
        "--without-gossip",
        "--without-mingle",
        "--without-heartbeat",
        "-n",
        f"{name}-{os.getpid()}@{s.node}",
    ]


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
        self.proc = subprocess.Popen(
            self.cmd,
            env=self.env,
            stdout=log,
            stderr=log,
            start_new_session=True,
            preexec_fn=_die_with_parent,
        )
        log.close()

    def run(self) -> None:
        backoff = 1.0
        while not self._stop.is_set():
            with self._lock:
                if self._stop.is_set():
                    return
                self._start()
            started = time.monotonic()
            proc = self.proc
            assert proc is not None
            rc = proc.wait()
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


def serve(
    host: str = "127.0.0.1",
    port: int = 8000,
    data_dir: str | Path = "rsf-data",
    concurrency: int | None = None,
) -> None:
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
    _metrics_dir("serve")
    check_database(who="rsf serve")
    check_bind(host, "rsf serve")  # no key on a non-loopback host: refuse, say why
    _metrics_port()
    env = dict(os.environ)
    env.pop("RSF_METRICS_PORT", None)  # the API's port covers the embedded worker
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


def api(
    host: str = "127.0.0.1", port: int = 8000, workers: int = 1, wait_db_s: float = 60.0
) -> None:
    """Run the HTTP API only (no worker) in ``workers`` uvicorn processes.

    Args:
        host: interface to bind.
        port: TCP port, 1..65535.
        workers: API processes, >= 1; they keep no state another process needs
            (results, jobs, sweeps and failures live in the database).
        wait_db_s: how long to wait for an unreachable database at start [s].
    """
    import uvicorn

    if workers < 1:
        raise StartupError(f"[rsf api] --workers must be >= 1 (got {workers})")
    _metrics_dir("api")
    check_database(wait_db_s, who="rsf api")
    check_bind(host, "rsf api")
    _metrics_port()
    uvicorn.run(
        "service.app:app",
        host=host,
        port=port,
        workers=workers,
        log_level="info",
        timeout_graceful_shutdown=10,
    )


def worker(concurrency: int | None = None, loglevel: str = "INFO", wait_db_s: float = 60.0) -> None:
    """Replace this process with a Celery worker (``concurrency`` processes, default
    the CPU count) on ``RSF_BROKER_URL`` and ``RSF_CACHE_URL``.

    With the default filesystem broker and SQLite the worker must run on the API's
    machine (same ``RSF_DATA_DIR``); with Redis and PostgreSQL it may run anywhere."""
    if concurrency is not None and concurrency < 1:
        raise StartupError(f"[rsf worker] --concurrency must be >= 1 (got {concurrency})")
    _metrics_dir("worker", remove_at_exit=False)  # this process becomes Celery (exec)
    check_database(wait_db_s, who="rsf worker")
    cmd = worker_command(concurrency, name="rsf", loglevel=loglevel)
    sys.stdout.flush()
    sys.stderr.flush()
    os.execv(cmd[0], cmd)


# ------------------------------------------------------------------ the commands
#: `rsf serve`, `rsf api`, `rsf worker` (mounted on `rsf` by rsfcli.main when asked for).
app = typer.Typer(rich_markup_mode=None, add_completion=False)

INSECURE = typer.Option(
    False,
    "--insecure",
    help="Serve without API keys (RSF_AUTH=off), even on a non-loopback interface.",
)


def _insecure(insecure: bool) -> None:
    if insecure:
        os.environ["RSF_AUTH"] = "off"


@app.command("serve")
def serve_command(
    host: str = typer.Option("127.0.0.1", "--host", help="Interface to bind."),
    port: int = typer.Option(8000, "--port", help="TCP port."),
    data_dir: Path = typer.Option(
        Path("rsf-data"),
        "--data-dir",
        help="Directory for the SQLite cache, sweep store and the filesystem broker.",
    ),
    insecure: bool = INSECURE,
) -> None:
    """Start the HTTP API (uvicorn) and an embedded Celery worker (filesystem broker unless RSF_BROKER_URL is set)."""
    _insecure(insecure)

    serve(host=host, port=port, data_dir=data_dir)


@app.command("api")
def api_command(
    host: str = typer.Option("127.0.0.1", "--host", help="Interface to bind."),
    port: int = typer.Option(8000, "--port", help="TCP port."),
    workers: int = typer.Option(
        1, "--workers", min=1, help="API processes (share only the database and broker)."
    ),
    wait_db: float = typer.Option(
        60.0, "--wait-db", min=0, help="Seconds to wait for an unreachable database at start."
    ),
    insecure: bool = INSECURE,
) -> None:
    """Start the HTTP API only (no worker); workers run with `rsf worker`, anywhere."""
    _insecure(insecure)

    api(host=host, port=port, workers=workers, wait_db_s=wait_db)


@app.command("worker")
def worker_command_line(
    concurrency: int | None = typer.Option(
        None, "--concurrency", min=1, help="Worker processes (default: CPU count)."
    ),
    loglevel: str = typer.Option("INFO", "--loglevel", help="Celery log level."),
    wait_db: float = typer.Option(
        60.0, "--wait-db", min=0, help="Seconds to wait for an unreachable database at start."
    ),
) -> None:
    """Start a Celery worker; needs only RSF_BROKER_URL and RSF_CACHE_URL (no shared disk)."""
    worker(concurrency=concurrency, loglevel=loglevel, wait_db_s=wait_db)
