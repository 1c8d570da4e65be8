"""Shared fixtures: free ports, real uvicorn / Celery worker / redis-server processes.

Every process is started by us, on 127.0.0.1, with its own data directory, and is
stopped by its pid (process group) at teardown.  Under CI=true a missing redis-server
is a failure, not a skip.
"""
from __future__ import annotations

import os
import shutil
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path
from typing import Iterator

import httpx
import pytest

ROOT = Path(__file__).resolve().parents[1]


def free_port() -> int:
    """A TCP port free on 127.0.0.1 right now."""
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def service_env(data_dir: Path, broker_url: str = "", **extra: str) -> dict[str, str]:
    """Environment for service/worker processes using ``data_dir``."""
    env = {k: v for k, v in os.environ.items() if not k.startswith("RSF_")}
    env.update(RSF_DATA_DIR=str(data_dir), RSF_BROKER_URL=broker_url,
               NUMBA_CACHE_DIR=os.environ.get("NUMBA_CACHE_DIR", str(ROOT / ".numba_cache")),
               PYTHONPATH=str(ROOT))
    env.update(extra)
    return env


class Proc:
    """A subprocess in its own session, logging to a file, stopped by process group."""

    def __init__(self, cmd: list[str], env: dict[str, str], log: Path) -> None:
        self.cmd, self.env, self.log = cmd, env, log
        fh = open(log, "ab")  # noqa: SIM115
        self.p = subprocess.Popen(cmd, env=env, stdout=fh, stderr=fh, cwd=ROOT,
                                  start_new_session=True)
        fh.close()

    @property
    def pid(self) -> int:
        return self.p.pid

    def alive(self) -> bool:
        return self.p.poll() is None

    def kill(self, sig: int = signal.SIGKILL) -> None:
        """Send ``sig`` to the whole process group (our child and its children)."""
        if self.alive():
            try:
                os.killpg(self.p.pid, sig)
            except ProcessLookupError:
                pass

    def stop(self, timeout: float = 20.0) -> None:
        """SIGTERM, then SIGKILL after ``timeout`` seconds."""
        if self.alive():
            self.kill(signal.SIGTERM)
            try:
                self.p.wait(timeout)
            except subprocess.TimeoutExpired:
                self.kill(signal.SIGKILL)
                self.p.wait(10)
        else:
            self.p.wait()

    def tail(self, n: int = 4000) -> str:
        try:
            return self.log.read_text(errors="replace")[-n:]
        except OSError:
            return ""


class Server(Proc):
    """uvicorn service.app:app on 127.0.0.1:<free port>."""

    def __init__(self, data_dir: Path, broker_url: str = "", **extra: str) -> None:
        self.port = free_port()
        self.url = f"http://127.0.0.1:{self.port}"
        super().__init__([sys.executable, "-m", "uvicorn", "service.app:app", "--host",
                          "127.0.0.1", "--port", str(self.port), "--log-level", "warning"],
                         service_env(data_dir, broker_url, **extra),
                         data_dir / f"uvicorn-{self.port}.log")
        deadline = time.monotonic() + 60
        while time.monotonic() < deadline:
            if not self.alive():
                raise RuntimeError("uvicorn exited:\n" + self.tail())
            try:
                if httpx.get(self.url + "/health", timeout=2).status_code == 200:
                    return
            except httpx.HTTPError:
                pass
            time.sleep(0.1)
        self.stop()
        raise RuntimeError("uvicorn did not become healthy:\n" + self.tail())


class Worker(Proc):
    """A real Celery worker (solo pool unless told) for the data dir and broker."""

    _n = 0

    def __init__(self, data_dir: Path, broker_url: str = "", pool: str = "solo",
                 concurrency: int = 1, plugin: bool = False, **extra: str) -> None:
        Worker._n += 1
        name = f"w{Worker._n}-{os.getpid()}@127.0.0.1"
        log = data_dir / f"worker-{Worker._n}.log"
        env = service_env(data_dir, broker_url, **extra)
        if plugin:
            env["PYTHONPATH"] = f"{ROOT}{os.pathsep}{ROOT / 'tests' / 'e2e'}"
        super().__init__([sys.executable, "-m", "celery", "-A", "worker.celery_app:app",
                          "worker", "-Q", "rsf", f"--pool={pool}",
                          f"--concurrency={concurrency}", "--loglevel=INFO",
                          "--without-gossip", "--without-mingle", "--without-heartbeat",
                          "-n", name, *(["--include", "test_worker_faultplugin"] if plugin
                                        else [])],
                         env, log)
        deadline = time.monotonic() + 60
        while time.monotonic() < deadline:
            if not self.alive():
                raise RuntimeError("celery worker exited:\n" + self.tail())
            if " ready." in self.tail(100_000):
                return
            time.sleep(0.1)
        self.stop()
        raise RuntimeError("celery worker did not become ready:\n" + self.tail())

    def stop(self, timeout: float = 10.0) -> None:
        """SIGKILL: the sweeps survive it by design, and a Celery warm or cold shutdown
        on the filesystem transport takes seconds (its loop blocks in drain_events)."""
        self.kill(signal.SIGKILL)
        self.p.wait(timeout)


class Redis(Proc):
    """redis-server on 127.0.0.1:<free port>, no persistence."""

    def __init__(self, exe: str, data_dir: Path) -> None:
        self.port = free_port()
        self.url = f"redis://127.0.0.1:{self.port}/0"
        super().__init__([exe, "--port", str(self.port), "--bind", "127.0.0.1", "--save", "",
                          "--appendonly", "no", "--dir", str(data_dir)], dict(os.environ),
                         data_dir / "redis.log")
        import redis
        deadline = time.monotonic() + 20
        while time.monotonic() < deadline:
            try:
                if redis.Redis(port=self.port, socket_timeout=1).ping():
                    return
            except redis.RedisError:
                time.sleep(0.05)
        self.stop()
        raise RuntimeError("redis-server did not start:\n" + self.tail())


@pytest.fixture
def procs() -> Iterator[list[Proc]]:
    """A list to register processes in; all are stopped at teardown."""
    started: list[Proc] = []
    yield started
    for p in reversed(started):
        p.stop()


@pytest.fixture(scope="session")
def redis_exe() -> str:
    """Path of redis-server; skipped locally if absent, a failure under CI=true."""
    exe = shutil.which("redis-server")
    if exe is None:
        msg = "redis-server not installed (apt-get install -y redis-server)"
        if os.environ.get("CI", "").lower() == "true":
            pytest.fail(msg + " -- required under CI=true")
        pytest.skip(msg)
    return exe


@pytest.fixture(scope="module")
def fs_stack(tmp_path_factory: pytest.TempPathFactory) -> Iterator[tuple[Server, Path]]:
    """A uvicorn server on the filesystem broker (no worker) and its data dir."""
    d = tmp_path_factory.mktemp("rsf-fs")
    # A generous inline budget: on a loaded machine a first query may be slow, and these
    # tests check answers, not deferral (tested on its own server).
    srv = Server(d, RSF_INLINE_BUDGET_S="120")
    yield srv, d
    srv.stop()


@pytest.fixture
def client_for():
    """Factory of httpx clients for a base URL (closed at teardown)."""
    clients: list[httpx.Client] = []

    def make(url: str) -> httpx.Client:
        c = httpx.Client(base_url=url, timeout=60)
        clients.append(c)
        return c
    yield make
    for c in clients:
        c.close()
