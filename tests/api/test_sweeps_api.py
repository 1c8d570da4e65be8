"""Sweeps in process (TestClient, real SQLite; chunks computed by calling the worker's
task body directly): N-D grids, scattered points, validation, lifecycle, data formats.
The same flows through real uvicorn + Celery workers are in tests/e2e/test_worker_sweeps.py."""

from __future__ import annotations

import io
import math
import sqlite3
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from fastapi.testclient import TestClient

from rsfcore import critical
from rsfcore.params import Params

pytestmark = pytest.mark.timeout(300)


def run_all(c: TestClient, sid: str) -> None:
    """Compute every chunk of ``sid`` in this process (what a worker does)."""
    from worker.tasks import run_chunk_body

    n = c.get(f"/v1/sweeps/{sid}").json()["n_chunks"]
    for k in range(n):
        run_chunk_body(sid, k)


def submit(c: TestClient, body: dict[str, Any], code: int = 202) -> dict[str, Any]:
    r = c.post("/v1/sweeps", json=body)
    assert r.status_code == code, r.text
    return r.json()


def rows(data: Path) -> dict[str, int]:
    con = sqlite3.connect(data / "cache.sqlite3", timeout=30)
    try:
        return {
            t: con.execute(f"SELECT count(*) FROM {t}").fetchone()[0]
            for t in ("sweeps", "sweep_chunks", "sweep_blocks", "sweep_inputs")
        }
    finally:
        con.close()


def ref_critical(
    ba: float, kappa: float, eps: float, vo: float, pert: str = "velocity-jump"
) -> critical.CriticalResult:
    return critical.critical_perturbation(Params(ba, kappa, eps, vo), pert, rtol=1e-10)


#: A lab machine in SI (fixed.physical of a sweep); not round numbers, so that the
#: conversion SI -> (ba, kappa, vo) rounds.
PH = {
    "a": 0.012,
    "b": 0.031,
    "Dc_m": 2.3e-5,
    "sigma_Pa": 4.7e7,
    "k_Pa_per_m": 6.1e10,
    "V_star_m_s": 1.3e-6,
    "V_load_m_s": 3.7e-6,
}


@pytest.mark.parametrize("pert", ["velocity-jump", "load-point-jump"])
def test_si_sweep_equals_dimensionless_sweep(c: TestClient, pert: str) -> None:
    import xarray as xr

    # the dimensionless groups written out here (eq: characteristic scales), not taken
    # from rsfcore.units
    ba = PH["b"] / PH["a"]
    kappa = PH["k_Pa_per_m"] * PH["Dc_m"] / (PH["a"] * PH["sigma_Pa"])
    vo = PH["V_load_m_s"] / PH["V_star_m_s"]
    eps = {"name": "eps", "values": [0.0, 0.4, 1.0]}
    si = submit(c, {"axes": [eps], "fixed": {"physical": PH}, "perturbation": pert})
    dl = submit(
        c,
        {"axes": [eps], "fixed": {"ba": ba, "kappa": kappa, "vo": vo}, "perturbation": pert},
    )
    assert si["id"] != dl["id"] and si["physical"]["V_load_m_s"] == PH["V_load_m_s"]
    assert si["fixed"]["ba"] == pytest.approx(ba, rel=1e-15)
    for sid in (si["id"], dl["id"]):
        run_all(c, sid)
    spec = c.get(f"/v1/sweeps/{si['id']}/spec").json()
    assert spec["physical"] == PH and spec["kappa_param"] == "kappa"
    got = {}
    for name, sid in (("si", si["id"]), ("dl", dl["id"])):
        r = c.get(f"/v1/sweeps/{sid}/data")
        assert r.status_code == 200
        got[name] = xr.open_dataset(io.BytesIO(r.content), engine="h5netcdf")
    a, b = got["si"]["critical_size"].values, got["dl"]["critical_size"].values
    # 1e-12: the same groups up to rounding of the conversion (a few ulp), and the
    # critical size is smooth in them; in practice the two are bit-identical
    assert np.isfinite(a[:2]).all() and (got["si"]["kind"].values[:2] == 1).all()
    np.testing.assert_allclose(a, b, rtol=1e-12, atol=0)  # inf (stable aging law) == inf
    np.testing.assert_array_equal(got["si"]["kind"].values, got["dl"]["kind"].values)
    for k, e in enumerate(eps["values"]):
        ref = ref_critical(ba, kappa, e, vo, pert)
        assert a[k] == pytest.approx(ref.critical_size or math.inf, rel=1e-12)
    ds = got["si"]
    assert ds.attrs["physical_Dc_m"] == PH["Dc_m"]
    assert ds.attrs["time_scale_s"] == pytest.approx(PH["Dc_m"] / PH["V_star_m_s"], rel=1e-15)
    assert ds.attrs["stress_scale_Pa"] == pytest.approx(PH["a"] * PH["sigma_Pa"], rel=1e-15)
    # the SI critical size, computed here from its definition: the slip rate right after
    # the jump V_load e^d, or the new load-point velocity V_load (1 + dv); few-ulp formulas
    if pert == "velocity-jump":
        si_var, expect = "critical_slip_rate_m_s", PH["V_load_m_s"] * np.exp(a)
    else:
        si_var, expect = "critical_load_point_velocity_m_s", PH["V_load_m_s"] * (1.0 + a)
    assert ds[si_var].dims == ("eps",) and ds[si_var].attrs["units"] == "m/s"
    np.testing.assert_allclose(ds[si_var].values, expect, rtol=1e-14)
    assert "critical_slip_rate_m_s" not in got["dl"] and "time_scale_s" not in got["dl"].attrs
    js = c.get(f"/v1/sweeps/{si['id']}/data", params={"format": "json"}).json()
    assert js["physical"] == PH


