"""The HTTP API in process (TestClient, real SQLite): caching, 422 problem+json, every
endpoint."""

from __future__ import annotations

import json
import math
import sqlite3
from pathlib import Path
from typing import Any

import pytest
from fastapi.testclient import TestClient

from rsfcore import limits

pytestmark = pytest.mark.timeout(120)


def db_rows(data: Path) -> dict[str, int]:
    con = sqlite3.connect(data / "cache.sqlite3", timeout=30)
    try:
        return {
            t: con.execute(f"SELECT count(*) FROM {t}").fetchone()[0]
            for t in ("results", "sweeps", "sweep_chunks", "sweep_points")
        }
    finally:
        con.close()


def test_health_and_openapi(c: TestClient) -> None:
    h = c.get("/health")
    assert h.status_code == 200 and h.json()["status"] == "ok"
    spec = c.get("/openapi.json").json()
    ba = spec["components"]["schemas"]["ClassifyRequest"]["properties"]["ba"]
    assert ba["exclusiveMinimum"] == 1 and ba["maximum"] == 1e6
    assert "Valid range: (1, 1e6]" in ba["description"]
    paths = set(spec["paths"])
    assert {
        "/v1/classify",
        "/v1/trajectory",
        "/v1/critical",
        "/v1/analytic/u",
        "/v1/boundaries",
        "/v1/stiffness",
        "/v1/sweeps",
        "/v1/sweeps/{sweep_id}",
        "/v1/sweeps/{sweep_id}/points",
        "/v1/cache/stats",
        "/health",
    } <= paths


def test_cache_hit_on_repeat(c: TestClient, api_stack) -> None:
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
    ("post", "/v1/classify", {"size": "big"}, "size", limits.VELOCITY_JUMP_SIZE.text),
    ("post", "/v1/trajectory", {"n_points": 1}, "n_points", "[2, 10000]"),
    (
        "post",
        "/v1/trajectory",
        {"physical": {"a": 0.01, "Dc": -1, "sigma": 1e6, "V_star": 1e-6}},
        "scales.Dc",
        "(0, 1e3] m",
    ),
    ("post", "/v1/critical", {"vo": -1}, "vo", limits.VO.text),
    ("post", "/v1/stiffness", {"case": "F"}, "case", "'A'..'E'"),
    (
        "post",
        "/v1/stiffness",
        {"case": "C", "physical": {"mu": 3e10, "sigma": 1e8, "a": 0.01, "b": 0.015, "Dc": 1e-4}},
        "h",
        "depth",
    ),
    (
        "post",
        "/v1/stiffness",
        {"case": "B", "physical": {"mu": 3e10, "sigma": 1e8, "a": 0.02, "b": 0.015, "Dc": 1e-4}},
        "b",
        "",
    ),
    ("post", "/v1/analytic/u", {"grid": {"n_phi": 0}}, "grid.n_phi", "[1, 500]"),
    ("get", "/v1/boundaries?ba=1", None, "ba", "(1, 1e6]"),
    (
        "post",
        "/v1/sweeps",
        {"x": {"name": "ba", "values": [2.0, 0.5]}, "y": {"name": "eps", "values": [0.1]}},
        "x.values[1]",
        "(1, 1e6]",
    ),
    (
        "post",
        "/v1/sweeps",
        {"x": {"name": "eps", "start": 0, "stop": 2, "n": 3}, "y": {"name": "ba", "values": [2]}},
        "x.stop",
        "[0, 1]",
    ),
    (
        "post",
        "/v1/sweeps",
        {"x": {"name": "eps", "values": [0.1]}, "y": {"name": "eps", "values": [0.2]}},
        "y.name",
        "kappa_ratio",
    ),
    (
        "post",
        "/v1/sweeps",
        {
            "x": {"name": "eps", "start": 0, "stop": 1, "n": 100_000},
            "y": {"name": "ba", "start": 2, "stop": 3, "n": 10_000},
        },
        "y.values",
        "<= 100000000 points",
    ),
    (
        "post",
        "/v1/sweeps",
        {"x": {"name": "kappa_ratio", "values": [1e6]}, "y": {"name": "ba", "values": [3.0]}},
        "x.values",
        "kappa_ratio*(ba-1) <= 1e6",
    ),
    ("get", "/v1/sweeps/not-an-id", None, "sweep_id", None),
    ("get", "/v1/sweeps/" + "a" * 32 + "/points?limit=0", None, "limit", None),
]


@pytest.mark.parametrize("method,path,body,field,valid", BAD, ids=[f"{b[1]}:{b[3]}" for b in BAD])
def test_bad_input_is_422_problem_json_and_writes_nothing(
    c: TestClient, api_stack, method: str, path: str, body: Any, field: str, valid: str | None
) -> None:
    data = api_stack[1]
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


def test_malformed_json_and_nan_are_422(c: TestClient) -> None:
    for raw in (b"{not json", b'{"ba": NaN}', b'{"ba": Infinity}', b"[]", b'{"zz": 1}'):
        r = c.post("/v1/classify", content=raw, headers={"content-type": "application/json"})
        assert r.status_code == 422, (raw, r.text)
        assert r.headers["content-type"].startswith("application/problem+json")
        assert r.json()["field"]


def test_trajectory_downsampled_with_physical_units(c: TestClient) -> None:
    body = {
        "ba": 2.0,
        "kappa": 0.8,
        "eps": 0.5,
        "size": 0.5,
        "n_points": 57,
        "physical": {"a": 0.01, "Dc": 1e-4, "sigma": 1e8, "V_star": 1e-6},
    }
    r = c.post("/v1/trajectory", json=body)
    assert r.status_code == 200, r.text
    tr = r.json()["trajectory"]
    assert 2 <= len(tr["T"]) == len(tr["phi"]) <= 57  # ends at the decision
    si = [k for k in tr if k not in ("T", "phi", "psi", "ln_theta", "slip", "load_point")]
    assert si, "SI columns expected with physical parameters"


