"""Single-query endpoints: classify, trajectory, critical, analytic U, boundaries, stiffness.

All are answered in the API process and cached (see :mod:`service.cached`).
"""
from __future__ import annotations

from typing import Annotated

from fastapi import APIRouter, Query
from starlette.responses import Response

from .. import compute
from ..cached import answer
from ..schemas import (AnalyticRequest, BoundariesRequest, ClassifyRequest, CriticalRequest,
                       StiffnessRequest, TrajectoryRequest)

router = APIRouter(prefix="/v1", tags=["compute"])
_R = {422: {"description": "Invalid input (problem+json naming the field and its range) "
                           "or a computation that could not be completed."}}


@router.post("/classify", responses=_R, summary="Stable or unstable?")
async def classify(req: ClassifyRequest) -> Response:
    """Certified outcome of one perturbation (outcome, certificate, peak_phi, blow-up or
    return time T = V_* t/Dc, rel_accuracy). Cached (field `cached`, header `X-Cache: hit|miss`)."""
    return await answer("classify", req, compute.classify)


@router.post("/trajectory", responses=_R, summary="One trajectory, downsampled")
async def trajectory(req: TrajectoryRequest) -> Response:
    """Outcome and the trajectory (T, phi, psi, ln_theta, slip, load_point) at
    ``n_points`` samples; SI columns when ``physical`` is given. Cached (field `cached`, header `X-Cache: hit|miss`)."""
    return await answer("trajectory", req, compute.trajectory)


@router.post("/critical", responses=_R, summary="Critical perturbation size")
async def critical(req: CriticalRequest) -> Response:
    """Same fields as `rsf critical --json`: kind (zero|finite|infinite), critical_size,
    rel_accuracy, method, perturbation, params. Cached (field `cached`, header `X-Cache: hit|miss`)."""
    return await answer("critical", req, compute.critical)


@router.post("/analytic/u", responses=_R, summary="Analytic Lyapunov function U")
async def analytic_u(req: AnalyticRequest) -> Response:
    """U at points (list) or on a grid (U[i][j] at phi[i], psi[j]). Cached (field `cached`, header `X-Cache: hit|miss`)."""
    return await answer("analytic_u", req, compute.analytic_u)


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