def test_3d_grid_with_vo_axis_matches_rsfcore(c: TestClient) -> None:
    body = {
        "axes": [
            {"name": "kappa_ratio", "start": 0.5, "stop": 4.0, "n": 5},
            {"name": "eps", "values": [0.0, 0.3, 0.6]},
            {"name": "vo", "values": [0.0, 1.0]},
        ],
        "fixed": {"ba": 2.5},
        "chunk_points": 7,
    }
    st = submit(c, body)
    assert st["created"] is True and st["resumed"] is False and st["n_total"] == 30
    assert st["dims"] == [
        {"name": "kappa_ratio", "n": 5},
        {"name": "eps", "n": 3},
        {"name": "vo", "n": 2},
    ]
    assert "axes" not in st and "spec" not in st  # polls do not resend axis values
    sid = st["id"]
    run_all(c, sid)
    st = c.get(f"/v1/sweeps/{sid}").json()
    assert st["status"] == "done" and st["n_done"] == 30 and st["n_failed"] == 0
    assert st["finished_at"].endswith("Z") and "T" in st["created_at"]
    pts = c.get(f"/v1/sweeps/{sid}/points", params={"limit": 100}).json()["points"]
    assert [p["idx"] for p in pts] == list(range(30))
    kinds = set()
    for p in pts:
        ref = ref_critical(2.5, p["kappa_ratio"] * 1.5, p["eps"], p["vo"])
        kinds.add(ref.kind)
        assert p["kind"] == ref.kind
        assert p["method"] == ref.method
        if ref.kind == "finite":
            # same compiled kernel: equal to 1e-12 relative (in fact identical)
            assert p["critical_size"] == pytest.approx(ref.critical_size, rel=1e-12)
    assert kinds == {"zero", "finite", "infinite"}
    # resubmitting a finished sweep is a lookup
    r = c.post("/v1/sweeps", json=body)
    assert r.status_code == 200 and r.headers["x-cache"] == "hit"


