"""Single-query endpoints: classify, trajectory, critical, analytic U, boundaries, stiffness.

All are answered in the API process and cached (see :mod:`service.answer`).  Trajectories
and U grids can also be fetched as PNG plots (``?format=png``; JSON is the default).
"""

from __future__ import annotations

import json
from collections.abc import Callable
from functools import partial
from typing import Annotated, Any

from fastapi import APIRouter, Query
from starlette.responses import Response

from rsfapp.adapter import single
from rsfapp.requests import (
    AnalyticRequest,
    BoundariesQueryRequest,
    BoundariesSIRequest,
    ClassifyPointsRequest,
    ClassifyRequest,
    CriticalRequest,
    StiffnessRequest,
    TrajectoryRequest,
)

from .. import images
from ..context import CtxDep
from ..errors import ProblemError
from ..images import choice, format_query, image, image_response, png_content
from ..responses import ClassifyResult, CriticalResult, TrajectoryResult
from ..tables import csv_table

router = APIRouter(prefix="/v1", tags=["compute"])


_R: dict[int | str, dict[str, Any]] = {
    422: {
        "description": "Invalid input (problem+json naming the field and its range) or a "
        "computation that could not be completed."
    }
}


@router.post(
    "/classify",
    responses={200: {"model": ClassifyResult, "description": "The outcome."}, **_R},
    summary="Stable or unstable?",
)
async def classify(req: ClassifyRequest, ctx: CtxDep) -> Response:
    """Certified outcome of one perturbation (outcome, certificate, peak_phi, blow-up or
    return time T = V_* t/Dc, rel_accuracy). Cached (field `cached`, header `X-Cache: hit|miss`)."""
    return await ctx.answer("classify", req, partial(single.classify, max_steps=ctx.quick_steps))


@router.post(
    "/classify/points",
    responses=_R,
    summary="Stable or unstable, for many start points of one parameter set",
)
async def classify_points(req: ClassifyPointsRequest, ctx: CtxDep) -> Response:
    """Outcome ("stable" | "unstable") of each start point (phi[i], psi[i]) for one
    parameter set, from the separatrix computed once (rsfcore.phase.classify_points);
    points within a safety margin of the separatrix are integrated, so each outcome is
    the one /v1/classify gives with that ``start``.  10^5 points take milliseconds.
    Cached (field `cached`, header `X-Cache: hit|miss`)."""
    return await ctx.answer("classify_points", req, single.classify_points)


_JSON_OR_PNG = ("json", "png")
_DEFERRED: dict[int | str, dict[str, Any]] = {
    202: {
        "description": "Still computing (JSON with `Location: /v1/results/{key}`, also for "
        "format=png): poll it, then repeat the request."
    }
}


async def _as_png(resp: Response, plot: Callable[[dict[str, Any]], bytes]) -> Response:
    """The PNG plot of a 200 JSON answer (other answers are returned unchanged)."""
    if resp.status_code != 200:
        return resp
    result = json.loads(bytes(resp.body))
    key = result["cache_key"]
    data, hit = await image(f"{key}.png", lambda: plot(result))
    return image_response(data, "png", hit, headers={"X-Cache-Key": key})


_TRAJ_FORMATS = ("json", "png", "csv")
_TRAJ_200 = png_content(
    "The outcome and trajectory (JSON), with format=png the phase plane "
    "(phi, psi) and phi(T) as a PNG image, with format=csv the samples "
    "as CSV.",
    model=TrajectoryResult,
)
_TRAJ_200[200]["content"]["text/csv"] = {"schema": {"type": "string"}}


@router.post(
    "/trajectory", responses={**_R, **_DEFERRED, **_TRAJ_200}, summary="One trajectory, downsampled"
)
async def trajectory(
    req: TrajectoryRequest,
    ctx: CtxDep,
    format: Annotated[
        str,
        format_query(  # noqa: A002
            _TRAJ_FORMATS,
            "json",
            "'png': phase-plane (phi, psi) and phi(T) "
            "plot of the trajectory; 'csv': the samples, one row each (header "
            "X-Sampling says the spacing).",
        ),
    ] = "json",
) -> Response:
    """Outcome and the trajectory (T, phi, psi, ln_theta, slip, load_point) at
    ``n_points`` samples, spaced as ``sampling`` says ('tau': evenly in the integrator's
    bounded time; 'T': evenly in T; 'seconds': evenly in t, needs physical); the answer's
    ``sampling`` field states it.  SI columns and an ``si`` block when ``physical`` (SI
    inputs) or ``scales`` is given. Cached (field `cached`, header `X-Cache: hit|miss`).
    With ``?format=png``: the phase plane and phi(T) as a PNG (image cached too); with
    ``?format=csv``: the samples as CSV."""
    fmt = choice(format, _TRAJ_FORMATS, "format")
    resp = await ctx.answer(
        "trajectory", req, partial(single.trajectory, max_steps=ctx.quick_steps)
    )
    if fmt == "csv":
        return _as_csv(resp)
    return resp if fmt == "json" else await _as_png(resp, images.trajectory_png)


