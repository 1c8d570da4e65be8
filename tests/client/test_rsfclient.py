"""rsfclient against a mock transport: retries, problem+json errors, 202 polling, sweeps."""

from __future__ import annotations

import json
from typing import Any

import httpx
import pytest

import rsfclient
from rsfclient import Client, ConnectionFailed, ProblemError, SweepCancelled


def test_exported_members() -> None:
    public = {m for m in vars(rsfclient) if not m.startswith("_")} | {"__version__"}
    assert sorted(rsfclient.__all__) == sorted(public)


def mock(handler: Any) -> Client:
    return Client("http://rsf.test", transport=httpx.MockTransport(handler), backoff=0.0)


def test_retries_503_and_connection_errors_then_answers() -> None:
    calls: list[str] = []

    def handler(req: httpx.Request) -> httpx.Response:
        calls.append(req.url.path)
        if len(calls) == 1:
            raise httpx.ConnectError("refused")
        if len(calls) == 2:
            return httpx.Response(
                503,
                headers={"Retry-After": "0"},
                json={"status": 503, "title": "Unavailable", "detail": "db"},
            )
        assert json.loads(req.content) == {
            "ba": 2.0,
            "kappa": 3.0,
            "eps": 0.2,
            "vo": 1.0,
            "perturbation": "velocity-jump",
            "rtol": 1e-10,
        }
        return httpx.Response(200, json={"kind": "finite", "critical_size": 1.5})

    with mock(handler) as c:
        assert c.critical(ba=2.0, kappa=3.0, eps=0.2)["critical_size"] == 1.5
    assert len(calls) == 3


def test_gives_up_after_retries() -> None:
    def handler(req: httpx.Request) -> httpx.Response:
        raise httpx.ConnectError("refused")

    c = Client("http://rsf.test", transport=httpx.MockTransport(handler), retries=2, backoff=0.0)
    with pytest.raises(ConnectionFailed, match="3 attempts"):
        c.critical()


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
        c.sweep(axes=[{"name": "eps", "start": 0, "stop": 2, "n": 3}])
    assert e.value.status == 422 and e.value.field == "axes[2].stop"
    assert e.value.valid == "[0, 1]" and e.value.problem == prob
    assert "axes[2].stop" in str(e.value)


def test_long_classify_is_polled() -> None:
    n = {"get": 0}

    def handler(req: httpx.Request) -> httpx.Response:
        if req.method == "POST":
            return httpx.Response(
                202, headers={"Location": "/v1/results/" + "a" * 64}, json={"status": "queued"}
            )
        n["get"] += 1
        if n["get"] < 3:
            return httpx.Response(
                202, json={"status": "running"}, headers={"Location": "/v1/results/" + "a" * 64}
            )
        return httpx.Response(200, json={"outcome": "stable"})

    with mock(handler) as c:
        assert c._answer("/v1/classify", {}, poll=0.0) == {"outcome": "stable"}
    assert n["get"] == 3


def test_sweep_wait_and_cancelled() -> None:
    seq = iter(
        [
            {"status": "running", "n_done": 5, "n_total": 10},
            {"status": "done", "n_done": 10, "n_total": 10, "n_failed": 0},
        ]
    )

    def handler(req: httpx.Request) -> httpx.Response:
        if req.method == "POST":
            body = json.loads(req.content)
            assert body["points"] == {"eps": [0.1, 0.2]}
            return httpx.Response(
                202,
                json={
                    "id": "f" * 32,
                    "status": "queued",
                    "n_done": 0,
                    "n_total": 10,
                    "resumed": True,
                },
            )
        return httpx.Response(200, json={"id": "f" * 32, **next(seq)})

    with mock(handler) as c:
        import numpy as np

        s = c.sweep(points={"eps": np.array([0.1, 0.2])})
        assert s.resumed and s.id == "f" * 32
        seen: list[str] = []
        st = s.wait(poll=0.0, on_status=lambda d: seen.append(d["status"]))
        assert st["status"] == "done" and seen == ["running", "done"]

    def cancelled(req: httpx.Request) -> httpx.Response:
        return httpx.Response(
            200, json={"id": "e" * 32, "status": "cancelled", "n_done": 1, "n_total": 9}
        )

    with mock(cancelled) as c, pytest.raises(SweepCancelled):
        c.get_sweep("e" * 32).wait(poll=0.0)