def test_scattered_points_and_data_formats(c: TestClient) -> None:
    import xarray as xr

    rng = np.random.default_rng(5)
    n = 40
    pts = {
        "ba": rng.uniform(1.2, 6.0, n).tolist(),
        "kappa": rng.uniform(0.0, 8.0, n).tolist(),
        "eps": rng.uniform(0.0, 0.9, n).tolist(),
    }
    st = submit(
        c,
        {
            "points": pts,
            "fixed": {"vo": 2.0},
            "perturbation": "load-point-jump",
            "chunk_points": 16,
        },
    )
    sid = st["id"]
    assert st["dims"] == [{"name": "point", "n": n, "parameters": ["ba", "kappa", "eps"]}]
    run_all(c, sid)
    r = c.get(f"/v1/sweeps/{sid}/data", params={"format": "netcdf"})
    assert r.status_code == 200 and r.headers["x-sweep-progress"] == f"{n}/{n}"
    ds = xr.open_dataset(io.BytesIO(r.content), engine="h5netcdf")
    assert ds["critical_size"].dims == ("point",)
    for v in (
        "critical_size",
        "kind",
        "outcome",
        "rel_accuracy",
        "failed",
        "method",
        "outcome_uncertain",
        "ba",
        "eps",
    ):
        assert v in ds
    for i in range(n):
        ref = ref_critical(pts["ba"][i], pts["kappa"][i], pts["eps"][i], 2.0, "load-point-jump")
        got = float(ds["critical_size"][i])
        assert ds["ba"][i] == pts["ba"][i]
        if ref.kind == "finite":
            assert got == pytest.approx(ref.critical_size, rel=1e-12)
        elif ref.kind == "infinite":
            assert math.isinf(got)
        else:
            assert got == 0.0
    csv = c.get(f"/v1/sweeps/{sid}/data", params={"format": "csv"}).text.splitlines()
    assert csv[0] == "idx,ba,kappa,eps,kind,critical_size,outcome,rel_accuracy,method,failed,error"
    assert len(csv) == n + 1
    js = c.get(f"/v1/sweeps/{sid}/data", params={"format": "json"}).json()
    assert len(js["data"]["critical_size"]) == n and js["coords"]["ba"] == pts["ba"]


def test_grid_netcdf_coordinates_and_partial_data(c: TestClient) -> None:
    import xarray as xr

    body = {
        "axes": [
            {"name": "eps", "start": 0.0, "stop": 0.8, "n": 3},
            {"name": "kappa_ratio", "start": 1.0, "stop": 9.0, "n": 4, "log": True},
        ],
        "fixed": {"ba": 3.0},
        "chunk_points": 5,
    }
    sid = submit(c, body)["id"]
    from worker.tasks import run_chunk_body

    run_chunk_body(sid, 0)  # one chunk of three: partial data
    r = c.get(f"/v1/sweeps/{sid}/data")
    ds = xr.open_dataset(io.BytesIO(r.content), engine="h5netcdf")
    assert ds["critical_size"].dims == ("eps", "kappa_ratio")
    np.testing.assert_array_equal(ds["eps"].values, [0.0, 0.4, 0.8])
    # geometric spacing 1, 9^(1/3), 9^(2/3), 9 (exact end points)
    np.testing.assert_allclose(ds["kappa_ratio"].values, 9.0 ** (np.arange(4) / 3), rtol=1e-15)
    assert ds["kappa_ratio"].values[-1] == 9.0
    # missing points are the CF _FillValue (-1 for the codes), decoded by xarray as NaN
    flat = ds["kind"].values.ravel()
    assert (flat[:5] >= 0).all() and np.isnan(flat[5:]).all()
    assert ds["kind"].encoding["_FillValue"] == -1
    assert np.isnan(ds["critical_size"].values.ravel()[5:]).all()
    assert (ds["computed"].values.ravel() == [1] * 5 + [0] * 7).all()
    assert ds.attrs["status"] == "running" and ds.attrs["fixed_ba"] == 3.0


def test_diagram_slice_of_3d_grid(c: TestClient) -> None:
    body = {
        "axes": [
            {"name": "ba", "values": [2.0, 3.0]},
            {"name": "kappa_ratio", "start": 0.5, "stop": 3.0, "n": 4},
            {"name": "eps", "start": 0.0, "stop": 0.9, "n": 3},
        ],
        "fixed": {"size": 0.7},
    }
    sid = submit(c, body)["id"]
    run_all(c, sid)
    d = c.get(f"/v1/sweeps/{sid}/diagram", params={"slice": "ba:3.0"}).json()
    assert d["x_name"] == "kappa_ratio" and d["y_name"] == "eps" and d["slice"] == {"ba": 3.0}
    assert len(d["outcome"]) == 4 and len(d["outcome"][0]) == 3
    assert all(all(row) for row in d["present"])
    png = c.get(f"/v1/sweeps/{sid}/diagram", params={"slice": "ba:3", "format": "png"})
    assert png.status_code == 200 and png.content[:4] == b"\x89PNG"
    r = c.get(f"/v1/sweeps/{sid}/diagram")
    assert r.status_code == 422 and r.json()["field"] == "slice"


