"""Shared fixtures: free ports, real uvicorn / Celery worker / redis-server /
PostgreSQL processes.

Every process is started by us, on 127.0.0.1, with its own data directory, and is
stopped by its pid (process group) at teardown.  Under CI=true a missing redis-server
or PostgreSQL server is a failure, not a skip.  PostgreSQL is one cluster for the
session (``postgres_cluster``) with a fresh database for each test (``postgres``):
``initdb`` is the expensive part, a database costs tens of milliseconds.
"""

from __future__ import annotations

import contextlib
import os
import shutil
import signal
import socket
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path
from typing import NamedTuple

import httpx
import pytest

from rsfcore._cache import cache_dir as kernel_cache_dir

ROOT = Path(__file__).resolve().parents[1]


def free_port() -> int:
    """A TCP port free on 127.0.0.1 right now."""
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def service_env(data_dir: Path, broker_url: str = "", **extra: str) -> dict[str, str]:
    """Environment for service/worker processes using ``data_dir``."""
    env = {k: v for k, v in os.environ.items() if not k.startswith("RSF_")}
    env.update(
        RSF_DATA_DIR=str(data_dir),
        RSF_BROKER_URL=broker_url,
        NUMBA_CACHE_DIR=str(
            kernel_cache_dir()
        ),  # rsfcore/_cache.py: the one every entry point uses
        PYTHONPATH=str(ROOT),
    )
    env.update(extra)
    return env


class Proc:
    """A subprocess in its own session, logging to a file, stopped by process group."""

    def __init__(self, cmd: list[str], env: dict[str, str], log: Path) -> None:
        self.cmd, self.env, self.log = cmd, env, log
        fh = open(log, "ab")  # noqa: SIM115
        self.p = subprocess.Popen(
            cmd, env=env, stdout=fh, stderr=fh, cwd=ROOT, start_new_session=True
        )
        fh.close()

    @property
    def pid(self) -> int:
        return self.p.pid

    def alive(self) -> bool:
        return self.p.poll() is None

    def kill(self, sig: int = signal.SIGKILL) -> None:
        """Send ``sig`` to the whole process group (our child and its children)."""
        if self.alive():
            with contextlib.suppress(ProcessLookupError):
                os.killpg(self.p.pid, sig)

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
        super().__init__(
            [
                sys.executable,
                "-m",
                "uvicorn",
                "service.app:app",
                "--host",
                "127.0.0.1",
                "--port",
                str(self.port),
                "--log-level",
                "warning",
            ],
            service_env(data_dir, broker_url, **extra),
            data_dir / f"uvicorn-{self.port}.log",
        )
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

    def __init__(
        self,
        data_dir: Path,
        broker_url: str = "",
        pool: str = "solo",
        concurrency: int = 1,
        plugin: bool = False,
        include: str = "",
        **extra: str,
    ) -> None:
        Worker._n += 1
        name = f"w{Worker._n}-{os.getpid()}@127.0.0.1"
        log = data_dir / f"worker-{Worker._n}.log"
        env = service_env(data_dir, broker_url, **extra)
        if plugin or include:
            env["PYTHONPATH"] = f"{ROOT}{os.pathsep}{ROOT / 'tests' / 'e2e'}"
        super().__init__(
            [
                sys.executable,
                "-m",
                "celery",
                "-A",
                "worker.celery_app:app",
                "worker",
                "-Q",
                "rsf",
                f"--pool={pool}",
                f"--concurrency={concurrency}",
                "--loglevel=INFO",
                "--without-gossip",
                "--without-mingle",
                "--without-heartbeat",
                "-n",
                name,
                *(["--include", "test_worker_faultplugin"] if plugin else []),
                *(["--include", include] if include else []),
            ],
            env,
            log,
        )
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
    """redis-server on 127.0.0.1:<free port>; with ``persist`` an append-only file
    fsynced on every write (as docker-compose.yml runs it), so :meth:`restart` keeps
    the queued messages."""

    def __init__(self, exe: str, data_dir: Path, persist: bool = False) -> None:
        self.exe, self.dir, self.persist = exe, data_dir, persist
        self.port = free_port()
        self.url = f"redis://127.0.0.1:{self.port}/0"
        self._start()

    def _start(self) -> None:
        durability = (
            ["--appendonly", "yes", "--appendfsync", "always"]
            if self.persist
            else ["--appendonly", "no"]
        )
        super().__init__(
            [
                self.exe,
                "--port",
                str(self.port),
                "--bind",
                "127.0.0.1",
                "--save",
                "",
                *durability,
                "--dir",
                str(self.dir),
            ],
            dict(os.environ),
            self.dir / "redis.log",
        )
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

    def restart(self, down_s: float = 0.0) -> None:
        """Stop (SIGTERM: clean shutdown), stay down ``down_s`` seconds, start again on
        the same port and directory."""
        self.stop()
        time.sleep(down_s)
        self._start()


