"""API keys, scopes, quotas and request bounds, in process (TestClient, real SQLite in a
temporary directory, RSF_AUTH=on).  The real-server version of the essentials is
tests/e2e/test_auth_server.py."""

from __future__ import annotations

import json
import logging
import os
import re
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from fastapi.testclient import TestClient

from rsfapp.config import get_settings
from rsfapp.store import stores_for
from rsfapp.store.keys import KeyStore, Scope
from service.app import create_app
from service.deps import get_queue
from tests.api.conftest import RecordingQueue

PROBLEM = "application/problem+json"
#: Path parameters that pass validation, so that only the key decides the answer.
PATH_VALUES = {"sweep_id": "0" * 32, "key": "0" * 64, "name": "no-such-figure", "var": "kind"}


class Env:
    """The app on a fresh data directory with auth forced on, and a key factory."""

    def __init__(self, client: TestClient, data: Path) -> None:
        self.c, self.data = client, data
        self.keys = KeyStore(stores_for(get_settings()).db)
        self.names: dict[str, str] = {}

    def key(self, scope: Scope = Scope.read, **quotas: Any) -> str:
        name = f"k{len(self.names) + 1}-{scope.value}"
        key = self.keys.create(name, scope, quotas)
        self.names[key] = name
        return key

    def revoke(self, key: str) -> None:
        assert self.keys.revoke(self.names[key])

    def h(self, key: str) -> dict[str, str]:
        return {"Authorization": f"Bearer {key}"}


@pytest.fixture(scope="module")
def env(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Env]:
    d = tmp_path_factory.mktemp("rsf-auth")
    saved = {k: v for k, v in os.environ.items() if k.startswith("RSF_")}
    for k in saved:
        del os.environ[k]
    # Defaults generous enough that only the quota tests (per-key overrides) meet them.
    os.environ.update(
        RSF_DATA_DIR=str(d),
        RSF_INLINE_BUDGET_S="120",
        RSF_AUTH="on",
        RSF_QUOTA_FRESH_PER_S="1000",
        RSF_QUOTA_CONCURRENT_REQUESTS="100",
        RSF_MAX_BODY_BYTES="65536",
    )
    try:
        app = create_app()
        queue = RecordingQueue()
        app.dependency_overrides[get_queue] = lambda: queue
        with TestClient(app, raise_server_exceptions=False) as client:
            yield Env(client, d)
    finally:
        for k in [k for k in os.environ if k.startswith("RSF_")]:
            del os.environ[k]
        os.environ.update(saved)


def operations(c: TestClient) -> list[tuple[str, str]]:
    """(METHOD, concrete path) of every operation of the OpenAPI schema."""
    ops = []
    for path, item in c.get("/openapi.json").json()["paths"].items():
        concrete = re.sub(r"\{(\w+)\}", lambda m: PATH_VALUES[m.group(1)], path)
        ops += [(m.upper(), concrete) for m in item if m in ("get", "post", "delete", "put")]
    return ops


def assert_problem(r: Any, status: int) -> dict[str, Any]:
    assert r.status_code == status, (r.status_code, r.text)
    assert r.headers["content-type"].startswith(PROBLEM), r.headers
    p = r.json()
    assert p["status"] == status and p["title"] and p["detail"]
    return p


def test_every_schema_operation_needs_a_key(env: Env) -> None:
    ops = operations(env.c)
    assert len(ops) >= 20  # the schema was read, not an empty list
    revoked = env.key()
    env.revoke(revoked)
    bad = {
        "none": {},
        "unknown": env.h("rsf_" + "A" * 43),
        "revoked": env.h(revoked),
        "basic": {"Authorization": "Basic dXNlcjpwYXNz"},
        "empty": {"Authorization": "Bearer "},
    }
    details = set()
    for method, path in ops:
        for label, headers in bad.items():
            r = env.c.request(
                method, path, headers=headers, json={} if method in ("POST", "PUT") else None
            )
            p = assert_problem(r, 401)
            assert r.headers["www-authenticate"].startswith("Bearer"), (method, path, label)
            details.add(p["detail"])
    # one message for every way of failing: nothing tells a revoked key from a wrong one
    assert len(details) == 1, details


def test_pages_and_schema_need_no_key(env: Env) -> None:
    for path in ("/", "/ui", "/static/app.js", "/openapi.json", "/docs"):
        assert env.c.get(path).status_code == 200, path


