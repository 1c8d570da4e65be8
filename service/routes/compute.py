"""Single-query endpoints: classify, trajectory, critical, analytic U, boundaries, stiffness.

All are answered in the API process and cached (see :mod:`service.cached`).  Trajectories
and U grids can also be fetched as PNG plots (``?format=png``; JSON is the default).
"""
from __future__ import annotations

import json
from typing import Annotated

from fastapi import APIRouter, Query
from starlette.responses import Response

from .. import compute
from ..cached import answer
from ..responses import ClassifyResult, CriticalResult, TrajectoryResult
from ..errors import ProblemError
from ..schemas import (AnalyticRequest, BoundariesRequest, ClassifyRequest, CriticalRequest,
                       StiffnessRequest, TrajectoryRequest)
from .figures import choice, format_query, image, image_response, png_content

router = APIRouter(prefix="/v1", tags=["compute"])
_R = {422: {"description": "Invalid input (problem+json naming the field and its range) "
                           "or a computation that could not be completed."}}


@router.post("/classify", responses={200: {"model": ClassifyResult, "description": "The outcome."}, **_R},
             summary="Stable or unstable?")
async def classify(req: ClassifyRequest) -> Response:
    """Certified outcome of one perturbation (outcome, certificate, peak_phi, blow-up or
    return time T = V_* t/Dc, rel_accuracy). Cached (field `cached`, header `X-Cache: hit|miss`)."""
    return await answer("classify", req, compute.classify)


_JSON_OR_PNG = ("json", "png")
_DEFERRED = {202: {"description": "Still computing (JSON with `Location: /v1/results/{key}`, "
                                  "also for format=png): poll it, then repeat the request."}}


async def _as_png(resp: Response, plot) -> Response:  # noqa: ANN001
    """The PNG plot of a 200 JSON answer (other answers are returned unchanged)."""
    if resp.status_code != 200:
        return resp
    result = json.loads(bytes(resp.body))
    key = result["cache_key"]
    data, hit = await image(f"{key}.png", lambda: plot(result))
    return image_response(data, "png", hit, headers={"X-Cache-Key": key})


@router.post("/trajectory", responses={**_R, **_DEFERRED, **png_content(
        "The outcome and trajectory (JSON), or with format=png the phase plane (phi, psi) "
        "and phi(T) as a PNG image.", model=TrajectoryResult)}, summary="One trajectory, downsampled")
async def trajectory(req: TrajectoryRequest,
                     format: Annotated[str, format_query(  # noqa: A002
                         _JSON_OR_PNG, "json", "'png': phase-plane (phi, psi) and phi(T) "
                         "plot of the trajectory.")] = "json") -> Response:
    """Outcome and the trajectory (T, phi, psi, ln_theta, slip, load_point) at
    ``n_points`` samples; SI columns when ``physical`` is given. Cached (field `cached`, header `X-Cache: hit|miss`).
    With ``?format=png``: the phase plane and phi(T) as a PNG (image cached too)."""
    fmt = choice(format, _JSON_OR_PNG, "format")
    resp = await answer("trajectory", req, compute.trajectory)
    return resp if fmt == "json" else await _as_png(resp, compute.trajectory_png)


@router.post("/critical", responses={200: {"model": CriticalResult, "description": "The critical size."}, **_R},
             summary="Critical perturbation size")
async def critical(req: CriticalRequest) -> Response:
    """Same fields as `rsf critical --json`: kind (zero|finite|infinite), critical_size,
    rel_accuracy, method, perturbation, params. Cached (field `cached`, header `X-Cache: hit|miss`)."""
    return await answer("critical", req, compute.critical)


@router.post("/analytic/u", responses={**_R, **png_content(
        "U at the points or on the grid (JSON), or with format=png (grid only) the contours "
        "of U (red: U = 0) as a PNG image.")}, summary="Analytic Lyapunov function U")
async def analytic_u(req: AnalyticRequest,
                     format: Annotated[str, format_query(  # noqa: A002
                         _JSON_OR_PNG, "json", "'png' (needs 'grid'): contours of U in the "
                         "(phi, psi) plane.")] = "json") -> Response:
    """U at points (list) or on a grid (U[i][j] at phi[i], psi[j]). Cached (field `cached`, header `X-Cache: hit|miss`).
    With ``?format=png`` and a grid (at least 2 x 2): contour plot of U (red: U = 0)."""
    fmt = choice(format, _JSON_OR_PNG, "format")
    if fmt == "png" and req.grid is None:
        raise ProblemError(422, "Invalid input", "format: png needs U on a grid (give "
                           "'grid', not 'points')", field="format",
                           valid="'json' (points or grid) or 'png' (grid only)")
    if fmt == "png":
        for f in ("n_phi", "n_psi"):
            if getattr(req.grid, f) < 2:
                raise ProblemError(422, "Invalid input", f"grid.{f}: a contour plot needs "
                                   "at least 2 values (valid range: [2, 500] with format=png)",
                                   field=f"grid.{f}", valid="[2, 500] with format=png")
    resp = await answer("analytic_u", req, compute.analytic_u)
    return resp if fmt == "json" else await _as_png(resp, compute.analytic_u_png)


@router.get("/boundaries", responses=_R, summary="Stability boundaries (query)")
async def boundaries_get(req: Annotated[BoundariesRequest, Query()]) -> Response:
    """kappa_crit, eps_crit, (a/b)_crit, acceleration line at the given phi values. Cached (field `cached`, header `X-Cache: hit|miss`)."""
    return await answer("boundaries", req, compute.boundaries)


@router.post("/boundaries", responses=_R, summary="Stability boundaries")
async def boundaries_post(req: BoundariesRequest) -> Response:
    """kappa_crit, eps_crit, (a/b)_crit, acceleration line at the given phi values. Cached (field `cached`, header `X-Cache: hit|miss`)."""
    return await answer("boundaries", req, compute.boundaries)


@router.post("/stiffness", responses=_R, summary="Continuum stiffness, critical dimension")
async def stiffness(req: StiffnessRequest) -> Response:
    """Eigenvalue k/k_* of case A-E and, given physical parameters, the critical
    dimension in metres (lambda_c, L_c or R_c). Cached (field `cached`, header `X-Cache: hit|miss`)."""
    return await answer("stiffness", req, compute.stiffness)
