"""Several hosts for real: an API process and two Celery workers acting as different hosts
(different RSF_NODE names and data directories, nothing shared on disk) on Redis (with
persistence) and PostgreSQL, all started here on free ports.

Cases: a sweep split across both workers with every point stored exactly once; Redis
restarted mid-sweep; PostgreSQL restarted mid-sweep (the API answers 503 problem+json
with Retry-After while it is down, never a 500 or a hang); a worker SIGKILLed mid-sweep
(its chunk is requeued by the other worker's reaper within the lease, no restart).
After each completed sweep (with and without a fault) every download is checked: NetCDF,
CSV, JSON, the diagram and the paged points, against each other and, at sampled points,
against rsfcore to 1e-12 (on PostgreSQL every format but /points was once a 503 "integer
out of range").  Plus SQLite damage: /health 503 with the reason, and ``rsf api`` refusing to start on a
damaged header with what is wrong and how to recover (no traceback).

The lease is 3 s here (default 30 s) to keep the run short; every chunk is slowed by
0.25 s (chunk_delay_plugin) so that a sweep is still running when a fault is injected.
"""

from __future__ import annotations

import csv
import io
import math
import sqlite3
import subprocess
import sys
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import httpx
import numpy as np
import pytest
from sqlalchemy import create_engine, text

from rsfcore import critical
from rsfcore.params import Params
from tests.conftest import ROOT, Postgres, Proc, Redis, Worker, free_port, service_env

pytestmark = pytest.mark.timeout(240)

LEASE_S = 3.0
CHUNK_DELAY_S = 0.25


def wait_for(pred: Callable[[], Any], timeout: float, what: str, dt: float = 0.1) -> Any:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        v = pred()
        if v:
            return v
        time.sleep(dt)
    raise AssertionError(f"timed out after {timeout} s waiting for {what}")


@dataclass
class Stack:
    pg: Postgres
    redis: Redis
    api: Proc  # `rsf api`, as docker-compose.yml runs it
    workers: dict[str, Worker]
    client: httpx.Client

    def sql(self, query: str, **params: Any) -> list[Any]:
        eng = create_engine(self.pg.url)
        try:
            with eng.connect() as conn:
                return list(conn.execute(text(query), params).all())
        finally:
            eng.dispose()


@pytest.fixture(scope="module")
def stack(
    tmp_path_factory: pytest.TempPathFactory, redis_exe: str, postgres_bin: Path
) -> Iterator[Stack]:
    base = tmp_path_factory.mktemp("multihost")
    dirs = {n: base / n for n in ("redis", "api", "host-a", "host-b")}
    for d in dirs.values():
        d.mkdir()
    pg = Postgres(postgres_bin)
    started: list[Proc] = []
    try:
        red = Redis(redis_exe, dirs["redis"], persist=True)
        started.append(red)
        env = {
            "RSF_CACHE_URL": pg.url,
            "RSF_LEASE_S": str(LEASE_S),
            "RSF_RETRY_AFTER_S": "2",
            "RSF_DB_RETRY_S": "1",
        }
        api, url = _rsf_api(
            dirs["api"], dirs["api"] / "api.log", red.url, RSF_NODE="api-host", **env
        )
        started.append(api)
        wait_for(
            lambda: (r := _get(url + "/health")) is not None and r.status_code == 200,
            60,
            "rsf api to be healthy",
        )
        workers = {}
        for node in ("host-a", "host-b"):
            workers[node] = Worker(
                dirs[node],
                red.url,
                include="chunk_delay_plugin",
                RSF_NODE=node,
                RSF_TEST_CHUNK_DELAY_S=str(CHUNK_DELAY_S),
                **env,
            )
            started.append(workers[node])
        with httpx.Client(base_url=url, timeout=10) as c:
            yield Stack(pg, red, api, workers, c)
    finally:
        for p in reversed(started):
            p.stop()
        pg.destroy()


def submit(st: Stack, n_kappa: int, n_eps: int, chunk: int) -> str:
    """A critical-size sweep over (kappa_ratio, eps) of n_kappa x n_eps points."""
    body = {
        "axes": [
            {"name": "kappa_ratio", "start": 0.3, "stop": 2.5, "n": n_kappa},
            {"name": "eps", "start": 0.05, "stop": 0.95, "n": n_eps},
        ],
        "fixed": {"ba": 2.0, "vo": 1.0},
        "chunk_points": chunk,
    }
    r = st.client.post("/v1/sweeps", json=body)
    assert r.status_code == 202, r.text
    return str(r.headers["location"].rsplit("/", 1)[1])


