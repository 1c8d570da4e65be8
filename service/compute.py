"""The one adapter between the service/worker and :mod:`rsfcore`.

Each function takes a validated request model, calls rsfcore and returns a JSON-safe
dict.  rsfcore's ``ParameterError`` becomes a 422 naming the field; a numerical failure
(e.g. ``UndecidedError``) becomes :class:`ComputeError` (reported as 422 "could not be
computed" by the API, recorded per point by sweeps).  Nothing here does I/O.
"""
from __future__ import annotations

import importlib
import math
from typing import Any

import numpy as np

import rsfcore
from rsfcore.params import ParameterError, Params, PhysicalParams

from .errors import ProblemError
from .schemas import (AnalyticRequest, BoundariesRequest, ClassifyRequest, CriticalRequest,
                      StiffnessRequest, TrajectoryRequest)

__all__ = ["ComputeError", "numerics_version", "classify", "trajectory", "critical",
           "analytic_u", "boundaries", "stiffness", "jsonsafe", "guard"]


class ComputeError(RuntimeError):
    """Valid input whose computation failed numerically (message says why)."""


def numerics_version() -> str:
    """rsfcore.NUMERICS_VERSION (part of every cache key)."""
    return str(getattr(rsfcore, "NUMERICS_VERSION", "dev"))


def _mod(name: str) -> Any:
    """rsfcore.<name>, imported lazily; 501-style problem if it does not exist yet."""
    try:
        return importlib.import_module(f"rsfcore.{name}")
    except ImportError as exc:  # pragma: no cover - only while the core is being written
        raise ComputeError(f"rsfcore.{name} is not available: {exc}") from exc


def jsonsafe(x: Any) -> Any:
    """Recursively convert numpy types to Python and non-finite floats to None."""
    if isinstance(x, dict):
        return {str(k): jsonsafe(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [jsonsafe(v) for v in x]
    if isinstance(x, np.ndarray):
        return jsonsafe(x.tolist())
    if isinstance(x, (np.floating, float)):
        v = float(x)
        return v if math.isfinite(v) else None
    if isinstance(x, np.integer):
        return int(x)
    if isinstance(x, np.bool_):
        return bool(x)
    return x


def guard(fn, *args: Any, **kwargs: Any) -> Any:  # noqa: ANN001
    """Call ``fn``; ParameterError -> 422 ProblemError, other failures -> ComputeError."""
    try:
        return fn(*args, **kwargs)
    except ParameterError as exc:
        raise ProblemError(422, "Invalid input", str(exc), field=exc.field,
                           valid=exc.valid) from None
    except (ProblemError, ComputeError):
        raise
    except (ArithmeticError, ValueError, RuntimeError, FloatingPointError) as exc:
        raise ComputeError(f"{type(exc).__name__}: {exc}") from exc


def _params(req: Any) -> Params:
    return guard(Params, ba=req.ba, kappa=req.kappa, eps=req.eps, vo=req.vo)


def classify(req: ClassifyRequest) -> dict[str, Any]:
    """Stable/unstable outcome with certificate, peak and times (dimensionless)."""
    traj = _mod("trajectory")
    start = None if req.start is None else (req.start.phi, req.start.psi)
    res = guard(traj.classify, _params(req), req.perturbation, req.size, start=start,
                rtol=req.rtol)
    return jsonsafe(res.to_dict())


def trajectory(req: TrajectoryRequest) -> dict[str, Any]:
    """Outcome plus the trajectory downsampled to ``n_points`` (SI columns if asked)."""
    traj = _mod("trajectory")
    p = _params(req)
    start = None if req.start is None else (req.start.phi, req.start.psi)
    physical = None
    if req.physical is not None:
        s = req.physical
        physical = guard(PhysicalParams.from_dimensionless, p, a=s.a, Dc=s.Dc, sigma=s.sigma,
                         V_star=s.V_star, f_star=s.f_star)
    res = guard(traj.simulate, p, req.perturbation, req.size, start=start, rtol=req.rtol,
                t_end=req.t_end, n_points=req.n_points, physical=physical)
    return jsonsafe(res.to_dict())


def critical(req: CriticalRequest) -> dict[str, Any]:
    """Critical perturbation size, same fields as ``rsf critical --json``."""
    crit = _mod("critical")
    res = guard(crit.critical_perturbation, _params(req), req.perturbation, rtol=req.rtol)
    return jsonsafe(res.to_dict())


def analytic_u(req: AnalyticRequest) -> dict[str, Any]:
    """U at the given points or on the grid (closed form, vectorised)."""
    an = _mod("analytic")
    if req.points is not None:
        phi = np.array([p.phi for p in req.points])
        psi = np.array([p.psi for p in req.points])
        out: dict[str, Any] = {"phi": phi, "psi": psi}
    else:
        g = req.grid
        phi1 = np.linspace(g.phi_min, g.phi_max, g.n_phi)
        psi1 = np.linspace(g.psi_min, g.psi_max, g.n_psi)
        phi, psi = np.meshgrid(phi1, psi1, indexing="ij")
        out = {"phi": phi1, "psi": psi1, "shape": [g.n_phi, g.n_psi]}
    with np.errstate(all="ignore"):
        if req.function == "kcrit":
            u = guard(an.U_kcrit, phi, psi, req.ba, req.eps, req.vo)
        else:
            u = guard(an.U_vo0, phi, psi, req.ba, req.kappa, req.eps)
    out.update(function=req.function, U=np.asarray(u, dtype=float))
    return jsonsafe(out)


def boundaries(req: BoundariesRequest) -> dict[str, Any]:
    """kappa_crit, eps_crit, (a/b)_crit, acceleration possibility and line."""
    b = _mod("boundaries")

    def soft(fn, *a: Any) -> Any:  # noqa: ANN001
        try:
            return guard(fn, *a)
        except ComputeError as exc:
            return {"error": str(exc)}

    out: dict[str, Any] = {
        "ba": req.ba, "kappa": req.kappa, "eps": req.eps,
        "kappa_crit": guard(b.kappa_crit, req.ba),
        "eps_crit": soft(b.eps_crit, req.ba, req.kappa),
        "ab_crit": soft(b.ab_crit, req.kappa, req.eps),
        "acceleration_possible": soft(b.acceleration_possible, req.ba, req.kappa, req.eps),
        "max_unstable_kappa": soft(b.max_unstable_kappa, req.ba, req.eps),
    }
    line = []
    for phi in req.phi:
        try:
            psi = guard(b.acceleration_line, req.ba, req.kappa, req.eps, phi)
            line.append({"phi": phi, "psi": psi})
        except ComputeError as exc:
            line.append({"phi": phi, "psi": None, "error": str(exc)})
    out["acceleration_line"] = line
    return jsonsafe(out)


def stiffness(req: StiffnessRequest) -> dict[str, Any]:
    """Eigenvalue k/k_* and, with physical parameters, the critical dimension [m]."""
    st = _mod("stiffness")
    phys = {} if req.physical is None else req.physical.model_dump()
    if phys and phys.get("h") is None:
        phys.pop("h")
    return jsonsafe(guard(st.stiffness_summary, req.case, req.mode, **phys))