@pytest.mark.parametrize(
    "body,field,valid",
    [
        (
            {
                "axes": [
                    {"name": "ba", "values": [2.0]},
                    {"name": "eps", "values": [0.1]},
                    {"name": "eps", "start": 0, "stop": 2, "n": 3},
                ]
            },
            "axes[2].name",
            "not already",
        ),
        (
            {
                "axes": [
                    {"name": "ba", "values": [2.0]},
                    {"name": "kappa", "values": [0.1]},
                    {"name": "eps", "start": 0, "stop": 2, "n": 3},
                ]
            },
            "axes[2].stop",
            "[0, 1]",
        ),
        (
            {"points": {"ba": [2.0] * 20, "eps": [0.1] * 17 + [1.5, 0.1, 0.1]}},
            "points.eps[17]",
            "[0, 1]",
        ),
        ({"points": {"ba": [2.0, 3.0], "eps": [0.1]}}, "points.eps", "length 2"),
        (
            {"axes": [{"name": "kappa", "values": [2.0]}], "fixed": {"kappa_ratio": 1.0}},
            "fixed.kappa_ratio",
            "null",
        ),
        (
            {"axes": [{"name": "vo", "values": [1.0, 0.0]}], "perturbation": "load-point-jump"},
            "axes[0].values[1]",
            "(0, 1e300]",
        ),
        (
            {
                "axes": [
                    {"name": "eps", "start": 0, "stop": 1, "n": 1000},
                    {"name": "ba", "start": 2, "stop": 3, "n": 1000},
                    {"name": "vo", "start": 1, "stop": 3, "n": 1000},
                ]
            },
            "axes",
            "<= 100000000",
        ),
        (
            {"axes": [{"name": "eps", "values": [0.1]}], "x": {"name": "ba", "values": [2.0]}},
            "x",
            "one of",
        ),
        # fixed.physical sets ba, kappa and vo: never given or swept with it
        (
            {"axes": [{"name": "eps", "values": [0.1]}], "fixed": {"physical": PH, "ba": 2.0}},
            "fixed.ba",
            "only eps and size",
        ),
        (
            {
                "axes": [{"name": "eps", "values": [0.1]}],
                "fixed": {"physical": PH, "kappa_ratio": 2.0},
            },
            "fixed.kappa_ratio",
            "only eps and size",
        ),
        (
            {"axes": [{"name": "kappa_ratio", "values": [1.0]}], "fixed": {"physical": PH}},
            "axes[0].name",
            "only eps and size",
        ),
        ({"points": {"vo": [1.0, 2.0]}, "fixed": {"physical": PH}}, "points.vo", "only eps"),
        (
            {"axes": [{"name": "eps", "values": [0.1]}], "fixed": {"physical": {**PH, "b": 0.01}}},
            "fixed.physical.b",
            "rate weakening",
        ),
        (
            {
                "axes": [{"name": "eps", "values": [0.1]}],
                "fixed": {"physical": {**PH, "V_load_m_s": 0.0}},
                "perturbation": "load-point-jump",
            },
            "fixed.physical.V_load_m_s",
            "m/s",
        ),
    ],
)
def test_bad_sweep_is_422_naming_field_and_writes_nothing(
    c: TestClient, api_stack, body: dict[str, Any], field: str, valid: str
) -> None:
    data = api_stack[1]
    c.get("/health")
    before = rows(data)
    r = c.post("/v1/sweeps", json=body)
    assert r.status_code == 422, r.text
    assert r.headers["content-type"].startswith("application/problem+json")
    p = r.json()
    assert p["field"] == field, p
    assert valid in (p.get("valid") or "") + p["detail"], p
    assert rows(data) == before


