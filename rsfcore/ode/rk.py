"""Shared compiled pieces of the DOP853 integrators (engine and separatrix).

Each function is one seam of an explicit Runge-Kutta driver, compiled with numba and
free of any right-hand side, so that :mod:`rsfcore.engine` (the 3/5-component
spring-slider system with events and dense output) and :mod:`rsfcore.separatrix` (the
scalar separatrix ODE) are two drivers over the same stage, error-norm, controller,
dense-output and root-finding code.  A driver owns its right-hand side and its loop;
it calls

* :func:`stage_sum` / :func:`stage_state`: the argument of stage s,
  y + h sum_{m<s} a_{s,m} k_m;
* :func:`solution_sum` / :func:`step_state`: the 8th-order solution
  y + h sum b_m k_m;
* :func:`error_scale`, :func:`error_norm`: Hairer's combined 5th/3rd-order error
  estimate, err = |h| E5^2 / sqrt(n (E5^2 + 0.01 E3^2)) in the weighted RMS norm
  (Hairer, Norsett & Wanner I, Sec. II.10, eq. (10.17));
* :func:`reject_factor`, :func:`accept_factor`: the step-size controller (elementary
  controller with safety 0.9 and bounds [0.2, 10], plus Gustafsson's predictive
  correction when the previous accepted step is given; Hairer & Wanner II, Sec. IV.8);
* :func:`initial_step_trial`, :func:`initial_step`: the starting-step heuristic of
  Hairer, Norsett & Wanner I, Sec. II.4, for order 8;
* :func:`dense_coeffs`, :func:`dense_eval`: the 7th-order continuous extension
  (after the driver has filled stages 14-16 with :func:`stage_state`);
* :func:`illinois_point`, :func:`illinois_update`: the Illinois variant of regula falsi
  for event location on the dense output;
* :func:`dense_component`, :func:`dense_invert`: one component of the dense output with
  its derivative, and the point where a monotone component takes a given value
  (safeguarded Newton: samples at given physical times, 2-3 evaluations of one
  component each instead of ~10 of all);
* :func:`stiffness_ratio`: Hairer's stiffness indicator h |lambda| ~ h ||f(y_13) - f(y_12)||
  / ||y_13 - y_12|| from the last two stages (dop853.f, "stiffness detection").

Array conventions (n = number of components):
  K: (16, n) stage derivatives, row m = k_{m+1}; rows 0..11 the step's stages,
     row 12 = f(y_new), rows 13..15 the dense-output stages.
  F: (7, n) dense-output coefficients of the last step.
All arithmetic is in the order of the original drivers, so results are bit-identical to
the code this module replaced (tests/core/test_critical.py, test_trajectory.py).

Every kernel is compiled with ``inline="always"``: numba inlines it into the driver at the
IR level, so the loops over stages and components unroll as they did when the drivers
held their own copies (measured: without inlining the engine takes 1.28x the CPU time per
step, 1016 against 793 ns; with it 796 ns, the same as before the split).  Numba's cache
does not track these cross-module calls: after editing this file, also touch the drivers
(rsfcore/engine.py, rsfcore/separatrix.py) or clear NUMBA_CACHE_DIR.

References: E. Hairer, S. P. Norsett, G. Wanner, Solving Ordinary Differential Equations I,
2nd ed., Springer 1993 (Secs. II.4, II.10); E. Hairer, G. Wanner, Solving Ordinary
Differential Equations II, 2nd ed., Springer 1996 (Sec. IV.8).
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np

from . import dop853_tableau as _t

__all__ = [
    "N_STAGES",
    "N_STAGES_EXTENDED",
    "SAFETY",
    "MIN_FACTOR",
    "MAX_FACTOR",
    "STIFF_THRESHOLD",
    "stage_sum",
    "stage_state",
    "solution_sum",
    "step_state",
    "error_scale",
    "error_norm",
    "reject_factor",
    "accept_factor",
    "initial_step_trial",
    "initial_step",
    "dense_coeffs",
    "dense_eval",
    "illinois_point",
    "illinois_update",
    "dense_component",
    "dense_invert",
    "stiffness_ratio",
]

N_STAGES = _t.N_STAGES
N_STAGES_EXTENDED = _t.N_STAGES_EXTENDED
#: safety factor of the controller
SAFETY = 0.9
#: smallest / largest step-size ratio per step
MIN_FACTOR = 0.2
MAX_FACTOR = 10.0
#: h |lambda| above which a step is taken as limited by stability (dop853.f uses 6.1;
#: the stability boundary of DOP853 on the negative real axis is ~6.0)
STIFF_THRESHOLD = 6.1

# contiguous float64 copies: numba freezes module-level arrays as constants
_A = np.ascontiguousarray(_t.A, dtype=np.float64)
_B = np.ascontiguousarray(_t.B, dtype=np.float64)
_C = np.ascontiguousarray(_t.C, dtype=np.float64)
_E3 = np.ascontiguousarray(_t.E3, dtype=np.float64)
_E5 = np.ascontiguousarray(_t.E5, dtype=np.float64)
_D = np.ascontiguousarray(_t.D, dtype=np.float64)
_NS = N_STAGES
_NSE = N_STAGES_EXTENDED

#: the nodes c_s (time fractions of the stages), for non-autonomous drivers
C_NODES = _C


@nb.njit(cache=True, nogil=True, error_model="numpy", inline="always")
def stage_sum(K, s, j):
    """sum_{m<s} a_{s,m} K[m, j]: the increment slope of stage s (0-based) for component j."""
    acc = 0.0
    for m in range(s):
        acc += _A[s, m] * K[m, j]
    return acc


@nb.njit(cache=True, nogil=True, error_model="numpy", inline="always")
def stage_state(K, y, h, s, out):
    """out = y + h sum_{m<s} a_{s,m} K[m]: the state at which stage s is evaluated.

    K (16, n), y (n,), out (n,); h the step (signed)."""
    for j in range(y.shape[0]):
        out[j] = y[j] + h * stage_sum(K, s, j)


@nb.njit(cache=True, nogil=True, error_model="numpy", inline="always")
def solution_sum(K, j):
    """sum_m b_m K[m, j] over the 12 stages: the 8th-order increment slope of component j."""
    acc = 0.0
    for m in range(_NS):
        acc += _B[m] * K[m, j]
    return acc


@nb.njit(cache=True, nogil=True, error_model="numpy", inline="always")
def step_state(K, y, h, out):
    """out = y + h sum_m b_m K[m]: the 8th-order solution at the end of the step."""
    for j in range(y.shape[0]):
        out[j] = y[j] + h * solution_sum(K, j)


@nb.njit(cache=True, nogil=True, error_model="numpy", inline="always")
def error_scale(y0, y1, rtol, atol, cap):
    """Weight of one component: atol + rtol min(max(|y0|, |y1|), cap) (cap = inf: none)."""
    return atol + min(max(abs(y0), abs(y1)), cap) * rtol


@nb.njit(cache=True, nogil=True, error_model="numpy", inline="always")
def error_norm(K, h, sc, n_norm):
    """Normalised local error of the step (accept when <= 1).

    K (16, n) with row 12 = f(y_new); h > 0 the step length; sc (>= n_norm,) the weights
    (:func:`error_scale`) of the first n_norm components, which alone enter the norm.
    Returns |h| E5^2 / sqrt(n_norm (E5^2 + 0.01 E3^2)) with E5^2, E3^2 the sums of the
    squared weighted 5th- and 3rd-order estimates (0 when both vanish).
    """
    e5 = 0.0
    e3 = 0.0
    for j in range(n_norm):
        a5 = 0.0
        a3 = 0.0
        for m in range(_NS + 1):
            a5 += _E5[m] * K[m, j]
            a3 += _E3[m] * K[m, j]
        e5 += (a5 / sc[j]) ** 2
        e3 += (a3 / sc[j]) ** 2
    if e5 == 0.0 and e3 == 0.0:
        return 0.0
    return h * e5 / math.sqrt((e5 + 0.01 * e3) * n_norm)


@nb.njit(cache=True, nogil=True, error_model="numpy", inline="always")
def reject_factor(err):
    """Step-size factor after a rejected step (err > 1 or not finite): in [0.2, 0.9)."""
    if not math.isfinite(err):
        return MIN_FACTOR
    return max(MIN_FACTOR, SAFETY * err ** (-1.0 / 8.0))


@nb.njit(cache=True, nogil=True, error_model="numpy", inline="always")
def accept_factor(err, h, h_prev, err_prev, rejected_last):
    """Step-size factor after an accepted step, and the floored error to remember.

    err <= 1 the step's error; h the step just taken; h_prev, err_prev the previous
    accepted step and its floored error (h_prev <= 0: none, the elementary controller
    alone).  With a previous step, Gustafsson's predictive correction
    fac * (h/h_prev) (err_prev/err)^(1/8) caps the factor when the error constant grows
    steadily (approaching a sharp peak).  After a rejection the step does not grow.
    Returns (factor in (0, 10], max(err, 1e-12)).
    """
    err_c = max(err, 1e-12)
    fac = min(MAX_FACTOR, SAFETY * err_c ** (-1.0 / 8.0))
    if h_prev > 0.0:
        fac = min(fac, fac * (h / h_prev) * (err_prev / err_c) ** (1.0 / 8.0))
    if rejected_last:
        fac = min(1.0, fac)
    return fac, err_c


@nb.njit(cache=True, nogil=True, error_model="numpy", inline="always")
def initial_step_trial(y, f, rtol, atol, n_norm):
    """First stage of the starting-step heuristic: (h0, d1).

    d0 = ||y||, d1 = ||f|| in the weighted RMS norm over n_norm components (weights
    atol + rtol |y|); h0 = 0.01 d0/d1, or 1e-6 when either is tiny.  The driver then
    evaluates f1 = f(y + h0 f) and calls :func:`initial_step`.
    """
    d0 = 0.0
    d1 = 0.0
    for j in range(n_norm):
        sc = atol + abs(y[j]) * rtol
        d0 += (y[j] / sc) ** 2
        d1 += (f[j] / sc) ** 2
    d0 = math.sqrt(d0 / n_norm)
    d1 = math.sqrt(d1 / n_norm)
    h0 = 1e-6 if (d0 < 1e-5 or d1 < 1e-5) else 0.01 * d0 / d1
    return h0, d1


@nb.njit(cache=True, nogil=True, error_model="numpy", inline="always")
def initial_step(h0, d1, y, f, f1, rtol, atol, n_norm):
    """Second stage of the starting-step heuristic (order 8): the first step size.

    d2 = ||f1 - f||/h0 estimates the second derivative; h1 = (0.01/max(d1, d2))^(1/8);
    returns min(100 h0, h1).
    """
    d2 = 0.0
    for j in range(n_norm):
        sc = atol + abs(y[j]) * rtol
        d2 += ((f1[j] - f[j]) / sc) ** 2
    d2 = math.sqrt(d2 / n_norm) / h0
    if d1 <= 1e-15 and d2 <= 1e-15:
        h1 = max(1e-6, h0 * 1e-3)
    else:
        h1 = (0.01 / max(d1, d2)) ** (1.0 / 8.0)
    return min(100.0 * h0, h1)


@nb.njit(cache=True, nogil=True, error_model="numpy", inline="always")
def dense_coeffs(K, y0, y1, f0, f1, h, F):
    """Fill F (7, n) with the 7th-order dense-output polynomial of the step y0 -> y1.

    K (16, n) must hold all 16 stages (rows 13..15 from :func:`stage_state` with the
    driver's right-hand side); f0, f1 the slopes at the step ends; h the step.
    """
    n = y0.shape[0]
    for j in range(n):
        dy = y1[j] - y0[j]
        F[0, j] = dy
        F[1, j] = h * f0[j] - dy
        F[2, j] = 2.0 * dy - h * (f1[j] + f0[j])
        for r in range(4):
            acc = 0.0
            for m in range(_NSE):
                acc += _D[r, m] * K[m, j]
            F[3 + r, j] = h * acc


@nb.njit(cache=True, nogil=True, error_model="numpy", inline="always")
def dense_eval(F, y0, x, out):
    """out = y(t0 + x h) from the dense-output polynomial F of the step, x in [0, 1]."""
    n = y0.shape[0]
    for j in range(n):
        acc = 0.0
        for i in range(7):
            acc += F[6 - i, j]
            if i % 2 == 0:
                acc *= x
            else:
                acc *= 1.0 - x
        out[j] = acc + y0[j]


@nb.njit(cache=True, nogil=True, error_model="numpy", inline="always")
def dense_component(F, y0j, j, x):
    """(y_j, d y_j/dx) at t0 + x h from the dense-output polynomial F of the step
    (component j, whose value at x = 0 is y0j); the same nesting as :func:`dense_eval`."""
    acc = 0.0
    dacc = 0.0
    for i in range(7):
        acc += F[6 - i, j]
        if i % 2 == 0:
            dacc = dacc * x + acc
            acc *= x
        else:
            dacc = dacc * (1.0 - x) - acc
            acc *= 1.0 - x
    return acc + y0j, dacc


@nb.njit(cache=True, nogil=True, error_model="numpy", inline="always")
def dense_invert(F, y0j, j, target, x0, x1, g0, g1, x_guess):
    """x in [x0, x1] where component j of the dense output equals ``target``, bracketed by
    g0 = y_j(x0) - target and g1 = y_j(x1) - target of opposite signs (or zero).

    Safeguarded Newton from ``x_guess`` on the polynomial itself: a Newton point outside
    the shrinking bracket is replaced by the midpoint, so it always terminates (at most
    100 evaluations).  Stops when |y_j - target| is within 4 ulp of ``target`` (the
    rounding of the polynomial's value; the sample is then as exact as the dense output),
    when the Newton correction is below 1e-15 of the step, or when the bracket is.
    Returns (x, d y_j/dx at the last evaluated point), the slope for the caller's next
    guess.  For a component increasing along the step (e.g. the time) a sample costs 2-3
    evaluations of one component.
    """
    if g0 == 0.0:
        return x0, 0.0
    if g1 == 0.0:
        return x1, 0.0
    up = g1 > 0.0
    tol = 8.9e-16 * abs(target)
    x = x_guess
    if not (x > x0 and x < x1):
        x = 0.5 * (x0 + x1)
    d = 0.0
    for _ in range(100):
        v, d = dense_component(F, y0j, j, x)
        g = v - target
        if abs(g) <= tol:
            return x, d
        if (g > 0.0) == up:
            x1 = x
        else:
            x0 = x
        xn = x - g / d if d != 0.0 else x0 - 1.0
        if not (xn > x0 and xn < x1):
            xn = 0.5 * (x0 + x1)
        if abs(xn - x) <= 1e-15 or x1 - x0 <= 1e-15:
            return xn, d
        x = xn
    return x, d


@nb.njit(cache=True, nogil=True, error_model="numpy", inline="always")
def illinois_point(x0, x1, g0, g1):
    """Next trial point of regula falsi in (x0, x1) for g0 = g(x0), g1 = g(x1) of opposite
    sign (the midpoint when the secant leaves the open interval)."""
    xm = (x0 * g1 - x1 * g0) / (g1 - g0)
    if not (xm > x0 and xm < x1):
        xm = 0.5 * (x0 + x1)
    return xm


@nb.njit(cache=True, nogil=True, error_model="numpy", inline="always")
def illinois_update(x0, x1, g0, g1, side, xm, gm):
    """Shrink the bracket with the trial (xm, gm); the Illinois rule halves the value kept
    at the end retained twice in a row.  Returns (x0, x1, g0, g1, side)."""
    if (gm > 0.0) == (g1 > 0.0):
        x1, g1 = xm, gm
        if side == -1:
            g0 *= 0.5
        side = -1
    else:
        x0, g0 = xm, gm
        if side == 1:
            g1 *= 0.5
        side = 1
    return x0, x1, g0, g1, side


@nb.njit(cache=True, nogil=True, error_model="numpy", inline="always")
def stiffness_ratio(K, y_new, y_stage12, h, n_norm):
    """Hairer's estimate of h |lambda|: h ||K[12] - K[11]|| / ||y_new - y_stage12||.

    Stages 12 and 13 are both evaluated at the end of the step (c = 1), at y_stage12 (the
    argument of stage 12) and y_new, so the quotient estimates the dominant eigenvalue of
    the Jacobian.  Returns 0 when the two states coincide.
    """
    num = 0.0
    den = 0.0
    for j in range(n_norm):
        num += (K[12, j] - K[11, j]) ** 2
        den += (y_new[j] - y_stage12[j]) ** 2
    if den > 0.0:
        return abs(h) * math.sqrt(num / den)
    return 0.0
