"""The separatrix method: critical perturbation sizes from one scalar ODE (Ciardo & Viesca).

With s_theta = ln theta = (psi - phi)/(b/a) and u = L = phi + s_theta, the trajectory that
separates return from runaway is the one with L -> L* as phi -> +inf.  Along it s_theta
is monotone while L > 0, and it solves the scalar ODE

    du/ds_theta = kappa expm1(s_theta - u)/G(u) - kappa_crit,                 (A)

started from its asymptotic expansion u = L* - c1 z - c2 z^2, z = e^(s_theta - L*)
(:func:`asym_coeffs`), towards increasing s_theta, where the separatrix attracts its
neighbours.  Near L = 0 (where d s_theta/ds = G(L) = 0) the roles are swapped:

    d s_theta/du = G(u) / (kappa expm1(s_theta - u) - kappa_crit G(u)).       (B)

The velocity-jump critical size is u at s_theta = 0; the load-point jump's is
expm1(s_theta) at u = 0 (module docstring of rsfcore.critical for the derivation and
the measured accuracy).  Both phases are integrated by :func:`_scalar_run`, one scalar
driver (events, landing, error propagation) over the shared DOP853 kernels of
rsfcore.ode.rk and RODASP (rsfcore.ode.rodasp, through rsfcore.ode.rodas4's step
kernel), with steps capped (``_H_MAX``) because the
embedded error estimate under-estimates long steps on this problem.

The stiff corner (kappa large, e.g. b/a = kappa = 1e6): the separatrix attracts its
neighbours at a rate ~kappa (d(rhs)/du of (A) is ~ -kappa e^(s_theta - u)/|G(u)|), so
DOP853's steps are limited by stability and the old driver ran out of its 2e5 steps
(bisection fallback, 0.2 - 0.6 s) or took 2e6 right-hand sides.  Now:

* DOP853 hands over to RODASP (:func:`_scalar_run` with RODASP steps: L-stable, the
  scalar ODE as the pair (x, y) with x' = 1 and the analytic Jacobian) once its steps are
  stability-limited (Hairer's test with the analytic d(rhs)/dy; where |d(rhs)/dy| > 1e3
  from h |d(rhs)/dy| > 0.2 on, as tight tolerances hold DOP853's stiff steps below 2),
  and back where steps are no longer limited by stability (EASY_HJ) or little damping is
  left before the end;
* RODASP keeps its order on this stiff problem (NUMERICS_VERSION 7; RODAS4, used before,
  falls to order ~1 there, like on the Prothero-Robinson problem: 10x the steps per
  decade of tolerance);
* its local tolerance is relaxed (up to 1e6 x, never above 1e-6) where the contraction
  still to come damps the errors (:func:`_relax`);
* the error weight includes the rounding of the right-hand side (:func:`_rhs_noise`):
  where kappa is large (A) and (B) are differences of terms ~kappa, and a tolerance
  below that rounding made steps shrink without end (2e6 right-hand sides);
* a velocity jump whose end lies near the separatrix's turning point (RODASP reaches
  |du/ds_theta| > 1 before s_theta = 0, where (A) is nearly singular) is finished in (B),
  locating the crossing of s_theta = 0;
* the phase-A error of a load-point jump enters phase B as its initial error and is
  propagated (damped) with it, and phase B's absolute tolerance scales with the smallest
  possible l = ln(1 + 1/(kappa_crit (1 - eps))) (l ~ 1e-6 at b/a = 1e6 needs s_theta to
  ~1e-16);
* runs whose propagated estimate misses rtol are repeated with tighter settings
  (``_RETRIES``), within a budget of right-hand sides (``_RETRY_NR_BUDGET``) and never
  below the rounding floor (``_RT_FLOOR``), and stop near it once a retry gains less
  than 2x (``_RETRY_MIN_GAIN``); a first run far off is repeated with relaxation caps
  ``_FAR_OFF_CAPS`` first; the answer then states the best run's estimate (accuracy_met
  false) instead of costing 0.3 - 0.5 s per retry.  The legs and phases of a run share
  one budget of right-hand sides.  At rtol 1e-12 .. 1e-13 every critical size of
  bench/bench_speed.py takes at most 1.1e5 right-hand sides (<= 9.3 ms CPU;
  NUMERICS_VERSION 8).

Measured (docs/accuracy.md, "The stiff corner"): b/a = kappa = 1e5 and 1e6, both
perturbations, in 2e4 - 2e5 right-hand sides (0.5 - 7 ms) with rel_accuracy 1e-10 met.

Units: all quantities dimensionless (`eq: characteristic scales`).  Valid for
kappa > kappa_crit, x = eps kappa/kappa_crit < 1, v_o > 0; callers
(rsfcore.critical) decide every other case first.

References: Ciardo & Viesca (`eq: critical trajectory condition`, `eq: limiting
trajectory 1`); E. Hairer, S. P. Norsett, G. Wanner, Solving Ordinary Differential
Equations I, 2nd ed., Springer 1993 (DOP853, Sec. II.10).
"""

from __future__ import annotations

import math
from enum import IntEnum

import numba as nb
import numpy as np

# (numba's cache does not track callees in other modules: this file was touched when
# rsfcore.laws.L_star began deciding x >= 1 on the exact 1 - x, NUMERICS_VERSION 5)
from .laws import G, L_star
from .ode import rk, rodas4, rodasp

__all__ = [
    "SeparatrixStatus",
    "S_OK",
    "S_U_NONPOSITIVE",
    "S_TURNING",
    "S_UNDERFLOW",
    "S_BUDGET",
    "S_OVERFLOW",
    "S_NO_START",
    "S_STIFF",
    "N_WORK",
    "STIFF_HJ",
    "STIFF_RUN",
    "asym_coeffs",
    "dfdx",
    "dfdy",
    "separatrix_critical",
    "separatrix_explicit",
]

# The kernels of rsfcore.ode.rk, .rodas4 and .rodasp are inlined into _scalar_run; numba's
# cache does not see edits there, so touch this file (or clear NUMBA_CACHE_DIR) after
# changing rk.py, rodas4.py or rodasp.py.

#: length of the stage workspace K the drivers take (13 stages: 12 + f at the step end)
N_WORK = rk.N_STAGES + 1
_C = rk.C_NODES

