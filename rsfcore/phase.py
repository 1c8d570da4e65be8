"""Phase-plane scenes: classify many start points of one parameter set without integrating each.

:func:`classify_points` answers, for arrays of start points (phi0, psi0) and one
:class:`rsfcore.Params`, the same stable/unstable question as
:func:`rsfcore.trajectory.classify` with ``start=(phi0, psi0)``, from structure computed
once per parameter set.  Coordinates (the v_o = 1 frame, where the system is invariant
under phi -> phi + ln v_o, psi -> psi + (1 - b/a) ln v_o):

    t = ln theta + ln v_o = (psi - phi)/(b/a) + ln v_o,      u = L = phi + (psi - phi)/(b/a).

In them the spring-slider (`eq:psi_T`, `eq:phi_T`) with slip s as the variable is the
autonomous system dt/ds = G(u), du/ds = kappa expm1(t - u) - kappa_crit G(u)
(rsfcore.laws; steady sliding is t = u = 0).

How each regime is decided (the same decisions, in the same order, as classify's plan):

* v_o = 0 or kappa = 0: dL/ds = g(L) exactly, so the outcome is fixed by u against L*
  (`eq: limiting trajectory2`): u > L* or u = L* (kappa > 0) unstable, else stable;
* v_o > 0 and the start is steady sliding itself: stable;
* kappa = kappa_crit (within classify's KCRIT_TOL): the sign of U of `eq: trajectories 1`
  (rsfcore.analytic.U_kcrit_sign; every orbit closed at eps = 1); starts whose U is zero
  within rounding are integrated;
* kappa < kappa_crit: unstable (linear instability; classify certifies it the same way);
* eps kappa >= kappa_crit (no L*, `eq: critical trajectory condition`): stable;
* kappa > kappa_crit with L* finite: the separatrix.  It is the trajectory with
  u -> L* as phi -> infinity, traced once from its asymptotic expansion (rsfcore.separatrix)
  backwards: first (A) u(t) while its slope |du/dt| <= 1, then (B) t(u) from there down
  through its turning point (u = 0, largest t) to u -> -infinity, where t(u) tends to a
  constant.  As a curve t = t_sep(u), u < L*, it bounds the basin of steady sliding:
  a start is stable iff u < L* and t < t_sep(u).  Both branches are integrated by DOP853
  (rsfcore.ode.rk) with their 7th-order dense output stored, so a point costs one binary
  search and one polynomial evaluation.  Where DOP853's steps are limited by stability
  (kappa large: b/a = kappa = 1e6, or b/a = 1e4, kappa = 1.0001e4), the tracing hands over
  to RODAS4 (rsfcore.ode.rodas4, the stiff hand-over of rsfcore.separatrix) with cubic
  Hermite dense output, at a tolerance of rtol clamped to [1e-10, 1e-8] (not 1e-3 rtol:
  RODAS4 loses order there, and at 1e-3 rtol, or at rtol <= 1e-12, it needed more than
  the 4e4 stored steps, so the tracing failed and every start was integrated, 13-23 s
  per 10^5 starts at rtol 1e-10, minutes at 1e-12); each stored step carries the curve's
  propagated error estimate, which widens the margin there.

Safety margin: a start whose distance to the separatrix (in u on branch A, in t on
branch B) is below MARGIN_FACTOR x rtol x (1 + |t| + |u|) plus the rounding of (t, u)
from (phi0, psi0) plus CURVE_ERR_FACTOR x the curve's propagated error estimate there, or
that lies beyond the traced range of the curve, is integrated with
rsfcore.trajectory.classify (method "integrated" in the result).  MARGIN_FACTOR is
calibrated (tests/core/test_phase.py): classify at rtol agrees with the side of the
separatrix for every start farther than the margin.

Accuracy: the traced separatrix is computed at 1e-3 of the requested rtol (floored at
1e-14; RODAS4 steps at rtol in [1e-10, 1e-8]), so its error is far below the margin
(measured against the separatrix method's critical sizes, which lie on the curve:
<= 3e-12 in the stiff corners at rtol 1e-10, where the margin is 1e-8, and <= 6e-12 at
rtol 1e-12 .. 1e-13, where the curve's estimate, <= 4e-10, widens the margin to ~4e-8);
outcomes are exact decisions of the same kind as classify's.  Speed: 1e5 random points in a few ms after warm-up
(bench/bench_phase.py); over a grid of parameter sets incl. the stiff corners
bench/bench_phase_grid.py.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from enum import IntEnum
from typing import Any

import numba as nb
import numpy as np
from numpy.typing import ArrayLike, NDArray

from . import limits as lim
from .analytic import U_kcrit_sign
from .errors import ParameterError

# (numba's cache does not track callees in other modules: this file was touched when
# rsfcore.laws.L_star began deciding x >= 1 on the exact 1 - x, NUMERICS_VERSION 5)
from .laws import G, L_star
from .ode import rk, rodas4
from .params import Params
from .separatrix import STIFF_HJ, STIFF_RUN, asym_coeffs, dfdx, dfdy

__all__ = [
    "Outcome",
    "PointMethod",
    "PointsResult",
    "Separatrix",
    "classify_points",
    "trace_separatrix",
    "MARGIN_FACTOR",
    "CURVE_ERR_FACTOR",
]

#: Safety margin factor (module docstring).  Calibrated (tests/core/test_phase.py,
#: docs/accuracy.md): classify at rtol agreed with the side of the traced separatrix for
#: every start rtol (1 + |t| + |u|) away or farther (rtol 1e-6, 1e-10, 1e-13; 4 parameter
#: sets x 60 starts per distance) and began to disagree at rtol/10; 100 leaves 100x.
MARGIN_FACTOR = 100.0
#: the traced curve's propagated error estimate enters the margin times this: DOP853's
#: estimate under-estimates this problem's error by up to ~100x (rsfcore.separatrix)
CURVE_ERR_FACTOR = 100.0
#: the KCRIT_TOL of rsfcore.trajectory: kappa within this relative band of kappa_crit is
#: decided by the sign of U there, so here too
_KCRIT_TOL = 1e-14
_U = 2.0**-53
F64 = NDArray[np.float64]


class Outcome(IntEnum):
    """Outcome code per point (the ``outcome`` array of :class:`PointsResult`)."""

    STABLE = 0
    UNSTABLE = 1
    #: the fallback integration could not certify an outcome within its budget
    UNDECIDED = 2


class PointMethod(IntEnum):
    """How a point was decided (the ``method`` array of :class:`PointsResult`)."""

    #: side of the traced separatrix
    SEPARATRIX = 0
    #: u >= L*: absorbing, runaway (exact)
    ABOVE_LSTAR = 1
    #: kappa = kappa_crit: sign of U (`eq: trajectories 1`)
    U_SIGN = 2
    #: v_o = 0 or kappa = 0: L against L* (`eq: limiting trajectory2`)
    FIXED_L = 3
    #: eps kappa >= kappa_crit: no runaway possible
    NO_RUNAWAY = 4
    #: kappa < kappa_crit: linear instability
    LINEAR = 5
    #: the start is steady sliding
    EQUILIBRIUM = 6
    #: within the safety margin (or outside the traced curve): rsfcore.trajectory.classify
    INTEGRATED = 7


@dataclass(frozen=True)
class PointsResult:
    """Outcome of :func:`classify_points`.

    Attributes:
        outcome: int8 array, :class:`Outcome` codes (0 stable, 1 unstable, 2 undecided).
        method: int8 array, :class:`PointMethod` codes.
        params: the parameters; rtol: the tolerance of the fallback integrations and of
            the margin.
        n_integrated: number of points that were integrated.
    """

    outcome: NDArray[np.int8]
    method: NDArray[np.int8]
    params: Params
    rtol: float
    n_integrated: int

    @property
    def unstable(self) -> NDArray[np.bool_]:
        """Boolean mask of the unstable points."""
        return self.outcome == Outcome.UNSTABLE

    def outcome_names(self) -> list[str]:
        """Outcome per point as "stable" / "unstable" / "undecided"."""
        names = ("stable", "unstable", "undecided")
        return [names[int(o)] for o in self.outcome.ravel()]

    def to_dict(self) -> dict[str, Any]:
        """JSON-safe dict."""
        return {
            "outcome": self.outcome_names(),
            "method": [PointMethod(int(m)).name.lower() for m in self.method.ravel()],
            "params": self.params.as_dict(),
            "rtol": self.rtol,
            "n_integrated": self.n_integrated,
        }


# ---------------------------------------------------------------------------------------
# the separatrix as a tabulated curve
_MAX_STEPS = 20_000
#: internal tolerance of the tracing = rtol x this (floored at 1e-14); DOP853's error
#: estimate under-estimates this problem's error by up to ~100x (rsfcore.separatrix)
_TRACE_TOL = 1e-3
#: RODAS4's tolerance in the stiff corner = rtol x this: RODAS4 loses order there (local
#: error ~h/kappa, rsfcore.separatrix), so at 1e-3 rtol it needs more steps than are
#: stored (the tracing failed); its propagated error estimate enters the margin instead
#: (CURVE_ERR_FACTOR).  Measured at rtol 1e-10 (bench/bench_phase_grid.py): 6e3 - 2e4
#: steps, estimates <= 6.4e-10 and true errors <= 3e-12 (against critical sizes)
_TRACE_TOL_STIFF = 1.0
#: ... but never looser than this: at rtol 1e-6 the estimate (1.5e-5 at b/a = 1e4,
#: kappa = 1.0001e4) widened the margin 15x and 79 of 1e5 random starts were integrated
#: (0.06 s CPU); at 1e-8 the tracing costs ~1-2 ms there
_STIFF_TOL_MAX = 1e-8
#: ... nor tighter than this: at rtol 1e-12 .. 1e-13 RODAS4 (order 4, and less on this
#: problem) filled the 4e4 stored rows in the stiff sets (b/a >= 1e4 with kappa/kappa_crit
#: <= 2, and the three corners), which were then integrated start by start (minutes per
#: 10^5 starts).  At 1e-10 they are traced in 2e4 rows or fewer; the curve's estimate
#: (<= 4e-10) enters the margin, and no random start of 10^5 fell inside it
#: (bench/bench_phase_grid.py); its true error at the critical sizes stayed <= 6e-12
_STIFF_TOL_MIN = 1e-10
_H_MAX_A = 0.5
_H_MAX_B = 0.1
#: branch B ends when the remaining change of t is below this fraction of the margin
_TAIL_FRAC = 1e-3
_U_FLOOR = -1.0e4

TR_OK = 0
TR_FAIL = 1


@nb.njit(cache=True, nogil=True)
def _lnG_neg(u: float, eps: float) -> float:
    """ln G(u) for u < 0 (G > 0), without overflow for very negative u."""
    a = -eps * u
    if a > 1.0:
        return a + math.log1p(-math.exp(-a)) - math.log(eps)
    return math.log(G(u, eps))


@nb.njit(cache=True, nogil=True)
def _rhs_a(t: float, u: float, kappa: float, kc: float, eps: float) -> float:
    """Branch A: du/dt = kappa expm1(t - u)/G(u) - kappa_crit (inf outside u > 0)."""
    g = G(u, eps)
    if not (g < 0.0) or t - u > 700.0:
        return math.inf
    return kappa * math.expm1(t - u) / g - kc


@nb.njit(cache=True, nogil=True)
def _rhs_b(u: float, t: float, kappa: float, kc: float, eps: float) -> float:
    """Branch B: dt/du = G(u)/(kappa expm1(t - u) - kappa_crit G(u)) (inf at a turning point).

    For u < -1 written as 1/(kappa Q - kappa_crit), Q = expm1(t - u)/G(u) formed through
    logarithms, so that nothing overflows as u -> -infinity.
    """
    if u > -1.0:
        g = G(u, eps)
        den = kappa * math.expm1(t - u) - kc * g
        if not (den > 0.0):
            return math.inf
        return g / den
    w = t - u
    if w <= 0.0:
        return math.inf
    lnq = w + math.log1p(-math.exp(-w)) - _lnG_neg(u, eps)
    if lnq > 700.0:
        return 1.0 / (kappa * math.exp(700.0))  # below any representable step change
    den = kappa * math.exp(lnq) - kc
    if not (den > 0.0):
        return math.inf
    return 1.0 / den


@nb.njit(cache=True, nogil=True)
def _rhs(mode: int, x: float, y: float, kappa: float, kc: float, eps: float) -> float:
    """Right-hand side of branch A (mode 0) or B (mode 1)."""
    if mode == 0:
        return _rhs_a(x, y, kappa, kc, eps)
    return _rhs_b(x, y, kappa, kc, eps)


@nb.njit(cache=True, nogil=True)
def _pair_rhs(z: F64, out: F64, mode: int, kappa: float, kc: float, eps: float) -> None:
    """The branch ODE as the autonomous pair z = (x, y): (x', y') = (1, f(x, y)) (RODAS4)."""
    out[0] = 1.0
    out[1] = _rhs(mode, z[0], z[1], kappa, kc, eps)


@nb.njit(cache=True, nogil=True, error_model="numpy")
def _branch(
    mode: int,
    x0: float,
    y0: float,
    x_end: float,
    kappa: float,
    kc: float,
    eps: float,
    rtol: float,
    stiff_rtol: float,
    h_max: float,
    switch_slope: float,
    tail_tol: float,
    xs: F64,
    ys: F64,
    hs_: F64,
    Fs: F64,
    es_: F64,
    n0: int,
    err0: float,
) -> tuple[int, int, float, float, int, float]:
    """Integrate branch A (mode 0, x = t increasing) or B (mode 1, x = u decreasing) and
    store every accepted step: start xs[k], ys[k], signed step hs_[k], dense coefficients
    Fs[k, :] and the propagated error estimate of y over the step es_[k] (from err0 at the
    start).  Stops at x_end, or (A) after a step ending with |slope| > switch_slope, or
    (B) once |slope| (1 + |x|) < tail_tol (the rest of the curve changes t by less).

    DOP853 (rsfcore.ode.rk, 7th-order dense output) at tolerance rtol; where its steps are
    limited by stability (Hairer's counting as in rsfcore.separatrix: STIFF_RUN steps in
    a row with h |df/dy| > STIFF_HJ, df/dy analytic) it hands over to RODAS4
    (rsfcore.ode.rodas4 on the pair (x, y), x' = 1, with the analytic Jacobian; cubic
    Hermite dense output, whose gap to RODAS4's own continuous extension is inside the
    error norm) at tolerance stiff_rtol, and back after 20 steps in a row with
    h |df/dy| < 2 (the engine's rule).  The stiff corner (b/a = kappa = 1e6): the
    separatrix attracts at a rate ~kappa e^(t - u)/|G(u)| ~ 1e5, so DOP853 alone filled
    its 4e4 rows before the end of branch A.
    Returns (status, n, x, y, RODAS4 steps, propagated error estimate at the end): the
    estimate is err <- err exp(h J) + |local error| over the accepted steps (h J the less
    contractive end of the step), an absolute error of y; es_[k] is the larger of its
    values at the two ends of step k."""
    direction = 1.0 if x_end >= x0 else -1.0
    K = np.empty((rk.N_STAGES_EXTENDED, 1))
    F = np.empty((7, 1))
    yv = np.empty(1)
    y1 = np.empty(1)
    f0 = np.empty(1)
    f1 = np.empty(1)
    sc = np.empty(1)
    C = rk.C_NODES
    W = np.zeros((rodas4.SCALAR_WORK, 2))  # RODAS4's workspace (rodas4.scalar_step)
    args = (mode, kappa, kc, eps)
    x = x0
    y = y0
    f = _rhs(mode, x, y, kappa, kc, eps)
    if not math.isfinite(f):
        return TR_FAIL, n0, x, y, 0, 0.0
    h = h_max * 0.1
    n = n0
    last_rejected = False
    n_try = 0
    stiff = False
    n_hits = 0
    n_easy = 0
    n_ros = 0
    J = dfdy(mode, x, y, kappa, kc, eps)
    err_sum = err0
    while n < xs.shape[0] and n_try < 10 * _MAX_STEPS:
        n_try += 1
        rem = (x_end - x) * direction
        if rem <= 0.0:
            return TR_OK, n, x, y, n_ros, err_sum
        final = False
        if h >= rem:
            h = rem
            final = True
        hs = h * direction
        err = math.inf
        ynew = y
        fnew = f
        if stiff:
            fx = dfdx(mode, x, y, kappa, kc, eps)
            ok, yr, fr = rodas4.scalar_step(_pair_rhs, args, x, y, f, fx, J, hs, W)
            if ok and math.isfinite(yr) and math.isfinite(fr):
                ynew = yr
                fnew = fr
                sc[0] = rk.error_scale(y, ynew, stiff_rtol, stiff_rtol, 1.0 + abs(x))
                err = rodas4.scalar_error(W, hs, sc[0], True)
            if not (err <= 1.0):
                h *= rodas4.reject_factor(err)
                last_rejected = True
                if h < 1e-14 * max(1.0, abs(x)):
                    return TR_FAIL, n, x, y, n_ros, err_sum
                continue
            y1[0] = ynew
            f0[0] = f
            f1[0] = fnew
            yv[0] = y
            rodas4.hermite_coeffs(yv, y1, f0, f1, hs, F)
            local = err * sc[0]
            n_ros += 1
        else:
            K[0, 0] = f
            ok = True
            for s in range(1, rk.N_STAGES):
                k = _rhs(mode, x + C[s] * hs, y + hs * rk.stage_sum(K, s, 0), kappa, kc, eps)
                if not math.isfinite(k):
                    ok = False
                    break
                K[s, 0] = k
            if ok:
                ynew = y + hs * rk.solution_sum(K, 0)
                fnew = _rhs(mode, x + hs, ynew, kappa, kc, eps)
                if math.isfinite(fnew) and math.isfinite(ynew):
                    K[rk.N_STAGES, 0] = fnew
                    sc[0] = rk.error_scale(y, ynew, rtol, rtol, 1.0 + abs(x))
                    err = rk.error_norm(K, h, sc, 1)
            if not (err <= 1.0):
                h *= rk.reject_factor(err)
                last_rejected = True
                if h < 1e-14 * max(1.0, abs(x)):
                    return TR_FAIL, n, x, y, n_ros, err_sum
                continue
            # dense output of the accepted step
            yv[0] = y
            ok = True
            for s in range(rk.N_STAGES + 1, rk.N_STAGES_EXTENDED):
                k = _rhs(mode, x + C[s] * hs, y + hs * rk.stage_sum(K, s, 0), kappa, kc, eps)
                if not math.isfinite(k):
                    ok = False
                K[s, 0] = k
            if not ok:
                h *= 0.5
                last_rejected = True
                continue
            y1[0] = ynew
            f0[0] = f
            f1[0] = fnew
            rk.dense_coeffs(K, yv, y1, f0, f1, hs, F)
            local = err * sc[0]
        Jn = dfdy(mode, x + hs, ynew, kappa, kc, eps)
        err_prev = err_sum
        if math.isfinite(Jn):
            err_sum = err_sum * math.exp(min(max(hs * J, hs * Jn), 50.0)) + local
        else:
            err_sum += local
        J = Jn if math.isfinite(Jn) else 0.0
        xs[n] = x
        ys[n] = y
        hs_[n] = hs
        for i in range(7):
            Fs[n, i] = F[i, 0]
        es_[n] = max(err_prev, err_sum)
        n += 1
        x = x + hs if not final else x_end
        y = ynew
        f = fnew
        if final:
            return TR_OK, n, x, y, n_ros, err_sum
        if switch_slope > 0.0 and abs(f) > switch_slope:
            return TR_OK, n, x, y, n_ros, err_sum
        # B: dt/du decays like e^((1 - eps) u) as u -> -inf, so the rest of the curve moves
        # t by about |dt/du|/(1 - eps)
        if tail_tol > 0.0 and abs(f) / max(1.0 - eps, 1e-6) < tail_tol * (1.0 + abs(y)):
            return TR_OK, n, x, y, n_ros, err_sum
        if stiff:
            fac, _ = rodas4.accept_factor(err, h, 0.0, 1.0, last_rejected)
            # back to DOP853 once the step is well inside its stability region
            n_easy = n_easy + 1 if h * abs(J) < 2.0 else 0
            if n_easy >= 20:
                stiff = False
                n_hits = 0
                n_easy = 0
        else:
            fac, _ = rk.accept_factor(err, h, 0.0, 1.0, last_rejected)
            # Hairer's counting (dop853.f), as rsfcore.separatrix
            if h * abs(J) > STIFF_HJ:
                n_hits += 1
                n_easy = 0
                if n_hits >= STIFF_RUN:
                    stiff = True
                    n_easy = 0
            else:
                n_easy += 1
                if n_easy >= 6:
                    n_hits = 0
        last_rejected = False
        h = min(h * fac, h_max)
    return TR_FAIL, n, x, y, n_ros, err_sum


@nb.njit(cache=True, nogil=True)
def _trace(
    kappa: float,
    kc: float,
    eps: float,
    rtol: float,
    stiff_rtol: float,
    margin_rtol: float,
    xs: F64,
    ys: F64,
    hs: F64,
    Fs: F64,
    es: F64,
) -> tuple[int, int, int, float, float, float, float, float, int]:
    """Trace the separatrix: branch A into rows [0, nA), branch B into [nA, nA + nB).

    rtol: DOP853's tolerance; stiff_rtol: RODAS4's (:func:`_branch`); es: the propagated
    error estimate per row (in u on A, in t on B; the error of u at the switch enters B
    times |dt/du| there).  Returns (status, nA, nB, s0, t_sw, u_sw, t_end, u_end, RODAS4
    steps)."""
    Ls, c1, c2 = asym_coeffs(kappa, kc, eps)
    nan = math.nan
    if not (Ls > 0.0) or not math.isfinite(Ls):
        return TR_FAIL, 0, 0, nan, nan, nan, nan, nan, 0
    cz = max(abs(c1), math.sqrt(abs(c2)), 1e-300)
    zt = min(max(1.0e-5 * (rtol / 1e-10) ** (1.0 / 3.0), 1e-7), 1e-4)
    s0 = Ls + math.log(zt / cz)  # (critical.py caps it at -5 for the jumps; not needed here)
    z0 = math.exp(s0 - Ls)
    u0 = Ls - z0 * (c1 + c2 * z0)
    st, nA, t_sw, u_sw, nra, ea = _branch(
        0, s0, u0, math.inf, kappa, kc, eps, rtol, stiff_rtol, _H_MAX_A, 1.0, 0.0, xs, ys, hs,
        Fs, es, 0, 0.0,
    )  # fmt: skip
    if st != TR_OK or not (u_sw > 0.0) or not math.isfinite(t_sw):
        return TR_FAIL, nA, 0, s0, t_sw, u_sw, nan, nan, nra
    tail = _TAIL_FRAC * margin_rtol
    eb0 = ea * abs(_rhs(1, u_sw, t_sw, kappa, kc, eps))
    st, n, u_end, t_end, nrb, eb = _branch(
        1, u_sw, t_sw, _U_FLOOR, kappa, kc, eps, rtol, stiff_rtol, _H_MAX_B, 0.0, tail, xs, ys,
        hs, Fs, es, nA, eb0,
    )  # fmt: skip
    if st != TR_OK:
        return TR_FAIL, nA, n - nA, s0, t_sw, u_sw, t_end, u_end, nra + nrb
    return TR_OK, nA, n - nA, s0, t_sw, u_sw, t_end, u_end, nra + nrb


@nb.njit(cache=True, nogil=True)
def _dense_at(Fs: F64, k: int, y0: float, x: float) -> float:
    """Dense-output polynomial of stored step k at fraction x in [0, 1] (scalar)."""
    acc = 0.0
    for i in range(7):
        acc += Fs[k, 6 - i]
        if i % 2 == 0:
            acc *= x
        else:
            acc *= 1.0 - x
    return acc + y0


@nb.njit(cache=True, nogil=True)
def _signed_distance(
    t0: float,
    u0: float,
    geom: F64,
    nA: int,
    nB: int,
    xs: F64,
    ys: F64,
    hs: F64,
    Fs: F64,
    es: F64,
) -> tuple[float, bool, float]:
    """(d, ok, e): d > 0 on the runaway side of the separatrix, < 0 in the basin; |d| is
    the distance in u (branch A) or in t (branch B); e the traced curve's propagated error
    estimate there (0 on the asymptotic expansion).  ok = False beyond the traced curve.
    geom = (L*, c1, c2, s0, t_switch, u_switch, t_end, u_end)."""
    Ls, c1, c2, s0, t_sw, u_sw, t_end, u_end = (
        geom[0],
        geom[1],
        geom[2],
        geom[3],
        geom[4],
        geom[5],
        geom[6],
        geom[7],
    )
    if u0 > u_sw:
        if t0 >= t_sw:
            return math.inf, True, 0.0  # right of branch A's end: t_sep(u0) < t_sw <= t0
        if t0 <= s0:
            z = math.exp(t0 - Ls)
            return u0 - (Ls - z * (c1 + c2 * z)), True, 0.0
        lo = 0
        hi = nA - 1
        while lo < hi:  # last step start <= t0 (starts increasing)
            mid = (lo + hi + 1) // 2
            if xs[mid] <= t0:
                lo = mid
            else:
                hi = mid - 1
        x = (t0 - xs[lo]) / hs[lo]
        return u0 - _dense_at(Fs, lo, ys[lo], min(max(x, 0.0), 1.0)), True, es[lo]
    if u0 < u_end:
        # t_sep has converged to t_end within the tail tolerance; beyond the floor: integrate
        if u_end <= _U_FLOOR:
            return 0.0, False, 0.0
        return t0 - t_end, True, es[nA + nB - 1]
    lo = nA
    hi = nA + nB - 1
    while lo < hi:  # last step start >= u0 (starts decreasing)
        mid = (lo + hi + 1) // 2
        if xs[mid] >= u0:
            lo = mid
        else:
            hi = mid - 1
    x = (u0 - xs[lo]) / hs[lo]
    return t0 - _dense_at(Fs, lo, ys[lo], min(max(x, 0.0), 1.0)), True, es[lo]


@nb.njit(cache=True, nogil=True)
def _classify_sep(
    phi0: F64,
    psi0: F64,
    ba: float,
    lnvo: float,
    geom: F64,
    nA: int,
    nB: int,
    xs: F64,
    ys: F64,
    hs: F64,
    Fs: F64,
    es: F64,
    mrtol: float,
    out: NDArray[np.int8],
    meth: NDArray[np.int8],
) -> None:
    """Compiled loop: outcome/method per point for the separatrix regime (v_o > 0)."""
    for i in range(phi0.shape[0]):
        p = phi0[i]
        q = psi0[i]
        lth = (q - p) / ba
        u0 = p + lth
        t0 = lth + lnvo
        if p == lnvo and u0 == 0.0:
            out[i] = 0
            meth[i] = 6
            continue
        if u0 >= geom[0]:
            out[i] = 1
            meth[i] = 1
            continue
        d, ok, e = _signed_distance(t0, u0, geom, nA, nB, xs, ys, hs, Fs, es)
        # margin: the requested accuracy, the rounding of (t0, u0) from (phi0, psi0) and the
        # traced curve's own error estimate there
        m = (
            mrtol * (1.0 + abs(t0) + abs(u0))
            + 8.0 * _U * (abs(p) + abs(q) / ba + abs(lnvo) + abs(lth))
            + CURVE_ERR_FACTOR * e
        )
        if not ok or abs(d) <= m:
            out[i] = 2
            meth[i] = 7
        elif d > 0.0:
            out[i] = 1
            meth[i] = 0
        else:
            out[i] = 0
            meth[i] = 0


@dataclass(frozen=True)
class Separatrix:
    """The traced separatrix of one parameter set (kappa > kappa_crit, L* finite, v_o > 0).

    geom = (L*, c1, c2, s0, t_switch, u_switch, t_end, u_end).  Branch A (rows [0, n_a)):
    u(t) for t in [s0, t_switch], stored by steps (start x, y, signed step h, 7 dense-output
    coefficients F).  Branch B (rows [n_a, n_a + n_b)): t(u) for u from u_switch down to
    u_end (t_sep -> t_end below).  Below t = s0 the asymptotic expansion
    u = L* - c1 z - c2 z^2, z = e^(t - L*), is used.  Coordinates of the module docstring
    (v_o = 1 frame).
    """

    geom: NDArray[np.float64]
    n_a: int
    n_b: int
    x: NDArray[np.float64]
    y: NDArray[np.float64]
    h: NDArray[np.float64]
    F: NDArray[np.float64]
    #: propagated error estimate per row (absolute, in u on branch A and in t on branch
    #: B); classify_points adds CURVE_ERR_FACTOR times it to the margin
    e: NDArray[np.float64]
    #: steps taken by RODAS4 (the stiff corner; cubic Hermite dense output on those rows)
    n_stiff: int = 0

    @property
    def L_star(self) -> float:
        """L*, the asymptote of u on branch A."""
        return float(self.geom[0])

    @property
    def t_switch(self) -> float:
        """t where branch A hands over to branch B."""
        return float(self.geom[4])

    @property
    def u_switch(self) -> float:
        """u where branch A hands over to branch B."""
        return float(self.geom[5])

    @property
    def s0(self) -> float:
        """Start of branch A (the asymptotic expansion below)."""
        return float(self.geom[3])

    @property
    def u_end(self) -> float:
        """End of branch B; t_sep(u) = t_end below it."""
        return float(self.geom[7])

    def curve_error(self, t: float, u: float) -> float:
        """The traced curve's propagated error estimate at the point of the curve nearest
        to (t, u) in the sense of :func:`classify_points` (absolute; in u on branch A, in t
        on branch B; 0 on the asymptotic expansion)."""
        _, _, e = _signed_distance(
            t, u, self.geom, self.n_a, self.n_b, self.x, self.y, self.h, self.F, self.e
        )
        return float(e)

    def _d(self, t: float, u: float) -> tuple[float, bool]:
        d, ok, _ = _signed_distance(
            t, u, self.geom, self.n_a, self.n_b, self.x, self.y, self.h, self.F, self.e
        )
        return float(d), bool(ok)

    def t_of_u(self, u: ArrayLike) -> NDArray[np.float64]:
        """The curve as t_sep(u) on branch B (u <= u_switch), for plots and tests."""
        uu = np.atleast_1d(np.asarray(u, dtype=np.float64))
        out = np.empty_like(uu)
        for i, v in enumerate(uu):
            d, ok = self._d(0.0, float(v))
            out[i] = -d if ok and v <= self.u_switch else math.nan
        return out

    def u_of_t(self, t: ArrayLike) -> NDArray[np.float64]:
        """The curve as u_sep(t) on branch A (t < t_switch), for plots and tests."""
        tt = np.atleast_1d(np.asarray(t, dtype=np.float64))
        out = np.empty_like(tt)
        for i, v in enumerate(tt):
            if v >= self.t_switch:
                out[i] = math.nan
                continue
            d, _ = self._d(float(v), self.L_star)
            out[i] = self.L_star - d
        return out


def trace_separatrix(params: Params, rtol: float = lim.DEFAULT_RTOL) -> Separatrix | None:
    """Trace the separatrix of ``params`` (module docstring); None where it does not apply
    (kappa <= kappa_crit (1 + KCRIT_TOL), eps kappa >= kappa_crit, v_o = 0) or the
    tracing failed (then classify_points integrates every point)."""
    kc = params.kappa_crit
    if params.vo == 0.0 or params.kappa <= kc * (1.0 + _KCRIT_TOL):
        return None
    if not math.isfinite(float(L_star(params.kappa, kc, params.eps))):
        return None
    tol = max(rtol * _TRACE_TOL, 1e-14)
    stiff_tol = max(min(rtol * _TRACE_TOL_STIFF, _STIFF_TOL_MAX), _STIFF_TOL_MIN)
    n = 2 * _MAX_STEPS
    xs, ys, hs, es = np.empty(n), np.empty(n), np.empty(n), np.empty(n)
    Fs = np.empty((n, 7))
    st, nA, nB, s0, t_sw, u_sw, t_end, u_end, n_ros = _trace(
        params.kappa, kc, params.eps, tol, stiff_tol, MARGIN_FACTOR * rtol, xs, ys, hs, Fs, es
    )
    if st != TR_OK or nA < 1 or nB < 1:
        return None
    Ls, c1, c2 = asym_coeffs(params.kappa, kc, params.eps)
    m = nA + nB
    geom = np.array([Ls, c1, c2, s0, t_sw, u_sw, t_end, u_end], dtype=np.float64)
    return Separatrix(
        geom,
        int(nA),
        int(nB),
        xs[:m].copy(),
        ys[:m].copy(),
        hs[:m].copy(),
        Fs[:m].copy(),
        es[:m].copy(),
        int(n_ros),
    )


def classify_points(
    params: Params,
    phi0: ArrayLike,
    psi0: ArrayLike,
    rtol: float = lim.DEFAULT_RTOL,
    *,
    integrate_margin: bool = True,
) -> PointsResult:
    """Stable/unstable outcome of many start points (phi0, psi0) for one parameter set.

    Args:
        params: dimensionless parameters (any valid set; module docstring for how each
            regime is decided).
        phi0, psi0: start points, arrays of the same shape; phi0 in [-1e4, 1e4] =
            ln(V/V_*), psi0 in [-1e8, 1e8] = (tau - tau_*)/(a sigma) (as classify's start).
        rtol: tolerance of the fallback integrations, [1e-13, 1e-3]; also sets the margin.
        integrate_margin: integrate the points within the margin (default).  False leaves
            them as Outcome.UNDECIDED (method INTEGRATED), for speed studies.

    Returns a :class:`PointsResult` whose outcome agrees with
    ``rsfcore.trajectory.classify(params, start=(phi0[i], psi0[i]), rtol=rtol)`` for every
    point (tests/core/test_phase.py, including starts 1e-9 from the separatrix, which
    are integrated).  ParameterError names the first bad point.
    """
    if not isinstance(params, Params):
        raise ParameterError("params", params, "an rsfcore.Params")
    rtol = lim.RTOL.check(rtol)
    p = np.asarray(phi0, dtype=np.float64)
    q = np.asarray(psi0, dtype=np.float64)
    if p.shape != q.shape:
        raise ParameterError("psi0", f"shape {q.shape}", f"the shape of phi0, {p.shape}")
    shape = p.shape
    p = np.ascontiguousarray(p.ravel())
    q = np.ascontiguousarray(q.ravel())
    for name, arr, L in (("phi0", p, lim.PHI_START), ("psi0", q, lim.PSI_START)):
        bad = L.bad_mask(arr)
        if bad.any():
            i = int(np.argmax(bad))
            raise ParameterError(f"{name}[{i}]", float(arr[i]), L.text)

    ba, kc, kappa, eps, vo = params.ba, params.kappa_crit, params.kappa, params.eps, params.vo
    out = np.empty(p.shape[0], dtype=np.int8)
    meth = np.empty(p.shape[0], dtype=np.int8)
    lstar = float(L_star(kappa, kc, eps))
    ell0 = p + (q - p) / ba
    if vo == 0.0 or kappa == 0.0:
        unst = (ell0 > lstar) | ((ell0 == lstar) & (kappa > 0.0))
        out[:] = np.where(unst, Outcome.UNSTABLE, Outcome.STABLE)
        meth[:] = PointMethod.FIXED_L
        if kappa == 0.0:
            meth[ell0 == lstar] = PointMethod.EQUILIBRIUM
        if not math.isfinite(lstar):
            meth[:] = PointMethod.NO_RUNAWAY
    else:
        lnvo = math.log(vo)
        eq = (p == lnvo) & (ell0 == 0.0)
        if abs(kappa - kc) <= _KCRIT_TOL * kc:
            sgn = U_kcrit_sign(p, q, ba, eps, vo)
            out[:] = np.where(
                sgn < 0, Outcome.STABLE, np.where(sgn > 0, Outcome.UNSTABLE, Outcome.UNDECIDED)
            )
            meth[:] = np.where(sgn == 0, PointMethod.INTEGRATED, PointMethod.U_SIGN)
        elif kappa < kc:
            out[:] = Outcome.UNSTABLE
            meth[:] = PointMethod.LINEAR
        elif not math.isfinite(lstar):
            out[:] = Outcome.STABLE
            meth[:] = PointMethod.NO_RUNAWAY
        else:
            sep = trace_separatrix(params, rtol)
            if sep is None:
                out[:] = Outcome.UNDECIDED
                meth[:] = PointMethod.INTEGRATED
            else:
                mrtol = MARGIN_FACTOR * rtol
                g, nA, nB = sep.geom, sep.n_a, sep.n_b
                _classify_sep(
                    p, q, ba, lnvo, g, nA, nB, sep.x, sep.y, sep.h, sep.F, sep.e, mrtol, out,
                    meth,
                )  # fmt: skip
        out[eq] = Outcome.STABLE
        meth[eq] = PointMethod.EQUILIBRIUM

    todo = np.flatnonzero(meth == PointMethod.INTEGRATED)
    if integrate_margin and todo.size:
        from .trajectory import UndecidedError, classify

        for k in todo.tolist():
            try:
                r = classify(
                    params, start=(float(p[k]), float(q[k])), rtol=rtol, check_accuracy=False
                )
                out[k] = Outcome.STABLE if r.outcome == "stable" else Outcome.UNSTABLE
            except UndecidedError:
                out[k] = Outcome.UNDECIDED
    return PointsResult(out.reshape(shape), meth.reshape(shape), params, rtol, int(todo.size))
