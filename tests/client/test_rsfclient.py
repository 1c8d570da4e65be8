"""rsfclient against a mock transport: what is sent (only what was given, SI nested),
which failures are retried (503, 429 with Retry-After, a reset) and which fail at once
(a refused connection, other statuses), problem+json errors, 202 polling, sweeps, fits."""

from __future__ import annotations

import json
import socket
import subprocess
import sys
from typing import Any

import httpx
import pytest

import rsfclient
from rsfclient import (
    Client,
    ConnectionFailed,
    CriticalResult,
    NotReady,
    ProblemError,
    SweepCancelled,
    axis,
)

CRITICAL = {
    "kind": "finite",
    "critical_size": 1.5,
    "log_critical_size": 1.5,
    "rel_accuracy": 1e-10,
    "accuracy_met": True,
    "reason": "",
    "method": "closed form",
    "perturbation": "velocity-jump",
    "params": {"ba": 2.0, "kappa": 3.0, "eps": 0.2, "vo": 1.0},
    "on_boundary": False,
    "cached": False,
    "cache_key": "a" * 64,
}
MACHINE = {
    "a": 0.010,
    "b": 0.014,
    "Dc_m": 20e-6,
    "sigma_Pa": 10e6,
    "k_Pa_per_m": 4e9,
    "V_star_m_s": 1e-6,
}


def test_exported_members() -> None:
    public = {m for m in vars(rsfclient) if not m.startswith("_")} | {"__version__"}
    assert sorted(rsfclient.__all__) == sorted(public)


def mock(handler: Any, **kw: Any) -> Client:
    return Client("http://rsf.test", transport=httpx.MockTransport(handler), backoff=0.0, **kw)


def recorder(answer: dict[str, Any]) -> tuple[list[dict[str, Any]], Any]:
    seen: list[dict[str, Any]] = []

    def handler(req: httpx.Request) -> httpx.Response:
        seen.append(json.loads(req.content) if req.content else {})
        return httpx.Response(200, json=answer)

    return seen, handler


def test_omitted_arguments_are_not_sent() -> None:
    """The issue's case: an SI question sends the machine only, so the server's
    defaults (eps, perturbation, rtol) apply and no dimensionless ba/kappa/vo clash."""
    seen, handler = recorder(CRITICAL)
    with mock(handler) as c:
        c.critical(**MACHINE)
        c.critical(physical=MACHINE, eps=0.5)
        c.critical(ba=2.0, kappa=3.0)
    assert seen == [
        {"physical": MACHINE},
        {"physical": MACHINE, "eps": 0.5},
        {"ba": 2.0, "kappa": 3.0},
    ]


def test_si_sizes_starts_and_tuples_are_sent_by_their_http_names() -> None:
    seen, handler = recorder(
        {
            "outcome": "stable",
            "certificate": "x",
            "rel_accuracy": 1e-9,
            "params": CRITICAL["params"],
            "start": {"phi": 1.0, "psi": 2.0},
        }
    )
    with mock(handler) as c:
        r = c.classify(**MACHINE, V_load_m_s=3e-6, factor=10.0, eps=0.25)
        c.classify(ba=2.0, start=(1.0, 2.0))
    assert seen[0] == {"physical": {**MACHINE, "V_load_m_s": 3e-6}, "factor": 10.0, "eps": 0.25}
    assert seen[1] == {"ba": 2.0, "start": {"phi": 1.0, "psi": 2.0}}
    assert r.outcome == "stable" and r.start is not None and r.start.psi == 2.0
    with mock(handler) as c, pytest.raises(ValueError, match="not both"):
        c.critical(physical=MACHINE, a=0.01)


