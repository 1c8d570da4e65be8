"""Critical sizes (and outcomes) at many arbitrary parameter points: one compiled call.

:func:`critical_points` is the array form of :func:`rsfcore.critical.critical_perturbation`
for points that are not on a 2-D grid (N-D grids flattened, scattered samples): the
parameters are 1-D arrays of equal length, any of them may vary, v_o included.  One
compiled loop (:func:`rsfcore.batchloop.points_kernel`) runs each point through the
per-point kernel of :func:`rsfcore.diagram.stability_diagram`
(:func:`rsfcore.critical.critical_point`: exact zero/infinite decisions, compiled closed
forms at kappa = kappa_crit and v_o = 0, the separatrix method elsewhere) and finishes it
(:func:`rsfcore.batchloop.finish_point`); then only the points the kernel flags
(``FLAG_FALLBACK``) are recomputed by bisection on certified classify() outcomes, one by
one.

v_o enters the critical size only through v_o = 0 versus v_o > 0: the system is invariant
under phi -> phi + ln v_o, psi -> psi + (1 - b/a) ln v_o, T -> v_o T, so critical sizes
of both perturbation kinds do not depend on v_o > 0 (module docstring of
rsfcore.critical).  The kernel computes every point at v_o = 1 or v_o = 0.

:func:`critical_grid` is the same computation at a range of flat indices of a grid (a
sweep's chunk) given by its axes' values (:class:`AxisTable`), without laying out the
parameters of the range: the compiled loop generates them
(:func:`rsfcore.batchloop.points_kernel`, which both functions run, so the same bits), and
reports which outputs are one repeated value over the range (:class:`GridResult`).

Failure isolation: a point whose fallback raises (e.g. UndecidedError) is marked in
``failed`` with its message in ``errors[i]``; every other point is kept.

Outcomes (``size`` given): as in stability_diagram, a perturbation of size >= 0 is
unstable iff size > critical size (kind zero: any size > 0), with ``outcome_uncertain``
where |size/critical - 1| is within the accuracy or kappa = kappa_crit up to rounding with
v_o > 0.  A negative size (a velocity drop, or a load-point slow-down dv in (-1, 0)) is
outside the critical-size statement and is certified by :func:`rsfcore.trajectory.classify`
per point (~60 us each).

Accuracy: identical numbers to ``critical_perturbation`` at each point (same kernel, same
fallback); tests/core/test_batch.py checks this to 1e-12 relative on random points.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray

from . import batchloop as _loop
from . import critical as _crit
from . import limits as lim
from .batchloop import OUTCOME_NONE, OUTCOME_STABLE, OUTCOME_UNSTABLE
from .params import ParameterError, Params

__all__ = [
    "AxisTable",
    "BatchResult",
    "GridResult",
    "critical_grid",
    "critical_points",
    "OUTCOME_STABLE",
    "OUTCOME_UNSTABLE",
    "OUTCOME_NONE",
    "KIND_FAILED",
]

#: kind / method code of a failed point
KIND_FAILED = -1


@dataclass
class BatchResult:
    """Per-point results of :func:`critical_points` (arrays of length n).

    Attributes:
        kind: int8 codes into rsfcore.critical.KINDS (0 zero, 1 finite, 2 infinite),
            KIND_FAILED (-1) where the point failed.
        critical_size: float64, 0 for kind zero, inf for infinite, nan where failed
            (dimensionless: d for a velocity jump, dv/v_o for a load-point jump).
        rel_accuracy: float64 estimated relative accuracy (0 for exact decisions, nan
            where failed).
        method: int8 codes into rsfcore.critical.METHODS, -1 where failed.
        on_boundary: bool, the point is on x = 1 or kappa = kappa_crit up to rounding.
        failed: bool, the point could not be computed (message in ``errors``).
        errors: {index: "ExceptionType: message"} for the failed points.
        outcome: None (no size) or int8 OUTCOME_STABLE / OUTCOME_UNSTABLE / OUTCOME_NONE.
        outcome_uncertain: None or bool (see the module docstring).
        n_fallback: points recomputed by bisection (or classify for negative sizes).
    """

    kind: NDArray[np.int8]
    critical_size: NDArray[np.float64]
    rel_accuracy: NDArray[np.float64]
    method: NDArray[np.int8]
    on_boundary: NDArray[np.bool_]
    failed: NDArray[np.bool_]
    errors: dict[int, str] = field(default_factory=dict)
    outcome: NDArray[np.int8] | None = None
    outcome_uncertain: NDArray[np.bool_] | None = None
    n_fallback: int = 0


def _arr(name: str, v: ArrayLike, n: int | None) -> NDArray[np.float64]:
    try:
        a = np.asarray(v, dtype=np.float64)
    except (TypeError, ValueError):
        raise ParameterError(name, v, "a 1-D array of finite numbers") from None
    if a.ndim > 1:
        raise ParameterError(name, f"shape {a.shape}", "a scalar or a 1-D array")
    if n is not None and a.ndim == 1 and a.size != n:
        raise ParameterError(name, f"length {a.size}", f"length {n} (as the other arrays)")
    return np.ascontiguousarray(np.broadcast_to(a, (n,) if n is not None else a.shape))


def _check(name: str, a: NDArray[np.float64], bad: NDArray[np.bool_], valid: str) -> None:
    if np.any(bad):
        i = int(np.argmax(bad))
        raise ParameterError(f"{name}[{i}]", float(a[i]), valid)


def _check_limit(limit: lim.Limit, a: NDArray[np.float64]) -> None:
    """ParameterError naming the first element of ``a`` outside ``limit`` and its range."""
    _check(limit.name, a, limit.bad_mask(a), limit.text)


def _check_inputs(
    ba: NDArray[np.float64],
    kappa: NDArray[np.float64] | None,
    eps: NDArray[np.float64],
    vo: NDArray[np.float64],
    pert: int,
) -> None:
    """The valid ranges of the parameters (rsfcore.limits: ParameterError naming the first
    bad element; ``kappa`` None: checked by the caller)."""
    _check_limit(lim.BA, ba)
    if kappa is not None:
        _check_limit(lim.KAPPA, kappa)
    _check_limit(lim.EPS, eps)
    _check_limit(lim.VO, vo)
    if pert == 1:
        _check("vo", vo, vo == 0.0, "> 0 for a load-point jump")


def _check_size(sz: NDArray[np.float64] | None, pert: int) -> None:
    """The valid range of perturbation sizes (rsfcore.limits; ParameterError naming the
    first bad one)."""
    if sz is not None:
        _check_limit(lim.VELOCITY_JUMP_SIZE if pert == 0 else lim.LOAD_POINT_JUMP_SIZE, sz)


def _perturbation(perturbation: str, rtol: float) -> tuple[int, float]:
    if perturbation not in _crit.PERTURBATIONS:
        raise ParameterError(
            "perturbation", perturbation, "one of " + ", ".join(_crit.PERTURBATIONS)
        )
    return _crit.PERTURBATIONS.index(perturbation), lim.RTOL.check(rtol)


def critical_points(
    ba: ArrayLike,
    kappa: ArrayLike,
    eps: ArrayLike,
    vo: ArrayLike,
    *,
    perturbation: str = "velocity-jump",
    rtol: float = _crit.DEFAULT_RTOL,
    size: ArrayLike | None = None,
) -> BatchResult:
    """Critical sizes (and outcomes for ``size``) at n parameter points.

    Args:
        ba: b/a, (1, 1e6]; 1-D array or scalar (1-D inputs share one length n).
        kappa: kappa = k/k_* (not the ratio), [0, 1e6]; length n or scalar.
        eps: evolution-law parameter, [0, 1]; length n or scalar.
        vo: load-point velocity v_o, 0 or (0, 1e300]; length n or scalar.
        perturbation: "velocity-jump" or "load-point-jump" (needs v_o > 0 at every point).
        rtol: requested relative accuracy of finite critical sizes, [1e-13, 1e-3].
        size: None, or perturbation sizes (length n or scalar): d in [-1e4, 1e4] for a
            velocity jump, dv/v_o > -1 for a load-point jump.

    Raises ParameterError naming the first bad element (e.g. ``eps[17]``).  Never raises
    for a numerical failure at one point: that point is marked ``failed``.
    """
    pert, rtol = _perturbation(perturbation, rtol)
    sizes = {
        int(np.size(v)) for v in (ba, kappa, eps, vo, size) if v is not None and np.ndim(v) >= 1
    }
    n = max(sizes) if sizes else 1
    ba_a = _arr("ba", ba, n)
    ka = _arr("kappa", kappa, n)
    ea = _arr("eps", eps, n)
    va = _arr("vo", vo, n)
    _check_inputs(ba_a, ka, ea, va, pert)
    sz = None if size is None else _arr("size", size, n)
    _check_size(sz, pert)
    one = np.ones(5, dtype=np.int64)
    r = _compute((ba_a, ka, ea, va, sz), one, 0, n, False, perturbation, rtol, lazy=False)
    return r.to_batch()


class AxisTable(NamedTuple):
    """A parameter of a grid (:func:`critical_grid`): its values along its axis and the
    axis's stride, the number of flat indices per step along it (the product of the
    lengths of the axes after it, C order).  The point with flat index i has the value
    ``values[(i // stride) % len(values)]``."""

    values: NDArray[np.float64]
    stride: int = 1


@dataclass
class GridResult:
    """Results of :func:`critical_grid` at the n points of a flat index range.

    Attributes:
        n: points in the range.
        values: per output (the names of :class:`BatchResult`'s arrays: kind,
            critical_size, rel_accuracy, method, on_boundary, failed, and outcome,
            outcome_uncertain when a size is given), its array of length n, or, where
            ``repeated`` says so, an array of length 1 whose element is every point's
            value (bit for bit).
        repeated: per output, True (one repeated value, stored once in ``values``), False
            (it varies), None (not known: the array is whole and may still be one value;
            after a per-point fallback).
        errors: {offset in the range: "ExceptionType: message"} for the failed points.
        n_fallback: points recomputed by bisection (or classify for negative sizes).
    """

    n: int
    values: dict[str, NDArray[np.generic]]
    repeated: dict[str, bool | None]
    errors: dict[int, str] = field(default_factory=dict)
    n_fallback: int = 0

    def array(self, name: str) -> NDArray[np.generic]:
        """The output ``name`` at every point (a repeated value laid out, same bits)."""
        v = self.values[name]
        return np.repeat(v, self.n) if self.repeated[name] else v

    def to_batch(self) -> BatchResult:
        """The same results as a :class:`BatchResult` (every array laid out)."""
        has = "outcome" in self.values
        return BatchResult(
            self.array("kind"),  # type: ignore[arg-type]
            self.array("critical_size"),  # type: ignore[arg-type]
            self.array("rel_accuracy"),  # type: ignore[arg-type]
            self.array("method"),  # type: ignore[arg-type]
            self.array("on_boundary"),  # type: ignore[arg-type]
            self.array("failed"),  # type: ignore[arg-type]
            dict(self.errors),
            self.array("outcome") if has else None,  # type: ignore[arg-type]
            self.array("outcome_uncertain") if has else None,  # type: ignore[arg-type]
            self.n_fallback,
        )


def _table(name: str, v: float | AxisTable) -> tuple[NDArray[np.float64], int]:
    """A parameter of :func:`critical_grid` as (values, stride), checked for shape."""
    t = v if isinstance(v, AxisTable) else AxisTable(np.array([v], dtype=np.float64), 1)
    a = _arr(name, t.values, None)
    if a.ndim != 1 or a.size == 0:
        raise ParameterError(name, f"shape {a.shape}", "a scalar or a non-empty 1-D table")
    if not int(t.stride) >= 1:
        raise ParameterError(f"{name}.stride", t.stride, ">= 1")
    return a, int(t.stride)


def critical_grid(
    ba: float | AxisTable,
    kappa: float | AxisTable,
    eps: float | AxisTable,
    vo: float | AxisTable,
    i0: int,
    i1: int,
    *,
    kappa_is_ratio: bool = False,
    perturbation: str = "velocity-jump",
    rtol: float = _crit.DEFAULT_RTOL,
    size: float | AxisTable | None = None,
    sizes_from_critical: bool = False,
) -> GridResult:
    """Critical sizes (and outcomes for ``size``) at the flat indices [i0, i1) of a grid:
    the results :func:`critical_points` gives on the range's parameters, bit for bit
    (the same compiled loop), without laying the parameters out.

    Args:
        ba, kappa, eps, vo, size: each a fixed value or an :class:`AxisTable` (values
            along its axis and the axis's stride); ranges as in :func:`critical_points`
            (size None: critical sizes only).
        i0, i1: the flat index range, 0 <= i0 <= i1.
        kappa_is_ratio: ``kappa`` holds kappa/kappa_crit, and kappa = kappa_ratio (ba - 1)
            (the same operation as on arrays), kappa_ratio >= 0 with kappa <= 1e6 at
            every combination of the two tables.
        perturbation, rtol: as in :func:`critical_points`.
        sizes_from_critical: sizes in :data:`rsfcore.limits.DIAGRAM_SIZE` (finite, >= 0,
            no upper end) instead of the ranges of :func:`critical_points`: every outcome
            is then decided from the critical size alone (never by classify, whose range
            bounds the others), as :func:`rsfcore.diagram.stability_diagram` does.

    Every value of every table is checked (ParameterError naming the table's element,
    e.g. ``eps[17]``), also those the range does not use.  The largest kappa of a ratio
    table is max(ratio) (max(ba) - 1): products and differences of non-negative doubles
    round monotonically, so no combination exceeds it.

    Cost: the compiled loop only (no parameter array; an output that is one repeated
    value over the range is not laid out: ``GridResult.repeated``)."""
    pert, rtol = _perturbation(perturbation, rtol)
    tb, sb = _table("ba", ba)
    tk, sk = _table("kappa", kappa)
    te, se = _table("eps", eps)
    tv, sv = _table("vo", vo)
    _check_inputs(tb, None if kappa_is_ratio else tk, te, tv, pert)
    if kappa_is_ratio:
        _check_limit(lim.KAPPA_RATIO, tk)
        top = float(tk.max()) * (float(tb.max()) - 1.0)
        if not top <= lim.KAPPA_MAX:
            raise ParameterError(
                "kappa_ratio", float(tk.max()), f"kappa_ratio*(b/a - 1) <= {lim.KAPPA_MAX:g}"
            )
    ts: NDArray[np.float64] | None = None
    ss = 1
    if size is not None:
        ts, ss = _table("size", size)
        if sizes_from_critical:
            _check("size", ts, lim.DIAGRAM_SIZE.bad_mask(ts), lim.DIAGRAM_SIZE.text)
        else:
            _check_size(ts, pert)
    i0, i1 = int(i0), int(i1)
    if not 0 <= i0 <= i1:
        raise ParameterError("i1", i1, f">= i0 = {i0} >= 0")
    strides = np.array([sb, sk, se, sv, ss], dtype=np.int64)
    return _compute((tb, tk, te, tv, ts), strides, i0, i1, kappa_is_ratio, perturbation, rtol)


#: the size table of a call without sizes (never read; read-only as every table
#: ``_arr`` gives, so the compiled loop has one signature)
_NO_SIZE = np.zeros(1)
_NO_SIZE.flags.writeable = False


def _compute(
    tables: tuple[
        NDArray[np.float64],
        NDArray[np.float64],
        NDArray[np.float64],
        NDArray[np.float64],
        NDArray[np.float64] | None,
    ],
    strides: NDArray[np.int64],
    i0: int,
    i1: int,
    kappa_is_ratio: bool,
    perturbation: str,
    rtol: float,
    lazy: bool = True,
) -> GridResult:
    """The compiled loop over [i0, i1) of checked tables, then the points it lists for
    Python (:func:`_finish_listed`)."""
    n = i1 - i0
    ba, kappa, eps, vo, sz = tables
    has_size = sz is not None
    m = n if has_size else 0
    kind = np.empty(n, dtype=np.int8)
    value = np.empty(n)
    acc = np.empty(n)
    meth = np.empty(n, dtype=np.int8)
    on_b = np.empty(n, dtype=np.bool_)
    outcome = np.empty(m, dtype=np.int8)
    unc = np.empty(m, dtype=np.bool_)
    same = np.empty(_loop.N_OUT, dtype=np.bool_)
    sp_idx = np.empty(n, dtype=np.int64)
    sp_flags = np.empty(n, dtype=np.int64)
    sp_par = np.empty((n, 5))
    pert = _crit.PERTURBATIONS.index(perturbation)
    n_sp = 0
    if n:
        n_sp = _loop.points_kernel(
            ba, kappa, eps, vo, _NO_SIZE if sz is None else sz, strides, i0, i1,
            kappa_is_ratio, has_size, pert, rtol, lazy,
            kind, value, acc, meth, on_b, outcome, unc, same, sp_idx, sp_flags, sp_par,
        )  # fmt: skip
    else:
        same[:] = False
    outs: dict[str, tuple[NDArray[np.generic], int]] = {
        "kind": (kind, _loop.OUT_KIND),
        "critical_size": (value, _loop.OUT_VALUE),
        "rel_accuracy": (acc, _loop.OUT_ACC),
        "method": (meth, _loop.OUT_METHOD),
        "on_boundary": (on_b, _loop.OUT_ON_BOUNDARY),
    }
    if has_size:
        outs["outcome"] = (outcome, _loop.OUT_OUTCOME)
        outs["outcome_uncertain"] = (unc, _loop.OUT_UNCERTAIN)
    values: dict[str, NDArray[np.generic]] = {}
    repeated: dict[str, bool | None] = {}
    if n_sp == 0:
        for name, (a, o) in outs.items():
            one = bool(same[o]) and n > 0
            values[name] = a[:1] if one else a
            repeated[name] = one
        values["failed"] = np.zeros(1 if lazy and n else n, dtype=np.bool_)
        repeated["failed"] = bool(lazy and n)
        return GridResult(n, values, repeated)
    # some points need Python: every output laid out, then those points finished
    for a, o in outs.values():
        if same[o]:
            a[1:] = a[0]
    failed = np.zeros(n, dtype=np.bool_)
    errors, n_fb = _finish_listed(
        kind, value, acc, meth, outcome, unc, failed,
        sp_idx[:n_sp], sp_flags[:n_sp], sp_par[:n_sp], has_size, perturbation, rtol,
    )  # fmt: skip
    values = {name: a for name, (a, _) in outs.items()}
    values["failed"] = failed
    return GridResult(n, values, dict.fromkeys(values, None if lazy else False), errors, n_fb)


def _bisect(p: Params, perturbation: str, rtol: float) -> tuple[int, float, float, int] | str:
    """(kind, critical size, accuracy, method) by :func:`rsfcore.critical.bisect_critical`
    (inf where infinite), or "ExceptionType: message" where it raised."""
    try:
        res = _crit.bisect_critical(p, perturbation, rtol=rtol)
    except Exception as exc:  # noqa: BLE001 - recorded per point, the batch goes on
        return f"{type(exc).__name__}: {exc}"[:2000]
    return (
        _crit.KINDS.index(res.kind),
        math.inf if res.critical_size is None else res.critical_size,
        res.rel_accuracy,
        _crit.M_ASYMPTOTE if res.method == _crit.METHODS[_crit.M_ASYMPTOTE] else _crit.M_BISECTION,
    )


def _finish_listed(
    kind: NDArray[np.int8],
    value: NDArray[np.float64],
    acc: NDArray[np.float64],
    meth: NDArray[np.int8],
    outcome: NDArray[np.int8],
    unc: NDArray[np.bool_],
    failed: NDArray[np.bool_],
    sp_idx: NDArray[np.int64],
    sp_flags: NDArray[np.int64],
    sp_par: NDArray[np.float64],
    has_size: bool,
    perturbation: str,
    rtol: float,
) -> tuple[dict[int, str], int]:
    """The points the compiled loop lists, in index order: FLAG_FALLBACK recomputed by
    bisection on certified classify() outcomes (a failure marks the point failed: kind
    and method -1, NaN size and accuracy), then finished as the loop finishes the
    others (:func:`rsfcore.batchloop.finish_point`); a negative size classified by
    :func:`rsfcore.trajectory.classify` (a failure marks the point failed, keeping its
    critical size).  A point listed again with the parameters of one already bisected (a
    size axis) takes that bisection's result instead of running it again.  Returns
    ({offset: message} of the failed points, points recomputed)."""
    from .trajectory import classify

    errors: dict[int, str] = {}
    n_fb = 0
    crtol = max(1e-13, min(1e-10, rtol))
    # bisections already run, by parameters (a size axis lists one point per size)
    done: dict[tuple[float, float, float, float], tuple[int, float, float, int] | str] = {}
    for j in range(sp_idx.size):
        i = int(sp_idx[j])
        fl = int(sp_flags[j])
        ba, kappa, eps, vo, sz = (float(x) for x in sp_par[j])
        p = Params(ba, kappa, eps, vo)
        if fl & _crit.FLAG_FALLBACK:
            n_fb += 1
            key = (ba, kappa, eps, vo)
            if key not in done:
                done[key] = _bisect(p, perturbation, rtol)
            got = done[key]
            if isinstance(got, str):
                failed[i] = True
                errors[i] = got
            else:
                kind[i], value[i], acc[i], meth[i] = got
        if failed[i]:
            kind[i] = KIND_FAILED
            meth[i] = -1
            value[i] = math.nan
            acc[i] = math.nan
        else:
            v, _, oc, u = _loop.finish_point(
                int(kind[i]), float(value[i]), float(acc[i]), fl, sz, vo, has_size
            )
            value[i] = v
            if has_size:
                outcome[i], unc[i] = oc, u
        if has_size and sz < 0.0:
            n_fb += 1
            try:
                r = classify(p, perturbation, sz, rtol=crtol, check_accuracy=False)
                outcome[i] = _loop.OUTCOMES.index(r.outcome)
                unc[i] = False
            except Exception as exc:  # noqa: BLE001 - recorded per point, the batch goes on
                failed[i] = True
                errors[i] = f"{type(exc).__name__}: {exc}"[:2000]
        if has_size and failed[i]:
            outcome[i] = OUTCOME_NONE
            unc[i] = False
    return errors, n_fb
