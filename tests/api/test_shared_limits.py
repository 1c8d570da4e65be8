"""Fresh-computation buckets and in-flight leases (the concurrent_requests quota)
shared through the database, and cached lookups answered from memory (service.admission,
service.limits, service.answer.FastHits, rsfapp.store.ratelimits, rsfapp.store.inflight).

In process: two separate app instances (each with its own middleware, as two API
processes have) on one SQLite file, RSF_AUTH=on.  The real-process version (two uvicorn
processes, SQLite and PostgreSQL) is tests/e2e/test_shared_limits_server.py."""

from __future__ import annotations

import asyncio
import os
import threading
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from fastapi.testclient import TestClient

from rsfapp.config import get_settings
from rsfapp.db.engine import Database, DatabaseUnavailable
from rsfapp.store import stores_for
from rsfapp.store.inflight import InflightStore
from rsfapp.store.keys import KeyStore, Scope, WouldBlock, hash_key
from rsfapp.store.ratelimits import RateLimitStore, capacity_of
from service.app import create_app
from service.deps import get_queue
from service.limits import Limits
from tests.api.conftest import RecordingQueue

PROBLEM = "application/problem+json"


class Two:
    """Two app instances on one data directory, and a key factory."""

    def __init__(self, a: TestClient, b: TestClient, data: Path) -> None:
        self.a, self.b, self.data = a, b, data
        self.keys = KeyStore(stores_for(get_settings()).db)
        self.n = 0

    def key(self, scope: Scope = Scope.read, **quotas: Any) -> dict[str, str]:
        self.n += 1
        return {"Authorization": f"Bearer {self.keys.create(f'shared{self.n}', scope, quotas)}"}


@pytest.fixture(scope="module")
def two(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Two]:
    d = tmp_path_factory.mktemp("rsf-shared-limits")
    saved = {k: v for k, v in os.environ.items() if k.startswith("RSF_")}
    for k in saved:
        del os.environ[k]
    os.environ.update(
        RSF_DATA_DIR=str(d),
        RSF_INLINE_BUDGET_S="120",
        RSF_AUTH="on",
        RSF_QUOTA_FRESH_PER_S="1000",
        RSF_QUOTA_CONCURRENT_REQUESTS="100",
    )
    try:
        apps = [create_app(), create_app()]
        for app in apps:
            queue = RecordingQueue()
            app.dependency_overrides[get_queue] = lambda q=queue: q
        with (
            TestClient(apps[0], raise_server_exceptions=False) as a,
            TestClient(apps[1], raise_server_exceptions=False) as b,
        ):
            yield Two(a, b, d)
    finally:
        for k in [k for k in os.environ if k.startswith("RSF_")]:
            del os.environ[k]
        os.environ.update(saved)


def limits_of(c: TestClient) -> Limits:
    """The rate-limit middleware instance of the app behind ``c``."""
    layer: Any = c.app.middleware_stack  # type: ignore[attr-defined]
    while not isinstance(layer, Limits):
        layer = layer.app
    return layer


def assert_429(r: Any) -> int:
    assert r.status_code == 429, (r.status_code, r.text)
    assert r.headers["content-type"].startswith(PROBLEM)
    assert "fresh_per_s" in r.json()["detail"]
    return int(r.headers["retry-after"])


def test_two_apps_share_one_bucket(two: Two) -> None:
    # 0.2 per second: capacity 1, and a token takes 5 s to come back, far longer than
    # the few requests below take even on a loaded machine
    h = two.key(Scope.submit, fresh_per_s=0.2)
    assert limits_of(two.a) is not limits_of(two.b)  # no shared middleware state
    first = {"size": 0.123, "eps": 0.37}
    r = two.a.post("/v1/classify", json=first, headers=h)
    assert r.status_code == 200 and r.headers["x-cache"] == "miss", r.text
    # the other app (another API process) sees the empty bucket: a fresh query is refused
    retry = assert_429(two.b.post("/v1/classify", json={"size": 0.124, "eps": 0.37}, headers=h))
    assert 1 <= retry <= 5  # ceil((1 - level) / rate) with level in (0, 1]
    # ... and so are the endpoints charged after their work (batch), before any work
    r = two.b.post("/v1/classify/batch", json={"items": [{"size": 0.125}]}, headers=h)
    assert_429(r)
    # cached answers need no token, in either app
    for c in (two.a, two.b):
        r = c.post("/v1/classify", json=first, headers=h)
        assert r.status_code == 200 and r.headers["x-cache"] == "hit", r.text
    # the bucket is in the database, not in either app
    store = RateLimitStore(Database(get_settings().effective_cache_url))
    kid = hash_key(h["Authorization"].split()[1])
    assert store.level(kid, 0.2) < 1.0


