"""The separatrix method: critical perturbation sizes from one scalar ODE (Ciardo & Viesca).

With s_theta = ln theta = (psi - phi)/(b/a) and u = L = phi + s_theta, the trajectory that
separates return from runaway is the one with L -> L* as phi -> +inf.  Along it s_theta
is monotone while L > 0, and it solves the scalar ODE

    du/ds_theta = kappa expm1(s_theta - u)/G(u) - kappa_crit,                 (A)

started from its asymptotic expansion u = L* - c1 z - c2 z^2, z = e^(s_theta - L*)
(:func:`_asym_coeffs`), towards increasing s_theta, where the separatrix attracts its
neighbours.  Near L = 0 (where d s_theta/ds = G(L) = 0) the roles are swapped:

    d s_theta/du = G(u) / (kappa expm1(s_theta - u) - kappa_crit G(u)).       (B)

The velocity-jump critical size is u at s_theta = 0; the load-point jump's is
expm1(s_theta) at u = 0 (module docstring of rsfcore.critical for the derivation and
the measured accuracy).  Both phases are integrated by :func:`_dop853_scalar`, a scalar
driver over the shared DOP853 kernels of rsfcore.ode.rk (the same stage, error norm and
controller as the spring-slider engine), with steps capped (``_H_MAX``) because the
embedded error estimate under-estimates long steps on this problem.

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

from .laws import G, L_star
from .ode import rk

__all__ = [
    "SeparatrixStatus",
    "S_OK",
    "S_U_NONPOSITIVE",
    "S_TURNING",
    "S_UNDERFLOW",
    "S_BUDGET",
    "S_OVERFLOW",
    "S_NO_START",
    "N_WORK",
]

# The kernels of rsfcore.ode.rk are inlined into _dop853_scalar; numba's cache does not
# see edits there, so touch this file (or clear NUMBA_CACHE_DIR) after changing rk.py.

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


# ints for the compiled kernels (and for old callers: critical.S_OK, ...)
S_OK = int(SeparatrixStatus.OK)
S_U_NONPOSITIVE = int(SeparatrixStatus.U_NONPOSITIVE)
S_TURNING = int(SeparatrixStatus.TURNING)
S_UNDERFLOW = int(SeparatrixStatus.UNDERFLOW)
S_BUDGET = int(SeparatrixStatus.BUDGET)
S_OVERFLOW = int(SeparatrixStatus.OVERFLOW)
S_NO_START = int(SeparatrixStatus.NO_START)


@nb.njit(cache=True, nogil=True)
def _asym_coeffs(kappa, kc, eps):
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
def _jac(mode, x, y, kappa, kc, eps):
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
def _rhs(mode, x, y, kappa, kc, eps):
    if mode == 0:
        return _f_theta(x, y, kappa, kc, eps)
    return _f_u(x, y, kappa, kc, eps)


@nb.njit(cache=True, nogil=True, error_model="numpy")
def _dop853_scalar(
    mode, x0, y0, x_end, kappa, kc, eps, rtol, atol, ycap, switch_slope, h0, K, h_max=_H_MAX
):
    """Integrate the scalar ODE (mode 0: (A), mode 1: (B)) from (x0, y0) towards x_end.

    K: workspace of N_WORK = 13 floats (the stages).  Error weight per step:
    atol + rtol * min(max(|y|, |y_new|), ycap) (rk.error_scale).  Steps are capped at
    h_max.  Stops exactly at x_end, or (mode 0 with switch_slope > 0) after the first
    accepted step whose end slope |dy/dx| exceeds switch_slope.
    Returns (status, x, y, err_prop, n_rhs, h).  err_prop is the propagated absolute
    error estimate: after each accepted step err <- err * exp(h J) + |local error
    estimate|, with h J the less contractive of the analytic d(rhs)/dy at the step ends
    (the separatrix attracts: J h < 0, old errors shrink).
    """
    Kw = K.reshape((K.shape[0], 1))  # the shared kernels take (stages, components)
    sc = np.empty(1)
    x = x0
    y = y0
    direction = 1.0 if x_end >= x0 else -1.0
    f = _rhs(mode, x, y, kappa, kc, eps)
    n_rhs = 1
    if not math.isfinite(f):
        return S_NO_START, x, y, 0.0, n_rhs, h0
    h = min(abs(h0), h_max)
    err_sum = 0.0
    J = _jac(mode, x, y, kappa, kc, eps)
    n = 0
    last_rejected = False
    while n < _MAX_STEPS:
        n += 1
        rem = (x_end - x) * direction
        if rem <= 0.0:
            return S_OK, x, y, err_sum, n_rhs, h
        final = False
        if h >= rem or (1.3 * h >= rem and not last_rejected):
            # land exactly on x_end (stretching the step by up to 30 % unless the last
            # attempt was rejected; error control rejects it if that was too much)
            h = rem
            final = True
        hs = h * direction
        Kw[0, 0] = f
        ok = True
        for s in range(1, rk.N_STAGES):
            k = _rhs(mode, x + _C[s] * hs, y + hs * rk.stage_sum(Kw, s, 0), kappa, kc, eps)
            if not math.isfinite(k):
                ok = False
                break
            Kw[s, 0] = k
        n_rhs += rk.N_STAGES
        ynew = 0.0
        fnew = 0.0
        err = math.inf
        if ok:
            ynew = y + hs * rk.solution_sum(Kw, 0)
            fnew = _rhs(mode, x + hs, ynew, kappa, kc, eps)
            if math.isfinite(fnew) and math.isfinite(ynew):
                Kw[rk.N_STAGES, 0] = fnew
                sc[0] = rk.error_scale(y, ynew, rtol, atol, ycap)
                err = rk.error_norm(Kw, h, sc, 1)
        if not (err <= 1.0):
            h *= rk.reject_factor(err)
            last_rejected = True
            if h < 1e-15 * max(1.0, abs(x)):
                return S_UNDERFLOW, x, y, err_sum, n_rhs, h
            continue
        Jn = _jac(mode, x + hs, ynew, kappa, kc, eps)
        # least contractive end of the step (a trapezoid over-contracts on long steps)
        prop = max(hs * J, hs * Jn)
        err_sum = err_sum * math.exp(min(prop, 50.0)) + err * sc[0]
        J = Jn
        x = x_end if final else x + hs
        y = ynew
        f = fnew
        if final:
            return S_OK, x, y, err_sum, n_rhs, h
        if switch_slope > 0.0 and abs(f) > switch_slope:
            return S_OK, x, y, err_sum, n_rhs, h
        # elementary controller (no predictive correction: h_prev = 0); err = 0 gives 10
        fac, _ = rk.accept_factor(err, h, 0.0, 1.0, last_rejected)
        last_rejected = False
        h = min(h * fac, h_max)
    return S_BUDGET, x, y, err_sum, n_rhs, h


@nb.njit(cache=True, nogil=True)
def _separatrix(kappa, kc, eps, pert, rtol, K):
    """Critical size by the separatrix method (kappa > kappa_crit, x < 1, v_o > 0).

    pert 0: velocity jump (returns d_crit); pert 1: load-point jump (returns dv_crit).
    Returns (status, value, abs_err, n_rhs).
    """
    Ls, c1, c2 = _asym_coeffs(kappa, kc, eps)
    if not (Ls > 0.0) or not math.isfinite(Ls):
        return S_NO_START, math.nan, math.nan, 0
    # start far enough out that the neglected O(z^3) terms are ~1e-3 rtol: measured
    # truncation ~1e-13 relative at c z0 = 1e-5, scaling as z0^3 (tests/core/test_critical.py)
    cz = max(abs(c1), math.sqrt(abs(c2)), 1e-300)
    zt = min(max(_Z_TARGET * (rtol / 1e-10) ** (1.0 / 3.0), 1e-7), 1e-4)
    s0 = min(Ls + math.log(zt / cz), _S0_MAX)
    z0 = math.exp(s0 - Ls)
    u0 = Ls - z0 * (c1 + c2 * z0)
    rt = rtol * (_TOL_FACTOR_V if pert == 0 else _TOL_FACTOR_L)
    if pert == 0:
        # (A) from s0 to s_theta = 0; atol keeps a floor for tiny d_crit
        st, t, u, es, nr, h = _dop853_scalar(
            0, s0, u0, 0.0, kappa, kc, eps, rt, rt * 1e-3 * Ls, math.inf, 0.0, 1.0, K
        )
        if st != S_OK:
            if st == S_NO_START:
                st = S_U_NONPOSITIVE
            return st, math.nan, math.nan, nr
        if not (u > 0.0):
            return S_U_NONPOSITIVE, math.nan, math.nan, nr
        return S_OK, u, es, nr
    # load-point jump: (A) until the slope |du/ds_theta| exceeds 1, then (B) down to u = 0.
    # The relative error of dv is the absolute error of l = ln(1 + dv) times
    # e^l/(e^l - 1), so errors are controlled in absolute terms (scale capped at 1).
    # l may exceed 709 (dv beyond the double range): then the status is S_OVERFLOW and the
    # value returned is l itself, with its absolute error (the relative error of dv).
    t_far = math.inf
    st, t, u, es, nr, h = _dop853_scalar(
        0, s0, u0, t_far, kappa, kc, eps, rt, rt * 1e-3, 1.0, 1.0, 1.0, K
    )
    if st != S_OK:
        if st == S_NO_START:
            st = S_TURNING
        return st, math.nan, math.nan, nr
    if not (u > 0.0):
        return S_TURNING, math.nan, math.nan, nr
    st2, u2, t2, es2, nr2, h2 = _dop853_scalar(
        1, u, t, 0.0, kappa, kc, eps, rt, rt * 1e-3, 1.0, 0.0, 0.1 * u, K, _H_MAX_B
    )
    nr += nr2
    if st2 != S_OK:
        if st2 == S_NO_START:
            st2 = S_TURNING
        return st2, math.nan, math.nan, nr
    # the phase-A error in u at the switch moves the end point by (dt/du) * du there;
    # propagate it as an error in t through phase B, then d dv = e^t dt
    es_t = es * abs(_f_u(u, t, kappa, kc, eps))
    dv = math.expm1(t2)
    if dv == math.inf:
        return S_OVERFLOW, t2, es_t + es2, nr
    if not (dv > 0.0):
        return S_TURNING, math.nan, math.nan, nr
    return S_OK, dv, (es_t + es2) * math.exp(t2), nr