#: internal tolerance = requested rtol times this factor.  DOP853's local error estimate
#: under-estimates the true local error of this scalar problem by up to ~100x, so the
#: factor is calibrated instead: over 2 x 1000 random points (b/a in [1.01, 50],
#: kappa/kappa_crit in [1.01, 6], eps up to x = 0.99) the delivered error stays below the
#: requested rtol (tests/core/test_critical.py re-checks a sample)
_TOL_FACTOR_V = 0.02
_TOL_FACTOR_L = 0.1
#: c z0 of the asymptotic start at rtol = 1e-10 (scaled as rtol^(1/3) for other rtol)
_Z_TARGET = 1.0e-5
_S0_MAX = -5.0
#: largest step in s_theta (or u): the separatrix varies like e^(s_theta) on a unit scale
#: and the embedded error estimate of DOP853 is unreliable on longer steps (measured:
#: 4-step solutions with 3x the requested error and 3000x under-estimated errors)
_H_MAX = 0.5
#: the same for phase (B), in u (measured: 15-step phase-B solutions 100x off at h <= 0.5)
_H_MAX_B = 0.1
_MAX_STEPS = 200_000
#: phase (B) of a load-point jump stops where phi = u - s_theta < -_PHI_FROZEN: the rest
#: of the way to u = 0 moves s_theta by < |G|/kappa e^-60 (added to the error estimate)
_PHI_FROZEN = 60.0
#: ulp(1): the rounding unit of s_theta relative to its size
_ULP1 = 2.220446049250313e-16
#: rounding of the right-hand side counted in the error weight, in ulp of its largest
#: term (:func:`_rhs_noise`)
_NOISE_ULPS = 4.0
#: stiffness switch: DOP853 hands over to RODASP after STIFF_RUN accepted steps with
#: h |d(rhs)/dy| > STIFF_HJ (not interrupted by 6 in a row below it) (DOP853's stability interval on the negative real
#: axis ends near -6, so such steps are limited by stability, not accuracy; where kappa is
#: large the separatrix attracts at a rate ~kappa and explicit steps shrink like 1/kappa)
STIFF_HJ = 2.0
#: where the rate itself is large (|d(rhs)/dy| > STIFF_J_FAST, the stiff corner) a step
#: counts as stiff from h |d(rhs)/dy| > STIFF_HJ_FAST on: at tight tolerances DOP853's
#: error estimate holds such steps below STIFF_HJ although stability limits them
#: (measured, load-point phase (B): b/a = 1e6, kappa = 999999.999999, eps = 0.9, rtol
#: 1e-12: h |J| 1.5 - 2.1 with |J| ~ 9e4 for 4.2e4 steps, 5e5 right-hand sides in
#: DOP853; b/a = 1e5, kappa = 99999.00001, rtol 1e-13: h |J| ~ 0.8, 3.5e5; b/a = 1e4,
#: kappa = 9999.000001, rtol 1e-13: h |J| ~ 0.36, 8.4e4), so the switch never came.
#: RODASP hands back there below EASY_HJ_FAST instead of EASY_HJ (hysteresis)
STIFF_HJ_FAST = 0.2
STIFF_J_FAST = 1.0e3
EASY_HJ_FAST = 0.05
STIFF_RUN = 10
#: and back: RODASP hands over to DOP853 after EASY_RUN accepted steps in a row with
#: h |d(rhs)/dy| < EASY_HJ (accuracy, not stability, limits them; DOP853's 8th order
#: then takes ~10x longer steps at tight tolerances).  Measured at b/a = kappa = 1e6: the
#: separatrix's last part before s_theta = 0 moves u at a rate ~700 while |J| ~ kappa/2,
#: so RODASP's steps there (3e-9 at rtol 1e-13) are far inside its stability region
EASY_HJ = 0.25
EASY_RUN = 6
#: at most this many hand-overs per phase (the last leg is RODASP without switching)
_MAX_SWITCHES = 6
#: largest relaxation of RODASP's local tolerance where later contraction damps the
#: errors (:func:`_scalar_run`); the propagated estimate checks the outcome
_RELAX_CAP = 1.0e6
_RELAX_RATE = 0.25
#: the relaxed tolerance never exceeds this (relax_cap <= _RELAX_TOL_MAX/rtol): farther
#: from the separatrix the linear damping model fails (measured at rtol 1e-7 with
#: rtol x 1e6: errors of 2e-6, 20x the request)
_RELAX_TOL_MAX = 1.0e-6
_RELAX_MARGIN = 5.0
#: relax DOP853's tolerance too?  No: in the non-stiff phases |J| can fall off long before
#: the end (b/a = 1.09e5, kappa = 5.2e5, load-point: |J| rem large at the start of (B) but
#: the path ends non-stiff), the damping model then over-relaxes and the runs erred 5e-8
#: (honestly estimated 1.2e-6, so every relaxed retry failed and the unrelaxed one took
#: 1e6 right-hand sides); RODAS4 runs only where the problem is stiff, so |J| is large there
_RELAX_EXPLICIT = False
#: runs whose propagated estimate misses the requested rtol are repeated with these
#: (rtol factor, relaxation cap), in order (measured right-hand sides at rtol 1e-10 in
#: brackets): b/a = kappa = 1e6 meets it on the second (12k + 21k); b/a = 8543,
#: kappa = 23741 (load-point) on the third (2k + 2k + 50k); the last, unrelaxed, is the
#: slow safety net (~1e6 at b/a = 1e6)
_RETRIES = ((0.1, 1.0e6), (0.1, 1.0e6), (0.01, 1.0e3), (0.01, 1.0))
#: a first run that exhausts the step budget is repeated at 10x the tolerance, up to this
#: (the answer then reports its own, larger, error estimate)
_LADDER_RTOL_MAX = 1.0e-10
#: separatrix runs use no looser tolerance than this: at b/a = 6e5, kappa = 1e6 a run at
#: rtol 1e-3 ran out of its budget (2.4e6 right-hand sides, 0.5 s; no RODAS4 relaxation
#: there) where one at 1e-6 takes 2.4e3 (0.2 ms); non-stiff runs cost ~2x more at 1e-6
#: than at 1e-3 (DOP853 is of order 8), a few hundredths of a ms
_RUN_RTOL_MAX = 1.0e-6
#: no retries after a first run that took more right-hand sides than this (~30 ms)
_RETRY_NR_MAX = 200_000
#: all retries together take about this many right-hand sides (~5 ms on a quiet
#: machine): each leg of a retry gets what is left / 6 steps (RODASP's right-hand sides
#: per step; DOP853's legs take 12 per step); a run out of them ends the retries and the
#: best run so far stands (before: retries at
#: rtol 1e-12 .. 1e-13 in the stiff corner ran out of the 2e5-step budget, 0.3 - 0.5 s
#: each, and stood anyway)
_RETRY_NR_BUDGET = 60_000
#: a first run whose estimate misses rtol by more than this factor is repeated unrelaxed
#: first
_FAR_OFF = 1.0e3
#: relaxation caps of the repeats of a first run that far off, in order, until one
#: meets rtol (within _RETRY_NR_BUDGET): the error of a relaxed run grows like
#: ~cap^1.5 where the contraction it counted on does not come (b/a = 6.0e5,
#: kappa = 1e6, eps = 0.051, load-point, rtol 1e-12: caps 1e6 / 1e4 / 1e2 / 1 gave
#: 1.1e-7 / 1.1e-10 / 4.3e-13 / 3.4e-11 in 3.7e3 / 8.0e3 / 4.2e4 / 1.6e5 right-hand
#: sides; at rtol 1e-13 cap 1e4 gave 7.9e-14 in 1.7e4, cap 1 7.4e-14 in 2.5e5)
_FAR_OFF_CAPS = (1.0e4, 1.0e2, 1.0)
#: right-hand sides of those repeats together (then the retries get what is left of
#: _RETRY_NR_BUDGET, if anything): b/a = 9.06e5, kappa = 1e6, eps = 0, load-point, rtol
#: 1e-10 took 6.1e3 + 1.5e4 (1.06e-10) + 5.5e4 (2.0e-11, met)
_FAR_OFF_NR_BUDGET = 100_000
#: the retries stop once one brings the error bound down by less than this factor
#: (measured: velocity jump at b/a = kappa = 1e6, rtol 1e-12: 4.6e-12 first, then
#: 1.6e-12, 1.2e-12, 1.2e-12 for 1.5e4, 1.8e4, 2.6e4 right-hand sides more; values
#: agree to 1e-15, the bound is the per-step rounding of the right-hand side)
_RETRY_MIN_GAIN = 0.5
#: ... where the retry's local tolerance is at most this (within 100x of _RT_FLOOR, where
#: the rounding of the right-hand side can set the bound); above it a small gain means
#: the relaxation, which the later retries tighten (b/a = 9.3e5, kappa = 1e6, load-point,
#: rtol 1e-10: 5.7e-8 after a 1.2x gain, met by the third retry)
_GAIN_RT = 1.0e-13
#: no retry with fewer than this many right-hand sides left
_RETRY_NR_MIN = 5_000
#: no retry whose internal local tolerance (rtol x _TOL_FACTOR_V/_L) is below this: the
#: right-hand side of (A) is a difference of terms ~kappa, so its rounding is ~kappa ulp
#: and RODASP's steps at a local 2e-15 were rejected 6.5e3 times in 2.1e4 (b/a = kappa
#: = 1e6), and a retry there ran out of budget
_RT_FLOOR = 1.0e-15
#: contraction profile buffer (steps per phase) of the retries; a run with more steps
#: leaves no profile (the next one relaxes by the linear model)
_PROF_LEN = 8192
#: with a recorded profile the factor is exp(_PROF_RATE x (contraction to come) - margin)
_PROF_RATE = 0.5


