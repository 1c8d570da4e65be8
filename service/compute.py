"""The one adapter between the service/worker and :mod:`rsfcore`.

Each function takes a validated request model, calls rsfcore and returns a JSON-safe
dict.  rsfcore's ``ParameterError`` becomes a 422 naming the field; a numerical failure
(e.g. ``UndecidedError``) becomes :class:`ComputeError` (reported as 422 "could not be
computed" by the API, recorded per point by sweeps).  Nothing here does I/O; the
``*_png``/``figure`` functions encode images in memory through :mod:`rsfplots`.
"""
from __future__ import annotations

import importlib
import math
import threading
from typing import Any

import numpy as np

import rsfcore
from rsfcore.jsonsafe import jsonsafe
from rsfcore.params import ParameterError, Params, PhysicalParams

from .errors import ProblemError
from .schemas import (AnalyticRequest, BoundariesRequest, ClassifyRequest, CriticalRequest,
                      StiffnessRequest, TrajectoryRequest)

__all__ = ["ComputeError", "NeedsQueue", "QUICK_STEPS", "numerics_version", "classify", "trajectory", "critical",
           "analytic_u", "boundaries", "stiffness", "jsonsafe", "guard", "trajectory_png",
           "analytic_u_png", "figure", "figure_list", "figure_names", "sweep_diagram",
           "diagram_png"]


class ComputeError(RuntimeError):
    """Valid input whose computation failed numerically (message says why)."""


class NeedsQueue(ComputeError):
    """The quick in-process attempt ran out of its step budget: a long integration,
    to be computed by a worker (service.cached routes it through the queue)."""


#: Step budget of the in-process attempt at a single query (~0.2-0.5 s of integration);
#: a query that needs more is a long integration and goes through the Celery queue.
QUICK_STEPS = 300_000


def numerics_version() -> str:
    """rsfcore.NUMERICS_VERSION (part of every cache key)."""
    return str(getattr(rsfcore, "NUMERICS_VERSION", "dev"))


def _mod(name: str) -> Any:
    """rsfcore.<name>, imported lazily; 501-style problem if it does not exist yet."""
    try:
        return importlib.import_module(f"rsfcore.{name}")
    except ImportError as exc:  # pragma: no cover - only while the core is being written
        raise ComputeError(f"rsfcore.{name} is not available: {exc}") from exc


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
        if getattr(exc, "reason", None) == "budget" and kwargs.get("max_steps") == QUICK_STEPS:
            raise NeedsQueue(str(exc)) from exc
        raise ComputeError(f"{type(exc).__name__}: {exc}") from exc


def _params(req: Any) -> Params:
    return guard(Params, ba=req.ba, kappa=req.kappa, eps=req.eps, vo=req.vo)


def classify(req: ClassifyRequest, max_steps: int | None = QUICK_STEPS) -> dict[str, Any]:
    """Stable/unstable outcome with certificate, peak and times (dimensionless).

    With the default ``max_steps`` a query needing more work raises :class:`NeedsQueue`;
    ``max_steps=None`` (the worker) uses rsfcore's full budget."""
    traj = _mod("trajectory")
    start = None if req.start is None else (req.start.phi, req.start.psi)
    kw = {} if max_steps is None else {"max_steps": max_steps}
    res = guard(traj.classify, _params(req), req.perturbation, req.size, start=start,
                rtol=req.rtol, **kw)
    return jsonsafe(res.to_dict())


def trajectory(req: TrajectoryRequest, max_steps: int | None = QUICK_STEPS) -> dict[str, Any]:
    """Outcome plus the trajectory downsampled to ``n_points`` (SI columns if asked);
    ``max_steps`` as in :func:`classify`."""
    traj = _mod("trajectory")
    p = _params(req)
    start = None if req.start is None else (req.start.phi, req.start.psi)
    physical = None
    if req.physical is not None:
        s = req.physical
        physical = guard(PhysicalParams.from_dimensionless, p, a=s.a, Dc=s.Dc, sigma=s.sigma,
                         V_star=s.V_star, f_star=s.f_star)
    kw = {} if max_steps is None else {"max_steps": max_steps}
    res = guard(traj.simulate, p, req.perturbation, req.size, start=start, rtol=req.rtol,
                t_end=req.t_end, n_points=req.n_points, physical=physical, **kw)
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


# ------------------------------------------------------------------ images (?format=png)
# Plots come from rsfplots (matplotlib Agg, no pyplot), imported lazily so that the JSON
# API does not load matplotlib.  Matplotlib's shared state (font cache, mathtext parser)
# is not guaranteed thread-safe, so every render holds one process-wide lock.

_render_lock = threading.Lock()


def _plots() -> Any:
    try:
        return importlib.import_module("rsfplots")
    except ImportError as exc:  # pragma: no cover - only while rsfplots is being written
        raise ComputeError(f"rsfplots is not available: {exc}") from exc


