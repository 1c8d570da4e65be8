"""Figures and plots over HTTP on a real uvicorn (and a real Celery worker for sweeps).

Every paper figure is fetched at draft quality (coarse grids, a few seconds in all) and
checked to be a real PNG; the image cache, SVG, ``?format=png`` of trajectories, U grids
and sweep diagrams (partial and finished), and the 404/422 problem+json answers.
"""

from __future__ import annotations

import json
import math
import struct
import time
from pathlib import Path
from typing import Any

import httpx
import pytest

from rsfapp.requests.figures import FIGURES
from tests.conftest import Worker

pytestmark = pytest.mark.timeout(180)
PNG_SIG = b"\x89PNG\r\n\x1a\n"


def png_size(data: bytes) -> tuple[int, int]:
    """(width, height) of a PNG after checking its signature and IHDR chunk."""
    assert data[:8] == PNG_SIG, data[:16]
    assert data[12:16] == b"IHDR"
    return struct.unpack(">II", data[16:24])


def assert_problem(r: httpx.Response, status: int, field: str) -> dict[str, Any]:
    assert r.status_code == status, r.text
    assert r.headers["content-type"].startswith("application/problem+json")
    p = r.json()
    assert p["status"] == status and p["field"] == field and p["detail"], p
    return p


def images(data: Path) -> set[str]:
    return {p.name for p in (data / "images").rglob("*") if p.is_file()}


@pytest.fixture(scope="module")
def c(fs_stack) -> httpx.Client:
    srv, _ = fs_stack
    with httpx.Client(base_url=srv.url, timeout=120) as client:
        yield client


def test_list_figures(c: httpx.Client) -> None:
    r = c.get("/v1/figures")
    assert r.status_code == 200 and r.headers["content-type"] == "application/json"
    body = r.json()
    assert [f["name"] for f in body["figures"]] == list(FIGURES)
    for f in body["figures"]:
        assert f["caption"].startswith(FIGURES[f["name"]].label) and len(f["caption"]) > 30
        assert f["url"] == f"/v1/figures/{f['name']}"
    assert body["formats"] == ["png", "svg", "json"] and "draft" in body["qualities"]


@pytest.mark.parametrize("name", list(FIGURES))
def test_each_figure_is_a_png(c: httpx.Client, fs_stack, name: str) -> None:
    r = c.get(f"/v1/figures/{name}", params={"quality": "draft"})
    assert r.status_code == 200, r.text[:500]
    assert r.headers["content-type"] == "image/png"
    w, h = png_size(r.content)
    assert w >= 300 and h >= 200 and len(r.content) > 10_000, (w, h, len(r.content))
    # Rendered once: the second request is read from the on-disk image cache.
    again = c.get(f"/v1/figures/{name}", params={"quality": "draft", "format": "PNG"})
    assert again.headers["x-cache"] == "hit" and again.content == r.content
    assert f"figure-{name}-draft.png" in images(fs_stack[1])


def test_figure_as_json(c: httpx.Client) -> None:
    """The data of a figure: the figure adapter's answer (the same in this process)."""
    from rsfapp.adapter.figures import figure
    from rsfapp.requests.figures import FigureRequest

    r = c.get("/v1/figures/continuum-modes", params={"format": "json", "quality": "draft"})
    assert r.status_code == 200 and r.headers["content-type"] == "application/json"
    want = figure(FigureRequest(name="continuum-modes", quality="draft"))
    assert r.json() == json.loads(json.dumps(want))
    again = c.get("/v1/figures/continuum-modes", params={"format": "json", "quality": "draft"})
    assert again.headers["x-cache"] == "hit" and again.content == r.content


def test_figure_as_svg(c: httpx.Client) -> None:
    r = c.get("/v1/figures/rate-neutral", params={"format": "svg", "quality": "draft"})
    assert r.status_code == 200 and r.headers["content-type"].startswith("image/svg+xml")
    assert b"<svg" in r.content[:2000] and r.content.rstrip().endswith(b"</svg>")


def test_unknown_figure_is_404_listing_names(c: httpx.Client) -> None:
    p = assert_problem(c.get("/v1/figures/fig-99"), 404, "name")
    assert p["valid_names"] == list(FIGURES)
    assert all(n in p["detail"] for n in FIGURES)