def postgres_bindir() -> Path | None:
    """Directory of initdb/pg_ctl/postgres: on PATH, else the newest
    /usr/lib/postgresql/<version>/bin (Debian's layout)."""
    exe = shutil.which("initdb")
    if exe and shutil.which("pg_ctl"):
        return Path(exe).resolve().parent
    found = sorted(
        Path("/usr/lib/postgresql").glob("*/bin/initdb"),
        key=lambda p: (
            float(p.parent.parent.name) if p.parent.parent.name.replace(".", "").isdigit() else 0.0
        ),
    )
    return found[-1].parent if found else None


class PgDatabase(NamedTuple):
    """One database of a :class:`Postgres` cluster: its name and SQLAlchemy URL."""

    name: str
    url: str


class Postgres:
    """A throw-away PostgreSQL cluster: initdb in a private temporary directory, run by
    an unprivileged user (PostgreSQL refuses root: when we are root it runs as the
    ``postgres`` account, else ``nobody``), listening on 127.0.0.1:<free port>, trust
    authentication for the local user ``rsf``, fsync off (test data only).

    :meth:`stop` / :meth:`start` / :meth:`restart` act on the same cluster and port;
    :meth:`destroy` removes it.  :attr:`url` is its ``postgres`` database;
    :meth:`create_database` makes more."""

    _n_databases = 0

    def __init__(self, bindir: Path) -> None:
        import pwd
        import tempfile

        self.bin = bindir
        self.dir = Path(tempfile.mkdtemp(prefix="rsf-pg-"))
        self.user: int | None = None
        self.group: int | None = None
        if os.geteuid() == 0:
            try:
                pw = pwd.getpwnam("postgres")
            except KeyError:
                pw = pwd.getpwnam("nobody")
            self.user, self.group = pw.pw_uid, pw.pw_gid
            os.chown(self.dir, pw.pw_uid, pw.pw_gid)
        self.data = self.dir / "data"
        self.port = free_port()
        self.url = self.database_url("postgres")
        self._run(
            [
                str(bindir / "initdb"),
                "-D",
                str(self.data),
                "-U",
                "rsf",
                "--auth=trust",
                "-E",
                "UTF8",
                "--no-sync",
            ]
        )
        self.start()

    def _run(self, cmd: list[str], check: bool = True) -> subprocess.CompletedProcess[str]:
        r = subprocess.run(
            cmd,
            user=self.user,
            group=self.group,
            capture_output=True,
            text=True,
            timeout=120,
            cwd=self.dir,
        )
        if check and r.returncode != 0:
            raise RuntimeError(
                f"{' '.join(cmd)} failed ({r.returncode}):\n{r.stdout}\n{r.stderr}\n{self.tail()}"
            )
        return r

    def tail(self, n: int = 4000) -> str:
        try:
            return (self.dir / "postgres.log").read_text(errors="replace")[-n:]
        except OSError:
            return ""

    def start(self) -> None:
        """Start the server and wait until it accepts connections."""
        self._run(
            [
                str(self.bin / "pg_ctl"),
                "-D",
                str(self.data),
                "-l",
                str(self.dir / "postgres.log"),
                "-w",
                "-t",
                "60",
                "-o",
                f"-p {self.port} -k {self.dir} -c listen_addresses=127.0.0.1 "
                "-c fsync=off -c max_connections=200",
                "start",
            ]
        )

    def stop(self, mode: str = "fast") -> None:
        """Stop the server (``fast``: disconnect clients, clean shutdown)."""
        self._run(
            [str(self.bin / "pg_ctl"), "-D", str(self.data), "-m", mode, "-w", "-t", "60", "stop"],
            check=False,
        )

    def restart(self, down_s: float = 0.0) -> None:
        """Stop, stay down ``down_s`` seconds, start on the same port."""
        self.stop()
        time.sleep(down_s)
        self.start()

    def database_url(self, name: str) -> str:
        """SQLAlchemy URL of database ``name`` on this cluster (user ``rsf``)."""
        return f"postgresql+psycopg://rsf@127.0.0.1:{self.port}/{name}"

    def _admin(self, sql: str) -> None:
        import psycopg

        with psycopg.connect(
            host="127.0.0.1", port=self.port, user="rsf", dbname="postgres", autocommit=True
        ) as conn:
            conn.execute(sql)  # type: ignore[arg-type]  # fixed statements of ours, not input

    def create_database(self) -> PgDatabase:
        """A new empty database (from ``template0``) with a name unique in this cluster."""
        Postgres._n_databases += 1
        name = f"rsf_t{Postgres._n_databases}"
        self._admin(f"CREATE DATABASE \"{name}\" TEMPLATE template0 ENCODING 'UTF8'")
        return PgDatabase(name, self.database_url(name))

    def drop_database(self, db: PgDatabase) -> None:
        """Drop ``db``, closing the connections still open to it."""
        self._admin(f'DROP DATABASE IF EXISTS "{db.name}" WITH (FORCE)')

    def destroy(self) -> None:
        """Stop (immediate) and delete the cluster."""
        self.stop("immediate")
        shutil.rmtree(self.dir, ignore_errors=True)


