"""rsfclient against the real app in process (TestClient's transport): every method gives
the same answer as the HTTP body it stands for, typed; every route of the API has a client
method and every request field a keyword argument of the same name (a new route or
field without one fails here)."""

from __future__ import annotations

import inspect
import json
import math
from typing import Any

import numpy as np
import pytest
from fastapi.testclient import TestClient

import rsfclient
from rsfapp.requests import (
    AnalyticRequest,
    BoundariesSIRequest,
    ClassifyPointsRequest,
    ClassifyRequest,
    CriticalRequest,
    StiffnessRequest,
    SweepFixed,
    SweepRequest,
    TrajectoryRequest,
)
from rsfapp.requests.figures import FigureRequest
from rsfapp.requests.fits import FitRequest
from rsfapp.requests.protocols import LoadHistoryRequest, SlideHoldSlideRequest, VelocityStepRequest
from rsfclient import Client, ItemError, ProblemError, axis

pytestmark = pytest.mark.timeout(300)

MACHINE = {
    "a": 0.010,
    "b": 0.014,
    "Dc_m": 20e-6,
    "sigma_Pa": 10e6,
    "k_Pa_per_m": 4e9,
    "V_star_m_s": 1e-6,
}

#: Client method -> the request model whose fields are its keyword arguments.
METHOD_MODELS: dict[str, tuple[type, ...]] = {
    "classify": (ClassifyRequest,),
    "trajectory": (TrajectoryRequest,),
    "critical": (CriticalRequest,),
    "boundaries": (BoundariesSIRequest,),
    "analytic_u": (AnalyticRequest,),
    "stiffness": (StiffnessRequest,),
    "classify_points": (ClassifyPointsRequest,),
    "velocity_step": (VelocityStepRequest,),
    "slide_hold_slide": (SlideHoldSlideRequest,),
    "load_history": (LoadHistoryRequest,),
    "submit_fit": (FitRequest,),
    "fit": (FitRequest,),
    "sweep": (SweepRequest, SweepFixed),
    "figure": (FigureRequest,),
    "figure_data": (FigureRequest,),
}
#: Every operation of the API (OpenAPI) -> the client method that asks it.
ROUTES: dict[tuple[str, str], str] = {
    ("post", "/v1/classify"): "classify",
    ("post", "/v1/trajectory"): "trajectory",
    ("post", "/v1/critical"): "critical",
    ("get", "/v1/boundaries"): "boundaries",
    ("post", "/v1/boundaries"): "boundaries",
    ("post", "/v1/analytic/u"): "analytic_u",
    ("post", "/v1/stiffness"): "stiffness",
    ("post", "/v1/classify/points"): "classify_points",
    ("post", "/v1/classify/batch"): "classify_batch",
    ("post", "/v1/critical/batch"): "critical_batch",
    ("post", "/v1/protocols/velocity-step"): "velocity_step",
    ("post", "/v1/protocols/slide-hold-slide"): "slide_hold_slide",
    ("post", "/v1/protocols/load-history"): "load_history",
    ("post", "/v1/fits"): "submit_fit",
    ("get", "/v1/fits/{key}"): "get_fit",
    ("post", "/v1/sweeps"): "sweep",
    ("get", "/v1/sweeps"): "sweeps",
    ("get", "/v1/sweeps/{sweep_id}"): "get_sweep",
    ("get", "/v1/sweeps/{sweep_id}/spec"): "Sweep.spec",
    ("get", "/v1/sweeps/{sweep_id}/points"): "Sweep.points",
    ("get", "/v1/sweeps/{sweep_id}/data"): "Sweep.data",
    ("get", "/v1/sweeps/{sweep_id}/diagram"): "Sweep.diagram",
    ("get", "/v1/sweeps/{sweep_id}/zarr/{key}"): "Sweep.to_xarray",  # lazy=True
    ("get", "/v1/sweeps/{sweep_id}/zarr/{var}/{key}"): "Sweep.to_xarray",  # lazy=True
    ("delete", "/v1/sweeps/{sweep_id}"): "Sweep.cancel",
    ("get", "/v1/figures"): "figures",
    ("get", "/v1/figures/{name}"): "figure",
    ("get", "/v1/results/{key}"): "result",
    ("get", "/health"): "health",
    ("get", "/v1/cache/stats"): "cache_stats",
    ("get", "/metrics"): "metrics",
}
#: Arguments of client methods that are not request fields.
NOT_FIELDS = {"self", "spec", "fixed", "timeout", "format", *rsfclient.MACHINE_FIELDS}


def test_every_route_has_a_client_method(c: TestClient) -> None:
    ops = {
        (m, p)
        for p, item in c.app.openapi()["paths"].items()  # type: ignore[attr-defined]
        for m in item
        if m in ("get", "post", "delete", "put", "patch")
    }
    assert ops == set(ROUTES), (
        f"routes without a client method: {sorted(ops - set(ROUTES))}; "
        f"table entries without a route: {sorted(set(ROUTES) - ops)}"
    )
    for name in ROUTES.values():
        owner, _, attr = name.rpartition(".")
        assert callable(getattr(getattr(rsfclient, owner or "Client"), attr)), name


