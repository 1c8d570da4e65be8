"""API keys on a real server: uvicorn bound to 127.0.0.1 with RSF_AUTH=on, keys made and
revoked with the real ``rsf keys`` CLI in another process, and ``rsf serve`` refusing a
non-loopback interface without a key."""

from __future__ import annotations

import json
import re
import shutil
import socket
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import httpx
import pytest

from tests.conftest import ROOT, Proc, free_port, service_env

pytestmark = pytest.mark.timeout(300)
PROBLEM = "application/problem+json"
PATH_VALUES = {
    "sweep_id": "0" * 32,
    "key": "0" * 64,
    "name": "no-such-figure",
    "var": "outcome",
}
RSF = str(Path(sys.executable).with_name("rsf"))


class AuthServer(Proc):
    """uvicorn service.app:app on 127.0.0.1 with auth forced on (access log at info)."""

    def __init__(self, data: Path, **extra: str) -> None:
        self.data = data
        self.port = free_port()
        self.url = f"http://127.0.0.1:{self.port}"
        self.env = service_env(data, RSF_AUTH="on", RSF_INLINE_BUDGET_S="60", **extra)
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
                "info",
            ],
            self.env,
            data / f"uvicorn-{self.port}.log",
        )
        deadline = time.monotonic() + 60
        while time.monotonic() < deadline:  # up = answers /health, here with 401
            if not self.alive():
                raise RuntimeError("uvicorn exited:\n" + self.tail())
            try:
                if httpx.get(self.url + "/health", timeout=2).status_code == 401:
                    return
            except httpx.HTTPError:
                pass
            time.sleep(0.1)
        self.stop()
        raise RuntimeError("uvicorn did not start:\n" + self.tail())

    def rsf(self, *args: str, check: bool = True) -> subprocess.CompletedProcess[str]:
        """The real `rsf` CLI on this server's data directory."""
        r = subprocess.run(
            [RSF, *args, "--data-dir", str(self.data)],
            env=self.env,
            capture_output=True,
            text=True,
            timeout=120,
            cwd=ROOT,
        )
        if check:
            assert r.returncode == 0, r.stderr
        return r

    def key(self, name: str, scope: str = "read", *quotas: str) -> str:
        q = [a for qq in quotas for a in ("--quota", qq)]
        out = self.rsf("keys", "create", "--name", name, "--scope", scope, *q).stdout.strip()
        assert re.fullmatch(r"rsf_[A-Za-z0-9_-]{43}", out), out  # 256 random bits
        return out


@pytest.fixture(scope="module")
def srv(tmp_path_factory: pytest.TempPathFactory) -> Iterator[AuthServer]:
    s = AuthServer(
        tmp_path_factory.mktemp("rsf-auth-e2e"),
        RSF_QUOTA_FRESH_PER_S="1000",
        RSF_QUOTA_CONCURRENT_REQUESTS="100",
    )
    yield s
    s.stop()


def h(key: str) -> dict[str, str]:
    return {"Authorization": f"Bearer {key}"}


def problem(r: httpx.Response, status: int) -> dict[str, Any]:
    assert r.status_code == status, (r.status_code, r.text)
    assert r.headers["content-type"].startswith(PROBLEM)
    return r.json()


def test_every_schema_operation_401_without_a_valid_key(srv: AuthServer) -> None:
    revoked = srv.key("to-revoke")
    srv.rsf("keys", "revoke", "to-revoke")
    schema = httpx.get(srv.url + "/openapi.json").json()
    n = 0
    with httpx.Client(base_url=srv.url, timeout=30) as c:
        for path, item in schema["paths"].items():
            concrete = re.sub(r"\{(\w+)\}", lambda m: PATH_VALUES[m.group(1)], path)
            for method in item:
                for headers in ({}, h(revoked), h("rsf_" + "x" * 43)):
                    r = c.request(
                        method.upper(),
                        concrete,
                        headers=headers,
                        json={} if method == "post" else None,
                    )
                    problem(r, 401)
                    assert r.headers["www-authenticate"].startswith("Bearer")
                    n += 1
    assert n >= 60


