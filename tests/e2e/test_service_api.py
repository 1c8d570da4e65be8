"""The HTTP API on a real uvicorn process: caching, 422 problem+json, every endpoint."""
from __future__ import annotations

import json
import math
import sqlite3
from pathlib import Path
from typing import Any

import httpx
import pytest

pytestmark = pytest.mark.timeout(120)


@pytest.fixture(scope="module")
def c(fs_stack) -> httpx.Client:
    srv, _ = fs_stack
    with httpx.Client(base_url=srv.url, timeout=60) as client:
        yield client


def db_rows(data: Path) -> dict[str, int]:
    con = sqlite3.connect(data / "cache.sqlite3", timeout=30)
    try:
        return {t: con.execute(f"SELECT count(*) FROM {t}").fetchone()[0]
                for t in ("results", "sweeps", "sweep_chunks", "sweep_points")}
    finally:
        con.close()


def test_health_and_openapi(c: httpx.Client) -> None:
    h = c.get("/health")
    assert h.status_code == 200 and h.json()["status"] == "ok"
    spec = c.get("/openapi.json").json()
    ba = spec["components"]["schemas"]["ClassifyRequest"]["properties"]["ba"]
    assert ba["exclusiveMinimum"] == 1 and ba["maximum"] == 1e6
    assert "Valid range: (1, 1e6]" in ba["description"]
    paths = set(spec["paths"])
    assert {"/v1/classify", "/v1/trajectory", "/v1/critical", "/v1/analytic/u",
            "/v1/boundaries", "/v1/stiffness", "/v1/sweeps", "/v1/sweeps/{sweep_id}",
            "/v1/sweeps/{sweep_id}/points", "/v1/cache/stats", "/health"} <= paths


def test_cache_hit_on_repeat(c: httpx.Client, fs_stack) -> None:
    body = {"ba": 3.0, "kappa": 1.7, "eps": 0.3, "vo": 1.0, "size": 2.5}
    before = c.get("/v1/cache/stats").json()
    r1 = c.post("/v1/classify", json=body)
    assert r1.status_code == 200, r1.text
    assert r1.headers["x-cache"] == "miss" and r1.json()["cached"] is False
    r2 = c.post("/v1/classify", json={**body, "kappa": 1.7e0})  # same canonical request
    assert r2.headers["x-cache"] == "hit" and r2.json()["cached"] is True
    a, b = r1.json(), r2.json()
    for d in (a, b):
        d.pop("cached")
    assert a == b and a["outcome"] in ("stable", "unstable")
    after = c.get("/v1/cache/stats").json()
    assert after["entries"] == before["entries"] + 1
    assert after["hits"] == before["hits"] + 1
    # A different tolerance is a different question.
    r3 = c.post("/v1/classify", json={**body, "rtol": 1e-8})
    assert r3.headers["x-cache"] == "miss"
    # The answer is rsfcore's.
    from rsfcore import trajectory
    from rsfcore.params import Params
    ref = trajectory.classify(Params(3.0, 1.7, 0.3, 1.0), "velocity-jump", 2.5).to_dict()
    assert a["outcome"] == ref["outcome"] and a["certificate"] == ref["certificate"]


