"""Sweeps with the perturbation size in SI (issue 15, item 1) and the SI columns of the
CSV, points and JSON outputs (in process: TestClient, chunks computed by the worker's task
body).

Every expected size here is converted by hand from its definition (d = ln(V_new/V_before),
dv = V_new/V_load - 1, `eq: characteristic scales`), never by rsfcore.units, and the
dimensionless groups of the machine likewise; the SI sweep must then equal the
dimensionless sweep built from those hand-converted numbers.
"""

from __future__ import annotations

import csv
import io
import math
from typing import Any

import numpy as np
import pytest
from fastapi.testclient import TestClient

from tests.api.test_sweeps_api import PH, rows, run_all, submit

pytestmark = pytest.mark.timeout(300)

VL = PH["V_load_m_s"]  # V_load > 0, so V_before = V_load (steady sliding at the load rate)
#: The machine's dimensionless groups, written out by hand (not by rsfcore.units).
DIMLESS = {
    "ba": PH["b"] / PH["a"],
    "kappa": PH["k_Pa_per_m"] * PH["Dc_m"] / (PH["a"] * PH["sigma_Pa"]),
    "vo": PH["V_load_m_s"] / PH["V_star_m_s"],
}
EPS = [0.0, 0.4]


def _nc(c: TestClient, sid: str) -> Any:
    import xarray as xr

    r = c.get(f"/v1/sweeps/{sid}/data")
    assert r.status_code == 200, r.text
    return xr.open_dataset(io.BytesIO(r.content), engine="h5netcdf")


def _both(c: TestClient, si_body: dict[str, Any], dl_body: dict[str, Any]) -> tuple[Any, Any]:
    """Submit and compute the SI sweep and its dimensionless twin; their NetCDF data."""
    si, dl = submit(c, si_body), submit(c, dl_body)
    assert si["id"] != dl["id"]
    for sid in (si["id"], dl["id"]):
        run_all(c, sid)
    return _nc(c, si["id"]), _nc(c, dl["id"])


def _same_results(a: Any, b: Any) -> None:
    # 1e-12: the SI sweep's groups and sizes equal the hand-converted ones to a few ulp
    # (one division or log each), and the critical size is smooth in them; outcomes are
    # chosen far from the critical size, so they cannot flip
    np.testing.assert_allclose(a["critical_size"].values, b["critical_size"].values, rtol=1e-12)
    for v in ("kind", "outcome", "failed"):
        np.testing.assert_array_equal(a[v].values, b[v].values)
    assert (a["failed"].values == 0).all() and (a["outcome"].values >= 0).all()
    assert not a["outcome_uncertain"].values.any()


@pytest.mark.parametrize(
    ("pert", "si_field", "value", "size"),
    [
        # velocity jump by a factor 20 and to a slip rate of 1e-4 m/s: d = ln(V_new/V_load)
        ("velocity-jump", "factor", 20.0, math.log(20.0)),
        ("velocity-jump", "new_slip_rate_m_s", 1e-4, math.log(1e-4 / VL)),
        # load-point jump by a factor 3 and to 1.2e-5 m/s: dv = V_new/V_load - 1
        ("load-point-jump", "factor", 3.0, 3.0 - 1.0),
        ("load-point-jump", "new_load_point_velocity_m_s", 1.2e-5, 1.2e-5 / VL - 1.0),
    ],
)
def test_fixed_si_size_equals_dimensionless_sweep(
    c: TestClient, pert: str, si_field: str, value: float, size: float
) -> None:
    eps = {"name": "eps", "values": EPS}
    a, b = _both(
        c,
        {"axes": [eps], "fixed": {"physical": PH, si_field: value}, "perturbation": pert},
        {"axes": [eps], "fixed": {**DIMLESS, "size": size}, "perturbation": pert},
    )
    # the stored conversion is the hand one to a few ulp (4e-16 covers 2 roundings)
    assert a.attrs["fixed_size"] == pytest.approx(size, rel=4e-16)
    assert a.attrs[f"fixed_{si_field}"] == value and a.attrs["output"] == "outcome"
    _same_results(a, b)