def test_lifecycle_cancel_resume_delete(c: TestClient, api_stack) -> None:
    body = {
        "axes": [
            {"name": "eps", "start": 0.0, "stop": 0.9, "n": 10},
            {"name": "kappa_ratio", "start": 1.0, "stop": 5.0, "n": 10},
        ],
        "chunk_points": 10,
    }
    st = submit(c, body)
    sid = st["id"]
    from worker.tasks import run_chunk_body

    run_chunk_body(sid, 0)
    r1 = c.delete(f"/v1/sweeps/{sid}")
    assert r1.status_code == 200 and r1.json()["status"] == "cancelled" and r1.json()["changed"]
    r2 = c.delete(f"/v1/sweeps/{sid}")
    assert r2.json()["changed"] is False
    assert r2.json()["finished_at"] == r1.json()["finished_at"]  # a second cancel changes nothing
    assert run_chunk_body(sid, 1) == {"skipped": True}
    again = c.post("/v1/sweeps", json=body)
    assert again.status_code == 202 and again.json()["resumed"] is True
    assert "x-cache" not in again.headers
    run_all(c, sid)
    st = c.get(f"/v1/sweeps/{sid}").json()
    assert st["status"] == "done" and st["n_done"] == 100
    assert c.delete(f"/v1/sweeps/{sid}").json()["changed"] is False  # done stays done
    assert c.delete(f"/v1/sweeps/{sid}", params={"purge": "true"}).status_code == 204
    assert c.get(f"/v1/sweeps/{sid}").status_code == 404
    con = sqlite3.connect(api_stack[1] / "cache.sqlite3")
    try:
        for t in ("sweep_blocks", "sweep_chunks", "sweeps"):
            assert (
                con.execute(
                    f"SELECT count(*) FROM {t} WHERE {'id' if t == 'sweeps' else 'sweep_id'} = ?",
                    (sid,),
                ).fetchone()[0]
                == 0
            )
    finally:
        con.close()


def test_huge_sweep_is_accepted_lazily(c: TestClient, api_stack) -> None:
    """10^8 points: 202 at once, a few thousand chunk rows at most, a window queued."""
    body = {
        "axes": [
            {"name": n, "start": lo, "stop": hi, "n": 100}
            for n, lo, hi in (
                ("ba", 1.5, 5.0),
                ("kappa_ratio", 0.5, 5.0),
                ("eps", 0.0, 0.9),
                ("vo", 0.0, 10.0),
            )
        ]
    }
    q = c.app.state.recording_queue
    before = len(q.chunks)
    st = submit(c, body)
    assert st["n_total"] == 10**8 and st["n_chunks"] <= 100_000
    assert len(q.chunks) - before == min(64, st["n_chunks"])
    r = c.delete(f"/v1/sweeps/{st['id']}", params={"purge": "true"})
    assert r.status_code == 204


def test_sweep_of_the_pre_array_layout_is_410(c: TestClient, api_stack) -> None:
    """A sweep stored before N-D sweeps (2-D spec, points as rows) keeps its status; its
    data endpoints say 410 Gone (re-submit), never 500."""
    sid = "0123456789abcdef" * 2
    con = sqlite3.connect(api_stack[1] / "cache.sqlite3")
    try:
        con.execute(
            "INSERT INTO sweeps (id, spec, status, n_total, n_chunks, numerics_version,"
            " created_at) VALUES (?, ?, 'done', 4, 1, '1', 0)",
            (
                sid,
                '{"x": {"name": "eps", "values": [0.1, 0.2]}, "y": {"name": "ba", '
                '"values": [2.0, 3.0]}, "fixed": {}, "perturbation": '
                '"velocity-jump", "rtol": 1e-10}',
            ),
        )
        con.commit()
    finally:
        con.close()
    st = c.get(f"/v1/sweeps/{sid}")
    assert st.status_code == 200 and st.json()["status"] == "done"
    for path in ("data", "points", "diagram", "spec"):
        r = c.get(f"/v1/sweeps/{sid}/{path}")
        assert r.status_code == 410, (path, r.text)
        assert r.headers["content-type"].startswith("application/problem+json")
    assert c.delete(f"/v1/sweeps/{sid}", params={"purge": "true"}).status_code == 204


def test_critical_si_edge_values() -> None:
    from rsfapp.sweepdata import critical_si
    from rsfcore.units import PhysicalInputs

    phys = PhysicalInputs(**PH)
    vl = PH["V_load_m_s"]
    # missing (NaN), infinite, zero, e^800 beyond double range, |d| beyond rsfcore's
    # range, an ordinary jump (expected values from the definition V_load e^d)
    cs = np.array([math.nan, math.inf, 0.0, 800.0, 2e4, -3.0])
    got = critical_si(phys, "velocity-jump", cs)
    assert np.isnan(got[0]) and math.isinf(got[1]) and math.isinf(got[3]) and math.isinf(got[4])
    assert got[2] == vl and got[5] == pytest.approx(vl * math.exp(-3.0), rel=1e-15)
    lp = critical_si(phys, "load-point-jump", np.array([-0.5, 0.0, math.inf]))
    np.testing.assert_array_equal(lp, [vl * 0.5, vl, math.inf])


