"""Bounded non-linear least squares for the fits: a trust-region Gauss-Newton
(Levenberg-Marquardt) method with box constraints by an active set and projection.

Minimises F(x) = 0.5 ||r(x)||^2 subject to lb <= x <= ub, for the few (<= 7) fitted
coordinates of rsfcore.fit and residual vectors of 10^3-10^6 samples.  Written for the
fits instead of scipy.optimize.least_squares, whose import (scipy.optimize pulls in
scipy.linalg, scipy.sparse, scipy.fft, scipy.special: ~0.3 s on a quiet machine, > 1 s on
a loaded one) was a quarter of ``rsf fit``'s wall time; the method is the same family as
scipy's "trf" with ``x_scale="jac"``:

* variables scaled by the Jacobian's column norms (never decreasing: the largest seen);
* each iteration solves min ||J s + r||^2 over ||D s|| <= Delta (D the scale) exactly,
  by the SVD of the p x p triangle of a QR of J (the secular equation for the
  Levenberg-Marquardt parameter by safeguarded Newton iterations, More 1978);
* a coordinate on a bound whose gradient points out of the box is held there (active
  set); the step of the others is projected onto the box;
* the radius: ratio rho of actual to predicted reduction; rho < 0.25 shrinks Delta to a
  quarter of the step, rho > 0.75 with the step on the trust-region boundary doubles it;
* termination as in scipy: ``ftol`` (dF < ftol F with rho > 0.25), ``xtol``
  (||dx|| < xtol (xtol + ||x||)), ``gtol`` (max_i |g_i| v_i < gtol with v_i the distance
  to the bound the gradient points to, or 1 without one), or ``max_nfev`` residual
  evaluations (status 0).

Agreement with scipy.optimize.least_squares(method="trf", x_scale="jac") at ftol = xtol =
gtol = 1e-10 on the fits of tests/core/test_fit.py and bench/bench_fit.py: the same
minimum (reported parameters within 1e-3 of their standard errors; measured in
tests/core/test_fit.py against scipy), in as many or fewer evaluations.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

__all__ = ["LsqResult", "least_squares"]

Vector = NDArray[np.float64]

_MESSAGES = {
    0: "The maximum number of function evaluations is exceeded.",
    1: "`gtol` termination condition is satisfied.",
    2: "`ftol` termination condition is satisfied.",
    3: "`xtol` termination condition is satisfied.",
    4: "Both `ftol` and `xtol` termination conditions are satisfied.",
    5: "Stopped by the caller.",
}


@dataclass(frozen=True)
class LsqResult:
    """Outcome of :func:`least_squares`.

    Attributes:
        x: the solution (the last accepted point); fun: its residuals; cost: 0.5 ||fun||^2.
        nfev, njev: residual and Jacobian evaluations.
        status: 0 evaluation budget, 1 gtol, 2 ftol, 3 xtol, 4 ftol and xtol (1-4:
            converged), 5 stopped by ``stop``; message: a sentence saying which.
    """

    x: Vector
    fun: Vector
    cost: float
    nfev: int
    njev: int
    status: int
    message: str


#: Fraction of the distance to a bound that a step crossing it is cut back by.
_BACK = 0.005


def _cl_scale(x: Vector, g: Vector, lb: Vector, ub: Vector) -> Vector:
    """Coleman-Li scaling: the distance to the bound the gradient points to (descent
    leaves through it); 1 where there is none.  Floored at 1e-300."""
    v = np.where(g > 0.0, x - lb, np.where(g < 0.0, ub - x, 1.0))
    v = np.where(np.isfinite(v), v, 1.0)
    return np.maximum(v, 1e-300)


def _tr_step(A: Vector, b: Vector, Delta: float) -> tuple[Vector, float, bool]:
    """The step z of min ||A z + b|| over ||z|| <= Delta (A with as many rows as columns or
    more, possibly singular): (z, the Levenberg-Marquardt parameter, whether the step lies
    on the trust-region boundary)."""
    U, S, Vt = np.linalg.svd(A, full_matrices=False)
    uf = U.T @ b
    tiny = S[0] * A.shape[0] * np.finfo(float).eps if S.size else 0.0
    keep = tiny < S

    def z_of(lam: float) -> Vector:
        den = S**2 + lam
        coef = np.where(keep | (lam > 0.0), S * uf / np.where(den > 0.0, den, 1.0), 0.0)
        return -(Vt.T @ coef)

    z = z_of(0.0)
    nz = float(np.linalg.norm(z))
    if nz <= Delta:
        return z, 0.0, False
    # phi(lam) = ||z(lam)|| - Delta decreases in lam; Newton on 1/||z|| - 1/Delta (More 1978)
    lo, hi = 0.0, float(np.linalg.norm(S * uf)) / Delta
    lam = max(1e-3 * hi, math.sqrt(lo * hi)) if hi > 0 else 0.0
    for _ in range(50):
        if not lo <= lam <= hi:
            lam = max(1e-3 * hi, math.sqrt(max(lo * hi, 0.0)))
        z = z_of(lam)
        nz = float(np.linalg.norm(z))
        phi = nz - Delta
        if abs(phi) < 1e-2 * Delta:
            break
        if phi > 0:
            lo = lam
        else:
            hi = lam
        den = S**2 + lam
        dnz = -float(np.sum((S * uf) ** 2 / den**3)) / nz  # d||z||/d lam
        lam = lam - (phi / Delta) * (nz / dnz) if dnz < 0 else 0.5 * (lo + hi)
    return z, lam, True


def least_squares(
    fun: Callable[[Vector], Vector],
    x0: Vector,
    jac: Callable[[Vector], NDArray[np.float64]],
    bounds: tuple[Vector, Vector],
    *,
    ftol: float = 1e-10,
    xtol: float = 1e-10,
    gtol: float = 1e-10,
    max_nfev: int = 200,
    stop: Callable[[float, float, int], bool] | None = None,
) -> LsqResult:
    """Minimise 0.5 ||fun(x)||^2 over lb <= x <= ub from x0 (inside the box).

    ``jac(x)`` is called only at points where ``fun`` was just evaluated (the fits reuse
    that run's states).  Exceptions raised by ``fun`` or ``jac`` propagate (the fits' time
    budget).  See the module docstring for the method and the termination tests.

    ``stop(rss, rss_linear, k)``, when given, is asked at each iterate after the first
    with ||r||^2, the minimum of the Gauss-Newton (linear) model's ||r + J s||^2 over the
    free coordinates (bounds ignored: a lower value than the bounded model's) and the
    number k of accepted steps; True ends the minimisation there (status 5).
    """
    lb, ub = (np.asarray(b, dtype=np.float64) for b in bounds)
    x = np.clip(np.asarray(x0, dtype=np.float64).copy(), lb, ub)
    r = fun(x)
    nfev, njev = 1, 1
    F = 0.5 * float(r @ r)
    J = jac(x)
    p = x.shape[0]
    d = np.sqrt(np.sum(J**2, axis=0))
    d[d == 0.0] = 1.0
    g = J.T @ r
    v = _cl_scale(x, g, lb, ub)
    Delta = float(np.linalg.norm(d * x / np.sqrt(np.where(g != 0.0, v * d, 1.0)))) or 1.0
    status = -1
    n_acc = 0
    while True:
        g = J.T @ r
        v = _cl_scale(x, g, lb, ub)
        if float(np.max(np.abs(g) * v)) < gtol:
            status = 1
            break
        # the active set: on a bound with the gradient pointing out of the box
        span = ub - lb
        at_lo = (x <= lb + 1e-12 * span) & (g > 0.0)
        at_hi = (x >= ub - 1e-12 * span) & (g < 0.0)
        free = ~(at_lo | at_hi)
        if not free.any():
            status = 1
            break
        Jf = J[:, free]
        Q, R = np.linalg.qr(Jf)
        qtr = Q.T @ r
        if stop is not None and n_acc > 0:
            rss = 2.0 * F
            if stop(rss, max(rss - float(qtr @ qtr), 0.0), n_acc):
                status = 5
                break
        actual = -1.0
        x_new, r_new, F_new = x, r, F
        step_norm = 0.0
        # Coleman-Li scaling: z = ds s; steps towards a near bound cost more, and the
        # scaling's derivative adds |g_i|/d_i z_i^2 to the model (as scipy's "trf")
        ds = d / np.sqrt(np.where(g != 0.0, v * d, 1.0))
        diag = np.abs(g) / d
        nf = int(free.sum())
        A = np.vstack([R / ds[free], np.diag(np.sqrt(diag[free]))])
        b = np.concatenate([qtr, np.zeros(nf)])
        lo_ok = lb + _BACK * (x - lb)  # a step stops short of a bound it would cross
        hi_ok = ub - _BACK * (ub - x)
        while actual <= 0.0 and nfev < max_nfev:
            zf, _, on_boundary = _tr_step(A, b, Delta)
            s = np.zeros(p)
            s[free] = zf / ds[free]
            x_new = np.clip(x + s, lo_ok, hi_ok)
            s = x_new - x
            z = ds * s
            step_scaled = float(np.linalg.norm(z))
            Js = J @ s
            pred = -(float(g @ s) + 0.5 * (float(Js @ Js) + float(diag @ z**2)))
            r_new = fun(x_new)
            nfev += 1
            if not np.all(np.isfinite(r_new)):
                Delta = 0.25 * step_scaled
                continue
            F_new = 0.5 * float(r_new @ r_new)
            actual = F - F_new
            ratio = actual / pred if pred > 0.0 else (1.0 if pred == actual == 0.0 else 0.0)
            if ratio < 0.25:
                Delta = 0.25 * step_scaled
            elif ratio > 0.75 and on_boundary:
                Delta = 2.0 * Delta
            step_norm = float(np.linalg.norm(s))
            ftol_ok = actual < ftol * F and ratio > 0.25
            xtol_ok = step_norm < xtol * (xtol + float(np.linalg.norm(x)))
            if ftol_ok or xtol_ok:
                status = 4 if ftol_ok and xtol_ok else (2 if ftol_ok else 3)
                break
            if Delta == 0.0:
                break
        if actual > 0.0:
            x, r, F = x_new, r_new, F_new
            n_acc += 1
            if status >= 0:
                break
            J = jac(x)
            njev += 1
            d = np.maximum(d, np.sqrt(np.sum(J**2, axis=0)))
        elif status >= 0:
            break
        if nfev >= max_nfev:
            status = 0
            break
        if Delta == 0.0:
            status = 3
            break
    return LsqResult(
        x=x, fun=r, cost=F, nfev=nfev, njev=njev, status=status, message=_MESSAGES[status]
    )