def render_locked(fn, *args: Any, **kwargs: Any) -> bytes:  # noqa: ANN001
    """Call the plotting function ``fn`` under the render lock, with :func:`guard`."""
    with _render_lock:
        try:
            return guard(fn, *args, **kwargs)
        except (ProblemError, ComputeError):
            raise
        except Exception as exc:  # noqa: BLE001 - a plot that fails is a 422, never a 500
            raise ComputeError(f"could not be plotted: {type(exc).__name__}: {exc}") from exc


def trajectory_png(result: dict[str, Any]) -> bytes:
    """Phase plane (phi, psi) and phi(T) of a trajectory answer (JSON dict) as PNG."""
    return render_locked(_plots().plot_trajectory, result, "png")


def analytic_u_png(result: dict[str, Any]) -> bytes:
    """Contours of U (red: U = 0) of a grid answer of ``analytic_u`` as PNG."""
    if result.get("shape") is None:
        raise ProblemError(422, "Invalid input", "format: png needs U on a grid (give 'grid', "
                           "not 'points')", field="format", valid="'json' (points or grid) "
                           "or 'png' (grid only)")
    title = f"U ({result.get('function')}): U = const., red: U = 0"
    return render_locked(_plots().plot_u_field, result, title=title, fmt="png")


def figure(name: str, fmt: str, quality: str) -> bytes:
    """Paper figure ``name`` regenerated from rsfcore (rsfplots.render) as png/svg bytes."""
    plots = _plots()
    return render_locked(plots.render, name, fmt, quality=quality)


def figure_list() -> list[dict[str, Any]]:
    """[{name, caption, label, note}] of every reproducible figure of the paper."""
    plots = _plots()
    out = []
    for item in plots.list_figures():
        spec = plots.FIGURES.get(item["name"])
        out.append({"name": item["name"], "caption": item["caption"],
                    "label": getattr(spec, "label", None), "note": getattr(spec, "note", "")})
    return out


def figure_names() -> list[str]:
    """Names of the reproducible figures."""
    return list(_plots().FIGURES)


_OUTCOME_CODE = {"stable": 0.0, "unstable": 1.0}
_KIND_CODE = {"zero": 0, "finite": 1, "infinite": 2}


def sweep_diagram(status: dict[str, Any], pts: list[dict[str, Any]]) -> dict[str, Any]:
    """Assemble a (finished or partial) sweep into a stability diagram.

    The same layout as ``rsfcore.diagram.DiagramResult.to_dict()``: ``critical_size[i][j]``
    at (x[i], y[j]) (null where infinite or missing), ``kind`` codes 0 zero / 1 finite /
    2 infinite, ``outcome`` codes 0 stable / 1 unstable (null where missing) when the sweep
    classifies a size; plus ``present[i][j]`` (point computed without error), ``status``,
    ``n_done``, ``n_total``, ``n_failed``.
    """
    spec = status["spec"]
    xs, ys = spec["x"]["values"], spec["y"]["values"]
    nx, ny = len(xs), len(ys)
    axes = (spec["x"]["name"], spec["y"]["name"])
    size_mode = spec["fixed"].get("size") is not None or "size" in axes
    cs: list[list[float | None]] = [[None] * ny for _ in range(nx)]
    kind = [[1] * ny for _ in range(nx)]
    outcome: list[list[float | None]] = [[None] * ny for _ in range(nx)]
    present = [[False] * ny for _ in range(nx)]
    for p in pts:
        i, j = int(p["i"]), int(p["j"])
        if not (0 <= i < nx and 0 <= j < ny) or p.get("error"):
            continue
        if size_mode:
            if p.get("outcome") in _OUTCOME_CODE:
                outcome[i][j] = _OUTCOME_CODE[p["outcome"]]
                present[i][j] = True
        elif p.get("kind") in _KIND_CODE:
            kind[i][j] = _KIND_CODE[p["kind"]]
            v = p.get("critical_size")
            cs[i][j] = float(v) if v is not None and math.isfinite(v) else None
            present[i][j] = True
    fixed = {k: v for k, v in spec["fixed"].items() if k not in axes and v is not None}
    return {"x_name": axes[0], "x": xs, "y_name": axes[1], "y": ys, "critical_size": cs,
            "kind": kind, "kind_legend": list(_KIND_CODE), "outcome": outcome if size_mode
            else None, "outcome_legend": list(_OUTCOME_CODE), "present": present,
            "perturbation": spec["perturbation"], "rtol": spec["rtol"], "fixed": fixed,
            "id": status["id"], "status": status["status"], "n_done": status["n_done"],
            "n_total": status["n_total"], "n_failed": status["n_failed"],
            "numerics_version": status.get("numerics_version")}


def diagram_png(diagram: dict[str, Any]) -> bytes:
    """A sweep diagram (:func:`sweep_diagram`) as PNG; missing or failed points are blank."""
    d = dict(diagram)
    if d["outcome"] is not None:
        d["outcome"] = [[math.nan if v is None else v for v in row] for row in d["outcome"]]
    return render_locked(_plots().plot_diagram, d, "png")
