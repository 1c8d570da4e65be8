"""One key's fresh-computation bucket and in-flight leases (concurrent_requests) shared
by two real API processes (two uvicorn servers on one database: a SQLite file, and
PostgreSQL), as `rsf api --workers N` and several API hosts run; the key is made by the
real `rsf keys` CLI.  In-process version: tests/api/test_shared_limits.py."""

from __future__ import annotations

import threading
from collections.abc import Iterator

import httpx
import pytest

from rsfapp.db.engine import Database
from rsfapp.store.inflight import InflightStore
from rsfapp.store.keys import hash_key
from tests.conftest import PgDatabase, Postgres
from tests.e2e.test_auth_server import AuthServer, h, problem

pytestmark = [pytest.mark.e2e, pytest.mark.timeout(300)]


@pytest.fixture(scope="module", params=["sqlite", "postgres"])
def pair(
    request: pytest.FixtureRequest, tmp_path_factory: pytest.TempPathFactory
) -> Iterator[tuple[AuthServer, AuthServer]]:
    """Two API processes on one database, shared by this module's tests on that database
    (each test makes its own key and asks its own questions, so neither sees the
    other's tokens, leases or cached answers)."""
    tmp_path = tmp_path_factory.mktemp(f"shared-{request.param}")
    extra = {"RSF_QUOTA_FRESH_PER_S": "1000", "RSF_QUOTA_CONCURRENT_REQUESTS": "100"}
    cluster: Postgres | None = None
    pg: PgDatabase | None = None
    if request.param == "postgres":
        cluster = request.getfixturevalue("postgres_cluster")
        pg = cluster.create_database()
        extra["RSF_CACHE_URL"] = pg.url
    else:
        extra["RSF_CACHE_URL"] = f"sqlite:///{tmp_path / 'shared.sqlite3'}"
    servers: list[AuthServer] = []
    try:
        for name in ("a", "b"):  # own data directories: only the database is shared
            d = tmp_path / name
            d.mkdir()
            servers.append(AuthServer(d, **extra))
        yield servers[0], servers[1]
    finally:
        for s in servers:
            s.stop()
        if cluster is not None and pg is not None:
            cluster.drop_database(pg)


def test_two_api_processes_share_one_bucket(pair: tuple[AuthServer, AuthServer]) -> None:
    a, b = pair
    assert a.env["RSF_CACHE_URL"] == b.env["RSF_CACHE_URL"]
    # 0.2 per second: capacity 1, a token back only after 5 s (longer than these requests)
    key = a.rsf("keys", "create", "--name", "slow", "--quota", "fresh_per_s=0.2").stdout.strip()
    first = {"size": 0.211, "eps": 0.17}
    with httpx.Client(base_url=a.url, timeout=60, headers=h(key)) as ca:
        r = ca.post("/v1/classify", json=first)
        assert r.status_code == 200 and r.headers["x-cache"] == "miss", r.text
    with httpx.Client(base_url=b.url, timeout=60, headers=h(key)) as cb:
        r = cb.post("/v1/classify", json={"size": 0.212, "eps": 0.17})
        p = problem(r, 429)
        assert "fresh_per_s" in p["detail"]
        assert 1 <= int(r.headers["retry-after"]) <= 5
        # a cached answer needs no token
        r = cb.post("/v1/classify", json=first)
        assert r.status_code == 200 and r.headers["x-cache"] == "hit", r.text


def test_two_api_processes_share_the_concurrency_quota(
    pair: tuple[AuthServer, AuthServer],
) -> None:
    """A lease taken in the shared database (a request of the key in flight in some
    other API process) is counted by both servers; cached lookups need none."""
    a, b = pair
    key = a.rsf("keys", "create", "--name", "one", "--quota", "concurrent_requests=1").stdout
    key = key.strip()
    cached = {"size": 0.221, "eps": 0.17}
    with httpx.Client(base_url=a.url, timeout=60, headers=h(key)) as ca:
        r = ca.post("/v1/classify", json=cached)
        assert r.status_code == 200 and r.headers["x-cache"] == "miss", r.text
    db = Database(a.env["RSF_CACHE_URL"])
    try:
        slots = InflightStore(db)
        lease = slots.acquire(hash_key(key), 1, 60.0)
        assert lease.admitted and lease.lease_id is not None
        try:
            for srv in (a, b):
                with httpx.Client(base_url=srv.url, timeout=60, headers=h(key)) as c:
                    p = problem(c.post("/v1/classify", json={"size": 0.222}), 429)
                    assert "concurrent_requests = 1" in p["detail"]
                    r = c.post("/v1/classify", json=cached)
                    assert r.status_code == 200 and r.headers["x-cache"] == "hit", r.text
        finally:
            slots.release(lease.lease_id)
        with httpx.Client(base_url=b.url, timeout=60, headers=h(key)) as cb:
            r = cb.post("/v1/classify", json={"size": 0.222})
            assert r.status_code == 200 and r.headers["x-cache"] == "miss", r.text
            # back to back: a lease is given back before the client has the whole answer
            for i in range(8):
                r = cb.post("/v1/classify", json={"size": 0.23 + 0.001 * i})
                assert r.status_code == 200 and r.headers["x-cache"] == "miss", r.text
                assert slots.held(hash_key(key)) == 0
    finally:
        db.dispose()


def test_concurrent_acquires_never_exceed_the_quota_on_postgres(postgres: PgDatabase) -> None:
    """Eight threads (own pooled connections, READ COMMITTED) race for the 3 leases of
    one key, five times (five keys): exactly 3 are granted each time (the per-key
    advisory lock serialises them; without it, 5 were granted in 1 of 5 such races)."""
    db = Database(postgres.url)
    store = InflightStore(db, clock=lambda: 1000.0)
    try:
        lock = threading.Lock()
        for key in ("k0", "k1", "k2", "k3", "k4"):
            granted: list[bool] = []
            start = threading.Barrier(8)

            def worker(
                key: str = key, granted: list[bool] = granted, start: threading.Barrier = start
            ) -> None:
                start.wait()
                for _ in range(4):
                    ok = store.acquire(key, 3, 30.0).admitted
                    with lock:
                        granted.append(ok)

            threads = [threading.Thread(target=worker) for _ in range(8)]
            for t in threads:
                t.start()
            for t in threads:
                t.join()
            assert len(granted) == 32 and sum(granted) == 3, key
            assert store.held(key) == 3
    finally:
        db.dispose()
