"""Single queries (classify, trajectory, critical, analytic U, boundaries, stiffness,
classify at many start points): request model of :mod:`rsfapp.requests.single` ->
rsfcore -> JSON-safe dict, dimensionless or SI.

Each function imports the rsfcore module it asks when it is called: a question that
needs no numba kernel (stiffness) does not load numba, and one that needs some loads
only its own (a CLI process answers one question)."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np

from rsfcore.jsonsafe import jsonsafe
from rsfcore.params import Params, PhysicalParams

from ..requests import (
    AnalyticRequest,
    BoundariesRequest,
    ClassifyPointsRequest,
    ClassifyRequest,
    CriticalRequest,
    StiffnessRequest,
    TrajectoryRequest,
)
from ._common import QUICK_STEPS, ComputeError, guard, json_dict
from ._si import critical_si, outcome_si, resolve_params, resolve_size, scales_si, si_inputs

__all__ = [
    "SAMPLING_NOTE",
    "analytic_u",
    "boundaries",
    "classify",
    "classify_points",
    "critical",
    "stiffness",
    "trajectory",
]


def classify(req: ClassifyRequest, max_steps: int | None = QUICK_STEPS) -> dict[str, Any]:
    """Stable/unstable outcome with certificate, peak and times (dimensionless; plus an
    ``si`` block when the request gave ``physical``).

    With the default ``max_steps`` a query needing more work raises :class:`NeedsQueue`;
    ``max_steps=None`` (the worker) uses rsfcore's full budget."""
    from rsfcore import trajectory as _traj

    p, phys = resolve_params(req)
    size = resolve_size(req, phys)
    start = None if req.start is None else (req.start.phi, req.start.psi)
    kw: dict[str, Any] = {} if max_steps is None else {"max_steps": max_steps}
    if req.log_size is not None:
        kw["log_size"] = req.log_size
    res = guard(_traj.classify, p, req.perturbation, size, start=start, rtol=req.rtol, **kw)
    out = json_dict(res.to_dict())
    out["rtol"] = req.rtol  # every answer echoes the parameters it used
    if phys is not None:
        out["si"] = jsonsafe(outcome_si(phys, out, req.log_size))
    return out


#: Meaning of each ``sampling`` value of a trajectory request (said in the answer).
SAMPLING_NOTE = {
    "tau": "evenly spaced in the integrator's bounded time tau (dense where the motion is "
    "fast); T is unevenly spaced",
    "T": "evenly spaced in T = V_* t/Dc",
    "seconds": "evenly spaced in t [s] (t = T Dc/V_*: evenly in T as well)",
}


def trajectory(req: TrajectoryRequest, max_steps: int | None = QUICK_STEPS) -> dict[str, Any]:
    """Outcome plus the trajectory downsampled to ``n_points`` (SI columns with
    ``physical`` or ``scales``), sampled as ``req.sampling`` says; ``max_steps`` as in
    :func:`classify`."""
    from rsfcore import trajectory as _traj

    p, phys = resolve_params(req)
    size = resolve_size(req, phys)
    start = None if req.start is None else (req.start.phi, req.start.psi)
    physical = None
    if phys is not None:
        physical = guard(phys.to_physical_params, req.eps, req.f_star)
    elif req.scales is not None:
        s = req.scales
        physical = guard(
            PhysicalParams.from_dimensionless,
            p,
            a=s.a,
            Dc_m=s.Dc,
            sigma_Pa=s.sigma,
            V_star_m_s=s.V_star,
            f_star=s.f_star,
        )
    t_end = req.t_end
    if req.t_end_s is not None and phys is not None:
        t_end = phys.T_from_time(req.t_end_s)
    kw: dict[str, Any] = {} if max_steps is None else {"max_steps": max_steps}
    if req.log_size is not None:
        kw["log_size"] = req.log_size
    res = guard(
        _traj.simulate,
        p,
        req.perturbation,
        size,
        start=start,
        rtol=req.rtol,
        t_end=t_end,
        n_points=req.n_points,
        physical=physical,
        sampling="tau" if req.sampling == "tau" else "time",
        **kw,
    )
    out = json_dict(res.to_dict())
    out["rtol"] = req.rtol  # every answer echoes the parameters it used
    out["sampling"] = {
        "kind": req.sampling,
        "n_points": req.n_points,
        "description": SAMPLING_NOTE[req.sampling],
    }
    if phys is not None:
        out["si"] = jsonsafe(outcome_si(phys, out, req.log_size))
    return out


def critical(req: CriticalRequest) -> dict[str, Any]:
    """Critical perturbation size, same fields as ``rsf critical --json``; with
    ``physical`` also an ``si`` block (critical slip rate [m/s] and shear-stress jump [Pa]
    of a velocity jump, critical load-point velocity [m/s])."""
    from rsfcore import critical as _critical

    p, phys = resolve_params(req)
    res = guard(_critical.critical_perturbation, p, req.perturbation, rtol=req.rtol)
    out = json_dict(res.to_dict())
    out["rtol"] = req.rtol  # every answer echoes the parameters it used
    if phys is not None:
        out["si"] = jsonsafe(critical_si(phys, out))
    return out