class SeparatrixStatus(IntEnum):
    """Outcome of the separatrix method (the kernels return the int)."""

    #: success: the value is the critical size
    OK = 0
    #: velocity jump: the separatrix reached L = 0 before s_theta = 0
    U_NONPOSITIVE = 1
    #: load-point jump: L stopped decreasing before L = 0
    TURNING = 2
    #: step size underflow
    UNDERFLOW = 3
    #: step budget exhausted
    BUDGET = 4
    #: load-point jump: dv = expm1(l) beyond the double range; the value is l = ln(1 + dv)
    OVERFLOW = 5
    #: asymptotic start not usable
    NO_START = 6
    #: internal (never returned by the method): DOP853's steps are limited by stability,
    #: the driver continues with RODASP
    STIFF = 7


# ints for the compiled kernels (and for old callers: critical.S_OK, ...)
S_OK = int(SeparatrixStatus.OK)
S_U_NONPOSITIVE = int(SeparatrixStatus.U_NONPOSITIVE)
S_TURNING = int(SeparatrixStatus.TURNING)
S_UNDERFLOW = int(SeparatrixStatus.UNDERFLOW)
S_BUDGET = int(SeparatrixStatus.BUDGET)
S_OVERFLOW = int(SeparatrixStatus.OVERFLOW)
S_NO_START = int(SeparatrixStatus.NO_START)
S_STIFF = int(SeparatrixStatus.STIFF)


@nb.njit(cache=True, nogil=True)
def asym_coeffs(kappa, kc, eps):
    """(L*, c1, c2) of the asymptotic expansion u = L* - c1 z - c2 z^2 + O(z^3)."""
    Ls = L_star(kappa, kc, eps)
    x = eps * kappa / kc
    omx = 1.0 - x
    lam = kc * omx
    mu = kappa / kc
    c1 = kappa / (lam + mu)
    br = 1.0 + omx * c1 / mu - (omx * omx / (mu * mu) + eps * omx / (2.0 * mu)) * c1 * c1
    c2 = kc * c1 * br / (2.0 + lam / mu)
    return Ls, c1, c2


@nb.njit(cache=True, nogil=True)
def _f_theta(t, u, kappa, kc, eps):
    """(A): du/ds_theta on the separatrix; inf where u <= 0 (G(u) >= 0: outside its domain)."""
    g = G(u, eps)
    if not (g < 0.0):
        return math.inf
    return kappa * math.expm1(t - u) / g - kc


@nb.njit(cache=True, nogil=True)
def _f_u(u, t, kappa, kc, eps):
    """(B): d s_theta/du on the separatrix; inf where dL/ds <= 0 (turning point)."""
    g = G(u, eps)
    den = kappa * math.expm1(t - u) - kc * g
    if not (den > 0.0):
        return math.inf
    return g / den


@nb.njit(cache=True, nogil=True)
def _rhs_noise(mode, x, y, kappa, kc, eps):
    """Rounding of one evaluation of the right-hand side, in its units: _NOISE_ULPS ulp of
    the largest term it is the difference of ((A): kappa expm1(s_theta - u)/G(u) and
    kappa_crit; (B): the denominator's kappa expm1(s_theta - u) and kappa_crit G(u),
    relative to the denominator).  Where kappa is large these terms are ~kappa while the
    difference is O(1), so local errors below ~h kappa ulp cannot be resolved."""
    if mode == 0:
        g = G(y, eps)
        t = abs(kappa * math.expm1(x - y) / g) + kc
    else:
        g = G(x, eps)
        a = kappa * math.expm1(y - x)
        b = kc * g
        den = a - b
        if den == 0.0:
            return 0.0  # (the right-hand side is not finite there: the step is rejected)
        t = abs(g / den) * (abs(a) + abs(b)) / abs(den)
    r = _NOISE_ULPS * _ULP1 * t
    return r if math.isfinite(r) else 0.0


@nb.njit(cache=True, nogil=True)
def dfdy(mode, x, y, kappa, kc, eps):
    """d(rhs)/dy of (A) (mode 0) or (B) (mode 1), analytic; used to propagate error estimates."""
    g = G(y if mode == 0 else x, eps)
    if mode == 0:
        # f = kappa expm1(t - u)/G(u) - kc, G'(u) = -e^(-eps u)
        e = math.exp(x - y)
        return -kappa * e / g + kappa * math.expm1(x - y) * math.exp(-eps * y) / (g * g)
    # f = G(u)/(kappa expm1(t - u) - kc G(u)), derivative in t; ~ -G e^(u - t)/kappa -> 0
    # where e^(t - u) overflows (load-point jumps beyond the double range)
    den = kappa * math.expm1(y - x) - kc * g
    jb = -g * kappa * math.exp(y - x) / (den * den)
    return jb if math.isfinite(jb) else 0.0


@nb.njit(cache=True, nogil=True)
def dfdx(mode, x, y, kappa, kc, eps):
    """d(rhs)/dx of (A) (mode 0, x = s_theta) or (B) (mode 1, x = u), analytic (RODASP)."""
    if mode == 0:
        # f = kappa expm1(t - u)/G(u) - kc: d/dt = kappa e^(t - u)/G(u)
        return kappa * math.exp(x - y) / G(y, eps)
    # f = G(u)/den, den = kappa expm1(t - u) - kc G(u), G'(u) = -e^(-eps u)
    g = G(x, eps)
    gp = -math.exp(-eps * x)
    den = kappa * math.expm1(y - x) - kc * g
    dden = -kappa * math.exp(y - x) - kc * gp
    r = (gp * den - g * dden) / (den * den)
    return r if math.isfinite(r) else 0.0