@pytest.mark.parametrize(
    "query,field",
    [
        ({"format": "gif"}, "format"),
        ({"quality": "best"}, "quality"),
    ],
)
def test_bad_figure_query_is_422(
    c: httpx.Client, fs_stack, query: dict[str, str], field: str
) -> None:
    before = images(fs_stack[1])
    p = assert_problem(c.get("/v1/figures/rate-neutral", params=query), 422, field)
    assert p["valid"] and "'" in p["valid"]
    assert images(fs_stack[1]) == before


def test_trajectory_png(c: httpx.Client, fs_stack) -> None:
    body = {"ba": 2.0, "kappa": 2.0, "eps": 0.25, "vo": 1.0, "size": 2.7, "n_points": 300}
    js = c.post("/v1/trajectory", json=body)
    assert js.status_code == 200 and js.headers["content-type"] == "application/json"
    assert js.json()["outcome"] == "stable" and len(js.json()["trajectory"]["phi"]) > 10
    r = c.post("/v1/trajectory", params={"format": "png"}, json=body)
    assert r.status_code == 200 and r.headers["content-type"] == "image/png", r.text[:300]
    w, h = png_size(r.content)
    assert w > h >= 300 and len(r.content) > 15_000
    assert r.headers["x-cache-key"] == js.json()["cache_key"]
    assert r.headers["x-cache"] == "miss"
    again = c.post("/v1/trajectory", params={"format": "png"}, json=body)
    assert again.headers["x-cache"] == "hit" and again.content == r.content
    # format is validated before anything is computed or stored.
    before = images(fs_stack[1])
    assert_problem(c.post("/v1/trajectory", params={"format": "svg"}, json=body), 422, "format")
    assert_problem(
        c.post("/v1/trajectory", params={"format": "png"}, json={**body, "eps": 2}), 422, "eps"
    )
    assert images(fs_stack[1]) == before


def test_analytic_u_png(c: httpx.Client) -> None:
    grid = {
        "function": "kcrit",
        "ba": 1.25,
        "eps": 0.3,
        "grid": {
            "phi_min": -3,
            "phi_max": 3,
            "n_phi": 61,
            "psi_min": -2,
            "psi_max": 2,
            "n_psi": 41,
        },
    }
    r = c.post("/v1/analytic/u", params={"format": "png"}, json=grid)
    assert r.status_code == 200 and r.headers["content-type"] == "image/png", r.text[:300]
    w, h = png_size(r.content)
    assert w >= 400 and h >= 300 and len(r.content) > 10_000
    # JSON stays the default.
    assert c.post("/v1/analytic/u", json=grid).json()["shape"] == [61, 41]
    pts = {"points": [{"phi": 0.5, "psi": 0.1}]}
    p = assert_problem(c.post("/v1/analytic/u", params={"format": "png"}, json=pts), 422, "format")
    assert "grid" in p["detail"]
    thin = {**grid, "grid": {**grid["grid"], "n_phi": 1}}
    assert_problem(c.post("/v1/analytic/u", params={"format": "png"}, json=thin), 422, "grid.n_phi")


def test_openapi_documents_formats(c: httpx.Client) -> None:
    spec = c.get("/openapi.json").json()["paths"]
    for path, method, enum in (
        ("/v1/trajectory", "post", ["json", "png", "csv"]),
        ("/v1/analytic/u", "post", ["json", "png"]),
        ("/v1/sweeps/{sweep_id}/diagram", "get", ["json", "png"]),
        ("/v1/figures/{name}", "get", ["png", "svg", "json"]),
    ):
        op = spec[path][method]
        fmt = next(p for p in op["parameters"] if p["name"] == "format")
        assert fmt["in"] == "query" and fmt["schema"]["enum"] == enum, fmt
        assert "image/png" in op["responses"]["200"]["content"], op["responses"]
    assert "/v1/figures" in spec and "/" not in spec and "/ui" not in spec


def wait_done(c: httpx.Client, sid: str, timeout: float = 90) -> dict[str, Any]:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        st = c.get(f"/v1/sweeps/{sid}").json()
        if st["status"] == "done":
            return st
        time.sleep(0.1)
    raise AssertionError(f"sweep {sid} not done after {timeout} s")


