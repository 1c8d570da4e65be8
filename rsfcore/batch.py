"""Critical sizes (and outcomes) at many arbitrary parameter points: one compiled call.

:func:`critical_points` is the array form of :func:`rsfcore.critical.critical_perturbation`
for points that are not on a 2-D grid (N-D grids flattened, scattered samples): the
parameters are 1-D arrays of equal length, any of them may vary, v_o included.  It runs
the same compiled loop as :func:`rsfcore.diagram.stability_diagram`
(:func:`rsfcore.critical.critical_batch`: exact zero/infinite decisions, compiled closed
forms at kappa = kappa_crit and v_o = 0, the separatrix method elsewhere), then recomputes
only the points the kernel flags (``FLAG_FALLBACK``) by bisection on certified
classify() outcomes, one by one.

v_o enters the critical size only through v_o = 0 versus v_o > 0: the system is invariant
under phi -> phi + ln v_o, psi -> psi + (1 - b/a) ln v_o, T -> v_o T, so critical sizes
of both perturbation kinds do not depend on v_o > 0 (module docstring of
rsfcore.critical).  The kernel is therefore called at most twice per batch (once for the
points with v_o > 0, once for v_o = 0).

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

import numpy as np
from numpy.typing import ArrayLike, NDArray

from . import critical as _crit
from .params import BA_MAX, KAPPA_MAX, ParameterError, check_range

__all__ = [
    "BatchResult",
    "critical_points",
    "OUTCOME_STABLE",
    "OUTCOME_UNSTABLE",
    "OUTCOME_NONE",
    "KIND_FAILED",
]

#: outcome codes (``BatchResult.outcome``); OUTCOME_NONE where not computed or failed
OUTCOME_STABLE, OUTCOME_UNSTABLE, OUTCOME_NONE = 0, 1, -1
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
    if perturbation not in _crit.PERTURBATIONS:
        raise ParameterError(
            "perturbation", perturbation, "one of " + ", ".join(_crit.PERTURBATIONS)
        )
    pert = _crit.PERTURBATIONS.index(perturbation)
    rtol = check_range("rtol", rtol, _crit.RTOL_RANGE[0], _crit.RTOL_RANGE[1])
    sizes = {
        int(np.size(v)) for v in (ba, kappa, eps, vo, size) if v is not None and np.ndim(v) >= 1
    }
    n = max(sizes) if sizes else 1
    ba_a = _arr("ba", ba, n)
    ka = _arr("kappa", kappa, n)
    ea = _arr("eps", eps, n)
    va = _arr("vo", vo, n)
    _check("ba", ba_a, ~((ba_a > 1.0) & (ba_a <= BA_MAX)), f"(1, {BA_MAX:g}]")
    _check("kappa", ka, ~((ka >= 0.0) & (ka <= KAPPA_MAX)), f"[0, {KAPPA_MAX:g}]")
    _check("eps", ea, ~((ea >= 0.0) & (ea <= 1.0)), "[0, 1]")
    _check("vo", va, ~((va >= 0.0) & (va <= 1e300)), "0 or (0, 1e300]")
    if pert == 1:
        _check("vo", va, va == 0.0, "> 0 for a load-point jump")
    sz: NDArray[np.float64] | None = None
    if size is not None:
        sz = _arr("size", size, n)
        if pert == 0:
            _check("size", sz, ~((sz >= -1e4) & (sz <= 1e4)), "[-1e4, 1e4]")
        else:
            _check("size", sz, ~((sz > -1.0) & (sz <= 1e300)), "(-1, 1e300]")

    kind = np.empty(n, dtype=np.int64)
    value = np.empty(n)
    acc = np.empty(n)
    meth = np.empty(n, dtype=np.int64)
    flags = np.zeros(n, dtype=np.int64)
    moving = va > 0.0
    if np.all(moving):
        _crit.critical_batch(ba_a, ka, ea, 1.0, pert, rtol, kind, value, acc, meth, flags)
    else:
        for sel, v in ((moving, 1.0), (~moving, 0.0)):
            idx = np.flatnonzero(sel)
            if idx.size == 0:
                continue
            k2, v2, a2, m2, f2 = (
                np.empty(idx.size, dtype=np.int64),
                np.empty(idx.size),
                np.empty(idx.size),
                np.empty(idx.size, dtype=np.int64),
                np.zeros(idx.size, dtype=np.int64),
            )
            _crit.critical_batch(ba_a[idx], ka[idx], ea[idx], v, pert, rtol, k2, v2, a2, m2, f2)
            kind[idx], value[idx], acc[idx], meth[idx], flags[idx] = k2, v2, a2, m2, f2

    failed = np.zeros(n, dtype=np.bool_)
    errors: dict[int, str] = {}
    fb = np.flatnonzero(flags & _crit.FLAG_FALLBACK)
    from .params import Params

    for i in fb:
        try:
            p = Params(float(ba_a[i]), float(ka[i]), float(ea[i]), float(va[i]))
            res = _crit.bisect_critical(p, perturbation, rtol=rtol)
            kind[i] = _crit.KINDS.index(res.kind)
            value[i] = math.inf if res.critical_size is None else res.critical_size
            acc[i] = res.rel_accuracy
            meth[i] = (
                _crit.M_ASYMPTOTE
                if res.method == _crit.METHODS[_crit.M_ASYMPTOTE]
                else _crit.M_BISECTION
            )
        except Exception as exc:  # noqa: BLE001 - recorded per point, the batch goes on
            failed[i] = True
            errors[int(i)] = f"{type(exc).__name__}: {exc}"[:2000]
    value[kind == _crit.KIND_ZERO] = 0.0
    value[kind == _crit.KIND_INFINITE] = math.inf
    kind[failed] = KIND_FAILED
    meth[failed] = -1
    value[failed] = math.nan
    acc[failed] = math.nan
    on_b = (flags & (_crit.FLAG_ON_X1 | _crit.FLAG_ON_KCRIT)) != 0
    out = BatchResult(
        kind.astype(np.int8),
        value,
        acc,
        meth.astype(np.int8),
        on_b,
        failed,
        errors,
        n_fallback=int(fb.size),
    )
    if sz is not None:
        _outcomes(out, sz, flags, ba_a, ka, ea, va, perturbation, rtol)
    return out


def _outcomes(
    out: BatchResult,
    sz: NDArray[np.float64],
    flags: NDArray[np.int64],
    ba: NDArray[np.float64],
    kappa: NDArray[np.float64],
    eps: NDArray[np.float64],
    vo: NDArray[np.float64],
    perturbation: str,
    rtol: float,
) -> None:
    """Fill out.outcome / out.outcome_uncertain from the critical sizes (size >= 0) or by
    classify() (size < 0)."""
    from .params import Params
    from .trajectory import classify

    k, cs = out.kind, out.critical_size
    unstable = ((k == _crit.KIND_ZERO) & (sz > 0.0)) | ((k == _crit.KIND_FINITE) & (sz > cs))
    with np.errstate(divide="ignore", invalid="ignore"):
        near = (k == _crit.KIND_FINITE) & (
            np.abs(sz / cs - 1.0) <= np.maximum(out.rel_accuracy, 4e-16)
        )
    on_kc = (flags & _crit.FLAG_ON_KCRIT) != 0
    outcome = np.where(unstable, OUTCOME_UNSTABLE, OUTCOME_STABLE).astype(np.int8)
    uncertain = near | (on_kc & (vo > 0.0))
    neg = np.flatnonzero(sz < 0.0)
    crtol = max(1e-13, min(1e-10, rtol))
    for i in neg:
        try:
            r = classify(
                Params(float(ba[i]), float(kappa[i]), float(eps[i]), float(vo[i])),
                perturbation,
                float(sz[i]),
                rtol=crtol,
                check_accuracy=False,
            )
            outcome[i] = OUTCOME_UNSTABLE if r.outcome == "unstable" else OUTCOME_STABLE
            uncertain[i] = False
        except Exception as exc:  # noqa: BLE001 - recorded per point, the batch goes on
            out.failed[i] = True
            out.errors[int(i)] = f"{type(exc).__name__}: {exc}"[:2000]
    outcome[out.failed] = OUTCOME_NONE
    uncertain[out.failed] = False
    out.outcome, out.outcome_uncertain = outcome, uncertain
    out.n_fallback += int(neg.size)