def status(st: Stack, sid: str) -> dict[str, Any]:
    r = st.client.get(f"/v1/sweeps/{sid}")
    assert r.status_code == 200, r.text
    return dict(r.json())


def wait_done(st: Stack, sid: str, timeout: float) -> dict[str, Any]:
    """Poll until done; a 503 (the database just came back: the API's one-second
    fail-fast window after an outage) means "ask again", anything else must be 200."""

    def done() -> dict[str, Any] | None:
        r = st.client.get(f"/v1/sweeps/{sid}")
        if r.status_code == 503:
            assert r.headers["content-type"].startswith("application/problem+json")
            return None
        assert r.status_code == 200, r.text
        return dict(r.json()) if r.json()["status"] == "done" else None

    return dict(wait_for(done, timeout, f"sweep {sid} done"))


def check_exactly_once(st: Stack, sid: str, n_total: int) -> None:
    """Every point stored exactly once: the stored blocks tile [0, n_total) without gap
    or overlap, one block per chunk, and every chunk is done."""
    blocks = st.sql("SELECT i0, i1 FROM sweep_blocks WHERE sweep_id = :s ORDER BY i0", s=sid)
    n_chunks = st.sql("SELECT n_chunks FROM sweeps WHERE id = :s", s=sid)[0][0]
    assert len(blocks) == n_chunks
    assert blocks[0][0] == 0 and blocks[-1][1] == n_total
    assert all(a[1] == b[0] for a, b in zip(blocks, blocks[1:], strict=False))
    left = st.sql(
        "SELECT count(*) FROM sweep_chunks WHERE sweep_id = :s AND status <> 'done'", s=sid
    )[0][0]
    assert left == 0


def check_downloads(st: Stack, sid: str, n_kappa: int, n_eps: int, samples: int = 12) -> None:
    """Every format of the finished sweep (``submit``'s grid): NetCDF, CSV, JSON, the
    diagram (JSON) and /points agree with each other exactly and, at ``samples`` points
    drawn at random plus both corners, with rsfcore's single-point critical size to
    1e-12 relative (the same compiled kernel: identical in fact; 1e-12 leaves room for a
    different summation order only)."""
    import xarray as xr

    n = n_kappa * n_eps
    got: dict[str, np.ndarray] = {}
    r = st.client.get(f"/v1/sweeps/{sid}/data", params={"format": "netcdf"}, timeout=60)
    assert r.status_code == 200, r.text[:300]
    with xr.open_dataset(io.BytesIO(r.content)) as ds:
        got["netcdf"] = ds["critical_size"].values.reshape(-1).astype(np.float64)
        kr, eps = ds["kappa_ratio"].values, ds["eps"].values
    r = st.client.get(f"/v1/sweeps/{sid}/data", params={"format": "csv"}, timeout=60)
    assert r.status_code == 200
    rows = list(csv.DictReader(io.StringIO(r.text)))
    assert len(rows) == n and [int(x["idx"]) for x in rows] == list(range(n))
    got["csv"] = np.array([float(x["critical_size"] or "nan") for x in rows])
    r = st.client.get(f"/v1/sweeps/{sid}/data", params={"format": "json"}, timeout=60)
    assert r.status_code == 200
    got["json"] = np.array(
        [math.inf if v is None else v for v in r.json()["data"]["critical_size"]], np.float64
    )
    r = st.client.get(f"/v1/sweeps/{sid}/diagram", timeout=60)
    assert r.status_code == 200, r.text[:300]
    d = r.json()
    assert (d["x_name"], d["y_name"]) == ("kappa_ratio", "eps")
    got["diagram"] = np.array(
        [math.inf if v is None else v for row in d["critical_size"] for v in row], np.float64
    )
    pts: list[float] = []
    off: int | None = 0
    while off is not None:
        r = st.client.get(f"/v1/sweeps/{sid}/points", params={"offset": off, "limit": 1000})
        assert r.status_code == 200
        pts += [
            math.inf if p["critical_size"] is None else p["critical_size"]
            for p in r.json()["points"]
        ]
        off = r.json()["next_offset"]
    got["points"] = np.array(pts)
    # infinite critical sizes are null in JSON: inf everywhere in the comparison
    base = np.where(np.isnan(got["netcdf"]), math.inf, got["netcdf"])
    assert base.shape == (n,) and np.isfinite(base).any()
    for fmt, a in got.items():
        b = np.where(np.isnan(a), math.inf, a)
        assert np.array_equal(b, base), fmt
    rng = np.random.default_rng(int(sid[:8], 16))
    for i in [0, n - 1, *rng.integers(0, n, samples).tolist()]:
        ki, ei = divmod(int(i), n_eps)
        ref = critical.critical_perturbation(
            Params(2.0, float(kr[ki]) * (2.0 - 1.0), float(eps[ei]), 1.0),
            "velocity-jump",
            rtol=1e-10,
        )
        want = math.inf if ref.critical_size is None else ref.critical_size
        if math.isinf(want):
            assert base[i] == want, i
        else:
            assert base[i] == pytest.approx(want, rel=1e-12), i


