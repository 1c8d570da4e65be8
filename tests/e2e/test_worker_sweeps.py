"""Sweeps through real Celery workers: filesystem broker, Redis, SIGKILL, cancel, failures.

Each test starts its own uvicorn + worker processes on a fresh data directory.
"""
from __future__ import annotations

import sqlite3
import time
from pathlib import Path
from typing import Any, Callable

import httpx
import pytest
from tests.conftest import Redis, Server, Worker

pytestmark = pytest.mark.timeout(180)


def wait_for(pred: Callable[[], Any], timeout: float, what: str, dt: float = 0.1) -> Any:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        v = pred()
        if v:
            return v
        time.sleep(dt)
    raise AssertionError(f"timed out after {timeout} s waiting for {what}")


def spec(nx: int, ny: int, *, size: float = 1.0, vo: float = 1.0, chunk: int | None = None,
         eps_values: list[float] | None = None) -> dict[str, Any]:
    """kappa_ratio x eps outcome sweep (velocity jump of the given size)."""
    ys = eps_values or [round(0.05 + 0.9 * j / max(ny - 1, 1), 6) for j in range(ny)]
    out: dict[str, Any] = {
        "x": {"name": "kappa_ratio", "start": 0.2, "stop": 1.5, "n": nx},
        "y": {"name": "eps", "values": ys},
        "fixed": {"ba": 2.0, "vo": vo, "size": size},
    }
    if chunk:
        out["chunk_points"] = chunk
    return out


def status(c: httpx.Client, sid: str) -> dict[str, Any]:
    r = c.get(f"/v1/sweeps/{sid}")
    assert r.status_code == 200, r.text
    return r.json()


def all_points(c: httpx.Client, sid: str) -> list[dict[str, Any]]:
    pts, off = [], 0
    while off is not None:
        r = c.get(f"/v1/sweeps/{sid}/points", params={"offset": off, "limit": 500})
        assert r.status_code == 200, r.text
        body = r.json()
        pts += body["points"]
        off = body["next_offset"]
    return pts


def db_counts(data: Path, sid: str) -> tuple[int, int]:
    """(rows, distinct indices) stored for a sweep, read straight from SQLite."""
    con = sqlite3.connect(data / "cache.sqlite3", timeout=30)
    try:
        return con.execute("SELECT count(*), count(DISTINCT idx) FROM sweep_points "
                           "WHERE sweep_id = ?", (sid,)).fetchone()
    finally:
        con.close()


def submit(c: httpx.Client, body: dict[str, Any]) -> str:
    r = c.post("/v1/sweeps", json=body)
    assert r.status_code == 202, r.text
    assert r.headers["location"].startswith("/v1/sweeps/")
    return r.headers["location"].rsplit("/", 1)[1]


def run_and_check(c: httpx.Client, data: Path) -> None:
    body = spec(6, 5, chunk=7)
    sid = submit(c, body)
    st = wait_for(lambda: (s := status(c, sid))["status"] == "done" and s, 90, "sweep done")
    assert st["n_done"] == st["n_total"] == 30 and st["n_failed"] == 0 and st["eta_s"] == 0
    pts = all_points(c, sid)
    assert sorted(p["idx"] for p in pts) == list(range(30))
    assert db_counts(data, sid) == (30, 30)
    # The worker's numbers are rsfcore's numbers.
    from rsfcore import trajectory
    from rsfcore.params import Params
    for p in pts[::7]:
        ref = trajectory.classify(Params.from_ratio(2.0, p["x"], p["y"], 1.0), "velocity-jump",
                                  1.0, rtol=1e-10)
        assert p["outcome"] == ref.outcome and p["error"] is None
    # Resubmitting the same sweep is a lookup.
    r = c.post("/v1/sweeps", json=body)
    assert r.status_code == 200 and r.headers["x-cache"] == "hit"
    assert r.headers["location"].endswith(sid)
    listed = c.get("/v1/sweeps").json()["sweeps"]
    assert any(s["id"] == sid for s in listed)


def test_sweep_filesystem_broker(tmp_path: Path, procs: list, client_for) -> None:
    procs.append(srv := Server(tmp_path))
    procs.append(Worker(tmp_path))
    run_and_check(client_for(srv.url), tmp_path)