def test_swept_si_slip_rate_axis_equals_dimensionless_size_axis(c: TestClient) -> None:
    """Velocity jump to slip rates below and above V_load (negative and positive d),
    explicit values; and the log-spaced start/stop form of the same axis."""
    v_new = [0.5 * VL, 3.0 * VL, 1e-3]
    d = [math.log(v / VL) for v in v_new]
    eps = {"name": "eps", "values": EPS}
    a, b = _both(
        c,
        {
            "axes": [{"name": "new_slip_rate_m_s", "values": v_new}, eps],
            "fixed": {"physical": PH},
        },
        {"axes": [{"name": "size", "values": d}, eps], "fixed": DIMLESS},
    )
    assert a["critical_size"].dims == ("new_slip_rate_m_s", "eps")
    assert a["new_slip_rate_m_s"].values.tolist() == v_new  # coordinates stay in SI
    # the converted size of each coordinate value, next to it (few ulp: one log)
    np.testing.assert_allclose(a["size"].values, d, rtol=4e-16)
    assert a["size"].dims == ("new_slip_rate_m_s",)
    _same_results(a, b)
    # start/stop/log form: V_k = V_0 (V_1/V_0)^(k/(n-1)) <-> d_k evenly spaced in d
    st = submit(
        c,
        {
            "axes": [
                {"name": "new_slip_rate_m_s", "start": 1e-7, "stop": 1e-3, "n": 5, "log": True}
            ],
            "fixed": {"physical": PH, "eps": 0.4},
        },
    )
    run_all(c, st["id"])
    ds = _nc(c, st["id"])
    d_lin = np.linspace(math.log(1e-7 / VL), math.log(1e-3 / VL), 5)
    # 1e-13 absolute: the axis value exp(ln V_0 + t ln(V_1/V_0)) rounds once more than
    # the linear spacing in d (|d| <= 9.3, so a few ulp of ln V ~ 16 are ~1e-14)
    np.testing.assert_allclose(ds["size"].values, d_lin, rtol=0, atol=1e-13)


def test_scattered_si_load_point_velocities(c: TestClient) -> None:
    """Scattered points of (new load-point velocity, eps) equal the dimensionless points."""
    v_new = [1.5 * VL, 0.2 * VL, 40.0 * VL, 1.5 * VL]
    eps = [0.1, 0.3, 0.0, 0.7]
    dv = [v / VL - 1.0 for v in v_new]
    a, b = _both(
        c,
        {
            "points": {"new_load_point_velocity_m_s": v_new, "eps": eps},
            "fixed": {"physical": PH},
            "perturbation": "load-point-jump",
        },
        {
            "points": {"size": dv, "eps": eps},
            "fixed": DIMLESS,
            "perturbation": "load-point-jump",
        },
    )
    np.testing.assert_allclose(a["size"].values, dv, rtol=4e-16)
    _same_results(a, b)


def _csv(c: TestClient, sid: str) -> list[dict[str, str]]:
    r = c.get(f"/v1/sweeps/{sid}/data", params={"format": "csv"})
    assert r.status_code == 200
    return list(csv.DictReader(io.StringIO(r.text)))


def _points(c: TestClient, sid: str) -> list[dict[str, Any]]:
    r = c.get(f"/v1/sweeps/{sid}/points", params={"limit": 10_000})
    assert r.status_code == 200
    pts: list[dict[str, Any]] = r.json()["points"]
    return pts