def nodes_of(st: Stack, sid: str) -> set[str]:
    """Nodes (hosts) that computed the sweep's chunks (owner = node:pid)."""
    rows = st.sql("SELECT owner FROM sweep_chunks WHERE sweep_id = :s", s=sid)
    return {str(r[0]).rsplit(":", 1)[0] for r in rows if r[0]}


def test_sweep_split_across_two_hosts_every_point_once(stack: Stack) -> None:
    sid = submit(stack, 40, 50, chunk=100)  # 2000 points, 20 chunks
    s = wait_done(stack, sid, 60)
    assert s["n_done"] == s["n_total"] == 2000 and s["n_failed"] == 0
    check_exactly_once(stack, sid, 2000)
    check_downloads(stack, sid, 40, 50)
    assert nodes_of(stack, sid) == {"host-a", "host-b"}
    h = stack.client.get("/health").json()
    assert h["status"] == "ok" and h["workers"]["hosts"] == ["host-a", "host-b"], h
    assert h["broker"]["ok"] and h["database"]["ok"] and h["database"]["dialect"] == "postgresql"


def test_cancel_resume_purge_while_both_hosts_claim(stack: Stack) -> None:
    """Cancel while both hosts claim chunks (once a 503 'deadlock detected': the cancel
    and a claim locked sweeps and chunks in opposite order), resume by submitting again,
    finish, download, purge."""
    sid = submit(stack, 40, 55, chunk=55)  # 2200 points, 40 chunks
    wait_for(lambda: status(stack, sid)["n_done"] > 0, 30, "progress")
    r = stack.client.delete(f"/v1/sweeps/{sid}")
    assert r.status_code == 200, r.text
    assert r.json()["status"] == "cancelled"
    sid2 = submit(stack, 40, 55, chunk=55)
    assert sid2 == sid
    s = wait_done(stack, sid, 90)
    assert s["n_done"] == 2200
    check_exactly_once(stack, sid, 2200)
    check_downloads(stack, sid, 40, 55, samples=4)
    assert stack.client.delete(f"/v1/sweeps/{sid}", params={"purge": "true"}).status_code == 204
    assert stack.client.get(f"/v1/sweeps/{sid}").status_code == 404
    assert stack.sql("SELECT count(*) FROM sweep_blocks WHERE sweep_id = :s", s=sid)[0][0] == 0


def test_redis_restart_mid_sweep(stack: Stack) -> None:
    sid = submit(stack, 40, 60, chunk=60)  # 2400 points, 40 chunks: ~5 s on two workers
    wait_for(lambda: 0 < status(stack, sid)["n_done"] < 1200, 30, "progress")
    stack.redis.restart(down_s=1.0)
    s = wait_done(stack, sid, 90)
    assert s["n_done"] == 2400
    check_exactly_once(stack, sid, 2400)


def test_postgres_restart_mid_sweep_503_then_resumes(stack: Stack) -> None:
    sid = submit(stack, 40, 61, chunk=61)  # 2440 points, 40 chunks
    wait_for(lambda: 0 < status(stack, sid)["n_done"] < 1200, 30, "progress")
    stack.pg.stop()
    answers = []
    t_end = time.monotonic() + 3.0
    while time.monotonic() < t_end:
        t0 = time.monotonic()
        r = stack.client.get(f"/v1/sweeps/{sid}")
        answers.append(
            (
                r.status_code,
                r.headers.get("content-type"),
                r.headers.get("retry-after"),
                time.monotonic() - t0,
                r.text[:200],
            )
        )
        time.sleep(0.2)
    h = stack.client.get("/health")
    stack.pg.start()
    # Never a 500 or a hang: 503 problem+json with Retry-After, within the retry window.
    assert answers and all(a[0] == 503 for a in answers), answers
    assert all(a[1].startswith("application/problem+json") and a[2] == "2" for a in answers)
    assert max(a[3] for a in answers) < 5.0, answers
    # /health: 503 with the reason (its report, or the problem+json of the API-key check
    # that needs the database before the handler runs)
    assert h.status_code == 503 and h.headers["retry-after"] == "2"
    hb = h.json()
    assert "unavailable" in " ".join(hb.get("reasons", [])) + hb.get("reason", ""), h.text
    s = wait_done(stack, sid, 90)
    assert s["n_done"] == 2440
    check_exactly_once(stack, sid, 2440)
    check_downloads(stack, sid, 40, 61)
    assert stack.client.get("/health").status_code == 200


