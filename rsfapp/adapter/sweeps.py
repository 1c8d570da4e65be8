"""Sweeps (:class:`rsfapp.requests.SweepRequest`): validated and expanded by
:func:`rsfapp.grid.expand`; the server computes them in chunks
(:func:`rsfapp.sweepdata.compute_chunk`, queued), while a small dimensionless 2-D sweep
(``rsf diagram``) is computed here, in this process, by rsfcore.diagram.stability_diagram
(the same decision per point: critical size, or the outcome of a fixed size)."""

from __future__ import annotations

from typing import Any

import numpy as np

from rsfcore import diagram as _diagram
from rsfcore.params import ParameterError

from ..requests import SweepRequest
from ._common import guard

__all__ = ["LOCAL_DIAGRAM_MAX_POINTS", "diagram", "diagram_summary"]

#: Largest local diagram (rsfcore.diagram.MAX_POINTS: one compiled call).
LOCAL_DIAGRAM_MAX_POINTS = _diagram.MAX_POINTS


def diagram(req: SweepRequest) -> _diagram.DiagramResult:
    """A dimensionless 2-D sweep (``x``/``y`` or two ``axes`` over kappa_ratio, eps, ba,
    size) computed in this process: the rsfcore DiagramResult (critical_size[i, j] at
    (x[i], y[j]), outcomes when a size is fixed or swept).  The axis values and the
    fixed parameters are the sweep's (:func:`rsfapp.grid.expand`: end points exact, the
    request model's defaults); ParameterError names the request's field."""
    from ..grid import expand  # lazily: it loads the service settings (pydantic-settings)

    spec = expand(req, LOCAL_DIAGRAM_MAX_POINTS)
    if spec.mode != "grid" or len(spec.axes) != 2:
        raise ParameterError("axes", len(spec.axes), "exactly two axes (x and y) for a diagram")
    if spec.physical is not None:
        raise ParameterError(
            "fixed.physical", "given", "null for a local diagram (SI sweeps: POST /v1/sweeps)"
        )
    for i, ax in enumerate(spec.axes):
        if ax.name not in _diagram.AXIS_NAMES:
            raise ParameterError(
                f"axes[{i}].name", ax.name, "one of " + ", ".join(_diagram.AXIS_NAMES)
            )
    f = spec.fixed
    kw: dict[str, Any] = {
        k: float(v) for k in ("ba", "eps", "vo") if (v := f.get(k)) is not None
    }  # a swept one is not fixed
    if spec.kappa_param == "kappa":
        kappa = f.get("kappa")
        if kappa is None or "ba" in spec.swept:
            raise ParameterError(
                "fixed.kappa", kappa, "kappa_ratio for a local diagram with a swept ba"
            )
        kw["kappa_ratio"] = float(kappa) / (kw["ba"] - 1.0)
    elif f.get("kappa_ratio") is not None:
        kw["kappa_ratio"] = float(f["kappa_ratio"])  # type: ignore[arg-type]
    x, y = spec.axes
    size = f.get("size")
    res: _diagram.DiagramResult = guard(
        _diagram.stability_diagram,
        x.name,
        x.all(),
        y.name,
        y.all(),
        perturbation=spec.perturbation,
        size=None if size is None else float(size),
        rtol=spec.rtol,
        **kw,
    )
    return res


def diagram_summary(res: _diagram.DiagramResult) -> dict[str, Any]:
    """Counts of a diagram: shape, finite/zero/infinite critical sizes, points on a
    boundary, the largest relative accuracy, and unstable outcomes when classified."""
    cs = np.asarray(res.critical_size)
    out: dict[str, Any] = {
        "shape": list(cs.shape),
        "n_finite": int(np.isfinite(cs).sum() - (cs == 0).sum()),
        "n_zero": int((cs == 0).sum()),
        "n_infinite": int(np.isinf(cs).sum()),
        "n_on_boundary": int(np.asarray(res.on_boundary).sum()),
        "max_rel_accuracy": float(np.max(np.asarray(res.rel_accuracy, dtype=float), initial=0.0)),
    }
    if getattr(res, "outcome", None) is not None:
        oc = np.asarray(res.outcome)
        out["n_unstable"] = (
            int((oc == "unstable").sum()) if oc.dtype.kind in "US" else int(oc.sum())
        )
    return out