def _required(msg: str) -> None:
    """Skip locally; under CI=true a missing part fails the run (never a silent skip)."""
    if os.environ.get("CI", "").lower() == "true":
        pytest.fail(msg + " -- required under CI=true")
    pytest.skip(msg)


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
        _required("redis-server not installed (apt-get install -y redis-server)")
    assert exe is not None
    return exe


@pytest.fixture(scope="session")
def postgres_bin() -> Path:
    """Directory of PostgreSQL's server programs; skipped locally if absent, a failure
    under CI=true."""
    d = postgres_bindir()
    if d is None:
        _required("PostgreSQL server not installed (apt-get install -y postgresql)")
    assert d is not None
    try:
        import psycopg  # noqa: F401
    except ImportError:
        _required("psycopg not installed (pip install -e '.[postgres]')")
    return d


@pytest.fixture(scope="session")
def postgres_cluster(postgres_bin: Path) -> Iterator[Postgres]:
    """One throw-away PostgreSQL cluster for the session: ``initdb`` and a server start
    cost 1-3 s (more on a loaded machine), so they are done once; each test gets its own
    database in it (:func:`postgres`).  Tests that stop or restart PostgreSQL start their
    own :class:`Postgres` instead (tests/e2e/test_multihost.py)."""
    pg = Postgres(postgres_bin)
    try:
        yield pg
    finally:
        pg.destroy()


@pytest.fixture
def postgres(postgres_cluster: Postgres) -> Iterator[PgDatabase]:
    """A fresh, empty database for one test on the session's cluster (CREATE DATABASE
    from ``template0``: tens of milliseconds), dropped at teardown with every connection
    the test left open (DROP DATABASE ... WITH (FORCE)).  Nothing a test writes (tables,
    rows, sequences, advisory locks: all per database) is seen by another."""
    db = postgres_cluster.create_database()
    try:
        yield db
    finally:
        postgres_cluster.drop_database(db)


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