def test_messages_lost_by_the_broker_are_sent_again(stack: Stack) -> None:
    """Redis loses the waiting messages (as after a crash without its last writes): here
    the first chunks of a second sweep, submitted while both workers chain the first
    sweep's chunks (each worker holds one lane of a sweep and takes its next pending
    chunk without a message, so a sweep's messages wait in the queue only while the
    workers are busy elsewhere).  The reapers see the queue empty while chunks stay
    queued for a lease, and send them again; both sweeps complete, every point once."""
    import redis

    first = submit(stack, 40, 59, chunk=59)  # 2360 points, 40 chunks
    wait_for(lambda: 0 < status(stack, first)["n_done"] < 1000, 30, "progress")
    sid = submit(stack, 40, 58, chunk=58)  # 2320 points, 40 chunks: its lanes wait
    r = redis.Redis(port=stack.redis.port)
    keys = r.keys("rsf*")
    assert keys and r.delete(*keys) >= 1
    for s_id, n in ((first, 2360), (sid, 2320)):
        s = wait_done(stack, s_id, 60)
        assert s["n_done"] == n
        check_exactly_once(stack, s_id, n)


def test_sigkill_one_host_mid_sweep_completes_on_the_other(stack: Stack) -> None:
    sid = submit(stack, 40, 80, chunk=80)  # 3200 points, 40 chunks
    held = wait_for(
        lambda: stack.sql(
            "SELECT idx FROM sweep_chunks WHERE sweep_id = :s AND status = 'running' "
            "AND owner LIKE 'host-a:%'",
            s=sid,
        ),
        30,
        "host-a to hold a chunk",
        dt=0.02,
    )
    idx = held[0][0]
    stack.workers["host-a"].kill()  # SIGKILL, mid-chunk, no restart
    t_kill = time.monotonic()
    n_left = 3200 - status(stack, sid)["n_done"]
    s = wait_done(stack, sid, 90)
    elapsed = time.monotonic() - t_kill
    assert s["n_done"] == 3200
    check_exactly_once(stack, sid, 3200)
    check_downloads(stack, sid, 40, 80)
    owner, attempts = stack.sql(
        "SELECT owner, attempts FROM sweep_chunks WHERE sweep_id = :s AND idx = :i", s=sid, i=idx
    )[0]
    assert owner.startswith("host-b:") and attempts >= 2
    # Within the lease plus the other host's own backlog (0.25 s per chunk at least, and
    # a generous 10 s for a loaded 2-core CI machine), not an hour or a restart.
    backlog = n_left / 80 * CHUNK_DELAY_S
    assert elapsed < LEASE_S + backlog + 10.0, (elapsed, backlog)
    h = stack.client.get("/health").json()
    assert h["workers"]["hosts"] == ["host-b"], h


def _rsf_api(data: Path, log: Path, broker_url: str = "", **extra: str) -> tuple[Proc, str]:
    """`rsf api` (HTTP only) on a free port; (process, base URL)."""
    port = free_port()
    cmd = [sys.executable, "-m", "rsfcli.main", "api", "--port", str(port), "--wait-db", "0"]
    return Proc(cmd, service_env(data, broker_url, **extra), log), f"http://127.0.0.1:{port}"