def _as_csv(resp: Response) -> Response:
    """The samples of a 200 trajectory answer as CSV (other answers unchanged)."""
    if resp.status_code != 200:
        return resp
    result = json.loads(bytes(resp.body))
    cols = result.get("trajectory") or {}
    samp = result.get("sampling", {}).get("kind", "tau")
    return Response(
        csv_table(cols),
        media_type="text/csv",
        headers={
            "X-Cache-Key": result["cache_key"],
            "X-Sampling": samp,
            "X-Cache": resp.headers.get("X-Cache", "miss"),
            "Content-Disposition": 'attachment; filename="trajectory.csv"',
        },
    )


@router.post(
    "/critical",
    responses={200: {"model": CriticalResult, "description": "The critical size."}, **_R},
    summary="Critical perturbation size",
)
async def critical(req: CriticalRequest, ctx: CtxDep) -> Response:
    """Same fields as `rsf critical --json`: kind (zero|finite|infinite), critical_size,
    rel_accuracy, method, perturbation, params. Cached (field `cached`, header `X-Cache: hit|miss`)."""
    return await ctx.answer("critical", req, single.critical)


@router.post(
    "/analytic/u",
    responses={
        **_R,
        **png_content(
            "U at the points or on the grid (JSON), or with format=png (grid only) the contours "
            "of U (red: U = 0) as a PNG image."
        ),
    },
    summary="Analytic Lyapunov function U",
)
async def analytic_u(
    req: AnalyticRequest,
    ctx: CtxDep,
    format: Annotated[
        str,
        format_query(  # noqa: A002
            _JSON_OR_PNG, "json", "'png' (needs 'grid'): contours of U in the (phi, psi) plane."
        ),
    ] = "json",
) -> Response:
    """U at points (list) or on a grid (U[i][j] at phi[i], psi[j]). Cached (field `cached`, header `X-Cache: hit|miss`).
    With ``?format=png`` and a grid (at least 2 x 2): contour plot of U (red: U = 0)."""
    fmt = choice(format, _JSON_OR_PNG, "format")
    if fmt == "png" and req.grid is None:
        raise ProblemError(
            422,
            "Invalid input",
            "format: png needs U on a grid (give 'grid', not 'points')",
            field="format",
            valid="'json' (points or grid) or 'png' (grid only)",
        )
    if fmt == "png":
        for f in ("n_phi", "n_psi"):
            if getattr(req.grid, f) < 2:
                raise ProblemError(
                    422,
                    "Invalid input",
                    f"grid.{f}: a contour plot needs "
                    "at least 2 values (valid range: [2, 500] with format=png)",
                    field=f"grid.{f}",
                    valid="[2, 500] with format=png",
                )
    resp = await ctx.answer("analytic_u", req, single.analytic_u)
    return resp if fmt == "json" else await _as_png(resp, images.analytic_u_png)


@router.get("/boundaries", responses=_R, summary="Stability boundaries (query)")
async def boundaries_get(req: Annotated[BoundariesQueryRequest, Query()], ctx: CtxDep) -> Response:
    """kappa_crit, eps_crit, (a/b)_crit, acceleration line at the given phi values.
    Cached (field `cached`, header `X-Cache: hit|miss`)."""
    return await ctx.answer("boundaries", req, single.boundaries)


@router.post("/boundaries", responses=_R, summary="Stability boundaries")
async def boundaries_post(req: BoundariesSIRequest, ctx: CtxDep) -> Response:
    """kappa_crit, eps_crit, (a/b)_crit, acceleration line at the given phi values;
    dimensionless (ba, kappa) or with the machine in SI (``physical``; then also an
    ``si`` block: k_crit [Pa/m], kappa/kappa_crit). Cached (field `cached`, header
    `X-Cache: hit|miss`)."""
    return await ctx.answer("boundaries", req, single.boundaries)


@router.post("/stiffness", responses=_R, summary="Continuum stiffness, critical dimension")
async def stiffness(req: StiffnessRequest, ctx: CtxDep) -> Response:
    """Eigenvalue k/k_* of case A-E and, given physical parameters, the critical
    dimension in metres (lambda_c, L_c or R_c). Cached (field `cached`, header `X-Cache: hit|miss`)."""
    return await ctx.answer("stiffness", req, single.stiffness)