def test_stiffness_and_critical_dimension(c: TestClient) -> None:
    r = c.post("/v1/stiffness", json={"case": "A"})
    assert r.status_code == 200 and math.isclose(r.json()["eigenvalue"], 2 * math.pi)
    phys = {
        "mu": 3e10,
        "nu": 0.25,
        "mode_of_slip": "II",
        "sigma": 1e8,
        "a": 0.01,
        "b": 0.015,
        "Dc": 1e-4,
    }
    r = c.post("/v1/stiffness", json={"case": "B", "physical": phys})
    body = r.json()
    assert r.status_code == 200 and body["critical_dimension_name"] == "L_c"
    from rsfcore.stiffness import critical_dimension

    assert math.isclose(body["critical_dimension_m"], critical_dimension("B", **phys))


def test_analytic_points_and_grid(c: TestClient) -> None:
    from rsfcore.analytic import U_kcrit, U_vo0

    r = c.post(
        "/v1/analytic/u",
        json={"points": [{"phi": 0.5, "psi": 0.2}, {"phi": -1, "psi": 0.0}], "eps": 0.3},
    )
    assert r.status_code == 200, r.text
    assert r.json()["U"] == pytest.approx(list(U_kcrit([0.5, -1], [0.2, 0.0], 2.0, 0.3)))
    r = c.post(
        "/v1/analytic/u", json={"function": "vo0", "kappa": 0.5, "grid": {"n_phi": 3, "n_psi": 4}}
    )
    g = r.json()
    assert r.status_code == 200 and g["shape"] == [3, 4] and len(g["U"]) == 3
    # eps omitted: the one default of every door (rsfcore.limits.EPS, 0.25), echoed
    assert g["params"] == {"ba": 2.0, "kappa": 0.5, "eps": 0.25, "vo": 1.0}
    assert g["U"][1][2] == pytest.approx(float(U_vo0(g["phi"][1], g["psi"][2], 2.0, 0.5, 0.25)))


def test_boundaries_get_and_post(c: TestClient) -> None:
    pytest.importorskip("rsfcore.boundaries")
    r1 = c.get("/v1/boundaries", params={"ba": 2.0, "kappa": 0.5, "eps": 0.5})
    r2 = c.post("/v1/boundaries", json={"ba": 2.0, "kappa": 0.5, "eps": 0.5, "phi": [1.0]})
    assert r1.status_code == 200 and r2.status_code == 200, (r1.text, r2.text)
    assert r1.json()["kappa_crit"] == pytest.approx(1.0)
    assert len(r2.json()["acceleration_line"]) == 1


def test_critical_same_fields_as_cli(c: TestClient) -> None:
    pytest.importorskip("rsfcore.critical")
    r = c.post(
        "/v1/critical",
        json={"ba": 2.0, "kappa": 0.5, "eps": 0.5, "vo": 1.0, "perturbation": "velocity-jump"},
    )
    assert r.status_code == 200, r.text
    d = r.json()
    assert {"kind", "critical_size", "rel_accuracy", "method"} <= set(d)
    assert d["kind"] in ("zero", "finite", "infinite")


def test_unknown_sweep_is_404_problem(c: TestClient) -> None:
    for m in ("GET", "DELETE"):
        r = c.request(m, "/v1/sweeps/" + "f" * 32)
        assert r.status_code == 404
        assert r.headers["content-type"].startswith("application/problem+json")
    r = c.get("/v1/nowhere")
    assert r.status_code == 404 and json.loads(r.text)["status"] == 404


def test_docs_pages_use_local_assets_only(c: TestClient) -> None:
    """/docs and /redoc must work on an offline lab network: no CDN URL in the pages, and
    every asset they reference is served by the app itself."""
    for page in ("/docs", "/redoc"):
        html = c.get(page)
        assert html.status_code == 200, page
        text = html.text
        assert "cdn." not in text and "googleapis" not in text, page
        import re

        refs = re.findall(r'(?:src|href)="(/docs-assets/[^"]+)"', text)
        assert refs, f"{page} references no local asset"
        for ref in refs:
            r = c.get(ref)
            assert r.status_code == 200 and len(r.content) > 100, ref


@pytest.fixture
def tiny_budget(api_stack, monkeypatch: pytest.MonkeyPatch) -> TestClient:
    """The app with a quick step budget of 10 steps: every real integration exceeds it."""
    monkeypatch.setenv("RSF_QUICK_STEPS", "10")
    return api_stack[0]


def test_long_query_goes_to_the_queue(tiny_budget: TestClient) -> None:
    """A classification that needs more than the quick step budget is not computed in the
    API process: it is recorded as a job and sent to the queue (202 + Location), and
    polling its location says it is queued."""
    c = tiny_budget
    body = {
        "ba": 2.0,
        "kappa": 2.0,
        "eps": 0.25,
        "vo": 1.0,
        "size": 2.65,
    }  # ~60 steps; asked only here
    r = c.post("/v1/classify", json=body)
    assert r.status_code == 202, r.text
    loc = r.headers["location"]
    queue = c.app.state.recording_queue  # type: ignore[attr-defined]
    assert queue.singles and queue.singles[-1][0] == "classify"
    assert queue.singles[-1][2] == loc.rsplit("/", 1)[1]
    again = c.get(loc)
    assert again.status_code == 202 and again.json()["status"] == "queued"