def _store_sweep(sid: str, eps: float) -> tuple[Any, Any]:
    """A 24-point sweep of 4 chunks created in the store with one chunk in flight (the
    other three pending, as when a sweep has more chunks than lanes): (store, spec)."""
    from rsfapp.config import get_settings
    from rsfapp.grid import expand
    from rsfapp.requests import SweepRequest
    from rsfapp.store import stores_for

    body = {
        "axes": [
            {"name": "kappa_ratio", "start": 1.2, "stop": 3.0, "n": 4},
            {"name": "ba", "start": 1.5, "stop": 6.0, "n": 6},
        ],
        "fixed": {"eps": eps, "vo": 1.0},
    }
    spec = expand(SweepRequest(**body), 10**6)
    st = stores_for(get_settings()).sweeps
    assert st.create(sid, spec, 6, "t", window=1).todo == [0]
    return st, spec


def _check_stored(st: Any, spec: Any, sid: str) -> None:
    """Every point stored once, bit-equal to rsfcore's batch kernel on the same points."""
    from rsfcore import batch

    blocks = list(st.blocks(sid))
    assert [(b.i0, b.i1) for b in blocks] == [(0, 6), (6, 12), (12, 18), (18, 24)]
    got = np.concatenate([b.arrays["critical_size"] for b in blocks])
    p = spec.params(0, 24)
    ref = batch.critical_points(p["ba"], p["kappa"], p["eps"], p["vo"], rtol=spec.rtol)
    assert got.tobytes() == ref.critical_size.tobytes()
    s = st.status(sid)
    assert s is not None and (s["status"], s["n_done"], s["n_failed"]) == ("done", 24, 0)


def test_a_task_chains_the_sweeps_pending_chunks(
    c: TestClient, monkeypatch: pytest.MonkeyPatch
) -> None:
    """With a chain budget, the task body computes its chunk and then the sweep's
    pending chunks, each claimed in the completion of the one before: one call for the
    four chunks, no message sent, every point stored once and equal to rsfcore's batch
    kernel.  Without a budget (direct calls) it computes one chunk and sends the next
    ones (up to the window; no worker registered here)."""
    import worker.tasks as tasks

    sent: list[tuple[str, int]] = []

    class Recorder:
        def __init__(self, *_a: Any) -> None:
            pass

        def send_chunk(self, sweep_id: str, idx: int) -> None:
            sent.append((sweep_id, idx))

    monkeypatch.setattr(tasks, "Queue", Recorder)
    st, spec = _store_sweep("chain-a", 0.3)
    out = tasks.run_chunk_body("chain-a", 0, chain_s=600.0)
    assert out == {"stored": 4, "chunks": 4, "points": 24} and sent == []
    _check_stored(st, spec, "chain-a")
    st2, _ = _store_sweep("chain-b", 0.4)
    assert tasks.run_chunk_body("chain-b", 0) == {"stored": 1, "chunks": 1, "points": 6}
    assert sent == [("chain-b", 1), ("chain-b", 2), ("chain-b", 3)]  # RSF_SWEEP_WINDOW 64
    s = st2.status("chain-b")
    assert s is not None and (s["status"], s["n_done"]) == ("running", 6)