@nb.njit(cache=True, nogil=True)
def _rhs(mode, x, y, kappa, kc, eps):
    if mode == 0:
        return _f_theta(x, y, kappa, kc, eps)
    return _f_u(x, y, kappa, kc, eps)


#: the method of a scalar run (:func:`_scalar_run`)
_EXPLICIT = 0  # DOP853 (rsfcore.ode.rk)
_ROSENBROCK = 1  # RODASP (rsfcore.ode.rodasp)


@nb.njit(cache=True, nogil=True)
def _pair_rhs(z, out, mode, kappa, kc, eps):
    """The scalar ODE as the autonomous pair z = (x, y): (x', y') = (1, f(x, y))."""
    out[0] = 1.0
    out[1] = _rhs(mode, z[0], z[1], kappa, kc, eps)


@nb.njit(cache=True, nogil=True, error_model="numpy")
def _scalar_run(
    method,
    mode,
    x0,
    y0,
    x_end,
    kappa,
    kc,
    eps,
    rtol,
    atol,
    ycap,
    switch_slope,
    h0,
    K,
    h_max,
    err0,
    relax_cap,
    y_stop,
    switch,
    rec,
    rec_n,
    use,
    use_n,
    tail,
    max_steps=_MAX_STEPS,
):
    """Integrate the scalar ODE (mode 0: (A), mode 1: (B)) from (x0, y0) towards x_end
    with DOP853 (method _EXPLICIT) or RODASP (method _ROSENBROCK).

    One driver, one set of events for both methods:

    * error weight per step atol + rtol min(max(|y|, |y_new|), ycap) (rk.error_scale),
      with rtol and atol multiplied by the relaxation factor (below); steps capped at
      h_max; the last step lands exactly on x_end (stretched by up to 30 % unless the last
      attempt was rejected; error control rejects it if that was too much);
    * stops at x_end, or (switch_slope > 0) after the first accepted step whose end slope
      |dy/dx| exceeds switch_slope, or (RODAS4, y_stop finite) where y crosses y_stop
      (located by the Illinois method on the length of the last step, each trial one RODAS4
      step from its start; returns the crossing x and y = y_stop);
    * the propagated absolute error estimate, from err0: after each accepted step
      err <- err exp(h J) + |local error estimate|, with h J the less contractive of the
      analytic d(rhs)/dy at the step ends (the separatrix attracts: J h < 0, old errors
      shrink); the contraction profile is recorded in rec/rec_n (:func:`_record`);
    * relaxation: with a profile of an earlier run (use/use_n > 1, tail) the factor of
      :func:`_relax_profile`; otherwise, RODAS4 only (and DOP853 if _RELAX_EXPLICIT), the
      linear model of :func:`_relax` (relax_cap itself when x_end is infinite); relax_cap
      is capped so that the relaxed tolerance stays <= _RELAX_TOL_MAX;
    * switch: DOP853 returns S_STIFF at the end of an accepted step once STIFF_RUN
      consecutive steps had h |J| > STIFF_HJ, or > STIFF_HJ_FAST where |J| > STIFF_J_FAST
      (not interrupted by 6 in a row below it:
      Hairer's counting in dop853.f); RODASP returns S_STIFF before a step once
      _RELAX_RATE |J| rem < 1 (little damping left before x_end: DOP853, whose 8th order
      needs few steps for the tight tolerance such undamped errors need, finishes), or
      after EASY_RUN accepted steps in a row with h |J| < EASY_HJ (EASY_HJ_FAST where
      |J| > STIFF_J_FAST);
    * the error weight adds h x the right-hand side's rounding (:func:`_rhs_noise`;
      divided by 1 + h |J| for RODASP, whose linear solve damps it);
    * at most max_steps attempted steps (S_BUDGET).

    DOP853: the shared kernels of rsfcore.ode.rk on K (N_WORK = 13 floats, the stages),
    elementary controller.  RODASP: rsfcore.ode.rodasp on the autonomous pair (x, y),
    x' = 1 (:func:`_pair_rhs`), whose Jacobian [[0, 0], [df/dx, df/dy]] is analytic
    (:func:`dfdx`, :func:`dfdy`): L-stable, so where the separatrix attracts at a rate
    ~kappa the step is limited by accuracy, not stability; rodas.f's controller without
    the predictive correction.  RODASP keeps order ~3-4 on this stiff problem, where
    RODAS4 fell to order ~1 (a local error ~h/kappa, as on the Prothero-Robinson test
    problem; tests/core/test_rodasp.py): at b/a = kappa = 1e6 to s_theta = 0, rtol 1e-12
    took 2.4e3 steps against 2.1e5.

    Returns (status, x, y, err_prop, n_rhs, h).
    """
    stiff = method == _ROSENBROCK
    Kw = K.reshape((K.shape[0], 1))  # the shared DOP853 kernels take (stages, components)
    relax_cap = min(relax_cap, max(1.0, _RELAX_TOL_MAX / rtol))
    sc = np.empty(1)
    W = np.zeros((rodas4.SCALAR_WORK, 2))  # RODASP's workspace (rodasp.scalar_step)
    args = (mode, kappa, kc, eps)
    x = x0
    y = y0
    direction = 1.0 if x_end >= x0 else -1.0
    f = _rhs(mode, x, y, kappa, kc, eps)
    n_rhs = 1
    if not math.isfinite(f):
        return S_NO_START, x, y, err0, n_rhs, h0
    if rec_n[0] == 0:
        _record(rec, rec_n, x, 0.0)
    h = min(abs(h0), h_max)
    err_sum = err0
    J = dfdy(mode, x, y, kappa, kc, eps)
    fx = dfdx(mode, x, y, kappa, kc, eps) if stiff else 0.0
    n = 0
    n_stiff = 0
    n_easy = 0
    last_rejected = False
    stop = stiff and math.isfinite(y_stop)
    while n < max_steps:
        n += 1
        rem = (x_end - x) * direction
        if rem <= 0.0:
            return S_OK, x, y, err_sum, n_rhs, h
        final = False
        if h >= rem or (1.3 * h >= rem and not last_rejected):
            h = rem
            final = True
        hs = h * direction
        # the right-hand side's rounding (:func:`_rhs_noise`) enters the weight: a local
        # error at that level is accepted (and counted in the propagated estimate) instead
        # of shrinking the step without end (measured before: b/a = kappa = 1e6, rtol
        # 1e-13, 2.3e6 right-hand sides and out of budget, in phase (B) near s_theta = 0);
        # a stiff step damps it by 1/(1 + h |J|) (the linear solve)
        noise = _rhs_noise(mode, x, y, kappa, kc, eps)
        if stiff and switch and math.isfinite(rem) and _RELAX_RATE * abs(J) * rem < 1.0:
            return S_STIFF, x, y, err_sum, n_rhs, h
        if use_n > 1:
            relax = _relax_profile(x, direction, relax_cap, use, use_n, tail)
        elif stiff or _RELAX_EXPLICIT:
            relax = _relax(relax_cap, J, rem, stiff)
        else:
            relax = 1.0
        ynew = 0.0
        fnew = math.nan
        err = math.inf
        if stiff:
            ok, ynew, fnew = rodasp.scalar_step(_pair_rhs, args, x, y, f, fx, J, hs, W)
            sc[0] = rk.error_scale(y, ynew, rtol * relax, atol * relax, ycap) + h * noise / (
                1.0 + h * abs(J)
            )
            if ok:
                n_rhs += rodas4.N_STAGES
                if math.isfinite(ynew) and math.isfinite(fnew):
                    err = rodas4.scalar_error(W, hs, sc[0], False)
        else:
            Kw[0, 0] = f
            ok = True
            for s in range(1, rk.N_STAGES):
                k = _rhs(mode, x + _C[s] * hs, y + hs * rk.stage_sum(Kw, s, 0), kappa, kc, eps)
                if not math.isfinite(k):
                    ok = False
                    break
                Kw[s, 0] = k
            n_rhs += rk.N_STAGES
            if ok:
                ynew = y + hs * rk.solution_sum(Kw, 0)
                fnew = _rhs(mode, x + hs, ynew, kappa, kc, eps)
                if math.isfinite(fnew) and math.isfinite(ynew):
                    Kw[rk.N_STAGES, 0] = fnew
                    sc[0] = rk.error_scale(y, ynew, rtol * relax, atol * relax, ycap) + h * noise
                    err = rk.error_norm(Kw, h, sc, 1)
        if not (err <= 1.0):
            h *= rodas4.reject_factor(err) if stiff else rk.reject_factor(err)
            last_rejected = True
            if h < 1e-15 * max(1.0, abs(x)):
                return S_UNDERFLOW, x, y, err_sum, n_rhs, h
            continue
        if stop and (ynew - y_stop) * (y - y_stop) <= 0.0 and ynew != y:
            # Illinois on the step length: g(s) = y(x + s) - y_stop, g(0) = y - y_stop
            s0 = 0.0
            g0 = y - y_stop
            s1 = hs
            g1 = ynew - y_stop
            xs = x + hs
            e_loc = abs(W[5, 1])  # k_6 of the step: its embedded error estimate
            for _ in range(60):
                sm = s1 - g1 * (s1 - s0) / (g1 - g0)
                if not (min(s0, s1) < sm < max(s0, s1)):
                    sm = 0.5 * (s0 + s1)
                okm, ym, _ = rodasp.scalar_step(_pair_rhs, args, x, y, f, fx, J, sm, W)
                if not okm:
                    break
                n_rhs += rodas4.N_STAGES
                if not math.isfinite(ym):
                    break
                gm = ym - y_stop
                xs = x + sm
                e_loc = abs(W[5, 1])
                if gm == 0.0 or abs(s1 - s0) <= 1e-15 * max(abs(x), 1.0):
                    break
                if gm * g1 < 0.0:
                    s0, g0 = s1, g1
                else:
                    g0 *= 0.5
                s1, g1 = sm, gm
            prop = max(hs * J, 0.0)
            return S_OK, xs, y_stop, err_sum * math.exp(min(prop, 50.0)) + e_loc, n_rhs, h
        Jn = dfdy(mode, x + hs, ynew, kappa, kc, eps)
        # least contractive end of the step (a trapezoid over-contracts on long steps)
        prop = max(hs * J, hs * Jn)
        err_sum = err_sum * math.exp(min(prop, 50.0)) + err * sc[0]
        _record(rec, rec_n, x + hs, max(0.0, -0.5 * (hs * J + hs * Jn)))
        J = Jn
        x = x_end if final else x + hs
        y = ynew
        f = fnew
        if stiff:
            fx = dfdx(mode, x, y, kappa, kc, eps)
        if final:
            return S_OK, x, y, err_sum, n_rhs, h
        if switch_slope > 0.0 and abs(f) > switch_slope:
            return S_OK, x, y, err_sum, n_rhs, h
        if stiff:
            if switch:
                # steps no longer limited by stability (h |J| < EASY_HJ, EASY_RUN in a
                # row): accuracy limits them, and DOP853 (order 8) takes longer ones
                if h * abs(J) < (EASY_HJ_FAST if abs(J) > STIFF_J_FAST else EASY_HJ):
                    n_easy += 1
                    if n_easy >= EASY_RUN:
                        return S_STIFF, x, y, err_sum, n_rhs, h
                else:
                    n_easy = 0
            # rodas.f's controller (no predictive correction: h_prev = 0)
            fac, _ = rodas4.accept_factor(err, h, 0.0, 1.0, last_rejected)
        else:
            if switch:
                # Hairer's counting (dop853.f): STIFF_RUN stiff steps, reset after 6 in a
                # row that are not
                if h * abs(J) > STIFF_HJ or (abs(J) > STIFF_J_FAST and h * abs(J) > STIFF_HJ_FAST):
                    n_stiff += 1
                    n_easy = 0
                    if n_stiff >= STIFF_RUN:
                        return S_STIFF, x, y, err_sum, n_rhs, h
                else:
                    n_easy += 1
                    if n_easy >= 6:
                        n_stiff = 0
            # elementary controller (no predictive correction: h_prev = 0); err = 0 gives 10
            fac, _ = rk.accept_factor(err, h, 0.0, 1.0, last_rejected)
        last_rejected = False
        h = min(h * fac, h_max)
    return S_BUDGET, x, y, err_sum, n_rhs, h