def test_openapi_shows_the_bearer_scheme_and_problem_json(env: Env) -> None:
    s = env.c.get("/openapi.json").json()
    scheme = s["components"]["securitySchemes"]["ApiKey"]
    assert scheme["type"] == "http" and scheme["scheme"] == "bearer"
    for path, item in s["paths"].items():
        for method, op in item.items():
            assert op["security"] == [{"ApiKey": []}], (method, path)
            assert op["x-required-scope"] in ("read", "submit", "admin")
            for code in ("401", "403"):
                assert code in op["responses"], (method, path, code)
            for code, r in op["responses"].items():
                if code[0] in "45":  # 400 may also come from the HTTP layer, as text
                    assert list(r["content"])[0] == PROBLEM, (method, path, code)
                    assert code == "400" or list(r["content"]) == [PROBLEM], (method, path)
    for path in ("/v1/classify", "/v1/critical", "/v1/stiffness", "/v1/analytic/u"):
        r202 = s["paths"][path]["post"]["responses"]["202"]
        assert "Location" in r202["headers"], path
    assert s["paths"]["/v1/sweeps"]["post"]["x-required-scope"] == "submit"
    assert s["paths"]["/v1/classify"]["post"]["x-required-scope"] == "read"


def test_read_key_queries_but_may_not_submit_or_cancel(env: Env) -> None:
    h = env.h(env.key(Scope.read))
    assert env.c.get("/health", headers=h).status_code == 200
    r = env.c.post("/v1/classify", json={"size": 0.5}, headers=h)
    assert r.status_code == 200, r.text
    assert env.c.get("/v1/sweeps", headers=h).status_code == 200
    sweep = {"x": {"name": "eps", "values": [0.1, 0.2]}, "y": {"name": "ba", "values": [2.0]}}
    p = assert_problem(env.c.post("/v1/sweeps", json=sweep, headers=h), 403)
    assert "submit" in p["detail"]
    for path in ("/v1/critical/batch", "/v1/classify/batch"):
        assert_problem(env.c.post(path, json={"items": []}, headers=h), 403)
    assert_problem(env.c.delete("/v1/sweeps/" + "0" * 32, headers=h), 403)


def test_submit_key_may_submit(env: Env) -> None:
    h = env.h(env.key(Scope.submit))
    sweep = {"x": {"name": "eps", "values": [0.1, 0.3]}, "y": {"name": "ba", "values": [2.5]}}
    r = env.c.post("/v1/sweeps", json=sweep, headers=h)
    assert r.status_code in (200, 202), r.text


def test_revoked_key_stops_at_once(env: Env) -> None:
    key = env.key(Scope.read)
    assert env.c.get("/v1/cache/stats", headers=env.h(key)).status_code == 200
    env.revoke(key)
    assert_problem(env.c.get("/v1/cache/stats", headers=env.h(key)), 401)


def test_fresh_computation_quota_429_then_reset_by_time(env: Env) -> None:
    rate = 4.0  # per second: the bucket refills one token in 0.25 s
    key = env.key(Scope.read, fresh_per_s=rate)
    h = env.h(key)
    codes, retry = [], None
    for i in range(8):  # 8 distinct (fresh) queries in a burst; capacity is 4
        r = env.c.post("/v1/classify", json={"size": 0.11 + 0.01 * i, "eps": 0.31}, headers=h)
        codes.append(r.status_code)
        if r.status_code == 429:
            assert_problem(r, 429)
            retry = int(r.headers["retry-after"])
    assert codes[:4] == [200] * 4, codes
    assert 429 in codes[4:], codes
    assert retry is not None and 1 <= retry <= 1 + 1 / rate  # whole seconds, >= 1
    # another key is not affected
    other = env.h(env.key(Scope.read, fresh_per_s=rate))
    assert (
        env.c.post("/v1/classify", json={"size": 0.91, "eps": 0.31}, headers=other).status_code
        == 200
    )
    time.sleep(retry + 0.05)
    r = env.c.post("/v1/classify", json={"size": 0.92, "eps": 0.31}, headers=h)
    assert r.status_code == 200, r.text


def test_cached_answers_do_not_use_the_fresh_quota(env: Env) -> None:
    key = env.key(Scope.read, fresh_per_s=1)
    h = env.h(key)
    body = {"size": 0.77, "eps": 0.41}
    assert env.c.post("/v1/classify", json=body).status_code == 401
    first = env.h(env.key(Scope.read))
    assert env.c.post("/v1/classify", json=body, headers=first).status_code == 200
    # now cached: the rate-1 key may ask it many times in a row
    for _ in range(5):
        r = env.c.post("/v1/classify", json=body, headers=h)
        assert r.status_code == 200 and r.headers["x-cache"] == "hit", r.text


