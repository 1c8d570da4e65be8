"""Closed forms of Ciardo & Viesca: Lyapunov functions U, critical trajectories, limits.

Every formula here was checked against direct integration (tests/test_analytic.py:
U is conserved along computed trajectories; each closed form matches its own limits).
They are written without cancellation for eps -> 0 (expm1/log1p and short series) and
evaluated exactly at eps = 0.  Where the printed paper differs, the docstring says so.

Notation: kappa_crit = b/a - 1, m = ((1 - b/a) phi - psi)/(b/a) = -L, with
L = phi + (psi - phi)/(b/a) = ln(V theta/Dc).
"""
from __future__ import annotations

import math

import numba as nb
import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.special import lambertw

from .laws import L_star
from .params import ParameterError, Params, check_range

__all__ = [
    "U_kcrit",
    "U_vo0",
    "psi_crit_kcrit",
    "psi_crit_vo0",
    "velocity_jump_crit_kcrit",
    "velocity_jump_crit_slip_law",
    "velocity_jump_crit_aging_asymptote",
    "velocity_jump_crit_vo0",
    "load_point_jump_crit_kcrit",
    "delta_tau",
]

_SER = 1.0e-4


def _expm1_over(eps: float, x: NDArray[np.float64]) -> NDArray[np.float64]:
    """expm1(eps x)/eps, exact limit x at eps = 0 and no loss for tiny eps (elementwise)."""
    ex = eps * x
    small = np.abs(ex) < _SER
    with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
        big = np.expm1(ex) / (eps if eps != 0.0 else 1.0)
    ser = x * (1.0 + ex * (0.5 + ex * (1.0 / 6.0 + ex / 24.0)))
    return np.where(small, ser, big)


def _log1p_over(eps: float, x: NDArray[np.float64]) -> NDArray[np.float64]:
    """log1p(eps x)/eps (nan where eps x <= -1), exact limit x at eps = 0."""
    ex = eps * x
    small = np.abs(ex) < _SER
    with np.errstate(invalid="ignore", divide="ignore"):
        big = np.log1p(ex) / (eps if eps != 0.0 else 1.0)
    ser = x * (1.0 - ex * (0.5 - ex * (1.0 / 3.0 - ex * 0.25)))
    return np.where(small, ser, big)


def _check_ba_eps(ba: float, eps: float) -> tuple[float, float]:
    return Params(ba=ba, kappa=0.0, eps=eps).ba, check_range("eps", eps, 0.0, 1.0)


def U_kcrit(phi: ArrayLike, psi: ArrayLike, ba: float, eps: float, vo: float = 1.0) -> NDArray[np.float64]:
    """Lyapunov function U(phi, psi) for kappa = kappa_crit and v_o > 0.

    Implements `eq: trajectories 1` with the integrating factor `eq: q function1`,
    q = (psi - phi)(1 - eps(1 - a/b)), rewritten for kappa = kappa_crit as

        U = (b/a) [kappa_crit v_o e^q / D - e^(q + phi) (expm1(eps m)/eps + 1)/(1 - eps)],
        D = (b/a)(1 - eps) + eps,

    which equals the printed form and has the exact slip-law limit (eps = 0)
    U = e^(psi - phi) [kappa_crit v_o - e^phi ((1 - b/a) phi - psi + b/a)].
    At eps = 1 (aging law) the printed form is singular and `eq: trajectories 1-2`,
    U = (b/a)[e^((psi - phi)/(b/a)) (v_o + e^phi/(b/a - 1)) kappa_crit - psi], is used.

    Args: phi, psi broadcastable arrays; ba in (1, 1e6]; eps in [0, 1]; vo in (0, 1e300].
    Returns U (same shape), +-inf where the true value exceeds the double range.
    Level sets of U are trajectories (conserved to integration accuracy: relative drift
    below 1e-9 at rtol 1e-10, tests/test_analytic.py).  U < 0: closed orbit (stable);
    U > 0: runaway when eps < 1.
    """
    ba, eps = _check_ba_eps(ba, eps)
    vo = check_range("vo", vo, 0.0, None, lo_open=True)
    phi = np.asarray(phi, dtype=np.float64)
    psi = np.asarray(psi, dtype=np.float64)
    kc = ba - 1.0
    with np.errstate(over="ignore", invalid="ignore"):
        if eps == 1.0:
            return ba * (np.exp((psi - phi) / ba) * (vo + np.exp(phi) / kc) * kc - psi)
        q = (psi - phi) * (1.0 - eps * (1.0 - 1.0 / ba))
        D = ba * (1.0 - eps) + eps
        m = ((1.0 - ba) * phi - psi) / ba
        bracket = (_expm1_over(eps, m) + 1.0) / (1.0 - eps)
        return ba * (kc * vo * np.exp(q) / D - np.exp(q + phi) * bracket)