@nb.njit(cache=True, nogil=True, error_model="numpy")
def _relax(relax_cap, J, rem, inf_relaxes):
    """Factor on the local tolerance of a step with d(rhs)/dy = J and rem left to x_end.

    An error made here is damped by about exp(-integral of |J|) before the end: by
    exp(-|J| rem/2) if |J| falls linearly to 0 there (phase (B) near u = 0).  The factor is
    min(relax_cap, exp(_RELAX_RATE |J| rem - _RELAX_MARGIN)) (>= 1), so a relaxed error
    arrives at the end damped by at least e^-_RELAX_MARGIN under that model; where the model
    is optimistic the propagated estimate, which uses every step's own J, shows it.  rem
    infinite (load-point phase (A), followed by the contraction of phase (B)): relax_cap
    if inf_relaxes, else 1."""
    if relax_cap <= 1.0:
        return 1.0
    if not math.isfinite(rem):
        return relax_cap if inf_relaxes else 1.0
    return min(
        relax_cap, math.exp(min(max(_RELAX_RATE * abs(J) * rem - _RELAX_MARGIN, 0.0), 700.0))
    )


@nb.njit(cache=True, nogil=True, error_model="numpy")
def _relax_profile(x, direction, relax_cap, use, use_n, tail):
    """Relaxation factor from a recorded contraction profile (a previous run of the phase).

    use[0, :use_n]: x at the accepted steps (monotone along ``direction``); use[1]: the
    integral of |J| dx from the phase start.  The contraction still to come from x is
    use[1, use_n - 1] - (use[1] interpolated at x) + tail (tail: later phases); the factor
    is min(relax_cap, exp(_PROF_RATE * that - _RELAX_MARGIN)) (>= 1).
    """
    last = use_n - 1
    if (x - use[0, 0]) * direction <= 0.0:
        lx = use[1, 0]
    elif (x - use[0, last]) * direction >= 0.0:
        lx = use[1, last]
    else:
        lo = 0
        hi = last
        while hi - lo > 1:
            mid = (lo + hi) // 2
            if (use[0, mid] - x) * direction <= 0.0:
                lo = mid
            else:
                hi = mid
        dx = use[0, hi] - use[0, lo]
        w = (x - use[0, lo]) / dx if dx != 0.0 else 0.0
        lx = use[1, lo] + w * (use[1, hi] - use[1, lo])
    rem = use[1, last] - lx + tail
    return min(relax_cap, math.exp(min(max(_PROF_RATE * rem - _RELAX_MARGIN, 0.0), 700.0)))