BAD: list[tuple[str, str, Any, str, str]] = [
    ("post", "/v1/classify", {"ba": 0.5}, "ba", "(1, 1e6]"),
    ("post", "/v1/classify", {"eps": 1.5}, "eps", "[0, 1]"),
    ("post", "/v1/classify", {"kappa": -1}, "kappa", "[0, 1e6]"),
    ("post", "/v1/classify", {"rtol": 0.5}, "rtol", "[1e-13, 1e-3]"),
    ("post", "/v1/classify", {"perturbation": "kick"}, "perturbation", "velocity-jump"),
    ("post", "/v1/classify", {"size": "big"}, "size", "[-1e3, 1e3]"),
    ("post", "/v1/trajectory", {"n_points": 1}, "n_points", "[2, 10000]"),
    ("post", "/v1/trajectory", {"physical": {"a": 0.01, "Dc": -1, "sigma": 1e6,
                                             "V_star": 1e-6}}, "physical.Dc", "(0, 1e3] m"),
    ("post", "/v1/critical", {"vo": -1}, "vo", "0 or (0, 1e300]"),
    ("post", "/v1/stiffness", {"case": "F"}, "case", "'A'..'E'"),
    ("post", "/v1/stiffness", {"case": "C", "physical": {"mu": 3e10, "sigma": 1e8,
                                                         "a": 0.01, "b": 0.015, "Dc": 1e-4}},
     "h", "depth"),
    ("post", "/v1/stiffness", {"case": "B", "physical": {"mu": 3e10, "sigma": 1e8,
                                                         "a": 0.02, "b": 0.015, "Dc": 1e-4}},
     "b", ""),
    ("post", "/v1/analytic/u", {"grid": {"n_phi": 0}}, "grid.n_phi", "[1, 500]"),
    ("get", "/v1/boundaries?ba=1", None, "ba", "(1, 1e6]"),
    ("post", "/v1/sweeps", {"x": {"name": "ba", "values": [2.0, 0.5]},
                            "y": {"name": "eps", "values": [0.1]}}, "x.values[1]", "(1, 1e6]"),
    ("post", "/v1/sweeps", {"x": {"name": "eps", "start": 0, "stop": 2, "n": 3},
                            "y": {"name": "ba", "values": [2]}}, "x.stop", "[0, 1]"),
    ("post", "/v1/sweeps", {"x": {"name": "eps", "values": [0.1]},
                            "y": {"name": "eps", "values": [0.2]}}, "y.name", "kappa_ratio"),
    ("post", "/v1/sweeps", {"x": {"name": "eps", "start": 0, "stop": 1, "n": 1000},
                            "y": {"name": "ba", "start": 2, "stop": 3, "n": 1000}},
     "y.values", "<= 40000 points"),
    ("post", "/v1/sweeps", {"x": {"name": "kappa_ratio", "values": [1e6]},
                            "y": {"name": "ba", "values": [3.0]}}, "x.values",
     "kappa_ratio*(ba-1) <= 1e6"),
    ("get", "/v1/sweeps/not-an-id", None, "sweep_id", None),
    ("get", "/v1/sweeps/" + "a" * 32 + "/points?limit=0", None, "limit", None),
]


@pytest.mark.parametrize("method,path,body,field,valid", BAD,
                         ids=[f"{b[1]}:{b[3]}" for b in BAD])
def test_bad_input_is_422_problem_json_and_writes_nothing(
        c: httpx.Client, fs_stack, method: str, path: str, body: Any, field: str,
        valid: str | None) -> None:
    data = fs_stack[1]
    c.get("/health")  # make sure the database exists
    before = db_rows(data)
    r = c.request(method.upper(), path, json=body)
    assert r.status_code == 422, r.text
    assert r.headers["content-type"].startswith("application/problem+json")
    p = r.json()
    assert p["status"] == 422 and p["title"] and p["detail"]
    assert p["field"] == field, p
    if valid:
        assert valid in (p["valid"] or "") + p["detail"], p
    assert db_rows(data) == before


def test_malformed_json_and_nan_are_422(c: httpx.Client) -> None:
    for raw in (b"{not json", b'{"ba": NaN}', b'{"ba": Infinity}', b"[]", b'{"zz": 1}'):
        r = c.post("/v1/classify", content=raw, headers={"content-type": "application/json"})
        assert r.status_code == 422, (raw, r.text)
        assert r.headers["content-type"].startswith("application/problem+json")
        assert r.json()["field"]


def test_trajectory_downsampled_with_physical_units(c: httpx.Client) -> None:
    body = {"ba": 2.0, "kappa": 0.8, "eps": 0.5, "size": 0.5, "n_points": 57,
            "physical": {"a": 0.01, "Dc": 1e-4, "sigma": 1e8, "V_star": 1e-6}}
    r = c.post("/v1/trajectory", json=body)
    assert r.status_code == 200, r.text
    tr = r.json()["trajectory"]
    assert 2 <= len(tr["T"]) == len(tr["phi"]) <= 57  # ends at the decision
    si = [k for k in tr if k not in ("T", "phi", "psi", "ln_theta", "slip", "load_point")]
    assert si, "SI columns expected with physical parameters"


