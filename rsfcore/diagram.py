"""Stability diagrams: critical perturbation sizes (or outcomes) on a 2-D parameter grid.

Axes are any two of ``kappa_ratio`` (kappa/kappa_crit), ``eps``, ``ba`` (b/a) and
``size`` (perturbation size: d for a velocity jump, dv/v_o for a load-point jump).  The
remaining parameters are fixed by keywords.  ``critical_size[i, j]`` is the critical size
at (x[i], y[j]): 0 where every perturbation grows (kind zero), inf where none runs away
(kind infinite).  With ``size`` given (or a ``size`` axis) the outcome of that
perturbation is decided from the critical size: unstable iff size > critical size.

The whole grid is one call of rsfcore.batch.critical_grid (its parameters generated from
the axes' values, never laid out): each point goes through the per-point kernel of every
batch (rsfcore.critical.critical_point: exact zero/infinite decisions, compiled closed
forms at kappa = kappa_crit, the separatrix method elsewhere) and the one definition of
the stored value, the boundary flag and the outcome (rsfcore.batchloop.finish_point), so
the diagram is, bit for bit, rsfcore.batch.critical_points on the same points
(tests/core/test_diagram.py).  A size axis is laid innermost, so each parameter point is
computed once for all its sizes.  The rare points where the separatrix method does not
apply are recomputed by bisection on classify() (a bisection that raises raises here).
Points on x = eps kappa/kappa_crit = 1 or kappa = kappa_crit up to rounding
(critical.BOUNDARY_RTOL) are flagged in ``on_boundary``.
"""

from __future__ import annotations

import csv
import io
import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from . import limits as lim
from ._version import NUMERICS_VERSION
from .batch import AxisTable, critical_grid
from .batchloop import OUTCOMES
from .critical import (
    DEFAULT_RTOL,
    KIND_FINITE,
    KINDS,
    METHODS,
    PERTURBATIONS,
    bisect_critical,
)
from .errors import UndecidedError
from .jsonsafe import finite_list
from .params import KAPPA_MAX, ParameterError, Params

__all__ = ["AXIS_NAMES", "DiagramResult", "stability_diagram", "OUTCOMES", "MAX_POINTS"]

AXIS_NAMES: tuple[str, ...] = ("kappa_ratio", "eps", "ba", "size")
#: largest number of grid points accepted in one call
MAX_POINTS = 4_000_000


