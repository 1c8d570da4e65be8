"""Sweeps through real Celery workers: N-D and scattered sweeps against rsfcore, the 2-D
form on Redis, SIGKILL mid-sweep, cancel of a 10^8-point sweep, failing points, NetCDF.

Each test starts its own uvicorn + worker processes on a fresh data directory.
"""

from __future__ import annotations

import io
import math
import sqlite3
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import httpx
import numpy as np
import pytest

from tests.conftest import Redis, Server, Worker
from worker.tasks import UNIT_MAX_CHUNKS

pytestmark = pytest.mark.timeout(180)


def wait_for(pred: Callable[[], Any], timeout: float, what: str, dt: float = 0.05) -> Any:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        v = pred()
        if v:
            return v
        time.sleep(dt)
    raise AssertionError(f"timed out after {timeout} s waiting for {what}")


def status(c: httpx.Client, sid: str) -> dict[str, Any]:
    r = c.get(f"/v1/sweeps/{sid}")
    assert r.status_code == 200, r.text
    return r.json()


def submit(c: httpx.Client, body: dict[str, Any]) -> str:
    r = c.post("/v1/sweeps", json=body)
    assert r.status_code == 202, r.text
    assert r.headers["location"].startswith("/v1/sweeps/")
    return r.headers["location"].rsplit("/", 1)[1]


def done(c: httpx.Client, sid: str, timeout: float = 90) -> dict[str, Any]:
    return wait_for(
        lambda: (s := status(c, sid))["status"] == "done" and s, timeout, f"sweep {sid} done"
    )


def exactly_once(data: Path, sid: str, n_total: int) -> None:
    """The stored blocks tile [0, n_total) exactly: every point stored once."""
    con = sqlite3.connect(data / "cache.sqlite3", timeout=30)
    try:
        rng = con.execute(
            "SELECT i0, i1 FROM sweep_blocks WHERE sweep_id = ? ORDER BY i0", (sid,)
        ).fetchall()
    finally:
        con.close()
    edge = 0
    for i0, i1 in rng:
        assert i0 == edge, (i0, edge)
        edge = i1
    assert edge == n_total


def check_against_rsfcore(js: dict[str, Any], params: Callable[[int], tuple], pert: str) -> set:
    """Every point of a /data?format=json document equals rsfcore's critical_perturbation."""
    from rsfcore import critical
    from rsfcore.params import Params

    kinds = set()
    d = js["data"]
    for i in range(js["n_total"]):
        ref = critical.critical_perturbation(Params(*params(i)), pert, rtol=1e-10)
        kinds.add(ref.kind)
        assert d["computed"][i] == 1 and d["failed"][i] == 0
        assert js["kind_legend"][d["kind"][i]] == ref.kind
        if ref.kind == "finite":
            # the worker runs the same compiled kernel: 1e-12 relative is the promise
            # (JSON carries repr() floats, so the agreement is in fact exact)
            assert d["critical_size"][i] == pytest.approx(ref.critical_size, rel=1e-12)
    return kinds