@nb.njit(cache=True, nogil=True, error_model="numpy")
def _record(rec, rec_n, x, lam_step):
    """Append (x, previous integral + lam_step) to the profile; rec_n[0] = -1 once full."""
    i = rec_n[0]
    if i < 0:
        return
    if i >= rec.shape[1]:
        rec_n[0] = -1
        return
    base = rec[1, i - 1] if i > 0 else 0.0
    rec[0, i] = x
    rec[1, i] = base + (lam_step if i > 0 else 0.0)
    rec_n[0] = i + 1


@nb.njit(cache=True, nogil=True)
def _integrate(
    mode,
    x0,
    y0,
    x_end,
    kappa,
    kc,
    eps,
    rtol,
    atol,
    ycap,
    switch_slope,
    h0,
    K,
    h_max,
    err0,
    relax_cap,
    stiff_slope,
    stiff_ok,
    rec,
    rec_n,
    use,
    use_n,
    tail,
    max_steps,
):
    """DOP853 (:func:`_scalar_run`), handing over to RODASP (the same driver, with
    relax_cap and switch slope stiff_slope) and back (up to _MAX_SWITCHES times; each leg
    at most max_steps steps) once its steps are
    limited by stability (never with stiff_ok False: DOP853 alone, the reference the
    tests compare with).  The legs share one budget: the first at most max_steps steps,
    each later one what is left of max_steps x rodas4.N_STAGES right-hand sides (S_BUDGET
    once spent; before, every leg had max_steps steps of its own, and retries meant to
    stay within _RETRY_NR_BUDGET took 2 - 3x it).  rec/rec_n: the contraction profile is recorded there;
    use/use_n/tail: a profile recorded by an earlier run relaxes the tolerance
    (:func:`_relax_profile`).  Returns (status, x, y, err_prop, n_rhs, h, used RODASP)."""
    st, x, y, es, nr, h = _scalar_run(
        _EXPLICIT, mode, x0, y0, x_end, kappa, kc, eps, rtol, atol, ycap, switch_slope, h0, K,
        h_max, err0, relax_cap, math.nan, stiff_ok, rec, rec_n, use, use_n, tail, max_steps,
    )  # fmt: skip
    used = False
    method = _EXPLICIT
    n_sw = 0
    nr_budget = max_steps * rodas4.N_STAGES
    while st == S_STIFF:
        n_sw += 1
        left = nr_budget - nr
        if method == _EXPLICIT or n_sw > _MAX_SWITCHES:
            # stiff: RODASP (the last leg without switching back)
            method = _ROSENBROCK
            used = True
            if left < rodas4.N_STAGES:
                return S_BUDGET, x, y, es, nr, h, used
            st, x, y, es, nr2, h = _scalar_run(
                _ROSENBROCK, mode, x, y, x_end, kappa, kc, eps, rtol, atol, ycap, stiff_slope,
                h, K, h_max, es, relax_cap, math.nan, n_sw < _MAX_SWITCHES, rec, rec_n, use,
                use_n, tail, left // rodas4.N_STAGES,
            )  # fmt: skip
        else:
            # no longer stiff (little damping left, or steps not limited by stability)
            method = _EXPLICIT
            if left < rk.N_STAGES:
                return S_BUDGET, x, y, es, nr, h, used
            st, x, y, es, nr2, h = _scalar_run(
                _EXPLICIT, mode, x, y, x_end, kappa, kc, eps, rtol, atol, ycap, switch_slope, h,
                K, h_max, es, relax_cap, math.nan, True, rec, rec_n, use, use_n, tail,
                left // rk.N_STAGES,
            )  # fmt: skip
        nr += nr2
    return st, x, y, es, nr, h, used