def U_vo0(phi: ArrayLike, psi: ArrayLike, ba: float, kappa: float, eps: float) -> NDArray[np.float64]:
    """Lyapunov function U(phi, psi) for a stationary load point (v_o = 0), any kappa > 0.

    Implements `eq: trajectories 2`,

        U = e^(psi (b/a - kappa eps - 1)/kappa) (kappa b/a) (1 - b/a + e^(eps n)(b/a - 1 - kappa eps))
            / (eps (b/a - 1)(b/a - 1 - kappa eps)),      n = ((b/a - 1) phi + psi)/(b/a) = L,

    evaluated as (kappa b/a) e^(...) [kappa_crit expm1(eps n)/eps - kappa e^(eps n)] /
    (kappa_crit (kappa_crit - kappa eps)), exact at eps = 0.  U = 0 is the line L = L*
    (`eq: limiting trajectory2`).  Singular (ParameterError) at kappa = 0 and at
    eps kappa = kappa_crit.  When eps kappa > kappa_crit U > 0 everywhere yet every
    trajectory is stable (the sign criterion holds only while eps kappa < kappa_crit).
    """
    ba, eps = _check_ba_eps(ba, eps)
    kappa = check_range("kappa", kappa, 0.0, None, lo_open=True)
    kc = ba - 1.0
    den = kc - kappa * eps
    if den == 0.0:
        raise ParameterError("kappa", kappa, "eps*kappa != b/a - 1 (U of eq: trajectories 2 is singular there)")
    phi = np.asarray(phi, dtype=np.float64)
    psi = np.asarray(psi, dtype=np.float64)
    n = ((ba - 1.0) * phi + psi) / ba
    with np.errstate(over="ignore", invalid="ignore"):
        num = kc * _expm1_over(eps, n) - kappa * np.exp(eps * n)
        return np.exp(psi * den / kappa) * kappa * ba * num / (kc * den)


def psi_crit_kcrit(phi: ArrayLike, ba: float, eps: float, vo: float = 1.0) -> NDArray[np.float64]:
    """Critical trajectory U = 0 for kappa = kappa_crit, psi as a function of phi.

    `eq: limiting trajectory 1` solved for psi without cancellation:
        psi = (1 - b/a) phi - (b/a) log1p(eps R)/eps,
        R = (1 - eps) kappa_crit v_o e^(-phi)/D - 1,  D = (b/a)(1 - eps) + eps,
    evaluated through 1 + eps R = (1 - eps)(1 + eps kappa_crit v_o e^(-phi)/D), which is
    positive for every phi (the curve exists at every phi).  Slip-law limit
    (eps = 0): psi = b/a - kappa_crit phi - kappa_crit v_o e^(-phi).  Note: the printed
    `eq: limiting trajectory 1b` has e^(+phi) where e^(-phi) is meant (reference README).
    eps in [0, 1); at eps = 1 every orbit is closed and there is no critical trajectory
    (ParameterError).
    """
    ba, eps = _check_ba_eps(ba, eps)
    if eps >= 1.0:
        raise ParameterError("eps", eps, "[0, 1) (the aging law has no critical trajectory)")
    vo = check_range("vo", vo, 0.0, None, lo_open=True)
    phi = np.asarray(phi, dtype=np.float64)
    kc = ba - 1.0
    D = ba * (1.0 - eps) + eps
    with np.errstate(over="ignore", invalid="ignore"):
        # 1 + eps R = (1 - eps)(1 + eps X), X = kappa_crit v_o e^-phi/D: no cancellation
        # as eps -> 1, where 1 + eps R -> 0
        X = kc * vo * np.exp(-phi) / D
        lg = _log1p_over(eps, np.asarray(-1.0)) + _log1p_over(eps, X)
        return (1.0 - ba) * phi - ba * lg


def psi_crit_vo0(phi: ArrayLike, ba: float, kappa: float, eps: float) -> NDArray[np.float64]:
    """Critical trajectory for v_o = 0 (`eq: limiting trajectory2`): psi = (1 - b/a) phi + (b/a) L*.

    L* = -log1p(-eps kappa/kappa_crit)/eps.  Exists iff eps kappa < kappa_crit
    (`eq: critical trajectory condition`), else ParameterError.
    """
    p = Params(ba=ba, kappa=kappa, eps=eps, vo=0.0)
    Ls = L_star(p.kappa, p.kappa_crit, p.eps)
    if not math.isfinite(Ls):
        raise ParameterError("kappa", kappa, "eps*kappa < b/a - 1 (otherwise no critical trajectory exists)")
    return (1.0 - p.ba) * np.asarray(phi, dtype=np.float64) + p.ba * Ls