@pytest.mark.parametrize("pert", ["velocity-jump", "load-point-jump"])
def test_csv_points_json_carry_the_si_columns_of_netcdf(c: TestClient, pert: str) -> None:
    """Critical sizes of an SI sweep (eps = 1: the aging law, infinite for a velocity jump
    here): the CSV column, the points field and the JSON data equal the NetCDF variable
    (the same conversion, printed with repr: bit for bit), which equals V_load e^d or
    V_load (1 + dv) computed here."""
    eps = [0.0, 0.4, 1.0]
    st = submit(
        c,
        {"axes": [{"name": "eps", "values": eps}], "fixed": {"physical": PH}, "perturbation": pert},
    )
    run_all(c, st["id"])
    ds = _nc(c, st["id"])
    name = (
        "critical_slip_rate_m_s" if pert == "velocity-jump" else "critical_load_point_velocity_m_s"
    )
    cs = ds["critical_size"].values
    want = VL * np.exp(cs) if pert == "velocity-jump" else VL * (1.0 + cs)
    nc = ds[name].values
    # 1e-14: V_load e^d by numpy's exp here vs math.exp in rsfcore.units (1 ulp each)
    np.testing.assert_allclose(nc, want, rtol=1e-14)
    table = _csv(c, st["id"])
    header = list(table[0])
    assert header == [
        "idx",
        "eps",
        "kind",
        "critical_size",
        name,
        "outcome",
        "rel_accuracy",
        "method",
        "failed",
        "error",
    ]
    assert [float(r[name]) for r in table] == nc.tolist()  # 'inf' where infinite
    pts = _points(c, st["id"])
    for p, v in zip(pts, nc.tolist(), strict=True):
        assert p[name] == (v if math.isfinite(v) else None)
        assert list(p).index(name) == list(p).index("critical_size") + 1
    js = c.get(f"/v1/sweeps/{st['id']}/data", params={"format": "json"}).json()
    assert js["data"][name] == [v if math.isfinite(v) else None for v in nc.tolist()]
    if pert == "velocity-jump":
        assert math.isinf(nc[2]) and pts[2][name] is None and table[2][name] == "inf"


def test_swept_si_size_columns_and_missing_points(c: TestClient) -> None:
    """A factor axis: CSV and points carry the dimensionless size (as NetCDF) and the SI
    critical size; points not computed yet have empty / null SI results."""
    f = [0.5, 4.0]
    st = submit(
        c,
        {
            "axes": [{"name": "factor", "values": f}, {"name": "eps", "values": [0.2, 0.6]}],
            "fixed": {"physical": PH},
            "chunk_points": 2,
        },
    )
    from worker.tasks import run_chunk_body

    run_chunk_body(st["id"], 0)  # only the first chunk: points 0, 1 (factor 0.5)
    table = _csv(c, st["id"])
    assert list(table[0])[:5] == ["idx", "factor", "eps", "size", "kind"]
    assert [float(r["size"]) for r in table] == [math.log(x) for x in f for _ in (0, 1)]
    assert table[0]["critical_slip_rate_m_s"] != "" and table[3]["critical_slip_rate_m_s"] == ""
    pts = _points(c, st["id"])
    assert [p["size"] for p in pts] == [math.log(x) for x in f for _ in (0, 1)]
    assert pts[0]["critical_slip_rate_m_s"] == pytest.approx(
        VL * math.exp(pts[0]["critical_size"]), rel=1e-14
    )
    assert pts[3]["computed"] is False and pts[3]["critical_slip_rate_m_s"] is None
    run_all(c, st["id"])
    ds = _nc(c, st["id"])
    assert ds["size"].values.tolist() == [math.log(x) for x in f]
    np.testing.assert_array_equal(
        ds["critical_slip_rate_m_s"].values.ravel(),
        [float(r["critical_slip_rate_m_s"]) for r in _csv(c, st["id"])],
    )


def test_dimensionless_sweep_outputs_unchanged(c: TestClient) -> None:
    st = submit(c, {"axes": [{"name": "eps", "values": [0.3]}], "fixed": {"size": 1.0}})
    run_all(c, st["id"])
    assert list(_csv(c, st["id"])[0]) == [
        "idx",
        "eps",
        "kind",
        "critical_size",
        "outcome",
        "rel_accuracy",
        "method",
        "failed",
        "error",
    ]
    p = _points(c, st["id"])[0]
    assert "size" not in p and not any(k.endswith("_m_s") for k in p)
    js = c.get(f"/v1/sweeps/{st['id']}/data", params={"format": "json"}).json()
    assert not any(k.endswith("_m_s") for k in js["data"])