@nb.njit(cache=True, nogil=True)
def separatrix_critical(kappa, kc, eps, pert, rtol, K):
    """Critical size by the separatrix method (kappa > kappa_crit, x < 1, v_o > 0).

    pert 0: velocity jump (returns d_crit); pert 1: load-point jump (returns dv_crit).
    Returns (status, value, abs_err, n_rhs).  The first run relaxes the local tolerance
    where the separatrix's contraction damps the errors (_RELAX_CAP, :func:`_relax`); if
    its propagated error estimate exceeds the requested rtol it is repeated with the
    tighter settings of _RETRIES until one meets it (a relaxed run costs ~1e4 right-hand
    sides at b/a = kappa = 1e6; without the relaxation the same estimate needs ~1e6).
    """
    # the first run records nothing (1-column buffers fill at once); retries record the
    # contraction profiles (phases A, B) and, after the first retry, relax by the previous
    # run's profile instead of the linear model
    tiny = np.empty((2, 2, 1))
    tiny_n = np.zeros(2, dtype=np.int64)
    # runs at no looser than _RUN_RTOL_MAX (the requested rtol is what the answer is
    # checked against): in the stiff corner a loose tolerance ran out of budget
    rr = min(rtol, _RUN_RTOL_MAX)
    st, val, err, nr, _ = _separatrix_run(
        kappa, kc, eps, pert, rr, K, _RELAX_CAP, True, tiny, tiny_n, tiny, 0, 0, _MAX_STEPS
    )
    if st == S_BUDGET:
        # the requested tolerance is beyond the step budget (the stiff corner at rtol
        # <= 1e-12 before RODASP and the rounding floor): the answer at the
        # tightest tolerance within it, 10x looser at a time up to _LADDER_RTOL_MAX, with
        # its own error estimate (accuracy_met False) instead of a bisection on classify
        # (2 - 5 s); retries (tighter still) would run out of budget too
        r = rr
        nr_last = nr
        while st == S_BUDGET and r * 10.0 <= _LADDER_RTOL_MAX * (1.0 + 1e-9):
            r *= 10.0
            st, val, err, nr_last, _ = _separatrix_run(
                kappa, kc, eps, pert, r, K, _RELAX_CAP, True, tiny, tiny_n, tiny, 0, 0, _MAX_STEPS
            )
            nr += nr_last
        return st, val, err + _rounding_floor(st, val, pert, nr_last), nr
    fl = _rounding_floor(st, val, pert, nr)
    # a retry tightens the integration, not the rounding: none once rounding takes half;
    # none after a first run of more than _RETRY_NR_MAX right-hand sides (a tighter run
    # costs more and ran out of budget in every such case measured: 0.5 s more at
    # b/a = kappa = 1e6, rtol 1e-13)
    if (
        st != S_OK
        or err + fl <= rtol * abs(val)
        or fl > 0.5 * rtol * abs(val)
        or nr > _RETRY_NR_MAX
    ):
        return st, val, err + fl, nr
    prof = np.empty((2, 2, 2, _PROF_LEN))
    pn = np.zeros((2, 2), dtype=np.int64)
    cur = 0
    na = 0
    nb_ = 0
    nr_run = nr
    tol_factor = _TOL_FACTOR_V if pert == 0 else _TOL_FACTOR_L
    nr_first = nr
    if err + fl > _FAR_OFF * rtol * abs(val):
        # far off: the relaxation over-relaxed (the contraction it counted on did not
        # come), and tighter relaxed retries cost more than one unrelaxed run at rtol
        # (b/a = 6.0e5, kappa = 1e6, eps = 0.051, load-point, rtol 1e-10: relaxed 2.7e-7,
        # unrelaxed 1.5e-11 in 4.1e4 right-hand sides, relaxed retries 2.8e5)
        for cap in _FAR_OFF_CAPS:
            left = _FAR_OFF_NR_BUDGET - (nr - nr_first)
            if left < _RETRY_NR_MIN:
                break
            st2, val2, err2, nr2, _ = _separatrix_run(
                kappa, kc, eps, pert, rr, K, cap, True, tiny, tiny_n, tiny, 0, 0,
                left // rodas4.N_STAGES,
            )  # fmt: skip
            nr += nr2
            if st2 == S_OK:
                fl2 = _rounding_floor(st2, val2, pert, nr2)
                if err2 + fl2 < err + fl:
                    st, val, err, nr_run, fl = st2, val2, err2, nr2, fl2
                if err + fl <= rtol * abs(val):
                    return st, val, err + fl, nr
            elif st2 == S_BUDGET:
                break  # a smaller cap costs more
    for i in range(len(_RETRIES)):
        r_i = rr * _RETRIES[i][0]
        left = _RETRY_NR_BUDGET - (nr - nr_first)
        if r_i * tol_factor < _RT_FLOOR or left < _RETRY_NR_MIN:
            # a local tolerance within rounding of the right-hand side (every later retry
            # is tighter), or the retries' budget spent: the best run so far stands
            break
        pn[cur, 0] = 0
        pn[cur, 1] = 0
        st2, val2, err2, nr2, _ = _separatrix_run(
            kappa, kc, eps, pert, r_i, K, _RETRIES[i][1], True, prof[cur], pn[cur],
            prof[1 - cur], na, nb_, left // rodas4.N_STAGES,
        )  # fmt: skip
        nr += nr2
        if st2 == S_BUDGET:
            # every later retry is tighter (a smaller rtol factor or relaxation cap), so
            # it would run out of budget too (0.3 - 0.5 s each at b/a = kappa = 1e6,
            # rtol 1e-12): the best run so far stands, with its estimate
            break
        if st2 == S_OK:
            fl2 = _rounding_floor(st2, val2, pert, nr2)
            best = err + _rounding_floor(st, val, pert, nr_run)
            if err2 + fl2 < best:
                # the run with the smaller error bound is kept (both are bounds)
                st, val, err, nr_run = st2, val2, err2, nr2
            if err2 + fl2 <= rtol * abs(val2):
                break
            if err2 + fl2 > _RETRY_MIN_GAIN * best and r_i * tol_factor <= _GAIN_RT:
                # the estimate has reached its floor (the right-hand side's rounding
                # counted per step, which a tighter run does not reduce): the best run
                # stands
                break
        na = max(pn[cur, 0], 0)
        nb_ = max(pn[cur, 1], 0)
        cur = 1 - cur
    return st, val, err + _rounding_floor(st, val, pert, nr_run), nr


@nb.njit(cache=True, nogil=True)
def _rounding_floor(st, val, pert, nr_run):
    """Rounding of s_theta ~ l = ln(1 + dv) accumulated over a load-point run's steps (not
    in the integration's estimate, and no retry can reduce it; 0 for a velocity jump): in
    (B) the right-hand side hardly depends on s_theta, so each step's rounding stays.
    Measured up to 0.94 sqrt(steps) ulp(l) against the asymptote at l ~ 7e7 (2.6e5 steps);
    the floor is 2 sqrt(n_rhs/12) ulp(l), in the units of the returned error (of dv for
    S_OK, of l for S_OVERFLOW)."""
    if pert == 0 or (st != S_OK and st != S_OVERFLOW):
        return 0.0
    lg = math.log1p(val) if st == S_OK else val
    f = 2.0 * math.sqrt(nr_run / 12.0) * _ULP1 * abs(lg)
    return f * math.exp(lg) if st == S_OK else f