def test_nd_and_scattered_sweeps_match_rsfcore(tmp_path: Path, procs: list, client_for) -> None:
    import xarray as xr

    procs.append(srv := Server(tmp_path))
    procs.append(Worker(tmp_path))
    c = client_for(srv.url)
    # 3-D grid over kappa (not the ratio), eps and v_o (0 included: closed form)
    grid = {
        "axes": [
            {"name": "kappa", "start": 0.5, "stop": 6.0, "n": 6},
            {"name": "eps", "values": [0.0, 0.25, 0.5]},
            {"name": "vo", "values": [0.0, 0.5, 3.0]},
        ],
        "fixed": {"ba": 2.5},
        "chunk_points": 10,
    }
    rng = np.random.default_rng(11)
    n = 30
    pts = {
        "ba": rng.uniform(1.5, 4.0, n).tolist(),
        "kappa_ratio": rng.uniform(0.5, 4.0, n).tolist(),
        "eps": rng.uniform(0.0, 0.9, n).tolist(),
    }
    scattered = {
        "points": pts,
        "fixed": {"vo": 2.0},
        "perturbation": "load-point-jump",
        "chunk_points": 8,
    }
    sid_g, sid_p = submit(c, grid), submit(c, scattered)
    st_g, st_p = done(c, sid_g), done(c, sid_p)
    assert st_g["n_done"] == 54 and st_g["n_failed"] == 0 and st_g["eta_s"] == 0
    assert st_p["n_done"] == n and st_p["n_failed"] == 0
    exactly_once(tmp_path, sid_g, 54)
    exactly_once(tmp_path, sid_p, n)

    js = c.get(f"/v1/sweeps/{sid_g}/data", params={"format": "json"}).json()
    ks, es, vs = js["coords"]["kappa"], js["coords"]["eps"], js["coords"]["vo"]

    def gp(i: int) -> tuple:
        a, b, v = np.unravel_index(i, (6, 3, 3))
        return 2.5, ks[a], es[b], vs[v]

    assert check_against_rsfcore(js, gp, "velocity-jump") == {"zero", "finite", "infinite"}
    js = c.get(f"/v1/sweeps/{sid_p}/data", params={"format": "json"}).json()
    assert check_against_rsfcore(
        js,
        lambda i: (pts["ba"][i], pts["kappa_ratio"][i] * (pts["ba"][i] - 1.0), pts["eps"][i], 2.0),
        "load-point-jump",
    )

    # NetCDF: axes as named coordinates, the variables of every point
    r = c.get(f"/v1/sweeps/{sid_g}/data", params={"format": "netcdf"})
    assert r.status_code == 200 and r.headers["content-type"] == "application/x-netcdf"
    ds = xr.open_dataset(io.BytesIO(r.content))
    assert ds["critical_size"].dims == ("kappa", "eps", "vo")
    assert ds["kappa"].values.tolist() == ks and ds["vo"].values.tolist() == [0.0, 0.5, 3.0]
    for v in ("critical_size", "kind", "outcome", "rel_accuracy", "failed"):
        assert ds[v].shape == (6, 3, 3)
    assert int(ds["failed"].sum()) == 0 and ds.attrs["fixed_ba"] == 2.5
    # resubmitting a finished sweep is a lookup
    r = c.post("/v1/sweeps", json=grid)
    assert r.status_code == 200 and r.headers["x-cache"] == "hit"


def test_xy_outcome_sweep_on_redis(tmp_path: Path, procs: list, client_for, redis_exe: str) -> None:
    """The original 2-D body keeps working; outcomes agree with stability_diagram."""
    from rsfcore.diagram import stability_diagram

    procs.append(red := Redis(redis_exe, tmp_path))
    procs.append(srv := Server(tmp_path, red.url))
    procs.append(Worker(tmp_path, red.url))
    c = client_for(srv.url)
    body = {
        "x": {"name": "kappa_ratio", "start": 0.2, "stop": 3.0, "n": 6},
        "y": {"name": "eps", "values": [0.05, 0.4, 0.8]},
        "fixed": {"ba": 2.0, "vo": 1.0, "size": 1.0},
        "chunk_points": 7,
    }
    sid = submit(c, body)
    done(c, sid)
    exactly_once(tmp_path, sid, 18)
    d = c.get(f"/v1/sweeps/{sid}/diagram").json()
    ref = stability_diagram("kappa_ratio", d["x"], "eps", d["y"], ba=2.0, vo=1.0, size=1.0)
    assert d["outcome"] == ref.outcome.astype(float).tolist()
    assert {0.0, 1.0} <= {v for row in d["outcome"] for v in row}


@pytest.mark.parametrize("broker", ["filesystem", "redis"])
def test_sigkill_mid_sweep_then_restart(
    tmp_path: Path, procs: list, client_for, broker: str, request: pytest.FixtureRequest
) -> None:
    url = ""
    if broker == "redis":
        procs.append(red := Redis(request.getfixturevalue("redis_exe"), tmp_path))
        url = red.url
    procs.append(srv := Server(tmp_path, url))
    c = client_for(srv.url)
    w = Worker(tmp_path, url, plugin=True, RSF_TEST_POINT_DELAY_S="0.005")
    procs.append(w)
    body = {
        "axes": [
            {"name": "kappa_ratio", "start": 0.5, "stop": 4.0, "n": 20},
            {"name": "eps", "start": 0.0, "stop": 0.9, "n": 15},
        ],
        "fixed": {"vo": 0.9},
        "chunk_points": 20,
    }
    sid = submit(c, body)
    # Progress and an ETA are visible while the sweep runs.
    st = wait_for(lambda: (s := status(c, sid))["n_done"] >= 60 and s, 60, "progress")
    assert st["status"] == "running" and st["n_done"] < st["n_total"] == 300
    assert st["eta_s"] is not None and st["eta_s"] > 0
    w.kill()  # SIGKILL, mid-chunk
    w.p.wait(10)
    n_killed = status(c, sid)["n_done"]
    assert n_killed < 300
    time.sleep(0.5)
    assert status(c, sid)["n_done"] == n_killed  # nobody works on it
    procs.append(Worker(tmp_path, url))
    st = done(c, sid)
    assert st["n_done"] == 300 and st["n_failed"] == 0
    exactly_once(tmp_path, sid, 300)
    js = c.get(f"/v1/sweeps/{sid}/data", params={"format": "json"}).json()
    assert all(js["data"]["computed"]) and None not in js["data"]["rel_accuracy"]


