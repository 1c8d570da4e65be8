"""Behind a reverse proxy, RSF_AUTH=auto without keys serves only this host
(service.proxies, RSF_TRUSTED_PROXIES).

In process: the app reached on 127.0.0.1 (a server bound to loopback, as ``rsf serve``
runs it) by a peer whose address the TestClient sets, with forwarding headers as nginx
writes them.  A request carrying forwarding headers is served without a key only when
its peer is a trusted proxy and the original client is loopback; otherwise 401, the
answer every remote request gets while the server has no key.  The real-uvicorn case is
tests/e2e/test_auth_server.py::test_forwarded_requests_are_refused_on_a_real_server.
"""

from __future__ import annotations

import os
from collections.abc import Iterator
from pathlib import Path

import pytest
from fastapi import FastAPI
from fastapi.testclient import TestClient
from pydantic import ValidationError

from rsfapp.config import Settings
from service.app import create_app
from service.proxies import original_client, parse_address

#: An endpoint that needs a key once one exists (admin for anonymous loopback requests).
URL = "/v1/cache/stats"
REMOTE = "203.0.113.9"  # TEST-NET-3: documentation addresses, never loopback


@pytest.fixture
def app(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Iterator[FastAPI]:
    for k in [k for k in os.environ if k.startswith("RSF_")]:
        monkeypatch.delenv(k)
    monkeypatch.setenv("RSF_DATA_DIR", str(tmp_path))
    monkeypatch.setenv("RSF_AUTH", "auto")
    yield create_app()


def status(app: FastAPI, peer: str, headers: dict[str, str] | None = None) -> int:
    """Status of GET URL reaching 127.0.0.1:8000 from ``peer`` with ``headers``."""
    with TestClient(app, base_url="http://127.0.0.1:8000", client=(peer, 40000)) as c:
        r = c.get(URL, headers=headers or {})
    if r.status_code == 401:
        assert r.headers["content-type"].startswith("application/problem+json")
        assert "loopback" in r.json()["detail"]
    return r.status_code


FORWARDED_FOR_REMOTE = [
    {"X-Forwarded-For": REMOTE},
    {"X-Real-IP": REMOTE},
    {"Forwarded": f"for={REMOTE};proto=https"},
    {"Forwarded": 'for="[2001:db8::9]:4711"'},
]


@pytest.mark.parametrize("headers", FORWARDED_FOR_REMOTE, ids=lambda h: next(iter(h)))
def test_forwarded_requests_are_not_loopback_without_trusted_proxies(
    app: FastAPI, headers: dict[str, str]
) -> None:
    """The issue's case: a local proxy forwards a remote client's request to a server
    bound to 127.0.0.1; it was served as admin, it is now 401."""
    assert status(app, "127.0.0.1") == 200  # the same peer, not forwarded: this host
    assert status(app, "127.0.0.1", headers) == 401
    # even a forwarding header naming loopback: no proxy is trusted
    assert status(app, "127.0.0.1", {next(iter(headers)): "127.0.0.1"}) == 401


def test_trusted_proxy_forwarding_a_loopback_client(
    app: FastAPI, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv("RSF_TRUSTED_PROXIES", "127.0.0.1, 10.0.0.0/8")
    # the original client is loopback, the peer a trusted proxy: this host
    assert status(app, "127.0.0.1", {"X-Forwarded-For": "127.0.0.1"}) == 200
    assert status(app, "127.0.0.1", {"X-Real-IP": "::1", "X-Forwarded-For": "::1"}) == 200
    assert status(app, "10.1.2.3", {"Forwarded": 'for="[::1]:5000"'}) == 200
    # ... through two trusted proxies
    assert status(app, "127.0.0.1", {"X-Forwarded-For": "127.0.0.1, 10.9.9.9"}) == 200
    # a remote client, through one or two trusted proxies
    assert status(app, "127.0.0.1", {"X-Forwarded-For": REMOTE}) == 401
    assert status(app, "127.0.0.1", {"X-Forwarded-For": f"{REMOTE}, 127.0.0.1"}) == 401
    # a remote client posing as loopback: nginx appends the address it saw
    assert status(app, "127.0.0.1", {"X-Forwarded-For": f"127.0.0.1, {REMOTE}"}) == 401
    # the headers disagree: every one must name a loopback client
    assert status(app, "127.0.0.1", {"X-Forwarded-For": "127.0.0.1", "X-Real-IP": REMOTE}) == 401
    # unreadable client: not loopback
    for bad in ("unknown", "_hidden", "not-an-address", ""):
        assert status(app, "127.0.0.1", {"Forwarded": f"for={bad}"}) == 401, bad
        assert status(app, "127.0.0.1", {"X-Forwarded-For": bad}) == 401, bad
    # a peer that is not a trusted proxy, whatever it forwards
    assert status(app, "192.168.7.7", {"X-Forwarded-For": "127.0.0.1"}) == 401
    assert status(app, "testclient", {"X-Forwarded-For": "127.0.0.1"}) == 401


def test_no_forwarding_headers_behaves_as_before(
    app: FastAPI, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv("RSF_TRUSTED_PROXIES", "127.0.0.1")
    assert status(app, "127.0.0.1") == 200
    assert status(app, REMOTE) == 200  # arrived on 127.0.0.1: the interface decides
    with TestClient(app, base_url="http://10.1.2.3:8000", client=("127.0.0.1", 1)) as c:
        assert c.get(URL, headers={"X-Forwarded-For": "127.0.0.1"}).status_code == 401


def test_keys_decide_once_one_exists(app: FastAPI, monkeypatch: pytest.MonkeyPatch) -> None:
    """Forwarding headers change nothing for a request with a key."""
    from rsfapp.config import get_settings
    from rsfapp.store import stores_for
    from rsfapp.store.keys import Scope

    key = stores_for(get_settings()).keys.create("lab", Scope.read)
    h = {"Authorization": f"Bearer {key}", "X-Forwarded-For": REMOTE}
    with TestClient(app, base_url="http://127.0.0.1:8000", client=("127.0.0.1", 1)) as c:
        assert c.get(URL, headers=h).status_code == 200
        assert c.get(URL, headers={"X-Forwarded-For": "127.0.0.1"}).status_code == 401


def test_parse_address() -> None:
    cases = {
        "203.0.113.9": "203.0.113.9",
        " 203.0.113.9 ": "203.0.113.9",
        "203.0.113.9:8080": "203.0.113.9",
        '"203.0.113.9:8080"': "203.0.113.9",
        "2001:db8::1": "2001:db8::1",
        '"[2001:db8::1]:4711"': "2001:db8::1",
        "[::1]": "::1",
        "fe80::1%eth0": "fe80::1",
        "::ffff:127.0.0.1": "127.0.0.1",
    }
    for text, want in cases.items():
        got = parse_address(text)
        assert got is not None and str(got) == want, text
    for bad in ("unknown", "_hidden", "", "[::1", "1.2.3", "localhost", "::1]:80"):
        assert parse_address(bad) is None, bad


def test_original_client_is_rightmost_untrusted() -> None:
    import ipaddress

    trusted = [ipaddress.ip_network("127.0.0.1"), ipaddress.ip_network("10.0.0.0/8")]
    a = [parse_address(x) for x in ("198.51.100.1", "203.0.113.9", "10.0.0.2", "127.0.0.1")]
    assert str(original_client(a, trusted)) == "203.0.113.9"
    assert str(original_client(a[2:], trusted)) == "10.0.0.2"  # all trusted: the oldest
    assert original_client([], trusted) is None
    assert original_client([None, a[2]], trusted) is None


def test_trusted_proxies_setting_is_checked(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("RSF_TRUSTED_PROXIES", "127.0.0.1, nginx.local")
    with pytest.raises(ValidationError, match="RSF_TRUSTED_PROXIES: 'nginx.local'"):
        Settings()
    monkeypatch.setenv("RSF_TRUSTED_PROXIES", " 127.0.0.1 ,::1, 10.0.0.0/8,")
    nets = Settings().trusted_proxy_networks
    assert [str(n) for n in nets] == ["127.0.0.1/32", "::1/128", "10.0.0.0/8"]