@pytest.mark.parametrize("method", sorted(METHOD_MODELS))
def test_keyword_arguments_are_the_request_fields(method: str) -> None:
    fields: set[str] = set()
    for model in METHOD_MODELS[method]:
        fields |= {f.alias or n for n, f in model.model_fields.items()}
    sig = set(inspect.signature(getattr(Client, method)).parameters)
    params = sig - NOT_FIELDS
    if method in ("fit", "submit_fit"):  # a fit takes k_Pa_per_m and sigma_Pa at top level
        params |= sig & {"k_Pa_per_m", "sigma_Pa"}
    if method == "sweep":
        fields -= {"fixed"}
    assert params == fields, (
        f"{method}: fields without an argument {sorted(fields - params)}, "
        f"arguments that are no field {sorted(params - fields)}"
    )


@pytest.fixture(scope="module")
def rc(c: TestClient) -> Client:
    """rsfclient on the in-process app."""
    return Client("http://testserver", transport=c._transport, retries=0, poll=0.0)


def same(answer: Any, http: dict[str, Any]) -> None:
    """The client's JSON equals the HTTP body, bit for bit (cache flags aside)."""
    skip = {"cached"}
    assert {k: v for k, v in answer.raw.items() if k not in skip} == {
        k: v for k, v in http.items() if k not in skip
    }


def test_single_queries_equal_their_http_answers(c: TestClient, rc: Client) -> None:
    si = rc.critical(**MACHINE)
    same(si, c.post("/v1/critical", json={"physical": MACHINE}).json())
    assert si.si is not None and si.params.ba == pytest.approx(1.4)
    d = rc.critical(ba=2.0, kappa=2.0, eps=0.25, perturbation="load-point-jump")
    same(
        d,
        c.post(
            "/v1/critical",
            json={"ba": 2.0, "kappa": 2.0, "eps": 0.25, "perturbation": "load-point-jump"},
        ).json(),
    )
    assert d.kind == "finite" and d.critical_size == pytest.approx(12.6842, rel=1e-5)

    cl = rc.classify(**MACHINE, eps=0.25, factor=10.0)
    same(cl, c.post("/v1/classify", json={"physical": MACHINE, "eps": 0.25, "factor": 10.0}).json())
    assert cl.outcome in ("stable", "unstable") and cl.si is not None

    tr = rc.trajectory(ba=2.0, kappa=2.0, eps=0.25, size=2.7, n_points=7)
    same(
        tr,
        c.post(
            "/v1/trajectory",
            json={"ba": 2.0, "kappa": 2.0, "eps": 0.25, "size": 2.7, "n_points": 7},
        ).json(),
    )
    df = tr.to_pandas()
    assert list(df["phi"]) == tr.trajectory["phi"] and len(df) == 7
    ds = tr.to_xarray()
    assert ds["psi"].values.tolist() == tr.trajectory["psi"]

    b = rc.boundaries(ba=2.0, kappa=2.0, eps=0.25, phi=np.array([0.0, 1.0]))
    same(b, c.post("/v1/boundaries", json={"ba": 2, "kappa": 2, "eps": 0.25, "phi": [0, 1]}).json())
    assert b.kappa_crit == 1.0 and list(b.to_pandas()["phi"]) == [0.0, 1.0]

    grid = {"phi_min": -1, "phi_max": 1, "n_phi": 3, "psi_min": 0, "psi_max": 2, "n_psi": 2}
    u = rc.analytic_u(ba=2.0, eps=0.25, grid=grid)
    same(u, c.post("/v1/analytic/u", json={"ba": 2.0, "eps": 0.25, "grid": grid}).json())
    da = u.to_xarray()
    assert da.dims == ("phi", "psi") and da.values.tolist() == u.U
    up = rc.analytic_u(ba=2.0, points=[(0.0, 1.0), {"phi": 1.0, "psi": 0.5}])
    assert up.to_pandas()["U"].tolist() == up.U and up.shape is None

    st = rc.stiffness(
        case="B", physical={"mu": 3e10, "sigma_Pa": 1e8, "a": 0.01, "b": 0.015, "Dc_m": 1e-5}
    )
    assert st.eigenvalue == pytest.approx(1.1577738836976, rel=1e-12)
    assert st.critical_dimension_name == "L_c"

    pts = rc.classify_points(ba=2.0, kappa=2.0, eps=0.25, phi=[0.0, 3.0], psi=[0.0, 3.0])
    assert pts.outcome == ["stable", "unstable"] and pts.to_pandas().shape == (2, 2)