_EPS = {"name": "eps", "values": [0.1]}
BAD_SI: list[tuple[dict[str, Any], str, str]] = [
    # SI size without the SI machine
    ({"axes": [_EPS], "fixed": {"factor": 2.0}}, "fixed.factor", "fixed.physical"),
    ({"axes": [{"name": "factor", "values": [2.0]}]}, "axes[0].name", "fixed.physical"),
    ({"points": {"new_slip_rate_m_s": [1e-5]}}, "points.new_slip_rate_m_s", "fixed.physical"),
    # the size stated twice
    ({"axes": [_EPS], "fixed": {"physical": PH, "factor": 2.0, "size": 1.0}}, "fixed.size", "one"),
    (
        {"axes": [_EPS], "fixed": {"physical": PH, "factor": 2.0, "new_slip_rate_m_s": 1e-5}},
        "fixed.new_slip_rate_m_s",
        "one statement",
    ),
    (
        {"axes": [{"name": "size", "values": [1.0]}], "fixed": {"physical": PH, "factor": 2.0}},
        "fixed.factor",
        "one statement",
    ),
    (
        {"axes": [{"name": "factor", "values": [2.0]}], "fixed": {"physical": PH, "size": 1.0}},
        "fixed.size",
        "one statement",
    ),
    (
        {
            "axes": [
                {"name": "new_slip_rate_m_s", "values": [1e-5]},
                {"name": "size", "values": [1.0]},
            ],
            "fixed": {"physical": PH},
        },
        "axes[0].name",
        "one statement",
    ),
    # the unit of the other perturbation kind
    (
        {"axes": [_EPS], "fixed": {"physical": PH, "new_load_point_velocity_m_s": 1e-5}},
        "fixed.new_load_point_velocity_m_s",
        "factor or new_slip_rate_m_s",
    ),
    (
        {
            "axes": [{"name": "new_slip_rate_m_s", "values": [1e-5]}],
            "fixed": {"physical": PH},
            "perturbation": "load-point-jump",
        },
        "axes[0].name",
        "factor or new_load_point_velocity_m_s",
    ),
    # values out of range: not > 0 (request model), a load-point factor whose dv rounds
    # to -1 or exceeds the sweep's size range 1e4
    ({"axes": [_EPS], "fixed": {"physical": PH, "factor": 0.0}}, "fixed.factor", "(0, 1e300]"),
    (
        {
            "axes": [{"name": "factor", "values": [2.0, 1e5]}],
            "fixed": {"physical": PH},
            "perturbation": "load-point-jump",
        },
        "axes[0].values[1]",
        "dv = V_new/V_load - 1",
    ),
    (
        {
            "points": {"factor": [2.0, 3.0, 1e-17]},
            "fixed": {"physical": PH},
            "perturbation": "load-point-jump",
        },
        "points.factor[2]",
        "(-1, 1e4]",
    ),
    (
        {
            "axes": [{"name": "new_load_point_velocity_m_s", "start": 1e-6, "stop": 1e300, "n": 3}],
            "fixed": {"physical": PH},
            "perturbation": "load-point-jump",
        },
        "axes[0].stop",
        "m/s",
    ),
]


@pytest.mark.parametrize(("body", "field", "valid"), BAD_SI, ids=[b[1] for b in BAD_SI])
def test_bad_si_size_is_422_naming_the_field(
    c: TestClient, api_stack: Any, body: dict[str, Any], field: str, valid: str
) -> None:
    c.get("/health")
    before = rows(api_stack[1])
    r = c.post("/v1/sweeps", json=body)
    assert r.status_code == 422, r.text
    assert r.headers["content-type"].startswith("application/problem+json")
    p = r.json()
    assert p["field"] == field, p
    assert valid in (p.get("valid") or "") + p["detail"], p
    assert rows(api_stack[1]) == before  # nothing written


def test_openapi_states_the_si_size_fields() -> None:
    """The schema says the SI size fields need fixed.physical (JSON Schema rule) and the
    axis names include them; so the contract test can generate only valid combinations."""
    from rsfapp.requests import SweepFixed, SweepRequest

    fx = SweepFixed.model_json_schema()
    for f in ("factor", "new_slip_rate_m_s", "new_load_point_velocity_m_s"):
        assert "needs fixed.physical" in fx["properties"][f]["description"]
    rules = [r["anyOf"] for r in fx["allOf"]]
    assert len(rules) == 3 and all(r[1]["required"] == ["physical"] for r in rules)
    names = SweepRequest.model_json_schema()["$defs"]["SweepAxis"]["properties"]["name"]["enum"]
    assert {"factor", "new_slip_rate_m_s", "new_load_point_velocity_m_s", "size"} <= set(names)