def test_read_key_403_on_sweep_submit_and_long_jobs(srv: AuthServer) -> None:
    k = srv.key("reader")
    with httpx.Client(base_url=srv.url, timeout=60, headers=h(k)) as c:
        assert c.get("/health").status_code == 200
        assert c.post("/v1/classify", json={"size": 0.5}).status_code == 200
        sweep = {"x": {"name": "eps", "values": [0.1, 0.2]}, "y": {"name": "ba", "values": [2.0]}}
        problem(c.post("/v1/sweeps", json=sweep), 403)
        problem(c.post("/v1/critical/batch", json={"items": [{}]}), 403)
        problem(c.post("/v1/classify/batch", json={"items": [{}]}), 403)
        problem(c.delete("/v1/sweeps/" + "0" * 32), 403)


def test_revoked_key_stops_at_once(srv: AuthServer) -> None:
    k = srv.key("short-lived")
    with httpx.Client(base_url=srv.url, timeout=30, headers=h(k)) as c:  # keep-alive
        assert c.get("/v1/cache/stats").status_code == 200
        srv.rsf("keys", "revoke", "short-lived")  # another process, same database
        problem(c.get("/v1/cache/stats"), 401)


def test_quota_429_with_retry_after_and_reset_by_time(srv: AuthServer) -> None:
    k = srv.key("slow", "read", "fresh_per_s=2")
    codes, retry = [], 0
    with httpx.Client(base_url=srv.url, timeout=60, headers=h(k)) as c:
        for i in range(5):
            r = c.post("/v1/classify", json={"size": 0.21 + 0.01 * i, "eps": 0.13})
            codes.append(r.status_code)
            if r.status_code == 429:
                problem(r, 429)
                retry = int(r.headers["retry-after"])
        assert codes[:2] == [200, 200] and 429 in codes, codes
        assert retry >= 1
        time.sleep(retry + 0.1)
        assert c.post("/v1/classify", json={"size": 0.29, "eps": 0.13}).status_code == 200


def test_body_refused_before_it_is_read(srv: AuthServer) -> None:
    """A 100 MB Content-Length is answered 413 while the client has sent no body byte."""
    k = srv.key("bodies")
    with socket.create_connection(("127.0.0.1", srv.port), timeout=10) as s:
        s.sendall(
            (
                f"POST /v1/classify HTTP/1.1\r\nHost: x\r\nAuthorization: Bearer {k}\r\n"
                "Content-Type: application/json\r\nContent-Length: 100000000\r\n\r\n"
            ).encode()
        )
        s.sendall(b"{" + b" " * 1000)  # a first sliver; the rest never comes
        data = b""
        while b"\r\n\r\n" not in data:
            chunk = s.recv(65536)
            if not chunk:
                break
            data += chunk
    head = data.split(b"\r\n", 1)[0]
    assert b" 413 " in head, data[:300]
    assert PROBLEM.encode() in data.lower()


def test_big_header_refused(srv: AuthServer) -> None:
    k = srv.key("headers")
    try:
        r = httpx.get(srv.url + "/health", headers={**h(k), "X-Pad": "a" * 60_000}, timeout=10)
    except httpx.HTTPError:  # the HTTP layer may close the connection itself
        return
    assert r.status_code in (400, 431), r.status_code


def test_keys_never_in_logs_or_responses(srv: AuthServer) -> None:
    k = srv.key("secretive")
    bodies = []
    with httpx.Client(base_url=srv.url, timeout=60, headers=h(k)) as c:
        for method, path, body in (
            ("GET", "/health", None),
            ("POST", "/v1/classify", {"no": 1}),
            ("GET", "/v1/sweeps", None),
            ("GET", "/v1/results/" + "1" * 64, None),
        ):
            r = c.request(method, path, json=body)
            bodies.append(r.text + json.dumps(dict(r.headers)))
    logs = srv.tail(10**7) + "".join(bodies)
    assert "GET /health" in srv.tail(10**7)  # the access log is on
    assert k not in logs and k[4:24] not in logs
    assert srv.rsf("keys", "list", "--json").stdout.count(k[4:24]) == 0


def test_serve_refuses_a_non_loopback_host_without_a_key(tmp_path: Path) -> None:
    env = service_env(tmp_path)
    r = subprocess.run(
        [
            RSF,
            "serve",
            "--host",
            "0.0.0.0",
            "--port",
            str(free_port()),
            "--data-dir",
            str(tmp_path),
        ],
        env=env,
        capture_output=True,
        text=True,
        timeout=120,
        cwd=ROOT,
    )
    assert r.returncode == 2, r.stderr
    assert "refusing to serve on 0.0.0.0" in r.stderr and "--insecure" in r.stderr
    assert "rsf keys create" in r.stderr