def analytic_u(req: AnalyticRequest) -> dict[str, Any]:
    """U at the given points or on the grid (closed form, vectorised)."""
    from rsfcore import analytic

    if req.points is not None:
        phi = np.array([p.phi for p in req.points])
        psi = np.array([p.psi for p in req.points])
        out: dict[str, Any] = {"phi": phi, "psi": psi}
    else:
        g = req.grid
        assert g is not None  # AnalyticRequest: exactly one of points or grid
        phi1 = np.linspace(g.phi_min, g.phi_max, g.n_phi)
        psi1 = np.linspace(g.psi_min, g.psi_max, g.n_psi)
        phi, psi = np.meshgrid(phi1, psi1, indexing="ij")
        out = {"phi": phi1, "psi": psi1, "shape": [g.n_phi, g.n_psi]}
    with np.errstate(all="ignore"):
        if req.function == "kcrit":
            u = guard(analytic.U_kcrit, phi, psi, req.ba, req.eps, req.vo)
        else:
            u = guard(analytic.U_vo0, phi, psi, req.ba, req.kappa, req.eps)
    out.update(
        function=req.function,
        params={"ba": req.ba, "kappa": req.kappa, "eps": req.eps, "vo": req.vo},
        U=np.asarray(u, dtype=float),
    )
    return json_dict(out)


def boundaries(req: BoundariesRequest) -> dict[str, Any]:
    """kappa_crit, eps_crit, (a/b)_crit, acceleration possibility and line; with
    ``physical`` (BoundariesSIRequest) b/a and kappa from the SI machine, plus an ``si``
    block (k_crit [Pa/m], kappa/kappa_crit)."""
    from rsfcore import boundaries as _bounds

    def soft(fn: Callable[..., Any], *a: Any) -> Any:
        try:
            return guard(fn, *a)
        except ComputeError as exc:
            return {"error": str(exc)}

    phys = si_inputs(req)
    ba, kappa = (req.ba, req.kappa) if phys is None else (phys.ba, phys.kappa)
    out: dict[str, Any] = {
        "ba": ba,
        "kappa": kappa,
        "eps": req.eps,
        "kappa_crit": guard(_bounds.kappa_crit, ba),
        "eps_crit": soft(_bounds.eps_crit, ba, kappa),
        "ab_crit": soft(_bounds.ab_crit, kappa, req.eps),
        "acceleration_possible": soft(_bounds.acceleration_possible, ba, kappa, req.eps),
        "max_unstable_kappa": soft(_bounds.max_unstable_kappa, ba, req.eps),
    }
    if phys is not None:
        out["si"] = {**scales_si(phys), "kappa_ratio": phys.kappa / phys.kappa_crit}
    line = []
    for phi in req.phi:
        try:
            psi = guard(_bounds.acceleration_line, ba, kappa, req.eps, phi)
            line.append({"phi": phi, "psi": psi})
        except ComputeError as exc:
            line.append({"phi": phi, "psi": None, "error": str(exc)})
    out["acceleration_line"] = line
    return json_dict(out)


def stiffness(req: StiffnessRequest) -> dict[str, Any]:
    """Eigenvalue k/k_* and, with physical parameters, the critical dimension [m]."""
    phys: dict[str, Any] = {}
    if req.physical is not None:
        ph = req.physical
        phys = {
            "mu": ph.mu,
            "nu": ph.nu,
            "mode_of_slip": ph.mode_of_slip,
            "sigma": ph.sigma_Pa,
            "a": ph.a,
            "b": ph.b,
            "Dc": ph.Dc_m,
        }
        if ph.h is not None:
            phys["h"] = ph.h
    from rsfcore.stiffness import stiffness_summary  # lazily: it loads scipy.integrate

    out = json_dict(guard(stiffness_summary, req.case, req.mode, **phys))
    if req.physical is not None:  # every answer echoes the parameters it used
        out["physical"] = req.physical.model_dump()
    return out


def classify_points(req: ClassifyPointsRequest) -> dict[str, Any]:
    """Outcomes of many start points for one parameter set (rsfcore.phase.classify_points:
    the separatrix once, points near it integrated); ``outcome[i]`` for (phi[i], psi[i])."""
    from rsfcore import phase as _phase

    p = guard(Params, ba=req.ba, kappa=req.kappa, eps=req.eps, vo=req.vo)
    res = guard(_phase.classify_points, p, np.asarray(req.phi), np.asarray(req.psi), req.rtol)
    out = json_dict(res.to_dict())
    out["rtol"] = req.rtol  # every answer echoes the parameters it used
    out["n_points"] = len(req.phi)
    return out