def test_sweep_diagram_partial_then_finished(c: httpx.Client, fs_stack, procs: list) -> None:
    data = fs_stack[1]
    body = {
        "x": {"name": "kappa_ratio", "start": 0.5, "stop": 2.5, "n": 4},
        "y": {"name": "eps", "values": [0.0, 0.4, 0.8]},
        "fixed": {"ba": 2.0, "vo": 1.0},
        "perturbation": "velocity-jump",
    }
    r = c.post("/v1/sweeps", json=body)
    assert r.status_code == 202, r.text
    sid = r.json()["id"]
    # No worker yet: an empty (partial) diagram, as JSON and as an uncached PNG.
    d0 = c.get(f"/v1/sweeps/{sid}/diagram").json()
    assert d0["status"] == "queued" and d0["n_done"] == 0 and d0["n_total"] == 12
    assert d0["present"] == [[False] * 3] * 4 and d0["outcome"] is None
    p0 = c.get(f"/v1/sweeps/{sid}/diagram", params={"format": "png"})
    assert p0.status_code == 200 and p0.headers["content-type"] == "image/png"
    assert p0.headers["x-sweep-status"] == "queued" and p0.headers["x-sweep-progress"] == "0/12"
    assert p0.headers["cache-control"] == "no-store"
    png_size(p0.content)

    procs.append(Worker(data))
    wait_done(c, sid)
    d = c.get(f"/v1/sweeps/{sid}/diagram").json()
    assert d["status"] == "done" and d["n_done"] == 12 and d["x_name"] == "kappa_ratio"
    assert d["present"] == [[True] * 3] * 4
    # The assembled grid is rsfcore's stability diagram of the same grid.
    from rsfcore.diagram import stability_diagram

    ref = stability_diagram("kappa_ratio", d["x"], "eps", d["y"], ba=2.0, vo=1.0).to_dict()
    assert d["kind"] == ref["kind"]
    for row, ref_row in zip(d["critical_size"], ref["critical_size"]):
        for v, w in zip(row, ref_row):
            assert (v is None and w is None) or math.isclose(v, w, rel_tol=1e-6), (v, w)
    png = c.get(f"/v1/sweeps/{sid}/diagram", params={"format": "png"})
    assert png.status_code == 200 and png.headers["x-sweep-status"] == "done"
    assert png.headers["x-sweep-progress"] == "12/12" and png.headers["x-cache"] == "miss"
    w, h = png_size(png.content)
    assert w >= 400 and h >= 300 and png.content != p0.content
    again = c.get(f"/v1/sweeps/{sid}/diagram", params={"format": "png"})
    assert again.headers["x-cache"] == "hit" and again.content == png.content

    # An outcome sweep (a size given): stable/unstable codes as classify says.
    body2 = {**body, "fixed": {"ba": 2.0, "vo": 1.0, "size": 1.5}}
    sid2 = c.post("/v1/sweeps", json=body2).json()["id"]
    wait_done(c, sid2)
    d2 = c.get(f"/v1/sweeps/{sid2}/diagram").json()
    from rsfcore import trajectory
    from rsfcore.params import Params

    for i, x in enumerate(d2["x"]):
        for j, y in enumerate(d2["y"]):
            out = trajectory.classify(
                Params.from_ratio(2.0, x, y, 1.0), "velocity-jump", 1.5
            ).outcome
            assert d2["outcome"][i][j] == {"stable": 0, "unstable": 1}[out]
    assert png_size(c.get(f"/v1/sweeps/{sid2}/diagram?format=png").content)[0] >= 400

    assert_problem(c.get(f"/v1/sweeps/{sid}/diagram", params={"format": "svg"}), 422, "format")
    r404 = c.get(f"/v1/sweeps/{'e' * 32}/diagram", params={"format": "png"})
    assert r404.status_code == 404
    assert r404.headers["content-type"].startswith("application/problem+json")


def test_dashboard_page_and_static_files(c: httpx.Client) -> None:
    for path in ("/", "/ui"):
        r = c.get(path)
        assert r.status_code == 200 and r.headers["content-type"].startswith("text/html")
        assert 'id="sweep-form"' in r.text and "/static/app.js" in r.text
    assert c.get("/static/app.js").headers["content-type"].startswith("text/javascript")
    assert c.get("/static/app.css").headers["content-type"].startswith("text/css")
    for bad in ("/static/nope.js", "/static/..%2Fapp.py", "/static/%2e%2e%2fsettings.py"):
        assert c.get(bad).status_code == 404, bad