def test_answers_are_typed_and_read_like_the_json() -> None:
    _, handler = recorder({**CRITICAL, "new_field": 7})
    with mock(handler) as c:
        r = c.critical(ba=2.0)
    assert isinstance(r, CriticalResult)
    assert r.kind == "finite" and r.critical_size == 1.5 and r.params.eps == 0.2
    assert r["critical_size"] == 1.5 and r.get("new_field") == 7 and "si" not in r
    assert r.si is None and r.to_dict() == {**CRITICAL, "new_field": 7}


def test_refused_connection_fails_at_once_naming_the_url() -> None:
    calls: list[int] = []

    def handler(req: httpx.Request) -> httpx.Response:
        calls.append(1)
        raise httpx.ConnectError("[Errno 111] Connection refused")

    with mock(handler) as c, pytest.raises(ConnectionFailed) as e:
        c.critical(ba=2.0)
    assert len(calls) == 1
    assert "http://rsf.test/v1/critical" in str(e.value) and "rsf serve" in str(e.value)
    assert "RSF_URL" in str(e.value)


def test_refused_by_a_real_closed_port_is_immediate(monkeypatch: pytest.MonkeyPatch) -> None:
    import rsfclient._http

    slept: list[float] = []
    monkeypatch.setattr(rsfclient._http.time, "sleep", slept.append)
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]  # closed once the block ends: nothing listens
    with Client(f"http://127.0.0.1:{port}") as c, pytest.raises(ConnectionFailed) as e:
        c.critical(ba=2.0)
    assert slept == []  # no backoff: the first refusal is the answer
    assert f"127.0.0.1:{port}" in str(e.value)


@pytest.mark.parametrize(
    ("first", "retried"),
    [
        (httpx.Response(503, headers={"Retry-After": "0"}, json={"status": 503}), True),
        (httpx.Response(503, json={"status": 503}), True),  # backoff without Retry-After
        (httpx.Response(429, headers={"Retry-After": "0"}, json={"status": 429}), True),
        (httpx.Response(429, json={"status": 429, "title": "Too many"}), False),
        (httpx.Response(502, json={"status": 502}), False),
        (httpx.Response(500, json={"status": 500}), False),
        (httpx.RemoteProtocolError("Server disconnected without sending a response."), True),
        (httpx.ReadError("[Errno 104] Connection reset by peer"), True),
        (httpx.ReadTimeout("timed out"), False),
    ],
)
def test_what_is_retried(first: Any, retried: bool) -> None:
    calls: list[int] = []

    def handler(req: httpx.Request) -> httpx.Response:
        calls.append(1)
        if len(calls) == 1:
            if isinstance(first, Exception):
                raise first
            return first
        return httpx.Response(200, json=CRITICAL)

    with mock(handler) as c:
        if retried:
            assert c.critical(ba=2.0).critical_size == 1.5
        else:
            with pytest.raises((ProblemError, ConnectionFailed)):
                c.critical(ba=2.0)
    assert len(calls) == (2 if retried else 1)


def test_gives_up_after_retries() -> None:
    def handler(req: httpx.Request) -> httpx.Response:
        return httpx.Response(503, headers={"Retry-After": "0"}, json={"status": 503})

    c = Client("http://rsf.test", transport=httpx.MockTransport(handler), retries=2)
    with pytest.raises(ProblemError) as e:
        c.critical()
    assert e.value.status == 503

    def reset(req: httpx.Request) -> httpx.Response:
        raise httpx.RemoteProtocolError("reset")

    c = Client("http://rsf.test", transport=httpx.MockTransport(reset), retries=2, backoff=0)
    with pytest.raises(ConnectionFailed, match="reset 3 times"):
        c.critical()