def test_sweep_redis_broker(tmp_path: Path, procs: list, client_for, redis_exe: str) -> None:
    procs.append(red := Redis(redis_exe, tmp_path))
    procs.append(srv := Server(tmp_path, red.url))
    procs.append(Worker(tmp_path, red.url))
    run_and_check(client_for(srv.url), tmp_path)


@pytest.mark.parametrize("broker", ["filesystem", "redis"])
def test_sigkill_mid_sweep_then_restart(tmp_path: Path, procs: list, client_for, broker: str,
                                        request: pytest.FixtureRequest) -> None:
    url = ""
    if broker == "redis":
        procs.append(red := Redis(request.getfixturevalue("redis_exe"), tmp_path))
        url = red.url
    procs.append(srv := Server(tmp_path, url))
    c = client_for(srv.url)
    w = Worker(tmp_path, url, plugin=True, RSF_TEST_POINT_DELAY_S="0.01")
    procs.append(w)
    sid = submit(c, spec(20, 15, chunk=20, vo=0.9))
    # Progress is visible while the sweep runs.
    st = wait_for(lambda: (s := status(c, sid))["n_done"] >= 60 and s, 60, "progress")
    assert st["status"] == "running" and st["n_done"] < st["n_total"] == 300
    assert st["eta_s"] is not None and st["eta_s"] > 0
    page = c.get(f"/v1/sweeps/{sid}/points", params={"limit": 10}).json()
    assert len(page["points"]) == 10 and page["n_total"] == 300
    w.kill()  # SIGKILL, mid-chunk
    w.p.wait(10)
    n_killed = status(c, sid)["n_done"]
    assert n_killed < 300
    time.sleep(0.5)
    assert status(c, sid)["n_done"] == n_killed  # nobody works on it
    procs.append(Worker(tmp_path, url, plugin=True, RSF_TEST_POINT_DELAY_S="0.001"))
    st = wait_for(lambda: (s := status(c, sid))["status"] == "done" and s, 90, "sweep done")
    assert st["n_done"] == 300 and st["n_failed"] == 0
    assert db_counts(tmp_path, sid) == (300, 300)
    assert sorted(p["idx"] for p in all_points(c, sid)) == list(range(300))


def test_cancel_stops_within_one_chunk(tmp_path: Path, procs: list, client_for) -> None:
    procs.append(srv := Server(tmp_path))
    procs.append(Worker(tmp_path, plugin=True, RSF_TEST_POINT_DELAY_S="0.01"))
    c = client_for(srv.url)
    chunk = 25
    sid = submit(c, spec(20, 20, chunk=chunk, vo=0.8))
    wait_for(lambda: status(c, sid)["n_done"] >= 30, 60, "progress")
    r = c.delete(f"/v1/sweeps/{sid}")
    assert r.status_code == 200 and r.json()["status"] == "cancelled"
    n_at_cancel = r.json()["n_done"]
    time.sleep(1.5)
    n1 = status(c, sid)["n_done"]
    time.sleep(1.0)
    st = status(c, sid)
    assert st["n_done"] == n1, "work continued after cancel"
    assert n1 - n_at_cancel <= chunk, (n_at_cancel, n1)
    assert st["status"] == "cancelled" and n1 < 400
    assert c.delete("/v1/sweeps/" + "0" * 32).status_code == 404


def test_failing_point_recorded_rest_go_on(tmp_path: Path, procs: list, client_for) -> None:
    procs.append(srv := Server(tmp_path))
    procs.append(Worker(tmp_path, plugin=True, RSF_TEST_FAIL_EPS="0.5"))
    c = client_for(srv.url)
    sid = submit(c, spec(4, 3, eps_values=[0.1, 0.5, 0.9], chunk=5, vo=0.7))
    st = wait_for(lambda: (s := status(c, sid))["status"] == "done" and s, 60, "sweep done")
    assert st["n_done"] == 12 and st["n_failed"] == 4
    assert all("injected failure at eps=0.5" in f["error"] for f in st["failures"])
    assert {f["j"] for f in st["failures"]} == {1}
    ok = [p for p in all_points(c, sid) if p["error"] is None]
    assert len(ok) == 8 and all(p["outcome"] in ("stable", "unstable") for p in ok)
