"""Hardened edges on a real uvicorn server (its own URL decoding and proxy-header
handling, not the TestClient's):

* hostile path parameters (null bytes, overlong names, encoded separators, invalid
  UTF-8) are 4xx problem+json and leave no traceback in the log (the in-process
  version over the whole route table is tests/api/test_path_params.py);
* RSF_AUTH=auto without keys, bound to 127.0.0.1: a request a local proxy forwarded for
  a remote client is refused 401, with or without trusted proxies configured; one
  forwarded by a trusted proxy for a loopback client is served (the in-process version
  is tests/api/test_proxies.py).  uvicorn itself rewrites the client address from
  ``X-Forwarded-For`` when the peer is 127.0.0.1 (its default ``--forwarded-allow-ips``);
  the answer must not depend on that.
"""

from __future__ import annotations

import http.client
import json
from collections.abc import Iterator
from pathlib import Path

import pytest

from tests.conftest import Server

pytestmark = pytest.mark.timeout(180)
REMOTE = "203.0.113.9"  # TEST-NET-3: never loopback
SWEEP = {"x": {"name": "eps", "values": [0.2]}, "y": {"name": "ba", "values": [2.0]}}

BAD_PATHS = [
    "/static/%00",
    "/static/app.js%00.png",
    "/static/%FF",
    "/static/%C0%AF",
    "/static/..%2F..%2Fservice%2Fapp.py",
    "/static/" + "a" * 300,
    "/docs-assets/%00",
    "/docs-assets/" + "b" * 5000 + ".js",
    "/v1/sweeps/%00",
    "/v1/sweeps/%ED%A0%80/data",
    "/v1/results/%00%2F",
    "/v1/fits/" + "c" * 300,
    "/v1/figures/%00",
]


def request(
    srv: Server, method: str, path: str, headers: dict[str, str] | None = None, body: object = None
) -> tuple[int, str, str]:
    """(status, content type, body) of one request sent exactly as written; a 307 is
    answered with its Location instead of the body."""
    conn = http.client.HTTPConnection("127.0.0.1", srv.port, timeout=60)
    try:
        data = None if body is None else json.dumps(body)
        hdrs = dict(headers or {})
        if data is not None:
            hdrs["Content-Type"] = "application/json"
        conn.request(method, path, body=data, headers=hdrs)
        r = conn.getresponse()
        text = r.read().decode("utf-8", "replace")
        if r.status == 307:
            text = r.getheader("location") or ""
        return r.status, r.getheader("content-type") or "", text
    finally:
        conn.close()


@pytest.fixture(scope="module")
def open_srv(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Server]:
    """auto mode, no key, no trusted proxy."""
    s = Server(tmp_path_factory.mktemp("edges"), RSF_AUTH="auto")
    yield s
    s.stop()


@pytest.mark.parametrize("path", BAD_PATHS, ids=lambda p: p[:40])
def test_hostile_paths_are_4xx_problems(open_srv: Server, path: str) -> None:
    status, ctype, text = request(open_srv, "GET", path)
    if status == 307:  # a trailing (decoded) slash: redirected without it, as every path
        assert text.endswith(path.removesuffix("%2F")), (path, text)
        status, ctype, text = request(open_srv, "GET", path.removesuffix("%2F"))
    assert 400 <= status < 500, (path[:80], status, text[:300])
    assert ctype.startswith("application/problem+json"), (path[:80], ctype)
    assert json.loads(text)["status"] == status


def test_no_traceback_after_hostile_paths(open_srv: Server) -> None:
    for path in BAD_PATHS:
        request(open_srv, "GET", path)
    log = open_srv.log.read_text(errors="replace")
    assert "Traceback" not in log and "Exception in ASGI" not in log, log[-4000:]


def test_forwarded_requests_are_refused_on_a_real_server(open_srv: Server, tmp_path: Path) -> None:
    # the case: POST /v1/sweeps through a local proxy for a remote client
    status, ctype, text = request(
        open_srv, "POST", "/v1/sweeps", {"X-Forwarded-For": REMOTE}, SWEEP
    )
    assert status == 401 and ctype.startswith("application/problem+json"), (status, text)
    assert "loopback" in json.loads(text)["detail"]
    for h in ({"X-Real-IP": REMOTE}, {"Forwarded": f"for={REMOTE}"}):
        assert request(open_srv, "GET", "/v1/cache/stats", h)[0] == 401, h
    # no proxy is trusted: not even a loopback client behind one
    assert request(open_srv, "GET", "/v1/cache/stats", {"X-Forwarded-For": "127.0.0.1"})[0] == 401
    assert request(open_srv, "GET", "/v1/cache/stats")[0] == 200  # not forwarded: this host

    trusting = Server(tmp_path, RSF_AUTH="auto", RSF_TRUSTED_PROXIES="127.0.0.1")
    try:
        fwd = {"X-Forwarded-For": "127.0.0.1", "X-Real-IP": "127.0.0.1"}
        assert request(trusting, "GET", "/v1/cache/stats", fwd)[0] == 200
        status, _, text = request(
            trusting, "POST", "/v1/sweeps", {"X-Forwarded-For": REMOTE}, SWEEP
        )
        assert status == 401, text
        spoof = {"X-Forwarded-For": f"127.0.0.1, {REMOTE}"}  # nginx appends what it saw
        assert request(trusting, "GET", "/v1/cache/stats", spoof)[0] == 401
    finally:
        trusting.stop()