def test_stiffness_and_critical_dimension(c: httpx.Client) -> None:
    r = c.post("/v1/stiffness", json={"case": "A"})
    assert r.status_code == 200 and math.isclose(r.json()["eigenvalue"], 2 * math.pi)
    phys = {"mu": 3e10, "nu": 0.25, "mode_of_slip": "II", "sigma": 1e8, "a": 0.01,
            "b": 0.015, "Dc": 1e-4}
    r = c.post("/v1/stiffness", json={"case": "B", "physical": phys})
    body = r.json()
    assert r.status_code == 200 and body["critical_dimension_name"] == "L_c"
    from rsfcore.stiffness import critical_dimension
    assert math.isclose(body["critical_dimension_m"], critical_dimension("B", **phys))


def test_analytic_points_and_grid(c: httpx.Client) -> None:
    from rsfcore.analytic import U_kcrit, U_vo0
    r = c.post("/v1/analytic/u", json={"points": [{"phi": 0.5, "psi": 0.2},
                                                  {"phi": -1, "psi": 0.0}], "eps": 0.3})
    assert r.status_code == 200, r.text
    assert r.json()["U"] == pytest.approx(list(U_kcrit([0.5, -1], [0.2, 0.0], 2.0, 0.3)))
    r = c.post("/v1/analytic/u", json={"function": "vo0", "kappa": 0.5,
                                       "grid": {"n_phi": 3, "n_psi": 4}})
    g = r.json()
    assert r.status_code == 200 and g["shape"] == [3, 4] and len(g["U"]) == 3
    assert g["U"][1][2] == pytest.approx(float(U_vo0(g["phi"][1], g["psi"][2], 2.0, 0.5, 0.0)))


def test_boundaries_get_and_post(c: httpx.Client) -> None:
    pytest.importorskip("rsfcore.boundaries")
    r1 = c.get("/v1/boundaries", params={"ba": 2.0, "kappa": 0.5, "eps": 0.5})
    r2 = c.post("/v1/boundaries", json={"ba": 2.0, "kappa": 0.5, "eps": 0.5, "phi": [1.0]})
    assert r1.status_code == 200 and r2.status_code == 200, (r1.text, r2.text)
    assert r1.json()["kappa_crit"] == pytest.approx(1.0)
    assert len(r2.json()["acceleration_line"]) == 1


def test_critical_same_fields_as_cli(c: httpx.Client) -> None:
    pytest.importorskip("rsfcore.critical")
    r = c.post("/v1/critical", json={"ba": 2.0, "kappa": 0.5, "eps": 0.5, "vo": 1.0,
                                     "perturbation": "velocity-jump"})
    assert r.status_code == 200, r.text
    d = r.json()
    assert {"kind", "critical_size", "rel_accuracy", "method"} <= set(d)
    assert d["kind"] in ("zero", "finite", "infinite")


def test_unknown_sweep_is_404_problem(c: httpx.Client) -> None:
    for m in ("GET", "DELETE"):
        r = c.request(m, "/v1/sweeps/" + "f" * 32)
        assert r.status_code == 404
        assert r.headers["content-type"].startswith("application/problem+json")
    r = c.get("/v1/nowhere")
    assert r.status_code == 404 and json.loads(r.text)["status"] == 404


def test_long_query_is_deferred_with_location(tmp_path: Path, procs: list) -> None:
    """A query exceeding the inline budget answers 202 + Location, then the result."""
    from tests.conftest import Server
    procs.append(srv := Server(tmp_path, RSF_INLINE_BUDGET_S="0.001"))
    with httpx.Client(base_url=srv.url, timeout=60) as c:
        body = {"ba": 2.0, "kappa": 1.2, "eps": 0.4, "size": 2.0, "n_points": 10000,
                "physical": {"a": 0.01, "Dc": 1e-4, "sigma": 1e8, "V_star": 1e-6}}
        r = c.post("/v1/trajectory", json=body)
        assert r.status_code == 202, r.text[:300]
        loc = r.headers["location"]
        assert loc == "/v1/results/" + r.json()["cache_key"]
        import time
        deadline = time.monotonic() + 30
        while (g := c.get(loc)).status_code == 202 and time.monotonic() < deadline:
            time.sleep(0.05)
        assert g.status_code == 200 and g.headers["x-cache"] == "hit"
        assert 0 < len(g.json()["trajectory"]["T"]) <= 10000
        assert c.post("/v1/trajectory", json=body).headers["x-cache"] == "hit"
        assert c.get("/v1/results/" + "0" * 64).status_code == 404