def test_other_keys_unaffected(two: Two) -> None:
    slow = two.key(fresh_per_s=0.2)
    assert two.a.post("/v1/classify", json={"size": 0.131}, headers=slow).status_code == 200
    assert_429(two.b.post("/v1/classify", json={"size": 0.132}, headers=slow))
    other = two.key(fresh_per_s=0.2)
    assert two.b.post("/v1/classify", json={"size": 0.133}, headers=other).status_code == 200


def test_fast_hits_byte_identical_and_still_authorised(two: Two) -> None:
    h = two.key()
    body = {"size": 0.141, "kappa": 0.8}
    miss = two.a.post("/v1/classify", json=body, headers=h)
    assert miss.status_code == 200 and miss.headers["x-cache"] == "miss"
    # the answer taught the fast path: the hits are answered before routing
    fast = limits_of(two.a).fast
    assert fast is not None
    served = fast.served
    hits = [two.a.post("/v1/classify", json=body, headers=h) for _ in range(3)]
    assert fast.served >= served + 2
    assert {r.headers["x-cache"] for r in hits} == {"hit"}
    assert len({r.content for r in hits}) == 1
    assert hits[0].json() == {**miss.json(), "cached": True}
    # a remembered body still needs a valid key, and the key's scope
    served = fast.served
    r = two.a.post("/v1/classify", json=body)
    assert r.status_code == 401 and r.headers["content-type"].startswith(PROBLEM)
    assert two.keys.revoke(f"shared{two.n}")  # the key h
    r = two.a.post("/v1/classify", json=body, headers=h)
    assert r.status_code == 401, r.text
    assert fast.served == served


def test_fast_hit_keeps_trajectory_quota(two: Two) -> None:
    big = two.key()
    small = two.key(trajectory_points=50)
    body = {"n_points": 60, "size": 0.3}
    for _ in range(3):  # learnt by the fast path after the first hit
        r = two.a.post("/v1/trajectory", json=body, headers=big)
        assert r.status_code == 200, r.text
    r = two.a.post("/v1/trajectory", json=body, headers=small)
    assert r.status_code == 422 and r.json()["field"] == "n_points", r.text