@dataclass
class DiagramResult:
    """A stability diagram on the grid x (axis 0) by y (axis 1).

    Attributes:
        x_name, y_name: axis names (AXIS_NAMES); x, y: the axis values (1-D).
        critical_size: (nx, ny) float array; 0 where kind is zero, inf where infinite.
        kind: (nx, ny) int8 codes into KINDS = ("zero", "finite", "infinite").
        on_boundary: (nx, ny) bool, point on x = 1 or kappa = kappa_crit up to rounding.
        rel_accuracy: (nx, ny) estimated relative accuracy of critical_size (0 for exact
            decisions).
        method: (nx, ny) int8 codes into ``methods`` (critical.METHODS).
        outcome: None, or (nx, ny) int8 codes into OUTCOMES (0 stable, 1 unstable) for the
            given size / the size axis.
        outcome_uncertain: None, or (nx, ny) bool: |size/critical - 1| within the accuracy,
            or kappa = kappa_crit up to rounding with v_o > 0 (zero and finite touch there).
        fixed: the fixed parameters (ba, kappa_ratio, eps, vo, size where not an axis).
        perturbation, rtol: as requested.
        n_fallback: parameter points recomputed by bisection (once for all their sizes).
    """

    x_name: str
    x: NDArray[np.float64]
    y_name: str
    y: NDArray[np.float64]
    critical_size: NDArray[np.float64]
    kind: NDArray[np.int8]
    on_boundary: NDArray[np.bool_]
    rel_accuracy: NDArray[np.float64]
    method: NDArray[np.int8]
    perturbation: str
    rtol: float
    fixed: dict[str, float | None]
    outcome: NDArray[np.int8] | None = None
    outcome_uncertain: NDArray[np.bool_] | None = None
    methods: tuple[str, ...] = field(default=METHODS)
    n_fallback: int = 0

    @property
    def finite(self) -> NDArray[np.bool_]:
        """Mask of points with a finite, positive critical size."""
        return self.kind == KIND_FINITE

    def to_dict(self) -> dict[str, Any]:
        """JSON-safe dict: nested lists [i][j]; infinite critical sizes are null."""
        cs = finite_list(self.critical_size)
        d: dict[str, Any] = {
            "x_name": self.x_name,
            "x": self.x.tolist(),
            "y_name": self.y_name,
            "y": self.y.tolist(),
            "critical_size": cs,
            "kind": self.kind.astype(int).tolist(),
            "kind_legend": list(KINDS),
            "on_boundary": self.on_boundary.tolist(),
            "rel_accuracy": self.rel_accuracy.tolist(),
            "method": self.method.astype(int).tolist(),
            "method_legend": list(self.methods),
            "perturbation": self.perturbation,
            "rtol": self.rtol,
            "fixed": dict(self.fixed),
            "n_fallback": int(self.n_fallback),
            "numerics_version": NUMERICS_VERSION,
            "outcome": None if self.outcome is None else self.outcome.astype(int).tolist(),
            "outcome_legend": list(OUTCOMES),
            "outcome_uncertain": None
            if self.outcome_uncertain is None
            else self.outcome_uncertain.tolist(),
        }
        return d

    def save(self, path: str | Path) -> Path:
        """Write the grid to .npz (arrays x, y, critical_size, kind, on_boundary,
        rel_accuracy[, outcome, outcome_uncertain] and a JSON ``meta`` string), .csv (one row
        per point: i, j, x, y, critical_size ('inf' where infinite), kind, on_boundary,
        rel_accuracy[, outcome, outcome_uncertain]) or .json (:meth:`to_dict`).
        Returns the path."""
        p = Path(path)
        ext = p.suffix.lower()
        if ext not in (".npz", ".csv", ".json"):
            raise ParameterError("path", str(path), "a file name ending in .npz, .csv or .json")
        if ext == ".json":
            p.write_text(json.dumps(self.to_dict()))
            return p
        if ext == ".npz":
            arrays: dict[str, Any] = {
                "x": self.x,
                "y": self.y,
                "critical_size": self.critical_size,
                "kind": self.kind,
                "on_boundary": self.on_boundary,
                "rel_accuracy": self.rel_accuracy,
                "method": self.method,
            }
            if self.outcome is not None:
                arrays["outcome"] = self.outcome
                arrays["outcome_uncertain"] = self.outcome_uncertain
            meta = {
                k: v
                for k, v in self.to_dict().items()
                if k
                in (
                    "x_name",
                    "y_name",
                    "kind_legend",
                    "method_legend",
                    "perturbation",
                    "rtol",
                    "fixed",
                    "outcome_legend",
                    "numerics_version",
                )
            }
            arrays["meta"] = np.array(json.dumps(meta))
            with open(p, "wb") as fh:
                np.savez(fh, **arrays)
            return p
        buf = io.StringIO()
        w = csv.writer(buf)
        head = [
            "i",
            "j",
            self.x_name,
            self.y_name,
            "critical_size",
            "kind",
            "on_boundary",
            "rel_accuracy",
        ]
        if self.outcome is not None:
            head += ["outcome", "outcome_uncertain"]
        w.writerow(head)
        for i in range(self.x.size):
            for j in range(self.y.size):
                row = [
                    i,
                    j,
                    repr(float(self.x[i])),
                    repr(float(self.y[j])),
                    repr(float(self.critical_size[i, j])),
                    KINDS[int(self.kind[i, j])],
                    int(self.on_boundary[i, j]),
                    repr(float(self.rel_accuracy[i, j])),
                ]
                if self.outcome is not None:
                    row += [OUTCOMES[int(self.outcome[i, j])], int(self.outcome_uncertain[i, j])]  # type: ignore[index]
                w.writerow(row)
        p.write_text(buf.getvalue())
        return p