def test_url_and_key_from_the_environment(monkeypatch: pytest.MonkeyPatch) -> None:
    seen: list[tuple[str, str | None]] = []

    def handler(req: httpx.Request) -> httpx.Response:
        seen.append((str(req.url), req.headers.get("authorization")))
        return httpx.Response(200, json=CRITICAL)

    monkeypatch.setenv("RSF_URL", "http://lab-host:9000/")
    monkeypatch.setenv("RSF_API_KEY", "rsf_k")
    with Client(transport=httpx.MockTransport(handler)) as c:
        assert c.base_url == "http://lab-host:9000"
        c.critical()
    monkeypatch.delenv("RSF_URL")
    monkeypatch.delenv("RSF_API_KEY")
    with Client(transport=httpx.MockTransport(handler)) as c:
        c.critical()
    assert seen == [
        ("http://lab-host:9000/v1/critical", "Bearer rsf_k"),
        ("http://127.0.0.1:8000/v1/critical", None),
    ]


def test_problem_json_is_carried() -> None:
    prob = {
        "type": "about:blank",
        "title": "Invalid input",
        "status": 422,
        "detail": "axes[2].stop: 2.0 out of range for eps",
        "field": "axes[2].stop",
        "valid": "[0, 1]",
    }

    def handler(req: httpx.Request) -> httpx.Response:
        return httpx.Response(422, json=prob, headers={"content-type": "application/problem+json"})

    with mock(handler) as c, pytest.raises(ProblemError) as e:
        c.sweep(axes=[axis("eps", 0, 2, 3)])
    assert e.value.status == 422 and e.value.field == "axes[2].stop"
    assert e.value.valid == "[0, 1]" and e.value.problem == prob
    assert "axes[2].stop" in str(e.value)


def test_long_classify_is_polled() -> None:
    n = {"get": 0}
    answer = {
        "outcome": "stable",
        "certificate": "returned_to_steady_state",
        "rel_accuracy": 1e-9,
        "params": CRITICAL["params"],
    }

    def handler(req: httpx.Request) -> httpx.Response:
        loc = {"Location": "/v1/results/" + "a" * 64}
        if req.method == "POST":
            return httpx.Response(202, headers=loc, json={"status": "queued"})
        n["get"] += 1
        if n["get"] < 3:
            return httpx.Response(202, json={"status": "running"}, headers=loc)
        return httpx.Response(200, json=answer)

    with mock(handler, poll=0.0) as c:
        assert c.classify(ba=2.0, size=3.0).outcome == "stable"
    assert n["get"] == 3


def _status(**kw: Any) -> dict[str, Any]:
    return {"id": "f" * 32, "status": "queued", "n_done": 0, "n_total": 10, **kw}


def test_sweep_body_wait_and_cancelled() -> None:
    import numpy as np

    seq = iter(
        [
            _status(status="running", n_done=5),
            _status(status="done", n_done=10, n_failed=0),
        ]
    )
    bodies: list[dict[str, Any]] = []

    def handler(req: httpx.Request) -> httpx.Response:
        if req.method == "POST":
            bodies.append(json.loads(req.content))
            return httpx.Response(202, json=_status(resumed=True, created=False))
        return httpx.Response(200, json=next(seq))

    with mock(handler) as c:
        s = c.sweep(points={"eps": np.array([0.1, 0.2])}, ba=2.0, kappa_ratio=3.0)
        assert s.resumed and s.id == "f" * 32 and s.last["n_total"] == 10
        seen: list[str] = []
        st = s.wait(poll=0.0, on_status=lambda d: seen.append(d.status))
        assert st.status == "done" and st.finished and seen == ["running", "done"]
    assert bodies == [{"points": {"eps": [0.1, 0.2]}, "fixed": {"ba": 2.0, "kappa_ratio": 3.0}}]

    with mock(handler) as c:  # SI: the machine goes into fixed.physical
        bodies.clear()
        c.sweep(axes=[axis("eps", values=[0.0, 1.0])], fixed={"eps": 0.5}, **MACHINE)
    assert bodies == [
        {
            "axes": [{"name": "eps", "values": [0.0, 1.0]}],
            "fixed": {"eps": 0.5, "physical": MACHINE},
        }
    ]
    with mock(handler) as c, pytest.raises(ValueError, match="eps given both"):
        c.sweep(axes=[axis("ba", 2, 3, 2)], fixed={"eps": 0.5}, eps=0.2)

    def cancelled(req: httpx.Request) -> httpx.Response:
        return httpx.Response(200, json=_status(status="cancelled", n_done=1, n_total=9))

    with mock(cancelled) as c, pytest.raises(SweepCancelled):
        c.get_sweep("e" * 32).wait(poll=0.0)