def test_batches_keep_order_and_errors(c: TestClient, rc: Client) -> None:
    items: list[dict[str, Any]] = [{"ba": 2.0, "kappa": 2.0}, dict(MACHINE), {"ba": 0.5}]
    r = rc.critical_batch(items)
    http = c.post(
        "/v1/critical/batch", json={"items": [items[0], {"physical": MACHINE}, items[2]]}
    ).json()
    assert r.raw == http
    assert (r.n_items, r.n_ok, r.n_failed) == (3, 2, 1)
    assert isinstance(r.results[2], ItemError) and r.results[2].field == "ba"
    assert r.results[1].si is not None
    df = r.to_pandas()
    assert df["error_field"].tolist()[2] == "ba" and df["kind"].tolist()[:2] == [
        r.results[0].kind,
        r.results[1].kind,
    ]
    cb = rc.classify_batch([{"ba": 2.0, "kappa": 2.0, "size": 3.0}])
    assert cb.results[0].outcome == "unstable"


def test_protocols(c: TestClient, rc: Client) -> None:
    vs = rc.velocity_step(**MACHINE, V1_m_s=1e-6, V2_m_s=1e-5, n_points=5)
    same(
        vs,
        c.post(
            "/v1/protocols/velocity-step",
            json={"physical": MACHINE, "V1_m_s": 1e-6, "V2_m_s": 1e-5, "n_points": 5},
        ).json(),
    )
    # n_points from the step on, plus the steady state before it (a fit record as written)
    assert vs.kind == "velocity-step" and len(vs.to_pandas()) == 5 + 1
    shs = rc.slide_hold_slide(**MACHINE, V_m_s=1e-6, hold_s=10, slide_before_s=10, slide_after_s=10)
    assert shs.kind == "slide-hold-slide" and "t_s" in shs.series
    lh = rc.load_history(
        **MACHINE, segments=[(10.0, 1e-6), {"duration_s": 10.0, "V_load_m_s": 2e-6}]
    )
    assert lh.kind == "load-history" and lh.segments is not None and len(lh.segments) == 2
    png = rc.render("velocity_step", "png", **MACHINE, V1_m_s=1e-6, V2_m_s=1e-5, n_points=5)
    assert png[:8] == b"\x89PNG\r\n\x1a\n"
    csv = rc.render("trajectory", "csv", ba=2.0, kappa=2.0, eps=0.25, size=2.7, n_points=7)
    assert csv.decode().splitlines()[0].startswith("T,")


def test_errors_name_the_field(rc: Client) -> None:
    with pytest.raises(ProblemError) as e:
        rc.critical(ba=0.5)
    assert e.value.status == 422 and e.value.field == "ba" and e.value.valid == "(1, 1e6]"
    with pytest.raises(ProblemError) as e:
        rc.critical(**MACHINE, ba=2.0)  # never both
    assert e.value.field == "ba"


def test_sweep_round_trip(c: TestClient, rc: Client) -> None:
    from worker.tasks import run_chunk_body

    s = rc.sweep(axes=[axis("kappa_ratio", 1.5, 3.0, 2), axis("eps", values=[0.1, 0.3])], ba=2.0)
    assert s.last.created and s.last.n_total == 4
    assert s.last.fixed is not None and s.last.fixed["ba"] == 2.0
    for k in range(s.last.n_chunks or 0):
        run_chunk_body(s.id, k)
    st = s.wait(poll=0.0, timeout=30)
    assert st.status == "done" and st.n_done == 4
    assert s.spec()["axes"][0]["name"] == "kappa_ratio"
    ds = s.to_xarray()
    assert ds["critical_size"].dims == ("kappa_ratio", "eps")
    pts = list(s.iter_points(limit=3))
    assert [p["idx"] for p in pts] == [0, 1, 2, 3]
    flat = ds["critical_size"].values.ravel().tolist()
    assert [p["critical_size"] for p in pts] == [None if math.isinf(v) else v for v in flat]
    df = s.to_pandas()
    assert len(df) == 4 and "critical_size" in df.columns
    assert s.diagram()["status"] == "done" and s.diagram_png()[:4] == b"\x89PNG"
    assert json.loads(s.data("json"))["id"] == s.id
    assert any(x.id == s.id for x in rc.sweeps())
    assert rc.get_sweep(s.id).last.status == "done"
    assert s.cancel().changed is False
    s.delete()
    with pytest.raises(ProblemError) as e:
        s.status()
    assert e.value.status == 404


def test_figures(rc: Client) -> None:
    figs = rc.figures()
    assert figs and all(f.url == f"/v1/figures/{f.name}" for f in figs)
    with pytest.raises(ProblemError) as e:
        rc.figure("no-such-figure")
    assert e.value.status == 404 and e.value.field == "name"
    # the data: the figure adapter's answer, typed; the quality left out is the model's
    from rsfapp.adapter.figures import figure

    d = rc.figure_data("continuum-modes", quality="draft")
    want = figure(FigureRequest(name="continuum-modes", quality="draft"))
    assert d.raw == json.loads(json.dumps(want)) and d.quality == "draft"
    assert d.label == want["label"] and d["cases"][0]["case"] == "B"
    with pytest.raises(ProblemError) as e:
        rc.figure_data("continuum-modes", quality="best")  # type: ignore[arg-type]
    assert e.value.status == 422 and e.value.field == "quality"