@nb.njit(cache=True, nogil=True)
def _separatrix_run(
    kappa, kc, eps, pert, rtol, K, relax_cap, stiff_ok, rec, rec_n, use, na, nb_, max_steps
):  # fmt: skip
    """One run of the separatrix method: (status, value, abs_err, n_rhs, used RODASP).

    rec (2, 2, P), rec_n (2,): the contraction profiles of phases A and B are recorded
    there; use (2, 2, P) with counts na, nb_ (0: none): profiles of an earlier run, which
    then set the relaxation (the contraction still to come from each point: the rest of
    the phase plus phase B's total for phase A).

    stiff_ok False with relax_cap 1: DOP853 alone with the strict tolerance (the method
    before the stiff switch; a reference where its step budget suffices)."""
    Ls, c1, c2 = asym_coeffs(kappa, kc, eps)
    if not (Ls > 0.0) or not math.isfinite(Ls):
        return S_NO_START, math.nan, math.nan, 0, False
    # start far enough out that the neglected O(z^3) terms are ~1e-3 rtol: measured
    # truncation ~1e-13 relative at c z0 = 1e-5, scaling as z0^3 (tests/core/test_critical.py)
    cz = max(abs(c1), math.sqrt(abs(c2)), 1e-300)
    zt = min(max(_Z_TARGET * (rtol / 1e-10) ** (1.0 / 3.0), 1e-7), 1e-4)
    s0 = Ls + math.log(zt / cz)
    if pert == 0:
        s0 = min(s0, _S0_MAX)  # a velocity jump ends at s_theta = 0: start before it
    # (a load-point jump ends at u = 0, s_theta = l > L*: starting at s_theta ~ L* - 15
    # instead of -5 skips ~2 L* steps along u = L* (2e4 at L* = 1e4))
    z0 = math.exp(s0 - Ls)
    u0 = Ls - z0 * (c1 + c2 * z0)
    rt = rtol * (_TOL_FACTOR_V if pert == 0 else _TOL_FACTOR_L)
    tail_a = use[1, 1, nb_ - 1] if nb_ > 0 else 0.0
    if na < 2:
        nb_ = 0  # profiles only as a pair
    # phase (B) ends near the separatrix's turning point, where s_theta is ~ l = ln(1 + dv)
    # and l >= ln(1 + 1/(kappa_crit (1 - eps))) (its value at kappa = kappa_crit; dv grows
    # with kappa): absolute errors in s_theta there must be ~rtol l, not rtol
    l_lo = math.log1p(1.0 / (kc * (1.0 - eps)))
    atol_b = rt * 1e-3 * min(1.0, l_lo)
    if pert == 0:
        # (A) from s0 to s_theta = 0; atol keeps a floor for tiny d_crit.  If RODASP took
        # over (stiff) and the slope |du/ds_theta| exceeds 1 first, the end lies near the
        # turning point: continue in (B) down in u until s_theta crosses 0
        st, t, u, es, nr, h, stiff = _integrate(
            0, s0, u0, 0.0, kappa, kc, eps, rt, rt * 1e-3 * Ls, math.inf, 0.0, 1.0, K, _H_MAX,
            0.0, relax_cap, 1.0, stiff_ok, rec[0], rec_n[0:1], use[0], na, tail_a,
            max_steps,
        )  # fmt: skip
        if st != S_OK:
            if st == S_NO_START:
                st = S_U_NONPOSITIVE
            return st, math.nan, math.nan, nr, stiff
        if not (u > 0.0):
            return S_U_NONPOSITIVE, math.nan, math.nan, nr, stiff
        if t == 0.0:
            return S_OK, u, es, nr, stiff
        fb = _f_u(u, t, kappa, kc, eps)
        st2, u2, t2, es2, nr2, h2 = _scalar_run(
            _ROSENBROCK, 1, u, t, 0.0, kappa, kc, eps, rt, atol_b, 1.0, 0.0, 0.1 * u, K,
            _H_MAX_B, es * abs(fb), relax_cap, 0.0, False, rec[1], rec_n[1:2], use[1], nb_, 0.0,
            max_steps,
        )  # fmt: skip
        nr += nr2
        if st2 != S_OK or t2 != 0.0 or not (u2 > 0.0):
            # s_theta stays below 0 down to L = 0: the separatrix misses the line
            return S_U_NONPOSITIVE, math.nan, math.nan, nr, stiff
        # an error dt in s_theta moves the crossing by dt / |ds_theta/du|
        slope = abs(_f_u(u2, 0.0, kappa, kc, eps))
        if not (slope > 0.0):
            return S_U_NONPOSITIVE, math.nan, math.nan, nr, stiff
        return S_OK, u2, es2 / slope, nr, stiff
    # load-point jump: (A) until the slope |du/ds_theta| exceeds 1, then (B) down to u = 0.
    # The relative error of dv is the absolute error of l = ln(1 + dv) times
    # e^l/(e^l - 1), so errors are controlled in absolute terms (scale capped at 1).
    # l may exceed 709 (dv beyond the double range): then the status is S_OVERFLOW and the
    # value returned is l itself, with its absolute error (the relative error of dv).
    t_far = math.inf
    st, t, u, es, nr, h, stiff = _integrate(
        0, s0, u0, t_far, kappa, kc, eps, rt, rt * 1e-3, 1.0, 1.0, 1.0, K, _H_MAX, 0.0,
        relax_cap, 1.0, stiff_ok, rec[0], rec_n[0:1], use[0], na, tail_a, max_steps,
    )  # fmt: skip
    if st != S_OK:
        if st == S_NO_START:
            st = S_TURNING
        return st, math.nan, math.nan, nr, stiff
    if not (u > 0.0):
        return S_TURNING, math.nan, math.nan, nr, stiff
    # the phase-A error in u at the switch moves the path by (dt/du) du in t: it enters
    # phase B as its initial error and is propagated (damped) with it
    es_t = es * abs(_f_u(u, t, kappa, kc, eps))
    # Below phi = u - s_theta = -_PHI_FROZEN the slider is stuck: (B) gives |ds_theta/du|
    # <= |G(u)| / (kappa (e^(-phi) - 1)), so s_theta, which only grows as u falls, moves by
    # at most |G(u_f)|/kappa e^(phi_f)/(1 - e^(phi_f)) on the rest of the way to u = 0
    # (|G| grows with u > 0).  Phase (B) stops at u_f = s_theta(switch) - _PHI_FROZEN and
    # adds that bound to its error: near b/a -> 1 the rest is ~L* / _H_MAX_B steps (1e5
    # at L* = 1e4, 24 ms) of a frozen s_theta.
    u_f = t - _PHI_FROZEN
    u_stop = u_f if 0.0 < u_f < u else 0.0
    # (phase B gets what phase A left of the budget: max_steps x rodas4.N_STAGES
    # right-hand sides in all)
    left_b = max_steps - nr // rodas4.N_STAGES
    if left_b <= 0:
        return S_BUDGET, math.nan, math.nan, nr, stiff
    st2, u2, t2, es2, nr2, h2, stiff2 = _integrate(
        1, u, t, u_stop, kappa, kc, eps, rt, atol_b, 1.0, 0.0, 0.1 * u, K, _H_MAX_B, es_t,
        relax_cap, 0.0, stiff_ok, rec[1], rec_n[1:2], use[1], nb_, 0.0, left_b,
    )  # fmt: skip
    nr += nr2
    stiff = stiff or stiff2
    if st2 != S_OK:
        if st2 == S_NO_START:
            st2 = S_TURNING
        return st2, math.nan, math.nan, nr, stiff
    if u_stop > 0.0:
        ph = u2 - t2
        if ph < -0.5 * _PHI_FROZEN:
            es2 += abs(G(u2, eps)) / kappa * math.exp(ph) / -math.expm1(ph)
        else:  # (not seen: s_theta fell on the way) the rest is integrated after all
            left_b = max_steps - nr // rodas4.N_STAGES
            if left_b <= 0:
                return S_BUDGET, math.nan, math.nan, nr, stiff
            st2, u2, t2, es2, nr3, h2, stiff3 = _integrate(
                1, u2, t2, 0.0, kappa, kc, eps, rt, atol_b, 1.0, 0.0, h2, K, _H_MAX_B, es2,
                relax_cap, 0.0, stiff_ok, rec[1], rec_n[1:2], use[1], nb_, 0.0, left_b,
            )  # fmt: skip
            nr += nr3
            stiff = stiff or stiff3
            if st2 != S_OK:
                return S_TURNING if st2 == S_NO_START else st2, math.nan, math.nan, nr, stiff

    dv = math.expm1(t2)
    if dv == math.inf:
        return S_OVERFLOW, t2, es2, nr, stiff
    if not (dv > 0.0):
        return S_TURNING, math.nan, math.nan, nr, stiff
    # d dv = e^l dl
    return S_OK, dv, es2 * math.exp(t2), nr, stiff


@nb.njit(cache=True, nogil=True)
def separatrix_explicit(kappa, kc, eps, pert, rtol, K):
    """The separatrix method with DOP853 alone (no RODASP, no relaxation): a reference."""
    tiny = np.empty((2, 2, 1))
    tiny_n = np.zeros(2, dtype=np.int64)
    st, val, err, nr, _ = _separatrix_run(
        kappa, kc, eps, pert, rtol, K, 1.0, False, tiny, tiny_n, tiny, 0, 0, _MAX_STEPS
    )
    return st, val, err, nr