def test_damaged_sqlite_health_503_and_startup_says_how_to_recover(tmp_path: Path) -> None:
    from rsfapp.db.engine import Database

    db_file = tmp_path / "cache.sqlite3"
    db = Database(f"sqlite:///{db_file}")
    db.ensure_schema()
    con = sqlite3.connect(db_file)
    con.executemany(
        "INSERT INTO jobs(key, kind, state, message, updated_at) VALUES (?,?,?,?,?)",
        [(f"{i:064x}", "classify", "failed", "x" * 400, 0.0) for i in range(400)],
    )
    con.commit()
    con.execute("PRAGMA wal_checkpoint(TRUNCATE)")
    con.close()
    db.dispose()
    # Damage one page in the last third of the file (the jobs table), not the header.
    size = db_file.stat().st_size
    with open(db_file, "r+b") as f:
        f.seek((size * 3 // 4) // 4096 * 4096)
        f.write(b"\xff" * 4096)
    p, url = _rsf_api(tmp_path, tmp_path / "api.log")
    try:
        r = wait_for(lambda: _get(url + "/health"), 60, "the API to answer")
        assert r.status_code == 503, r.text
        body = r.json()
        assert body["status"] == "degraded" and not body["database"]["ok"]
        assert "damaged" in body["database"]["reason"], body
        assert "mv " in body["database"]["hint"]
    finally:
        p.stop()
    # A damaged header: start-up refuses, says what and how, no traceback.
    with open(db_file, "r+b") as f:
        f.write(b"this is no database file")
    r2 = subprocess.run(
        [sys.executable, "-m", "rsfcli.main", "api", "--port", str(free_port()), "--wait-db", "0"],
        env=service_env(tmp_path),
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert r2.returncode == 1
    assert "cannot start" in r2.stderr and "is damaged" in r2.stderr, r2.stderr
    assert "how to recover" in r2.stderr and "Traceback" not in r2.stderr + r2.stdout


def _get(url: str) -> httpx.Response | None:
    try:
        return httpx.get(url, timeout=5)
    except httpx.HTTPError:
        return None


def _fake_sweep(
    conn: Any,
    sid: str,
    n_chunks: int,
    status: str,
    chunk_status: str,
    heartbeat: float | None = None,
) -> None:
    from rsfapp.db.tables import chunks, sweeps

    conn.execute(
        sweeps.insert().values(
            id=sid,
            spec="{}",
            status=status,
            n_total=n_chunks,
            n_chunks=n_chunks,
            numerics_version="t",
            created_at=time.time(),
        )
    )
    conn.execute(
        chunks.insert(),
        [
            {
                "sweep_id": sid,
                "idx": i,
                "i0": i,
                "i1": i + 1,
                "status": chunk_status,
                "owner": "gone:1",
                "heartbeat": heartbeat,
                "attempts": 1,
            }
            for i in range(n_chunks)
        ],
    )


@pytest.mark.parametrize("dialect", ["postgresql", "sqlite"])
def test_completion_is_race_free_and_self_repairing(
    dialect: str, tmp_path: Path, request: pytest.FixtureRequest
) -> None:
    """The last two chunks of a sweep finishing at the same moment close it (READ
    COMMITTED write skew would leave it running); a sweep left running with every chunk
    done is closed by the reaper's scan; an expired lease is taken back exactly once
    by concurrent reapers."""
    import threading

    from sqlalchemy import select

    from rsfapp.db.engine import Database
    from rsfapp.db.tables import sweeps
    from rsfapp.store.sweeps import SweepStore, encode_block

    url = (
        request.getfixturevalue("postgres").url
        if dialect == "postgresql"
        else f"sqlite:///{tmp_path / 'c.sqlite3'}"
    )
    db = Database(url)
    store = SweepStore(db)
    n = 25
    with db.write() as conn:
        for k in range(n):
            _fake_sweep(conn, f"race{k:028d}", 2, "running", "running", time.time())
        _fake_sweep(conn, "stuck" + "0" * 27, 3, "running", "done")
        _fake_sweep(conn, "lease" + "0" * 27, 1, "running", "running", time.time() - 100)
    for k in range(n):
        sid = f"race{k:028d}"
        gate = threading.Barrier(2)

        def finish(i: int, sid: str = sid, gate: threading.Barrier = gate) -> None:
            gate.wait()
            # as a worker does: the block, then the chunk (done only with its block)
            store.store_block(sid, i, i, i + 1, encode_block({"x": np.zeros(1)}), {})
            store.finish_chunk(sid, i, complete=True)

        ts = [threading.Thread(target=finish, args=(i,)) for i in (0, 1)]
        for t in ts:
            t.start()
        for t in ts:
            t.join()
    with db.read() as conn:
        left = conn.execute(
            select(sweeps.c.id).where(sweeps.c.id.like("race%"), sweeps.c.status != "done")
        ).all()
    assert left == []
    # Two reapers at once: the expired chunk is requeued by exactly one of them.
    got: list[list[tuple[str, int]]] = []
    gate2 = threading.Barrier(2)

    def reap() -> None:
        gate2.wait()
        got.append(SweepStore(db).reap_expired(30.0))

    ts = [threading.Thread(target=reap) for _ in range(2)]
    for t in ts:
        t.start()
    for t in ts:
        t.join()
    assert sorted(x for g in got for x in g) == [("lease" + "0" * 27, 0)]
    closed, _send = store.close_finished()
    assert closed == 1
    with db.read() as conn:
        st = conn.execute(select(sweeps.c.status).where(sweeps.c.id == "stuck" + "0" * 27))
        assert st.scalar() == "done"
    db.dispose()