def velocity_jump_crit_vo0(ba: float, kappa: float, eps: float) -> float:
    """Critical velocity jump for v_o = 0 (`eq: analytical phi crit`): (1/eps) ln(1/(1 - eps kappa/kappa_crit)).

    Equals L*; +inf when eps kappa >= kappa_crit.  Relative accuracy ~1e-16.
    """
    p = Params(ba=ba, kappa=kappa, eps=eps, vo=0.0)
    return float(L_star(p.kappa, p.kappa_crit, p.eps))


def velocity_jump_crit_slip_law(ba: float) -> float:
    """Exact slip-law (eps = 0) critical velocity jump at kappa = kappa_crit, v_o > 0.

    `eq: asymptotic solution critical velocity jump slip law`: 1 + W0((a/b - 1)/e) with
    the principal branch of Lambert W (the root of b/a phi = b/a - kappa_crit e^(-phi)).
    Relative accuracy ~1e-15.
    """
    ba = Params(ba=ba, kappa=0.0, eps=0.0).ba
    return float(1.0 + lambertw((1.0 / ba - 1.0) / math.e, 0).real)


def velocity_jump_crit_aging_asymptote(ba: float, eps: float) -> float:
    """Leading-order asymptote as eps -> 1 (`eq: asymptotic solution critical velocity jump aging law`).

    ln(2 - b/a + 1/(1 - eps)); an approximation (not exact) valid for 1 - eps << 1.
    """
    ba, eps = _check_ba_eps(ba, eps)
    if eps >= 1.0:
        return math.inf
    arg = 2.0 - ba + 1.0 / (1.0 - eps)
    if arg <= 0.0:
        raise ParameterError("eps", eps, "close enough to 1 that 2 - b/a + 1/(1 - eps) > 0")
    return math.log(arg)


@nb.njit(cache=True, nogil=True)
def _em(d):
    """expm1(-d) + d >= 0 without cancellation (Taylor series below d = 0.5)."""
    if d >= 0.5:
        return math.expm1(-d) + d
    term = 0.5 * d * d
    acc = 0.0
    k = 2
    while abs(term) > 1e-18 * acc or acc == 0.0:
        acc += term
        k += 1
        term *= -d / k
        if term == 0.0:
            break
    return acc


@nb.njit(cache=True, nogil=True)
def _lmr(eps, R, d, kc, D):
    """(log1p(eps R) - eps R)/eps <= 0 without cancellation (series below |eps R| = 0.1).

    For |eps R| >= 0.1 uses 1 + eps R = (1 - eps)(1 + eps kc e^(-d)/D) (exact identity for
    R = q e^(-d) - 1), accurate also as eps -> 1 where 1 + eps R -> 0.
    """
    y = eps * R
    if abs(y) >= 0.1:
        return (math.log1p(-eps) + math.log1p(eps * kc * math.exp(-d) / D) - y) / eps
    # -eps R^2 (1/2 - y/3 + y^2/4 - ...)
    acc = 0.0
    p = 1.0
    for k in range(2, 40):
        t = p / k
        acc += t if k % 2 == 0 else -t
        p *= y
        if abs(p) < 1e-18:
            break
    return -eps * R * R * acc