def test_trajectory_points_quota(env: Env) -> None:
    h = env.h(env.key(Scope.read, trajectory_points=50))
    p = assert_problem(env.c.post("/v1/trajectory", json={"n_points": 51}, headers=h), 422)
    assert p["field"] == "n_points" and "50" in p["valid"]
    assert (
        env.c.post("/v1/trajectory", json={"n_points": 50, "size": 0.3}, headers=h).status_code
        == 200
    )


def test_body_limit_413_before_reading(env: Env) -> None:
    h = env.h(env.key(Scope.read))
    limit = 65536
    r = env.c.post("/v1/classify", content=b"{" + b" " * limit + b"}", headers=h)
    p = assert_problem(r, 413)
    assert str(limit) in p["detail"]

    read = []

    def chunks() -> Iterator[bytes]:  # no Content-Length: counted while it streams
        for i in range(100):
            read.append(i)
            yield b" " * 16384

    r = env.c.post("/v1/classify", content=chunks(), headers=h)
    assert_problem(r, 413)
    # batch endpoints have the larger limit: this body is refused for its content only
    r = env.c.post(
        "/v1/classify/batch",
        headers={**env.h(env.key(Scope.submit)), "Content-Type": "application/json"},
        content=json.dumps({"items": [{"size": 0.5}] * 2000}).encode(),
    )
    assert r.status_code != 413, r.text


def test_header_limit_431(env: Env) -> None:
    h = env.h(env.key(Scope.read))
    assert_problem(env.c.get("/health", headers={**h, "X-Pad": "a" * 60_000}), 431)


def test_cors_off_by_default(env: Env) -> None:
    h = env.h(env.key(Scope.read))
    r = env.c.get("/health", headers={**h, "Origin": "http://evil.example"})
    assert "access-control-allow-origin" not in r.headers
    r = env.c.options(
        "/v1/classify",
        headers={"Origin": "http://lab.example", "Access-Control-Request-Method": "POST"},
    )
    assert "access-control-allow-origin" not in r.headers