def _axis(name: str, values: ArrayLike) -> NDArray[np.float64]:
    try:
        a = np.asarray(values, dtype=np.float64)
    except (TypeError, ValueError):
        raise ParameterError(name, values, "a 1-D sequence of finite numbers") from None
    if a.ndim == 0:
        a = a.reshape(1)
    if a.ndim != 1 or a.size == 0 or not np.all(np.isfinite(a)):
        raise ParameterError(name, values, "a non-empty 1-D sequence of finite numbers")
    return a


def _check_values(name: str, a: NDArray[np.float64]) -> None:
    if name == "ba":
        bad = lim.BA.bad_mask(a)
        valid = lim.BA.text
    elif name == "eps":
        bad = lim.EPS.bad_mask(a)
        valid = lim.EPS.text
    elif name == "kappa_ratio":
        bad = lim.KAPPA_RATIO.bad_mask(a)
        valid = "[0, 1e6/(b/a - 1)]"
    else:
        bad = lim.DIAGRAM_SIZE.bad_mask(a)
        valid = lim.DIAGRAM_SIZE.text + " (the critical size refers to positive perturbations)"
    if np.any(bad):
        raise ParameterError(name, float(a[np.argmax(bad)]), valid)


def stability_diagram(
    x_name: str,
    x_values: ArrayLike,
    y_name: str,
    y_values: ArrayLike,
    *,
    ba: float = 2.0,
    kappa_ratio: float = 2.0,
    eps: float = 0.25,
    vo: float = 1.0,
    perturbation: str = "velocity-jump",
    size: float | None = None,
    rtol: float = DEFAULT_RTOL,
) -> DiagramResult:
    """Critical perturbation sizes (and outcomes for a size) on the grid x_values by y_values.

    Args:
        x_name, y_name: two different names from AXIS_NAMES.
        x_values, y_values: 1-D finite values (ba in (1, 1e6], eps in [0, 1],
            kappa_ratio >= 0 with kappa = kappa_ratio (b/a - 1) <= 1e6, size >= 0).
        ba, kappa_ratio, eps, vo: the parameters not on an axis (vo = 0 or > 0); defaults
            b/a = 2, kappa/kappa_crit = 2, eps = 0.25, v_o = 1 (rsfcore.limits).
        perturbation: "velocity-jump" or "load-point-jump" (the latter needs vo > 0).
        size: perturbation size for the outcome mode (not with a "size" axis), >= 0.
        rtol: requested relative accuracy of the finite critical sizes, [1e-13, 1e-3].

    Returns a DiagramResult; critical_size[i, j] belongs to (x[i], y[j]).  On the
    benchmark grid (100 x 100, kappa_ratio in [1, 5] x eps in [0, 0.99], velocity jump)
    it takes ~0.04 s on one core after warm-up, with ~5e-13 relative error on the finite
    points (bench/bench_diagram.py).
    """
    if x_name not in AXIS_NAMES:
        raise ParameterError("x_name", x_name, "one of " + ", ".join(AXIS_NAMES))
    if y_name not in AXIS_NAMES:
        raise ParameterError("y_name", y_name, "one of " + ", ".join(AXIS_NAMES))
    if x_name == y_name:
        raise ParameterError("y_name", y_name, f"an axis different from x_name={x_name!r}")
    if perturbation not in PERTURBATIONS:
        raise ParameterError("perturbation", perturbation, "one of " + ", ".join(PERTURBATIONS))
    rtol = lim.RTOL.check(rtol)
    xv = _axis(x_name, x_values)
    yv = _axis(y_name, y_values)
    _check_values(x_name, xv)
    _check_values(y_name, yv)
    nx, ny = xv.size, yv.size
    if nx * ny > MAX_POINTS:
        raise ParameterError("x_values", f"{nx} x {ny}", f"at most {MAX_POINTS} grid points")
    # the fixed parameters (validated through Params)
    p_fixed = Params.from_ratio(ba, kappa_ratio, eps, vo)
    size_axis = "size" in (x_name, y_name)
    if size_axis and size is not None:
        raise ParameterError("size", size, "None when 'size' is an axis")
    if size is not None:
        size = lim.DIAGRAM_SIZE.check(size)
    pert = PERTURBATIONS.index(perturbation)
    if pert == 1 and p_fixed.vo == 0.0:
        raise ParameterError(
            "vo", vo, "> 0 for a load-point jump (relative jump of a moving load point)"
        )

    # kappa = kappa_ratio (b/a - 1) <= KAPPA_MAX at every point (the first bad one in
    # C order of the grid named)
    vals = {"ba": p_fixed.ba, "kappa_ratio": float(kappa_ratio), "eps": p_fixed.eps}

    def along(name: str) -> NDArray[np.float64]:
        if name == x_name:
            return xv[:, None]
        if name == y_name:
            return yv[None, :]
        return np.asarray(vals[name])

    r_g, ba_g = np.broadcast_arrays(along("kappa_ratio"), along("ba"))
    bad = r_g * (ba_g - 1.0) > KAPPA_MAX
    if np.any(bad):
        raise ParameterError(
            "kappa_ratio",
            float(r_g.ravel()[np.argmax(bad)]),
            f"kappa_ratio*(b/a - 1) <= {KAPPA_MAX:g}",
        )

    # The grid in C order with a size axis innermost (x = size: laid out as (y, x) and
    # transposed), so the compiled loop computes each parameter point once and decides
    # its outcome at every size (rsfcore.batch.critical_grid: the loop and the finishing
    # rules of every batch, rsfcore.batchloop.finish_point).
    swap = x_name == "size"
    (o_name, o_v), (i_name, i_v) = (
        ((y_name, yv), (x_name, xv)) if swap else ((x_name, xv), (y_name, yv))
    )
    tab: dict[str, float | AxisTable] = {
        name: AxisTable(o_v, i_v.size)
        if name == o_name
        else AxisTable(i_v, 1)
        if name == i_name
        else v
        for name, v in vals.items()
    }
    size_t: float | AxisTable | None = size
    if size_axis:
        size_t = AxisTable(o_v, i_v.size) if o_name == "size" else AxisTable(i_v, 1)
    g = critical_grid(
        tab["ba"],
        tab["kappa_ratio"],
        tab["eps"],
        p_fixed.vo,
        0,
        nx * ny,
        kappa_is_ratio=True,
        perturbation=perturbation,
        rtol=rtol,
        size=size_t,
        sizes_from_critical=True,
    )
    if g.errors:
        # a bisection that raised: rerun it at the first such point, so its exception
        # reaches the caller as it is
        first = min(g.errors)
        at = {o_name: o_v[first // i_v.size], i_name: i_v[first % i_v.size]}
        q = {k: float(at.get(k, v)) for k, v in vals.items()}
        bisect_critical(
            Params(q["ba"], q["kappa_ratio"] * (q["ba"] - 1.0), q["eps"], p_fixed.vo),
            perturbation,
            rtol=rtol,
        )
        raise UndecidedError(f"({x_name}, {y_name}) point {first}: {g.errors[first]}")

    def grid(name: str) -> NDArray[Any]:
        a = g.array(name).reshape(o_v.size, i_v.size)
        return np.ascontiguousarray(a.T) if swap else a

    res = DiagramResult(
        x_name=x_name,
        x=xv,
        y_name=y_name,
        y=yv,
        critical_size=grid("critical_size"),
        kind=grid("kind"),
        on_boundary=grid("on_boundary"),
        rel_accuracy=grid("rel_accuracy"),
        method=grid("method"),
        perturbation=perturbation,
        rtol=rtol,
        fixed={
            k: (None if k in (x_name, y_name) else v)
            for k, v in {
                "ba": p_fixed.ba,
                "kappa_ratio": float(kappa_ratio),
                "eps": p_fixed.eps,
                "vo": p_fixed.vo,
                "size": size,
            }.items()
        },
        # parameter points bisected (a size axis lists each of them once per size)
        n_fallback=g.n_fallback // (i_v.size if size_axis else 1),
    )
    if size_axis or size is not None:
        res.outcome = grid("outcome")
        res.outcome_uncertain = grid("outcome_uncertain")
    return res
