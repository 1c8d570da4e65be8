"""Fresh-computation buckets shared through the database, and cached lookups answered
from memory (service.limits, service.answer.FastHits, rsfapp.store.ratelimits).

In process: two separate app instances (each with its own middleware, as two API
processes have) on one SQLite file, RSF_AUTH=on.  The real-process version (two uvicorn
processes, SQLite and PostgreSQL) is tests/e2e/test_shared_limits_server.py."""

from __future__ import annotations

import os
import threading
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from fastapi.testclient import TestClient

from rsfapp.config import get_settings
from rsfapp.db.engine import Database, DatabaseUnavailable
from rsfapp.store import stores_for
from rsfapp.store.keys import KeyStore, Scope, hash_key
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

    monkeypatch.setattr(KeyStore, "verify", down)
    r = two.a.post("/v1/classify", json=body, headers=h)
    assert r.status_code == 503 and r.headers["content-type"].startswith(PROBLEM), r.text
    assert "retry-after" in r.headers
