"""Numerics of one sweep point via rsfcore (pure: no I/O).

Points are computed one by one with the same rsfcore calls as
``rsfcore.diagram.stability_diagram`` makes per grid point (critical_perturbation, or
classify when a size is given), so that a failing point is recorded with its message
while the others are kept, and a cancel or a crash costs at most one point.
"""
from __future__ import annotations

import math
from typing import Any

from rsfcore.params import Params

__all__ = ["point_values", "compute_point"]


def point_values(spec: dict[str, Any], xv: float, yv: float) -> dict[str, Any]:
    """Parameter values at grid point (xv, yv): the fixed ones with the two axes set."""
    vals = dict(spec["fixed"])
    vals[spec["x"]["name"]] = xv
    vals[spec["y"]["name"]] = yv
    return vals


def _f(v: Any) -> float | None:
    try:
        v = float(v)
    except (TypeError, ValueError):
        return None
    return v if math.isfinite(v) else None


def compute_point(spec: dict[str, Any], xv: float, yv: float) -> dict[str, Any]:
    """One point: critical size (kind, critical_size) or, with a size, the outcome.

    Returns {"kind", "critical_size", "outcome", "rel_accuracy", "error"}; exceptions of
    rsfcore are caught and returned as ``error`` (type and message).
    """
    v = point_values(spec, xv, yv)
    try:
        p = Params.from_ratio(v["ba"], v["kappa_ratio"], v["eps"], v["vo"])
        if v.get("size") is not None:
            from rsfcore import trajectory
            r = trajectory.classify(p, spec["perturbation"], v["size"], rtol=spec["rtol"])
            return {"kind": None, "critical_size": None, "outcome": r.outcome,
                    "rel_accuracy": _f(r.rel_accuracy), "error": None}
        from rsfcore import critical
        c = critical.critical_perturbation(p, spec["perturbation"], rtol=spec["rtol"])
        d = c.to_dict()
        return {"kind": d.get("kind"), "critical_size": _f(d.get("critical_size")),
                "outcome": None, "rel_accuracy": _f(d.get("rel_accuracy")), "error": None}
    except Exception as exc:  # noqa: BLE001 - every failure is recorded, the sweep goes on
        return {"kind": None, "critical_size": None, "outcome": None, "rel_accuracy": None,
                "error": f"{type(exc).__name__}: {exc}"[:2000]}
