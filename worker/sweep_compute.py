"""Numerics of one sweep segment: one x value, a run of y values, via rsfcore.

A segment is first computed with ``rsfcore.diagram.stability_diagram`` (one call for
the whole run); if that raises, the segment is redone point by point so that a failing
point is recorded with its message while the others are kept.  Pure: no I/O.
"""
from __future__ import annotations

import math
from typing import Any, Callable

from rsfcore.params import Params

__all__ = ["point_values", "compute_point", "compute_segment", "KIND_NAMES"]

#: rsfcore.diagram kind codes -> names (order of CriticalResult kinds).
KIND_NAMES = {0: "zero", 1: "finite", 2: "infinite"}


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


def _diagram(spec: dict[str, Any], xv: float, ys: list[float]) -> list[dict[str, Any]] | None:
    """The segment through rsfcore.diagram, or None if unavailable or it raised."""
    try:
        from rsfcore import diagram
    except ImportError:
        return None
    fixed = {k: v for k, v in spec["fixed"].items()
             if k not in (spec["x"]["name"], spec["y"]["name"])}
    try:
        d = diagram.stability_diagram(spec["x"]["name"], [xv], spec["y"]["name"], ys,
                                      perturbation=spec["perturbation"], rtol=spec["rtol"],
                                      **fixed)
    except Exception:  # noqa: BLE001 - redo point by point to isolate the failure
        return None
    with_size = spec["fixed"].get("size") is not None or "size" in (
        spec["x"]["name"], spec["y"]["name"])
    out = []
    for j in range(len(ys)):
        if with_size:
            oc = d.outcome[0][j]
            out.append({"kind": None, "critical_size": None,
                        "outcome": oc if isinstance(oc, str) else
                        ("unstable" if int(oc) else "stable"),
                        "rel_accuracy": None, "error": None})
        else:
            kind = d.kind[0][j]
            out.append({"kind": KIND_NAMES.get(int(kind), str(kind)),
                        "critical_size": _f(d.critical_size[0][j]), "outcome": None,
                        "rel_accuracy": None, "error": None})
    return out


def compute_segment(spec: dict[str, Any], xv: float, ys: list[float],
                    cancelled: Callable[[], bool] | None = None,
                    per_point: bool = False) -> list[dict[str, Any]]:
    """Results for (xv, y) for y in ys, in order; stops early (shorter list) on cancel."""
    if not per_point:
        res = _diagram(spec, xv, ys)
        if res is not None:
            return res
    out = []
    for yv in ys:
        if cancelled is not None and cancelled():
            break
        out.append(compute_point(spec, xv, yv))
    return out