def test_cors_allowed_origins_from_setting(env: Env, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("RSF_CORS_ORIGINS", "http://lab.example, http://other.example")
    app = create_app()
    with TestClient(app) as c:
        r = c.options(
            "/v1/classify",
            headers={
                "Origin": "http://lab.example",
                "Access-Control-Request-Method": "POST",
                "Access-Control-Request-Headers": "authorization,content-type",
            },
        )
        assert r.status_code == 200
        assert r.headers["access-control-allow-origin"] == "http://lab.example"
        assert "authorization" in r.headers["access-control-allow-headers"].lower()
        r = c.get("/health", headers={"Origin": "http://evil.example"})
        assert "access-control-allow-origin" not in r.headers


def test_keys_never_in_responses_or_logs(env: Env, caplog: pytest.LogCaptureFixture) -> None:
    key = env.key(Scope.read)
    revoked = env.key(Scope.read)
    env.revoke(revoked)
    caplog.set_level(logging.DEBUG)
    seen: list[str] = []
    for k in (key, revoked, "rsf_" + "B" * 43):
        for method, path, body in (
            ("GET", "/health", None),
            ("POST", "/v1/classify", {"x": 1}),
            ("POST", "/v1/sweeps", {}),
            ("GET", "/v1/cache/stats", None),
        ):
            r = env.c.request(method, path, json=body, headers=env.h(k))
            seen.append(r.text + json.dumps(dict(r.headers)))
    text = "\n".join(seen) + "\n".join(rec.getMessage() for rec in caplog.records)
    for k in (key, revoked):
        assert k not in text and k[4:20] not in text
    # the database holds hashes only
    for f in env.data.glob("cache.sqlite3*"):
        blob = f.read_bytes()
        assert key.encode() not in blob and revoked.encode() not in blob


def test_auto_mode_open_on_loopback_until_a_key_exists(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    for k in [k for k in os.environ if k.startswith("RSF_")]:
        monkeypatch.delenv(k)
    monkeypatch.setenv("RSF_DATA_DIR", str(tmp_path))
    monkeypatch.setenv("RSF_AUTH", "auto")
    app = create_app()
    with TestClient(app) as c:  # in-process transport counts as loopback
        assert c.get("/v1/cache/stats").status_code == 200
        # the same app reached on a non-loopback interface: refused, saying why
        remote = TestClient(app, base_url="http://10.1.2.3:8000")
        p = assert_problem(remote.get("/v1/cache/stats"), 401)
        assert "loopback" in p["detail"] and "rsf keys create" in p["detail"]
        key = KeyStore(stores_for(get_settings()).db).create("first", Scope.read)
        assert_problem(c.get("/v1/cache/stats"), 401)
        assert (
            c.get("/v1/cache/stats", headers={"Authorization": f"Bearer {key}"}).status_code == 200
        )


def test_auto_mode_refuses_anonymous_requests_on_other_interfaces() -> None:
    from service.proxies import from_this_host

    def local(server: tuple[str, int] | None) -> bool:
        scope = {"type": "http", "server": server, "headers": [], "method": "GET", "path": "/"}
        return from_this_host(scope, ())

    assert local(("127.0.0.1", 8000)) and local(("::1", 8000))
    assert local(None)  # unix socket
    assert not local(("10.1.2.3", 8000)) and not local(("192.168.0.7", 80))


def sweep(*eps: float) -> dict[str, Any]:
    return {"x": {"name": "eps", "values": list(eps)}, "y": {"name": "ba", "values": [2.0]}}


def test_only_the_owner_or_an_admin_cancels_a_sweep(env: Env) -> None:
    alice, bob = env.h(env.key(Scope.submit)), env.h(env.key(Scope.submit))
    admin = env.h(env.key(Scope.admin))
    ids = []
    for body in (sweep(0.11, 0.12), sweep(0.13, 0.14)):
        r = env.c.post("/v1/sweeps", json=body, headers=alice)
        assert r.status_code == 202, r.text
        ids.append(r.json()["id"])
    p = assert_problem(env.c.delete(f"/v1/sweeps/{ids[0]}", headers=bob), 403)
    assert "another key" in p["detail"]
    # bob re-submitting alice's sweep gets it back, but it stays alice's
    assert env.c.post("/v1/sweeps", json=sweep(0.11, 0.12), headers=bob).json()["id"] == ids[0]
    assert_problem(env.c.delete(f"/v1/sweeps/{ids[0]}", headers=bob), 403)
    assert env.c.get(f"/v1/sweeps/{ids[0]}", headers=bob).json()["status"] == "queued"
    assert env.c.delete(f"/v1/sweeps/{ids[0]}", headers=alice).status_code == 200
    assert env.c.delete(f"/v1/sweeps/{ids[1]}", headers=admin).status_code == 200
    for i in ids:
        assert env.c.get(f"/v1/sweeps/{i}", headers=bob).json()["status"] == "cancelled"
    # an unknown sweep is still 404 (not 403) for a non-admin key
    assert_problem(env.c.delete("/v1/sweeps/" + "f" * 32, headers=bob), 404)


def test_concurrent_sweeps_quota(env: Env) -> None:
    h = env.h(env.key(Scope.submit, concurrent_sweeps=1))
    r = env.c.post("/v1/sweeps", json=sweep(0.21, 0.22), headers=h)
    assert r.status_code == 202, r.text
    r2 = env.c.post("/v1/sweeps", json=sweep(0.23, 0.24), headers=h)
    p = assert_problem(r2, 429)
    assert "concurrent_sweeps" in p["detail"] and int(r2.headers["retry-after"]) >= 1
    assert env.c.delete(f"/v1/sweeps/{r.json()['id']}", headers=h).status_code == 200
    assert env.c.post("/v1/sweeps", json=sweep(0.23, 0.24), headers=h).status_code == 202


def test_points_per_day_quota(env: Env) -> None:
    key = env.key(Scope.submit, points_per_day=5)
    h = env.h(key)
    assert (
        env.c.post("/v1/sweeps", json=sweep(0.31, 0.32, 0.33, 0.34), headers=h).status_code == 202
    )
    assert env.keys.points_used(env.names[key]) == 4
    # the same sweep again costs nothing (it exists); a new 2-point sweep is refused
    assert (
        env.c.post("/v1/sweeps", json=sweep(0.31, 0.32, 0.33, 0.34), headers=h).status_code == 202
    )
    assert env.keys.points_used(env.names[key]) == 4
    r = env.c.post("/v1/sweeps", json=sweep(0.35, 0.36), headers=h)
    p = assert_problem(r, 429)
    assert "points_per_day" in p["detail"]
    assert 1 <= int(r.headers["retry-after"]) <= 86400  # until 00:00 UTC
    assert env.c.post("/v1/sweeps", json=sweep(0.37), headers=h).status_code == 202
    assert env.keys.points_used(env.names[key]) == 5


def test_405_lists_every_method_of_the_path(env: Env) -> None:
    h = env.h(env.key(Scope.read))
    r = env.c.request("OPTIONS", "/v1/sweeps", headers=h)
    assert r.status_code == 405 and r.headers["allow"] == "GET, POST"
    r = env.c.put("/v1/sweeps/" + "0" * 32, headers=h)
    assert r.status_code == 405 and r.headers["allow"] == "DELETE, GET"


def test_python_client_takes_the_key_from_rsf_api_key(monkeypatch: pytest.MonkeyPatch) -> None:
    import httpx

    from rsfclient import Client

    seen: list[str | None] = []

    def handler(request: httpx.Request) -> httpx.Response:
        seen.append(request.headers.get("authorization"))
        return httpx.Response(200, json={"status": "ok"})

    monkeypatch.setenv("RSF_API_KEY", "rsf_from_env")
    with Client("http://lab:8000", transport=httpx.MockTransport(handler)) as c:
        c.request("GET", "/health")
    with Client(
        "http://lab:8000", api_key="rsf_explicit", transport=httpx.MockTransport(handler)
    ) as c:
        c.request("GET", "/health")
    monkeypatch.delenv("RSF_API_KEY")
    with Client("http://lab:8000", transport=httpx.MockTransport(handler)) as c:
        c.request("GET", "/health")
    assert seen == ["Bearer rsf_from_env", "Bearer rsf_explicit", None]


def test_daily_points_reset_with_the_utc_day(env: Env) -> None:
    key = env.key(Scope.submit)
    name = env.names[key]
    day = 20_000  # any UTC day number; the next day starts from zero
    assert env.keys.reserve_points(name, 7, 10, day=day) == 3
    assert env.keys.reserve_points(name, 4, 10, day=day) == -1  # refused, nothing added
    assert env.keys.points_used(name, day=day) == 7
    assert env.keys.reserve_points(name, 10, 10, day=day + 1) == 0
    env.keys.refund_points(name, 100, day=day)  # never below zero
    assert env.keys.points_used(name, day=day) == 0


def test_long_integration_needs_submit_scope_and_step_budget(tmp_path, monkeypatch) -> None:
    """A single query that outgrows the in-process step budget goes to the queue only for
    a key with scope 'submit' whose step budget allows it; a read key gets 403 (nothing
    queued), a submit key with a small step budget gets 403 naming the quota."""
    from fastapi.testclient import TestClient

    from rsfapp.config import get_settings
    from rsfapp.store import stores_for
    from rsfapp.store.keys import Scope
    from service.app import create_app
    from service.deps import get_queue
    from tests.api.conftest import RecordingQueue

    for k in [k for k in __import__("os").environ if k.startswith("RSF_")]:
        monkeypatch.delenv(k)
    monkeypatch.setenv("RSF_DATA_DIR", str(tmp_path))
    monkeypatch.setenv("RSF_AUTH", "on")
    monkeypatch.setenv("RSF_QUICK_STEPS", "10")  # every real integration exceeds it
    keys = stores_for(get_settings()).keys
    read = keys.create("reader", Scope.read)
    submit = keys.create("submitter", Scope.submit)
    small = keys.create("small", Scope.submit, {"step_budget": 10})
    app = create_app()
    queue = RecordingQueue()
    app.dependency_overrides[get_queue] = lambda: queue
    body = {"ba": 2.0, "kappa": 2.0, "eps": 0.25, "size": 2.61}
    with TestClient(app) as c:
        r = c.post("/v1/classify", json=body, headers={"Authorization": f"Bearer {read}"})
        assert r.status_code == 403, r.text
        assert "scope 'submit'" in r.json()["detail"] and not queue.singles
        r = c.post("/v1/classify", json=body, headers={"Authorization": f"Bearer {small}"})
        assert r.status_code == 403 and "step_budget" in r.json()["detail"]
        assert not queue.singles
        r = c.post("/v1/classify", json=body, headers={"Authorization": f"Bearer {submit}"})
        assert r.status_code == 202, r.text
        assert [s[0] for s in queue.singles] == ["classify"]