@nb.njit(cache=True, nogil=True)
def _vjump_kcrit(ba, eps):
    """Critical velocity jump at kappa = kappa_crit, v_o > 0 (compiled).

    psi_crit(d) = d for `eq: limiting trajectory 1` (psi_crit - d = -ba h(d)) with
    h(d) = d + log1p(eps R)/eps, R = q e^(-d) - 1, q = (1 - eps) kc/D, D = ba(1 - eps) + eps.
    Since 1 - q = 1/D, R = q expm1(-d) - 1/D and h is evaluated without cancellation as

        h(d) = (d - 1)/D + q (expm1(-d) + d) + (log1p(eps R) - eps R)/eps,

    (at b/a = 1e6 the root is ~1e-3 and the naive form loses 5 digits).  h(0) < 0 <= h(L*);
    safeguarded Newton (bisection fallback) to |dd| <= 4e-16 d.  inf at eps = 1.
    Accuracy: ~1e-15 relative (checked against mpmath in the tests).
    """
    if eps >= 1.0:
        return math.inf
    kc = ba - 1.0
    D = ba * (1.0 - eps) + eps
    q = (1.0 - eps) * kc / D
    lo = 0.0
    hi = L_star(kc, kc, eps)
    for _ in range(60):
        R = q * math.expm1(-hi) - 1.0 / D
        if (hi - 1.0) / D + q * _em(hi) + _lmr(eps, R, hi, kc, D) >= 0.0:
            break
        hi *= 2.0
    # start from the small-d asymptote d^2 (1 - eps)/2 ~ 1/D when it is inside the bracket
    d = math.sqrt(2.0 / (D * max(q * (1.0 - eps), 1e-300)))
    if not (d > lo and d < hi):
        d = 0.5 * (lo + hi)
    for _ in range(200):
        R = q * math.expm1(-d) - 1.0 / D
        h = (d - 1.0) / D + q * _em(d) + _lmr(eps, R, d, kc, D)
        if h == 0.0:
            return d
        if h < 0.0:
            lo = d
        else:
            hi = d
        # h'(d) = 1 - q e^(-d)/(1 + eps R) = (1/D + eps R - q expm1(-d))/(1 + eps R) ... use
        # the direct form (its rounding only slows Newton, not the root)
        dh = 1.0 - q * math.exp(-d) / (1.0 + eps * R)
        dn = d - h / dh if dh > 0.0 else 0.5 * (lo + hi)
        if not (dn > lo and dn < hi):
            dn = 0.5 * (lo + hi)
        if abs(dn - d) <= 4.0e-16 * abs(dn) or hi - lo <= 4.0e-16 * hi:
            return dn
        d = dn
    return d


def velocity_jump_crit_kcrit(ba: float, eps: float) -> float:
    """Critical velocity jump at kappa = kappa_crit, v_o > 0 (intersection of psi = phi with U = 0).

    Solves psi_crit_kcrit(d) = d (`eq: limiting trajectory 1` with psi = phi) with the
    compiled, cancellation-free :func:`_vjump_kcrit` (safeguarded Newton); the root is
    unique because psi_crit - phi is decreasing.  +inf at eps = 1.  Independent of v_o by
    the scaling invariance.  Relative accuracy ~1e-15 for b/a up to 1e4 and ~2e-13 at
    b/a = 1e6 (checked against 60-digit mpmath in tests/test_critical.py); at eps = 0 it
    equals the Lambert-W form of :func:`velocity_jump_crit_slip_law`.
    """
    ba, eps = _check_ba_eps(ba, eps)
    return float(_vjump_kcrit(ba, eps))


def load_point_jump_crit_kcrit(ba: float, eps: float) -> float:
    """Critical relative load-point jump (dv/v_o)_crit at kappa = kappa_crit: 1/(kappa_crit (1 - eps)).

    Derived from `eq: trajectories 1`: the jump v_o -> v_o(1 + dv) from steady state
    puts the system, in the new load point's frame, at phi = -ln(1+dv),
    psi = (b/a - 1) ln(1+dv), where (1 - b/a) phi - psi = 0, so U = 0 reduces to
    e^(-ln(1+dv)) = kappa_crit (1 - eps)/D with D = (b/a)(1 - eps) + eps, i.e.
    1 + dv = D/(kappa_crit (1 - eps)).  +inf at eps = 1.  Exact (closed form).
    """
    ba, eps = _check_ba_eps(ba, eps)
    if eps == 1.0:
        return math.inf
    return 1.0 / ((ba - 1.0) * (1.0 - eps))


def delta_tau(slip_over_Dc: ArrayLike, v2_over_v1: float, eps: float) -> NDArray[np.float64]:
    """Stress transient after an imposed velocity step V1 -> V2 (`eq: delta tau`), in units of b sigma.

    (tau - tau_2)/(b sigma) = (1/eps) ln(1 + ((theta_1/theta_2)^eps - 1) e^(-delta/Dc)),
    theta_1/theta_2 = V2/V1, for slip delta >= 0 since the step at constant V2 (infinitely
    stiff machine).  Exact; evaluated as log1p(expm1(eps ln(V2/V1)) e^(-delta/Dc))/eps,
    which at eps = 0 is ln(V2/V1) e^(-delta/Dc).
    """
    eps = check_range("eps", eps, 0.0, 1.0)
    r = check_range("v2_over_v1", v2_over_v1, 0.0, None, lo_open=True)
    s = np.asarray(slip_over_Dc, dtype=np.float64)
    lr = math.log(r)
    w = float(_expm1_over(eps, np.asarray(lr)))  # (r^eps - 1)/eps
    x = w * np.exp(-s)  # so that 1 + eps x is the argument of the log
    return _log1p_over(eps, x)