def test_fit_submit_result_and_wait() -> None:
    key = "c" * 64
    state = {"polls": 0}
    done = {"status": "converged", "ok": True, "law": "aging", "params": {"a": 0.01}}

    def handler(req: httpx.Request) -> httpx.Response:
        if req.method == "POST":
            body = json.loads(req.content)
            assert body == {"record": json.dumps({"t_s": [0.0, 1.0]}), "law": "aging"}
            return httpx.Response(202, json={"status": "queued", "cache_key": key})
        assert req.url.path == f"/v1/fits/{key}"
        state["polls"] += 1
        if state["polls"] < 3:
            return httpx.Response(202, json={"status": "running", "progress": "fitting"})
        return httpx.Response(200, json=done)

    with mock(handler, poll=0.0) as c:
        f = c.submit_fit({"t_s": [0.0, 1.0]}, law="aging")
        with pytest.raises(NotReady) as e:
            f.result()
        assert e.value.state == "running" and e.value.progress == "fitting"
        res = f.wait(poll=0.0)
        assert res.ok and res.params == {"a": 0.01} and f.result() is res


def test_client_imports_nothing_heavy() -> None:
    """A light install: importing the client loads httpx and the standard library, none
    of the service's packages, numpy, pydantic, pandas or xarray."""
    code = (
        "import sys, rsfclient; heavy = ('rsfcore', 'rsfapp', 'service', 'worker', 'rsfcli', "
        "'rsfplots', 'numpy', 'pydantic', 'pandas', 'xarray', 'fastapi', 'numba'); "
        "print(sorted(m for m in heavy if m in sys.modules))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "[]"


def test_client_modules_import_none_of_the_service_packages() -> None:
    """Every import statement of rsfclient (lazy ones too): the client is a separate light
    package that talks HTTP only (tests/app/test_layers.py checks the other packages)."""
    import ast
    from pathlib import Path

    ours = {"rsfcore", "rsfapp", "rsfplots", "service", "worker", "rsfcli"}
    optional = {"pandas", "xarray", "rich", "httpx"}
    bad = []
    for f in sorted(Path(rsfclient.__file__).parent.glob("*.py")):
        for node in ast.walk(ast.parse(f.read_text())):
            names = (
                [a.name for a in node.names]
                if isinstance(node, ast.Import)
                else [node.module]
                if isinstance(node, ast.ImportFrom) and node.level == 0 and node.module
                else []
            )
            for n in names:
                top = n.split(".")[0]
                if top in ours or (top not in optional and top not in sys.stdlib_module_names):
                    bad.append(f"{f.name}:{node.lineno} imports {n}")
    assert not bad, bad


def test_fit_stiffness_in_pa_per_m_is_sent_top_level() -> None:
    """k_Pa_per_m and sigma_Pa are fields of the fit request itself (not a ``physical``
    machine as in the single queries)."""
    seen: list[dict[str, Any]] = []

    def handler(req: httpx.Request) -> httpx.Response:
        seen.append(json.loads(req.content))
        return httpx.Response(202, json={"status": "queued", "cache_key": "d" * 64})

    with mock(handler) as c:
        c.submit_fit("t_s,v_lp_m_s,mu\n", k_Pa_per_m=2e10, sigma_Pa=1e7, windows=[(0.0, 60.0)])
    assert seen == [
        {
            "record": "t_s,v_lp_m_s,mu\n",
            "k_Pa_per_m": 2e10,
            "sigma_Pa": 1e7,
            "windows": [[0.0, 60.0]],
        }
    ]