def test_concurrent_takes_never_exceed_the_bucket(tmp_path: Path) -> None:
    """Eight threads race for the tokens of one key through one SQLite file: exactly
    ``capacity`` takes succeed (no refill: a frozen clock)."""
    db = Database(f"sqlite:///{tmp_path / 'b.sqlite3'}")
    store = RateLimitStore(db, clock=lambda: 1000.0)
    rate = 5.0
    granted: list[bool] = []
    lock = threading.Lock()

    def worker() -> None:
        for _ in range(4):
            ok = store.take("k", rate).admitted
            with lock:
                granted.append(ok)

    threads = [threading.Thread(target=worker) for _ in range(8)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert len(granted) == 32
    assert sum(granted) == capacity_of(rate) == 5


def test_bucket_refill_and_charges(tmp_path: Path) -> None:
    """Level, refill and Retry-After against the closed form of a token bucket:
    level(t) = min(cap, level(t0) + rate (t - t0)); exact in binary here (rates and
    times are sums of powers of two)."""
    now = [1000.0]
    store = RateLimitStore(Database(f"sqlite:///{tmp_path / 'c.sqlite3'}"), clock=lambda: now[0])
    assert store.level("k", 4.0) == 4.0  # unseen key: full
    assert [store.take("k", 4.0).admitted for _ in range(5)] == [True] * 4 + [False]
    refused = store.take("k", 4.0)
    assert refused.tokens == 0.0 and refused.wait_s == 0.25
    now[0] += 0.5
    assert store.level("k", 4.0) == 2.0
    assert store.charge("k", 4.0, 3.0) == -1.0  # charges after the work may overdraw
    assert store.wait_s("k", 4.0) == 0.5
    now[0] += 100.0
    assert store.level("k", 4.0) == 4.0  # never above capacity
    now[0] -= 200.0  # a host whose clock lags the last stamp: no refill, no tokens made
    lagging = store.take("k", 4.0)
    assert not lagging.admitted and lagging.tokens == -1.0
    with pytest.raises(ValueError, match="rate"):
        store.take("k", 0.0)


def test_fast_hit_database_down_is_503_not_500(two: Two, monkeypatch: pytest.MonkeyPatch) -> None:
    """A database error while the fast path authenticates is left to the app, which
    answers 503 problem+json (never a 500 from outside the app's error handlers)."""
    h = two.key()
    body = {"size": 0.151}
    for _ in range(2):  # answered, then learnt by the fast path
        assert two.a.post("/v1/classify", json=body, headers=h).status_code == 200

    def down(self: KeyStore, key: str) -> None:
        raise DatabaseUnavailable("connection refused (test)")

    def cannot(self: KeyStore, key: str) -> None:
        raise WouldBlock  # the event-loop read gives up; the read in a thread finds it down

    monkeypatch.setattr(KeyStore, "verify_inline", cannot)
    monkeypatch.setattr(KeyStore, "verify", down)
    r = two.a.post("/v1/classify", json=body, headers=h)
    assert r.status_code == 503 and r.headers["content-type"].startswith(PROBLEM), r.text
    assert "retry-after" in r.headers


def kid_of(h: dict[str, str]) -> str:
    return hash_key(h["Authorization"].split()[1])


def assert_429_inflight(r: Any, quota: int) -> None:
    assert r.status_code == 429, (r.status_code, r.text)
    assert r.headers["content-type"].startswith(PROBLEM)
    assert f"concurrent_requests = {quota}" in r.json()["detail"]
    assert r.headers["retry-after"] == "1"


def wait_for(cond: Any, timeout: float = 60.0) -> None:
    deadline = time.monotonic() + timeout
    while not cond():
        assert time.monotonic() < deadline, "condition not met in time"
        time.sleep(0.02)


def test_two_apps_share_the_concurrency_quota(two: Two, monkeypatch: pytest.MonkeyPatch) -> None:
    """A computing request in flight in app a uses the key's only lease: app b refuses
    the key's next computing requests (single query and batch) until it ends; cached
    lookups hold no lease and are answered meanwhile."""
    import service.answer

    h = two.key(Scope.submit, concurrent_requests=1)
    kid = kid_of(h)
    slots = InflightStore(Database(get_settings().effective_cache_url))
    cached = {"size": 0.161, "eps": 0.2}
    assert two.a.post("/v1/classify", json=cached, headers=h).status_code == 200
    assert slots.held(kid) == 0  # released when the request ended

    release = threading.Event()
    entered = threading.Event()

    original = service.answer._compute

    async def blocked(*args: Any) -> str | None:  # size 0.162 stands for a long computation
        if args[3].get("size") != 0.162:
            return await original(*args)
        entered.set()
        await asyncio.to_thread(release.wait, 60)
        return None  # answered 202 (deferred)

    monkeypatch.setattr(service.answer, "_compute", blocked)
    out: list[Any] = []
    t = threading.Thread(
        target=lambda: out.append(two.a.post("/v1/classify", json={"size": 0.162}, headers=h))
    )
    t.start()
    try:
        wait_for(entered.is_set)
        assert slots.held(kid) == 1
        assert_429_inflight(two.b.post("/v1/classify", json={"size": 0.163}, headers=h), 1)
        r = two.b.post("/v1/classify/batch", json={"items": [{"size": 0.164}]}, headers=h)
        assert_429_inflight(r, 1)
        for c in (two.a, two.b):  # cached lookups take no lease
            r = c.post("/v1/classify", json=cached, headers=h)
            assert r.status_code == 200 and r.headers["x-cache"] == "hit", r.text
        # another key is not affected
        other = two.key(concurrent_requests=1)
        assert two.b.post("/v1/classify", json={"size": 0.165}, headers=other).status_code == 200
    finally:
        release.set()
        t.join(60)
    assert out and out[0].status_code == 202, out
    assert slots.held(kid) == 0  # given back when the request ended
    r = two.b.post("/v1/classify/batch", json={"items": [{"size": 0.164}]}, headers=h)
    assert r.status_code == 200, r.text
    assert slots.held(kid) == 0


def test_expired_leases_do_not_block(two: Two) -> None:
    """A lease left by a process that died (expired) is ignored and deleted; a live one
    of another process counts."""
    h = two.key(concurrent_requests=1)
    kid = kid_of(h)
    db = Database(get_settings().effective_cache_url)
    past = InflightStore(db, clock=lambda: time.time() - 3600.0)
    dead = past.acquire(kid, 1, 60.0)  # expired 3540 s ago
    assert dead.admitted
    slots = InflightStore(db)
    assert slots.held(kid) == 0
    r = two.a.post("/v1/classify", json={"size": 0.171}, headers=h)
    assert r.status_code == 200 and r.headers["x-cache"] == "miss", r.text
    assert dead.lease_id is not None and not slots.renew(dead.lease_id, 60.0)  # purged
    live = slots.acquire(kid, 1, 60.0)  # a request in flight in another process
    assert live.admitted and live.lease_id is not None
    assert_429_inflight(two.b.post("/v1/classify", json={"size": 0.172}, headers=h), 1)
    slots.release(live.lease_id)
    assert two.b.post("/v1/classify", json={"size": 0.172}, headers=h).status_code == 200


def test_concurrent_acquires_never_exceed_the_quota(tmp_path: Path) -> None:
    """Eight threads race for the 3 leases of one key through one SQLite file: exactly 3
    are granted (frozen clock: nothing expires); a released one is granted again."""
    store = InflightStore(Database(f"sqlite:///{tmp_path / 'l.sqlite3'}"), clock=lambda: 1000.0)
    granted: list[str] = []
    refused: list[int] = []
    lock = threading.Lock()

    def worker() -> None:
        for _ in range(4):
            lease = store.acquire("k", 3, 30.0)
            with lock:
                if lease.admitted and lease.lease_id is not None:
                    granted.append(lease.lease_id)
                else:
                    refused.append(lease.held)

    threads = [threading.Thread(target=worker) for _ in range(8)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert len(granted) == 3 and len(refused) == 29
    assert set(refused) == {3} and store.held("k") == 3
    store.release(granted[0])
    assert store.held("k") == 2
    again = store.acquire("k", 3, 30.0)
    assert again.admitted and again.held == 3


def test_lease_expiry_renewal_and_purge(tmp_path: Path) -> None:
    """Leases expire ``lease_s`` after their last renewal (closed-form times), an expired
    lease is neither counted nor revived, and purge deletes every expired lease."""
    now = [1000.0]
    store = InflightStore(Database(f"sqlite:///{tmp_path / 'e.sqlite3'}"), clock=lambda: now[0])
    a, b = store.acquire("k", 2, 10.0), store.acquire("k", 2, 10.0)
    assert a.admitted and b.admitted and a.lease_id and b.lease_id
    assert store.acquire("k", 2, 10.0) == (False, None, 2)
    now[0] = 1006.0
    assert store.renew(a.lease_id, 10.0)  # a now expires at 1016, b at 1010
    now[0] = 1010.0
    assert store.held("k") == 1  # b expired exactly now
    assert not store.renew(b.lease_id, 10.0)  # not revived
    c = store.acquire("k", 2, 10.0)
    assert c.admitted and c.held == 2
    other = store.acquire("other", 1, 1.0)  # expires at 1011
    assert other.admitted
    now[0] = 1030.0
    assert store.held("k") == 0 and store.held("other") == 0
    assert store.purge() == 3  # a, c and other (b was deleted by c's acquisition)
    assert store.purge() == 0
    with pytest.raises(ValueError, match="quota"):
        store.acquire("k", 0, 10.0)
    with pytest.raises(ValueError, match="lease_s"):
        store.acquire("k", 1, 0.0)


def test_gate_renews_its_lease_and_gives_it_back(tmp_path: Path) -> None:
    """A request outliving its lease keeps it (renewed every lease_s / 3: here every
    1 s for a 3 s lease, held 4.5 s; only a 2 s stall of the event loop could lose it);
    a request refused a token gives its lease back at once."""
    from service.admission import FreshGate, QuotaError

    db = Database(f"sqlite:///{tmp_path / 'g.sqlite3'}")
    slots, buckets = InflightStore(db), RateLimitStore(db)

    async def scenario() -> None:
        gate = FreshGate(buckets, "k", 1000.0, slots, quota=1, lease_s=3.0)
        await gate.admit()
        await asyncio.sleep(4.5)
        assert slots.held("k") == 1
        assert not slots.acquire("k", 1, 3.0).admitted
        await gate.release()
        assert slots.held("k") == 0
        await asyncio.sleep(1.2)  # the renewer is stopped: nothing comes back
        assert slots.held("k") == 0
        # an empty bucket (rate 0.2: capacity 1, taken here first)
        assert buckets.take("slow", 0.2).admitted
        refused = FreshGate(buckets, "slow", 0.2, slots, quota=1, lease_s=3.0)
        with pytest.raises(QuotaError, match="fresh_per_s"):
            await refused.admit()
        assert refused.lease_id is None and slots.held("slow") == 0

    asyncio.run(scenario())
    db.dispose()