def test_cancelling_another_keys_sweep_is_refused(srv: AuthServer) -> None:
    alice, bob = srv.key("alice", "submit"), srv.key("bob", "submit")
    admin = srv.key("root", "admin")
    body = {"x": {"name": "eps", "values": [0.1, 0.2]}, "y": {"name": "ba", "values": [2.5]}}
    with httpx.Client(base_url=srv.url, timeout=60) as c:
        r = c.post("/v1/sweeps", json=body, headers=h(alice))
        assert r.status_code == 202, r.text
        sid = r.json()["id"]
        problem(c.delete(f"/v1/sweeps/{sid}", headers=h(bob)), 403)
        assert c.get(f"/v1/sweeps/{sid}", headers=h(bob)).json()["status"] == "queued"
        assert c.delete(f"/v1/sweeps/{sid}", headers=h(admin)).status_code == 200
        assert c.get(f"/v1/sweeps/{sid}", headers=h(bob)).json()["status"] == "cancelled"


def test_dashboard_asks_for_the_key_once_and_sends_it(srv: AuthServer, tmp_path: Path) -> None:
    """Headless chromium: the page loads without a key, shows the key form after the
    first 401, and once the key is entered every request of the page carries it (health,
    the figure list, a single query with its phase-plane PNG)."""
    from tests.e2e.test_ui_browser import Browser

    exe = shutil.which("chromium") or "/usr/bin/chromium"
    if not Path(exe).exists():
        pytest.skip("chromium not installed")
    k = srv.key("browser")
    browser = Browser(exe, tmp_path)
    try:
        browser.navigate(srv.url + "/")
        browser.wait("!document.querySelector('#key-form').hidden", 30, "the key form")
        assert not browser.js("document.querySelector('#health').classList.contains('ok')")
        browser.js(
            f"document.querySelector('#key-input').value = {json.dumps(k)};"
            " document.querySelector('#key-form').requestSubmit(); true"
        )
        browser.wait(
            "document.querySelector('#health').classList.contains('ok')", 30, "/health with the key"
        )
        assert browser.js("document.querySelector('#key-form').hidden")
        assert browser.js("sessionStorage.getItem('rsf-api-key')") == k
        assert browser.js("localStorage.length") == 0 and browser.js("document.cookie") == ""
        browser.wait(
            "document.querySelectorAll('#figure-select option').length >= 5",
            30,
            "the list of paper figures",
        )
        browser.js("document.querySelector('#query-submit').click(), true")
        browser.wait(
            "document.querySelector('#phase-img').naturalWidth > 0 && "
            "!document.querySelector('#phase-figure').hidden",
            90,
            "the phase-plane plot",
        )
        # a reload keeps the key for this tab's session: no prompt again
        browser.navigate(srv.url + "/")
        browser.wait(
            "document.querySelector('#health').classList.contains('ok')",
            30,
            "/health after a reload",
        )
        assert browser.js("document.querySelector('#key-form').hidden")
        assert not browser.exceptions(), browser.exceptions()
    finally:
        browser.close()


def test_client_and_cli_use_the_key(srv: AuthServer, monkeypatch: pytest.MonkeyPatch) -> None:
    from rsfclient import Client, ProblemError

    k = srv.key("client", "submit")
    monkeypatch.delenv("RSF_API_KEY", raising=False)
    with Client(srv.url, retries=0) as c, pytest.raises(ProblemError) as err:
        c.request("GET", "/v1/cache/stats")
    assert err.value.status == 401
    monkeypatch.setenv("RSF_API_KEY", k)
    with Client(srv.url, retries=0) as c:
        assert c.request("GET", "/v1/cache/stats").status_code == 200
    env = {**srv.env, "RSF_API_KEY": k}
    r = subprocess.run(
        [RSF, "sweep", "status", "--url", srv.url, "0" * 32],
        env=env,
        capture_output=True,
        text=True,
        timeout=120,
        cwd=ROOT,
    )
    out = r.stdout + r.stderr
    assert "no sweep with id" in out and "401" not in out, out  # authenticated: a 404