def test_cancel_of_1e8_point_sweep_stops_within_one_work_unit(
    tmp_path: Path, procs: list, client_for
) -> None:
    procs.append(srv := Server(tmp_path))
    procs.append(Worker(tmp_path))
    c = client_for(srv.url)
    chunk = 20_000
    body = {
        "axes": [
            {"name": n, "start": lo, "stop": hi, "n": 100}
            for n, lo, hi in (
                ("ba", 1.5, 5.0),
                ("kappa_ratio", 0.5, 5.0),
                ("eps", 0.0, 0.9),
                ("vo", 0.1, 10.0),
            )
        ],
        "chunk_points": chunk,
    }
    t0 = time.monotonic()
    sid = submit(c, body)
    assert time.monotonic() - t0 < 10  # accepted at once (generous: a loaded CI machine)
    st = wait_for(lambda: (s := status(c, sid))["n_done"] > 0 and s, 60, "progress")
    assert st["n_total"] == 10**8 and st["eta_s"] > 0
    r = c.delete(f"/v1/sweeps/{sid}")
    assert r.status_code == 200 and r.json()["status"] == "cancelled" and r.json()["changed"]
    n_at_cancel = r.json()["n_done"]
    # the running work unit (at most one: a solo worker; chained chunks are claimed and
    # completed in units of at most UNIT_MAX_CHUNKS chunks, ~0.25 s of work) may still be
    # stored, nothing after it
    n1 = (
        wait_for(
            lambda: (
                (n := status(c, sid)["n_done"]) >= 0
                and time.sleep(1.0) is None
                and status(c, sid)["n_done"] == n
                and n + 1
            ),
            30,
            "work to stop",
        )
        - 1
    )
    assert n1 - n_at_cancel <= UNIT_MAX_CHUNKS * chunk, (n_at_cancel, n1)
    time.sleep(1.0)
    st = status(c, sid)
    assert st["n_done"] == n1 and st["status"] == "cancelled"
    # a second cancel changes nothing
    r2 = c.delete(f"/v1/sweeps/{sid}")
    assert r2.json()["changed"] is False and r2.json()["finished_at"] == r.json()["finished_at"]
    assert c.delete("/v1/sweeps/" + "0" * 32).status_code == 404


def test_failing_points_recorded_rest_go_on(tmp_path: Path, procs: list, client_for) -> None:
    procs.append(srv := Server(tmp_path))
    procs.append(Worker(tmp_path, plugin=True, RSF_TEST_FAIL_EPS="0.5"))
    c = client_for(srv.url)
    body = {
        "axes": [
            {"name": "kappa_ratio", "values": [1.5, 2.0, 3.0, 4.0]},
            {"name": "eps", "values": [0.1, 0.5, 0.9]},
        ],
        "fixed": {"vo": 0.7},
        "chunk_points": 5,
    }
    sid = submit(c, body)
    st = done(c, sid, 60)
    assert st["n_done"] == 12 and st["n_failed"] == 4
    assert all("injected failure at eps=0.5" in f["error"] for f in st["failures"])
    assert {f["index"][1] for f in st["failures"]} == {1}
    assert {f["params"]["eps"] for f in st["failures"]} == {0.5}
    js = c.get(f"/v1/sweeps/{sid}/data", params={"format": "json"}).json()
    failed = js["data"]["failed"]
    assert sum(failed) == 4 and all(js["data"]["kind"][i] == -1 for i in range(12) if failed[i])
    ok = [i for i in range(12) if not failed[i]]
    assert all(js["data"]["kind"][i] >= 0 for i in ok)
    assert not any(
        js["data"]["critical_size"][i] is None and js["data"]["kind"][i] != 2 for i in ok
    )
    csv = c.get(f"/v1/sweeps/{sid}/data", params={"format": "csv"}).text.splitlines()
    assert sum("injected failure" in line for line in csv) == 4
    assert math.isfinite(len(csv))
