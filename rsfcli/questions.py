"""`rsf boundaries`, `rsf analytic-u`, `rsf classify-points`, `rsf critical-batch`,
`rsf classify-batch`: the questions of POST /v1/boundaries, /v1/analytic/u,
/v1/classify/points, /v1/critical/batch and /v1/classify/batch, asked in this process.

As every computing command (rsfcli.common): the HTTP route's request model is built from
the options given (each spelled as its JSON field; objects and lists of objects as JSON
text) and answered through the same :mod:`rsfapp.adapter` function, so ``--json`` prints
the route's answer.  The batch commands read the request body (``{"items": [...]}``, or
the bare list) from a file, or from stdin with ``-``.
"""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Any

import typer

from rsfapp.requests import (
    AnalyticRequest,
    BoundariesSIRequest,
    ClassifyPointsRequest,
    PhysicalSI,
)
from rsfapp.requests.batch import ClassifyBatchRequest, CriticalBatchRequest

from .common import emit, fail, given, json_value, model_option, run

__all__ = ["app", "register"]

JSON = typer.Option(False, "--json", help="Print one JSON object.")


def _lines(d: dict[str, Any]) -> list[str]:
    return [f"{k} {v}" for k, v in d.items()]


def boundaries(
    ba: float | None = model_option(BoundariesSIRequest, "ba"),
    kappa: float | None = model_option(BoundariesSIRequest, "kappa"),
    eps: float | None = model_option(BoundariesSIRequest, "eps"),
    phi: list[float] | None = model_option(
        BoundariesSIRequest,
        "phi",
        help="phi (-) at which to give psi on the acceleration line, repeated.",
    ),
    a: float | None = model_option(PhysicalSI, "a"),
    b: float | None = model_option(PhysicalSI, "b"),
    dc_m: float | None = model_option(PhysicalSI, "Dc_m"),
    sigma_pa: float | None = model_option(PhysicalSI, "sigma_Pa"),
    k_pa_per_m: float | None = model_option(PhysicalSI, "k_Pa_per_m"),
    v_star_m_s: float | None = model_option(PhysicalSI, "V_star_m_s"),
    v_load_m_s: float | None = model_option(PhysicalSI, "V_load_m_s"),
    as_json: bool = JSON,
) -> None:
    """Stability boundaries: kappa_crit, eps_crit, (a/b)_crit, acceleration possibility and
    line at --phi; with the machine in SI (--a --b --Dc_m --sigma_Pa --k_Pa_per_m
    --V_star_m_s instead of --ba --kappa) also k_crit [Pa/m] and kappa/kappa_crit."""
    from rsfapp import adapter

    physical = given(
        a=a,
        b=b,
        Dc_m=dc_m,
        sigma_Pa=sigma_pa,
        k_Pa_per_m=k_pa_per_m,
        V_star_m_s=v_star_m_s,
        V_load_m_s=v_load_m_s,
    )
    body = given(ba=ba, kappa=kappa, eps=eps, phi=phi or None)
    if physical:
        body["physical"] = physical
    d = run(BoundariesSIRequest, body, adapter.boundaries)
    emit(d, as_json, _lines(d))


def analytic_u(
    function: str | None = model_option(AnalyticRequest, "function"),
    ba: float | None = model_option(AnalyticRequest, "ba"),
    eps: float | None = model_option(AnalyticRequest, "eps"),
    vo: float | None = model_option(AnalyticRequest, "vo"),
    kappa: float | None = model_option(AnalyticRequest, "kappa"),
    points: str | None = model_option(
        AnalyticRequest,
        "points",
        help='Points as JSON, e.g. \'[{"phi": 0, "psi": 1}]\'; give --points or --grid.',
    ),
    grid: str | None = model_option(
        AnalyticRequest,
        "grid",
        help='A grid as JSON: \'{"phi_min": .., "phi_max": .., "n_phi": .., '
        '"psi_min": .., "psi_max": .., "n_psi": ..}\'; give --points or --grid.',
    ),
    as_json: bool = JSON,
) -> None:
    """Analytic Lyapunov function U (closed forms of the paper) at points or on a grid."""
    from rsfapp import adapter

    body = given(
        function=function,
        ba=ba,
        eps=eps,
        vo=vo,
        kappa=kappa,
        points=json_value("points", points),
        grid=json_value("grid", grid),
    )
    d = run(AnalyticRequest, body, adapter.analytic_u)
    emit(d, as_json, _lines(d))


def classify_points(
    ba: float | None = model_option(ClassifyPointsRequest, "ba"),
    kappa: float | None = model_option(ClassifyPointsRequest, "kappa"),
    eps: float | None = model_option(ClassifyPointsRequest, "eps"),
    vo: float | None = model_option(ClassifyPointsRequest, "vo"),
    phi: list[float] = model_option(
        ClassifyPointsRequest, "phi", required=True, help="Start phi0 (-), repeated."
    ),
    psi: list[float] = model_option(
        ClassifyPointsRequest, "psi", required=True, help="Start psi0 (-), repeated."
    ),
    rtol: float | None = model_option(ClassifyPointsRequest, "rtol"),
    as_json: bool = JSON,
) -> None:
    """Outcomes of many start points (--phi[i], --psi[i]) for one parameter set."""
    from rsfapp import adapter

    body = given(ba=ba, kappa=kappa, eps=eps, vo=vo, phi=phi, psi=psi, rtol=rtol)
    d = run(ClassifyPointsRequest, body, adapter.classify_points)
    emit(d, as_json, _lines(d))


FILE = typer.Argument(
    ...,
    help='JSON file with the request body {"items": [...]} (or the bare list); - for stdin.',
)


def _items_body(file: str) -> Any:
    text = sys.stdin.read() if file == "-" else None
    if text is None:
        path = Path(file)
        if not path.is_file():
            fail(f"file: {file!r} is not a readable file")
        text = path.read_text(encoding="utf-8")
    body = json_value("items", text)
    return {"items": body} if isinstance(body, list) else body


def _batch_lines(d: dict[str, Any]) -> list[str]:
    lines = [f"n_items {d['n_items']}  n_ok {d['n_ok']}  n_failed {d['n_failed']}"]
    return lines + [str(r) for r in d["results"]]


def critical_batch(file: str = FILE, as_json: bool = JSON) -> None:
    """Critical sizes of many items (each as `rsf critical` / `rsf si critical` takes it)."""
    from rsfapp import adapter

    d = run(CriticalBatchRequest, _items_body(file), lambda r: adapter.critical_batch(r.items))
    emit(d, as_json, _batch_lines(d))


def classify_batch(file: str = FILE, as_json: bool = JSON) -> None:
    """Outcomes of many items (each as `rsf classify` / `rsf si classify` takes it); an
    item needing more than the quick step budget is an error entry (ask it alone)."""
    from rsfapp import adapter

    d = run(ClassifyBatchRequest, _items_body(file), lambda r: adapter.classify_batch(r.items))
    emit(d, as_json, _batch_lines(d))


def register(app: typer.Typer) -> None:
    """Add these commands to ``app`` (the `rsf` root)."""
    app.command("boundaries")(boundaries)
    app.command("analytic-u")(analytic_u)
    app.command("classify-points")(classify_points)
    app.command("critical-batch")(critical_batch)
    app.command("classify-batch")(classify_batch)


#: These commands on their own (mounted on `rsf` by rsfcli.main when asked for).
app = typer.Typer(rich_markup_mode=None, add_completion=False)
register(app)
