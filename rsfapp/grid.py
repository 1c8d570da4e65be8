"""Expand a :class:`~rsfapp.requests.SweepRequest` into axis values and a stored spec, validating ranges.

Errors name the offending field (e.g. ``x.values[3]``, ``y.stop``) and its range, and are
raised before anything is written.
"""
from __future__ import annotations

import math
from typing import Any

import numpy as np
from rsfcore.params import ParameterError, Params

from .requests import AXIS_RANGES, SweepAxis, SweepRequest

__all__ = ["SpecError", "axis_values", "expand"]


class SpecError(ParameterError):
    """An invalid sweep spec: ``field`` names the input (e.g. ``x.values[3]``)."""

    def __init__(self, field: str, detail: str, valid: str) -> None:
        self.field, self.value, self.valid = field, None, valid
        ValueError.__init__(self, f"{field}: {detail} (valid range: {valid})")


def _bad(field: str, detail: str, valid: str) -> SpecError:
    return SpecError(field, detail, valid)


def _in_range(name: str, v: float) -> bool:
    lo, hi, _ = AXIS_RANGES[name]
    if not math.isfinite(v) or v > hi or v < lo:
        return False
    return not (name == "ba" and v <= 1.0)


def axis_values(ax: SweepAxis, which: str) -> list[float]:
    """Values of one axis (explicit or start/stop/n), each checked against its range."""
    valid = AXIS_RANGES[ax.name][2]
    if ax.values is not None:
        if any(v is not None for v in (ax.start, ax.stop, ax.n)):
            raise _bad(f"{which}.values", "give either values or start/stop/n", valid)
        vals = [float(v) for v in ax.values]
        for k, v in enumerate(vals):
            if not _in_range(ax.name, v):
                raise _bad(f"{which}.values[{k}]", f"{v!r} out of range for {ax.name}", valid)
        return vals
    for f in ("start", "stop", "n"):
        if getattr(ax, f) is None:
            raise _bad(f"{which}.{f}", "required when values is not given",
                       "[1, 1000]" if f == "n" else valid)
    for f in ("start", "stop"):
        if not _in_range(ax.name, getattr(ax, f)):
            raise _bad(f"{which}.{f}", f"{getattr(ax, f)!r} out of range for {ax.name}", valid)
    if ax.log:
        if ax.start <= 0 or ax.stop <= 0:
            raise _bad(f"{which}.start", "log spacing needs start, stop > 0", "> 0")
        vals = np.geomspace(ax.start, ax.stop, ax.n).tolist()
    else:
        vals = np.linspace(ax.start, ax.stop, ax.n).tolist()
    vals[0], vals[-1] = float(ax.start), float(ax.stop)  # exact end points
    return [min(max(v, AXIS_RANGES[ax.name][0]), AXIS_RANGES[ax.name][1]) for v in vals]


def expand(req: SweepRequest, max_points: int) -> dict[str, Any]:
    """Validated spec {x:{name,values}, y:{name,values}, fixed, perturbation, rtol}."""
    if req.x.name == req.y.name:
        raise _bad("y.name", "x and y must be different parameters",
                   "one of kappa_ratio, eps, ba, size other than x.name")
    xs, ys = axis_values(req.x, "x"), axis_values(req.y, "y")
    n = len(xs) * len(ys)
    if n > max_points:
        raise _bad("y.values", f"grid of {n} points exceeds the limit", f"<= {max_points} points")
    fixed = req.fixed.model_dump()
    axes = (req.x.name, req.y.name)
    # Every parameter combination must be valid for rsfcore (checked on the extremes of
    # each axis: the constraints are monotone in each parameter).
    cand = {name: [v] for name, v in fixed.items()}
    cand[req.x.name] = sorted({min(xs), max(xs)})
    cand[req.y.name] = sorted({min(ys), max(ys)})
    for ba in cand["ba"]:
        for kr in cand["kappa_ratio"]:
            try:
                Params.from_ratio(ba, kr, fixed["eps"], fixed["vo"])
            except ParameterError as exc:
                field = ("x.values" if "kappa_ratio" == axes[0] else "y.values") \
                    if "kappa_ratio" in axes else "fixed.kappa_ratio"
                raise _bad(field, str(exc), "kappa_ratio*(ba-1) <= 1e6") from None
    size_given = fixed["size"] is not None or "size" in axes
    if req.perturbation == "load-point-jump":
        if fixed["vo"] == 0:
            raise _bad("fixed.vo", "load-point-jump needs vo > 0", "(0, 1e300]")
        if size_given and min(cand["size"]) <= -1:
            raise _bad("fixed.size" if "size" not in axes else
                       ("x.values" if axes[0] == "size" else "y.values"),
                       "load-point-jump needs size > -1", "(-1, 1e3]")
    return {"x": {"name": req.x.name, "values": xs}, "y": {"name": req.y.name, "values": ys},
            "fixed": fixed, "perturbation": req.perturbation, "rtol": req.rtol}