def test_an_error_in_a_chained_chunk_is_retried_on_that_chunk(
    c: TestClient, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A chained chunk whose computation fails (here an OSError, an outage) is released
    and the task retried on *that* chunk, not on its message's chunk (done already):
    the retry then finishes the sweep, every point stored once."""
    import worker.tasks as tasks

    st, spec = _store_sweep("chain-err", 0.5)
    orig = tasks.compute_block
    failed: list[int] = []

    def flaky(sp: Any, i0: int, i1: int) -> Any:
        if i0 == 6 and not failed:
            failed.append(i0)
            raise OSError("injected: disk gone")
        return orig(sp, i0, i1)

    retries: list[dict[str, Any]] = []

    def fake_retry(**kw: Any) -> Exception:
        retries.append(kw)
        return RuntimeError("retry")

    monkeypatch.setattr(tasks, "compute_block", flaky)
    monkeypatch.setattr(tasks.run_chunk, "retry", fake_retry)
    with pytest.raises(RuntimeError, match="retry"):
        tasks.run_chunk("chain-err", 0)
    assert failed == [6] and len(retries) == 1
    assert retries[0]["args"] == ("chain-err", 1) and retries[0]["max_retries"] is None
    s = st.status("chain-err")
    assert s is not None and s["n_done"] == 6  # chunk 0 stored, chunk 1 released
    # chunks 1-3 were one work unit: 1 waits for its retry, 2 and 3 are given back
    assert [_status_of(st, "chain-err", i) for i in (1, 2, 3)] == ["queued", "pending", "pending"]
    assert tasks.run_chunk_body(*retries[0]["args"], chain_s=600.0)["chunks"] == 3
    _check_stored(st, spec, "chain-err")


def _status_of(st: Any, sid: str, idx: int) -> str:
    from sqlalchemy import and_, select

    from rsfapp.db.tables import chunks

    with st.db.read() as conn:
        return str(
            conn.execute(
                select(chunks.c.status).where(and_(chunks.c.sweep_id == sid, chunks.c.idx == idx))
            ).scalar()
        )


def test_chained_chunks_complete_in_work_units(
    c: TestClient, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A chaining task claims the sweep's next pending chunks as a work unit and
    completes the unit in one transaction: the message's chunk alone, then the other
    three together (each chunk takes far less than UNIT_SECONDS, set to 600 s); with units capped
    at two chunks, [0], [1, 2], [3].  Each chunk is still its own block, every point
    stored once and bit-equal to rsfcore's batch kernel."""
    import worker.tasks as tasks
    from rsfapp.store.sweeps import SweepStore

    runs: list[list[int]] = []
    orig = SweepStore.complete_run

    def spy(self: SweepStore, sid: str, run: Any, *a: Any, **kw: Any) -> Any:
        runs.append([i for i, _ in run])
        return orig(self, sid, run, *a, **kw)

    monkeypatch.setattr(SweepStore, "complete_run", spy)
    monkeypatch.setattr(tasks, "UNIT_SECONDS", 600.0)  # whatever the machine's load
    st, spec = _store_sweep("unit-a", 0.3)
    assert tasks.run_chunk_body("unit-a", 0, chain_s=600.0) == {
        "stored": 4,
        "chunks": 4,
        "points": 24,
    }
    assert runs == [[0], [1, 2, 3]]
    _check_stored(st, spec, "unit-a")
    runs.clear()
    monkeypatch.setattr(tasks, "UNIT_MAX_CHUNKS", 2)
    st, spec = _store_sweep("unit-b", 0.35)
    assert tasks.run_chunk_body("unit-b", 0, chain_s=600.0)["chunks"] == 4
    assert runs == [[0], [1, 2], [3]]
    _check_stored(st, spec, "unit-b")


def test_work_unit_size() -> None:
    """unit_chunks: about UNIT_SECONDS of work at the last unit's pace, no more than the
    chain time left (rounded up), capped by UNIT_MAX_CHUNKS and UNIT_MAX_BYTES, at least
    one chunk while the chain goes on, none after."""
    from worker.tasks import UNIT_MAX_BYTES, UNIT_MAX_CHUNKS, UNIT_SECONDS, unit_chunks

    assert unit_chunks(UNIT_SECONDS / 5, 1e3, 60.0) == 5
    assert unit_chunks(UNIT_SECONDS / 5, 1e3, UNIT_SECONDS / 5 * 1.5) == 2  # time left
    assert unit_chunks(UNIT_SECONDS * 3, 1e3, 60.0) == 1  # a slow chunk: a unit of one
    assert unit_chunks(1e-6, 1e3, 60.0) == UNIT_MAX_CHUNKS
    assert unit_chunks(1e-6, UNIT_MAX_BYTES / 3, 60.0) == 3  # big blocks
    assert unit_chunks(1e-6, 1e3, 0.0) == unit_chunks(1e-6, 1e3, -1.0) == 0
