"""Closed forms of Ciardo & Viesca: Lyapunov functions U, critical trajectories, limits.

Every formula here was checked against direct integration (tests/core/test_analytic.py:
U is conserved along computed trajectories, see docs/accuracy.md for the measured drift
law; each closed form matches its own limits).  They are written without cancellation for
eps -> 0 (expm1/log1p and short series) and evaluated exactly at eps = 0.  Where the
printed paper differs, the docstring says so.

Closed-form critical sizes come with an accuracy bound derived from the conditioning of
the formula at the given inputs (not machine epsilon), tested against 50-digit mpmath
evaluations of the same formulas (tests/core/test_closed_form_accuracy.py):
:func:`closed_form_critical` returns it with ``accuracy_met`` against a requested rtol.

Notation: kappa_crit = b/a - 1, m = ((1 - b/a) phi - psi)/(b/a) = -L, with
L = phi + (psi - phi)/(b/a) = ln(V theta/Dc).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numba as nb
import numpy as np
from numpy.typing import ArrayLike, NDArray

# (numba's cache does not track callees in other modules: this file was touched when
# rsfcore.laws.L_star began deciding x >= 1 on the exact 1 - x, NUMERICS_VERSION 5)
from .laws import L_star
from .params import ParameterError, Params, check_range

__all__ = [
    "U_kcrit",
    "U_kcrit_scale",
    "U_kcrit_sign",
    "U_vo0",
    "U_vo0_scale",
    "psi_crit_kcrit",
    "psi_crit_vo0",
    "velocity_jump_crit_kcrit",
    "velocity_jump_crit_slip_law",
    "velocity_jump_crit_aging_asymptote",
    "velocity_jump_crit_vo0",
    "load_point_jump_crit_kcrit",
    "velocity_jump_crit_kcrit_acc",
    "kcrit_jump_side",
    "closed_form_critical",
    "ClosedFormResult",
    "L_star_acc",
    "UNIT_ROUNDOFF",
    "delta_tau",
    "ljump_kcrit_acc",
    "vjump_kcrit_acc",
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


def _kcrit_parts(
    phi: ArrayLike, psi: ArrayLike, ba: float, eps: float, vo: float
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """(r, s, m, log P) with U = P r for eps < 1 (module notation of :func:`U_kcrit`).

    With phi1 = phi - ln v_o, w = e^(-max(phi1, 0)) and G = G(L):
    P = (b/a) v_o theta^D / w > 0 (theta = e^((psi - phi)/(b/a))),
    r = w [kappa_crit/D - e^phi1 (G + 1)/(1 - eps)] (bounded: no overflow at large phi),
    m = w [kappa_crit/D + e^phi1 (|G| + 1)/(1 - eps)] >= |r|, so that P m = U_kcrit_scale,
    s = m + w e^phi1 [(|G| + 1)|phi1| + e^(-eps L)(|phi| + 2|ln theta|)]/(1 - eps) bounds
    the rounding of r: |fl(r) - r| <= 8 u s (u = 2^-53; the extra terms carry the
    rounding of L and of phi - ln v_o through G' = -e^(-eps L) and exp).  r depends on phi
    only through phi1 and L, so it is the same in every v_o frame.
    """
    phi = np.asarray(phi, dtype=np.float64)
    psi = np.asarray(psi, dtype=np.float64)
    kc = ba - 1.0
    D = ba * (1.0 - eps) + eps
    lnvo = math.log(vo)
    with np.errstate(over="ignore", invalid="ignore"):
        lth = (psi - phi) / ba
        L = phi + lth
        phi1 = phi - lnvo
        top = np.maximum(phi1, 0.0)
        w = np.exp(-top)
        g = _expm1_over(eps, -L)  # expm1(-eps L)/eps = G(L)
        e1 = np.exp(phi1 - top) / (1.0 - eps)  # w e^phi1/(1 - eps) <= 1/(1 - eps)
        r = kc / D * w - e1 * (g + 1.0)
        m = kc / D * w + e1 * (np.abs(g) + 1.0)
        dL = np.abs(phi) + 2.0 * np.abs(lth)  # rounding of L and of phi1, in ulps
        s = m + e1 * ((np.abs(g) + 1.0) * np.abs(phi1) + np.exp(-eps * L) * dL)
        logP = math.log(ba) + D * lth + lnvo + top
    return r, s, m, logP


def _times_exp(x: NDArray[np.float64], logP: NDArray[np.float64]) -> NDArray[np.float64]:
    """x e^logP without spurious overflow/underflow/nan (0 stays 0, the sign is kept)."""
    with np.errstate(over="ignore", invalid="ignore", divide="ignore", under="ignore"):
        P = np.exp(logP)
        direct = P * x
        viaLog = np.sign(x) * np.exp(logP + np.log(np.abs(x)))
        ok = np.isfinite(direct) & (((P > 0.0) & np.isfinite(P)) | (x == 0.0))
        return np.where(ok, direct, np.where(x == 0.0, 0.0, viaLog))


def U_kcrit(
    phi: ArrayLike, psi: ArrayLike, ba: float, eps: float, vo: float = 1.0
) -> NDArray[np.float64]:
    """Lyapunov function U(phi, psi) for kappa = kappa_crit and v_o > 0.

    Implements `eq: trajectories 1` with the integrating factor `eq: q function1`,
    q = (psi - phi)(1 - eps(1 - a/b)) = D ln theta, rewritten for kappa = kappa_crit as

        U = (b/a) [kappa_crit v_o e^q / D - e^(q + phi) (expm1(eps m)/eps + 1)/(1 - eps)],
        D = (b/a)(1 - eps) + eps,  m = -L,

    which equals the printed form and has the exact slip-law limit (eps = 0)
    U = e^(psi - phi) [kappa_crit v_o - e^phi ((1 - b/a) phi - psi + b/a)].  It is
    evaluated as U = P r with P = (b/a) v_o e^q > 0 formed through its logarithm and
    r = kappa_crit/D - e^(phi - ln v_o)(G(L) + 1)/(1 - eps), so that far from v_o = 1
    (where e^q alone over- or underflows: b/a = 1e4, v_o = 1e-6 gave nan and v_o = 1e3 gave
    0 before) the sign is kept and U is +-inf or +-0 only when its true value is beyond
    the double range.  At eps = 1 (aging law) the printed form is singular and
    `eq: trajectories 1-2`, U = (b/a)[e^((psi - phi)/(b/a)) (v_o + e^phi/(b/a - 1))
    kappa_crit - psi], is used.

    Args: phi, psi broadcastable arrays; ba in (1, 1e6]; eps in [0, 1]; vo in (0, 1e300].
    Returns U (same shape).  U < 0: closed orbit (stable); U > 0: runaway when eps < 1
    (for a sign decision use :func:`U_kcrit_sign`, which accounts for rounding).
    Level sets of U are trajectories.  Along a computed trajectory U drifts (measured law,
    docs/accuracy.md, tests/core/test_u_drift.py):

        |U(T) - U(0)| <= 10 rtol M (1 + Y)(1 + V),

    M = max of :func:`U_kcrit_scale` along the path, Y = max(|phi|, |ln theta|) along it,
    V = total variation of phi (about 2 x amplitude x number of oscillations): linear in
    the number of oscillations; the relative drift is this over |U(0)|, and |U(0)|
    vanishes like (1 - d/d_crit) at the separatrix.
    """
    ba, eps = _check_ba_eps(ba, eps)
    vo = check_range("vo", vo, 0.0, None, lo_open=True)
    phi = np.asarray(phi, dtype=np.float64)
    psi = np.asarray(psi, dtype=np.float64)
    kc = ba - 1.0
    if eps == 1.0:
        with np.errstate(over="ignore", invalid="ignore"):
            lth = (psi - phi) / ba
            return ba * (kc * np.exp(lth + math.log(vo)) + np.exp(phi + lth) - psi)
    r, _, _, logP = _kcrit_parts(phi, psi, ba, eps, vo)
    return _times_exp(r, logP)


def U_kcrit_scale(
    phi: ArrayLike, psi: ArrayLike, ba: float, eps: float, vo: float = 1.0
) -> NDArray[np.float64]:
    """Scale M >= |U| of :func:`U_kcrit`: the sum of the magnitudes of the terms of U.

    U is a difference of such terms, so its rounding error is a few u M and its drift
    along computed trajectories is proportional to rtol M (law in :func:`U_kcrit`).
    M/|U| is the condition number of U: large near the separatrix, where U -> 0.
    Same arguments and normalisation as :func:`U_kcrit`.
    """
    ba, eps = _check_ba_eps(ba, eps)
    vo = check_range("vo", vo, 0.0, None, lo_open=True)
    phi = np.asarray(phi, dtype=np.float64)
    psi = np.asarray(psi, dtype=np.float64)
    kc = ba - 1.0
    if eps == 1.0:
        with np.errstate(over="ignore", invalid="ignore"):
            lth = (psi - phi) / ba
            return ba * (kc * np.exp(lth + math.log(vo)) + np.exp(phi + lth) + np.abs(psi))
    _, _, m, logP = _kcrit_parts(phi, psi, ba, eps, vo)
    return _times_exp(m, logP)


def U_kcrit_sign(
    phi: ArrayLike, psi: ArrayLike, ba: float, eps: float, vo: float = 1.0
) -> NDArray[np.int64]:
    """Sign of U of :func:`U_kcrit` that rounding cannot flip: -1 (closed orbit, stable),
    +1 (open orbit, runaway for eps < 1) or 0 (|r| <= 8 u s: within rounding of U = 0, the
    critical trajectory, undecidable in double precision from this start).

    Computed from the reduced form r = U/P (P > 0, :func:`_kcrit_parts`), which neither
    over- nor underflows for any v_o.  At eps = 1 every orbit is closed: -1 everywhere.
    """
    ba, eps = _check_ba_eps(ba, eps)
    vo = check_range("vo", vo, 0.0, None, lo_open=True)
    if eps == 1.0:
        return -np.ones(np.broadcast(np.asarray(phi), np.asarray(psi)).shape, dtype=np.int64)
    r, s, _, _ = _kcrit_parts(phi, psi, ba, eps, vo)
    with np.errstate(invalid="ignore"):
        certain = np.abs(r) > 8.0 * UNIT_ROUNDOFF * s
        sign = np.where(certain & (r < 0.0), -1, np.where(certain & (r > 0.0), 1, 0))
        return sign.astype(np.int64)


def U_vo0(
    phi: ArrayLike, psi: ArrayLike, ba: float, kappa: float, eps: float
) -> NDArray[np.float64]:
    """Lyapunov function U(phi, psi) for a stationary load point (v_o = 0), any kappa > 0.

    Implements `eq: trajectories 2`,

        U = e^(psi (b/a - kappa eps - 1)/kappa) (kappa b/a)
            (1 - b/a + e^(eps n)(b/a - 1 - kappa eps))
            / (eps (b/a - 1)(b/a - 1 - kappa eps)),      n = ((b/a - 1) phi + psi)/(b/a) = L,

    evaluated as (kappa b/a) e^(...) [kappa_crit expm1(eps n)/eps - kappa e^(eps n)] /
    (kappa_crit (kappa_crit - kappa eps)), exact at eps = 0.  U = 0 is the line L = L*
    (`eq: limiting trajectory2`).  Singular (ParameterError) at kappa = 0 and at
    eps kappa = kappa_crit.  When eps kappa > kappa_crit U > 0 everywhere yet every
    trajectory is stable (the sign criterion holds only while eps kappa < kappa_crit).
    The prefactor is formed through its logarithm (no spurious overflow).

    Along a computed trajectory (measured law, docs/accuracy.md, tests/core/test_u_drift.py)

        |U(T) - U(0)| <= 10 rtol M (1 + Y)(1 + V),

    M = max of :func:`U_vo0_scale` along the path, Y = max(|phi|, |ln theta|), V = total
    variation of phi; relative to |U(0)|, which vanishes like L* - L(0) at the critical line.
    """
    ba, eps = _check_ba_eps(ba, eps)
    kappa = check_range("kappa", kappa, 0.0, None, lo_open=True)
    kc = ba - 1.0
    den = kc - kappa * eps
    if den == 0.0:
        raise ParameterError(
            "kappa", kappa, "eps*kappa != b/a - 1 (U of eq: trajectories 2 is singular there)"
        )
    phi = np.asarray(phi, dtype=np.float64)
    psi = np.asarray(psi, dtype=np.float64)
    n = ((ba - 1.0) * phi + psi) / ba
    with np.errstate(over="ignore", invalid="ignore"):
        num = kc * _expm1_over(eps, n) - kappa * np.exp(eps * n)
        logP = psi * den / kappa + math.log(kappa * ba / (kc * abs(den)))
    return _times_exp(math.copysign(1.0, den) * num, logP)


def U_vo0_scale(
    phi: ArrayLike, psi: ArrayLike, ba: float, kappa: float, eps: float
) -> NDArray[np.float64]:
    """Scale M >= |U| of :func:`U_vo0`: the sum of the magnitudes of its terms.

    The rounding of U is a few u M; its drift along computed trajectories follows the
    law of :func:`U_vo0` (docs/accuracy.md).  Same arguments as :func:`U_vo0`.
    """
    ba, eps = _check_ba_eps(ba, eps)
    kappa = check_range("kappa", kappa, 0.0, None, lo_open=True)
    kc = ba - 1.0
    den = kc - kappa * eps
    if den == 0.0:
        raise ParameterError(
            "kappa", kappa, "eps*kappa != b/a - 1 (U of eq: trajectories 2 is singular there)"
        )
    phi = np.asarray(phi, dtype=np.float64)
    psi = np.asarray(psi, dtype=np.float64)
    n = ((ba - 1.0) * phi + psi) / ba
    with np.errstate(over="ignore", invalid="ignore"):
        m = kc * np.abs(_expm1_over(eps, n)) + kappa * np.exp(eps * n)
        logP = psi * den / kappa + math.log(kappa * ba / (kc * abs(den)))
    return _times_exp(m, logP)


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
    Ls = L_star_acc(p.kappa, p.kappa_crit, p.eps)[0]
    if not math.isfinite(Ls):
        raise ParameterError(
            "kappa", kappa, "eps*kappa < b/a - 1 (otherwise no critical trajectory exists)"
        )
    return (1.0 - p.ba) * np.asarray(phi, dtype=np.float64) + p.ba * Ls


#: Unit roundoff of IEEE double precision, 2^-53 (half the spacing of doubles at 1).
UNIT_ROUNDOFF = 2.0**-53
#: rel_accuracy of L* (`eq: analytical phi crit`) in units of UNIT_ROUNDOFF; derivation in
#: :func:`L_star_acc`, checked against 50-digit mpmath (tests/core/test_closed_form_accuracy.py).
_LSTAR_ULPS = 6.0
#: rel_accuracy of the kappa = kappa_crit load-point jump 1/(kappa_crit (1 - eps)): three
#: roundings (1 - eps, the product, the reciprocal) plus one for safety.
_LJUMP_ULPS = 4.0
#: Factor on the condition-number bound of the kappa = kappa_crit velocity jump
#: (:func:`vjump_kcrit_acc`): each term of the residual passes through up to ~8 roundings
#: (gamma_8 of a running error analysis); the largest measured error / (u S/(|h'| d)) was
#: 2.2 over 20000 random points (b/a in 1 + [1e-12, 1e6], eps in [0, 1 - 1e-15]).
_VJUMP_COND_FACTOR = 8.0
#: Floor of the same bound in ulps: the Newton stop |dd| <= 4e-16 d plus final rounding.
_VJUMP_FLOOR_ULPS = 8.0


@nb.njit(cache=True, nogil=True)
def L_star_acc(kappa: float, kc: float, eps: float) -> tuple[float, float]:
    """L* = -ln(1 - x)/eps, x = eps kappa/kappa_crit, with its relative accuracy (compiled).

    `eq: analytical phi crit` (the v_o = 0 critical velocity jump) and the root of g(L) of
    laws.py.  Returns (L*, rel_accuracy); (inf, 0) when x >= 1.  Inputs: kappa in
    [0, 1e6], kc = b/a - 1 in (0, 1e6), eps in [0, 1].

    Accuracy (u = 2^-53, each elementary operation correctly rounded or within 1 ulp):
    * x < 1e-4 (and eps = 0): r(1 + x/2 + x^2/3 + x^3/4), r = kappa/kc; truncation
      < x^4/5 < 2e-17, rounding < 4u;
    * x < 0.5: -log1p(-x)/eps with x carrying 2u; the condition number of log1p(-x) in x
      is x/((1 - x)|ln(1 - x)|) <= 1.45, so < 2.9u + 2u;
    * x >= 0.5: 1 - x is formed as ((kc - p) - e)/kc with p + e = eps kappa exactly
      (kc - p is exact by Sterbenz), so 1 - x carries < 2u and ln(1 - x) < 2u/ln 2 + u
      relative.  The naive -log1p(-x)/eps used before loses 1/((1 - x)|ln(1 - x)|) ulps:
      2.7e-5 relative at x = 1 - 1.3e-13 (measured against mpmath).
    Bound reported: 6u = 6.7e-16 everywhere (max measured 2.7u over 5000 mpmath points).
    The value is rsfcore.laws.L_star (this algorithm, used by every caller).
    """
    v = L_star(kappa, kc, eps)
    if math.isinf(v) or v == 0.0:
        return v, 0.0
    return v, _LSTAR_ULPS * UNIT_ROUNDOFF


@nb.njit(cache=True, nogil=True)
def _h_kcrit(d: float, eps: float, kc: float, D: float, q: float) -> tuple[float, float, float]:
    """Residual h(d) of the kappa = kappa_crit velocity jump, its slope h'(d) and the size S
    of the rounding in h (sum of the magnitudes of everything added), see vjump_kcrit_acc.
    """
    em1 = math.expm1(-d)
    R = q * em1 - 1.0 / D
    t1 = (d - 1.0) / D
    t2 = q * _em(d)
    y = eps * R
    X = kc * math.exp(-d) / D
    if abs(y) >= 0.1:
        # log1p(eps R) = ln((1 - eps)(1 + eps X)) formed as one product (1 - eps is exact
        # for eps >= 1/2): its rounding is ~3u absolute, where log1p(-eps) + log1p(eps X)
        # cancels two terms of size ln(1/(1 - eps)) (2.6x less noise at eps = 0.997)
        lp = math.log((1.0 - eps) * (1.0 + eps * X))
        t3 = (lp - y) / eps
        s3 = (abs(lp) + 3.0 + abs(y)) / eps
    else:
        t3 = _lmr(eps, R, d, kc, D)
        # t3 ~ -eps R^2/2: the rounding of R (itself a difference) enters twice
        s3 = abs(t3)
        if R != 0.0:
            s3 += 2.0 * abs(t3 / R) * (abs(q * em1) + 1.0 / D)
    # h' = 1 - q e^-d/(1 + eps R) = (1/D - q expm1(-d))/(1 + eps X): both terms positive
    hp = (1.0 / D - q * em1) / (1.0 + eps * X)
    return t1 + t2 + t3, hp, abs(t1) + abs(t2) + s3


@nb.njit(cache=True, nogil=True)
def vjump_kcrit_acc(ba: float, eps: float) -> tuple[float, float]:
    """Critical velocity jump at kappa = kappa_crit, v_o > 0, and its relative accuracy (compiled).

    psi_crit(d) = d for `eq: limiting trajectory 1` (psi_crit - d = -ba h(d)) with
    h(d) = d + log1p(eps R)/eps, R = q e^(-d) - 1, q = (1 - eps) kc/D, D = ba(1 - eps) + eps.
    Since 1 - q = 1/D, R = q expm1(-d) - 1/D and h is evaluated without cancellation of
    its leading terms as

        h(d) = (d - 1)/D + q (expm1(-d) + d) + (log1p(eps R) - eps R)/eps,

    (at b/a = 1e6 the root is ~1e-3 and the naive form loses 5 digits).  h(0) < 0 <= h(L*);
    safeguarded Newton (bisection fallback) to |dd| <= 4e-16 d.  Returns (inf, 0) at eps = 1.

    Accuracy bound (returned): the computed residual carries a rounding error of a few
    u S, S = sum of the magnitudes of the terms added in h; the root moves by that
    divided by h'(d), which is small as eps -> 1 with large b/a (~(1 - eps) e^d, so the
    root is ill-conditioned there in double precision).  So

        rel_accuracy = 8 u S/(|h'(d)| d) + 8u,

    where 8 counts the roundings each term passes through (the largest measured ratio of
    error to u S/(|h'| d) was 2.2) and 8u covers the Newton stop.  Measured against
    50-digit mpmath over 20000 random points: error up to 9.1e-13 (b/a = 6.7e5,
    eps = 0.986; the bound there 1.3e-11), at most 0.5 of the bound everywhere
    (tests/core/test_closed_form_accuracy.py).
    """
    if eps >= 1.0:
        return math.inf, 0.0
    kc = ba - 1.0
    D = ba * (1.0 - eps) + eps
    q = (1.0 - eps) * kc / D
    lo = 0.0
    hi = L_star_acc(kc, kc, eps)[0]
    for _ in range(60):
        if _h_kcrit(hi, eps, kc, D, q)[0] >= 0.0:
            break
        hi *= 2.0
    # start from the small-d asymptote d^2 (1 - eps)/2 ~ 1/D when it is inside the bracket
    d = math.sqrt(2.0 / (D * max(q * (1.0 - eps), 1e-300)))
    if not (d > lo and d < hi):
        d = 0.5 * (lo + hi)
    for _ in range(200):
        h, hp, S = _h_kcrit(d, eps, kc, D, q)
        if h == 0.0:
            break
        if h < 0.0:
            lo = d
        else:
            hi = d
        dn = d - h / hp if hp > 0.0 else 0.5 * (lo + hi)
        if not (dn > lo and dn < hi):
            dn = 0.5 * (lo + hi)
        if abs(dn - d) <= 4.0e-16 * abs(dn) or hi - lo <= 4.0e-16 * hi:
            d = dn
            break
        d = dn
    h, hp, S = _h_kcrit(d, eps, kc, D, q)
    acc = _VJUMP_COND_FACTOR * UNIT_ROUNDOFF * S / (abs(hp) * d) + _VJUMP_FLOOR_ULPS * UNIT_ROUNDOFF
    return d, acc


@nb.njit(cache=True, nogil=True)
def _vjump_kcrit(ba: float, eps: float) -> float:
    """Value of :func:`vjump_kcrit_acc` alone (compiled; used by rsfcore.critical)."""
    return vjump_kcrit_acc(ba, eps)[0]


@nb.njit(cache=True, nogil=True)
def ljump_kcrit_acc(ba: float, eps: float) -> tuple[float, float, float]:
    """(dv, ln(1 + dv), rel_accuracy) of the kappa = kappa_crit load-point jump (compiled).

    dv = 1/(kappa_crit (1 - eps)): 1 - eps (exact for eps >= 1/2, else one rounding), the
    product and the reciprocal give < 3u; reported 4u.  ln(1 + dv) = log1p(dv) is finite
    for every valid input (dv <= 1/(1e-12 * 2^-53) ~ 1e28).  (inf, inf, 0) at eps = 1.
    """
    if eps >= 1.0:
        return math.inf, math.inf, 0.0
    dv = 1.0 / ((ba - 1.0) * (1.0 - eps))
    return dv, math.log1p(dv), _LJUMP_ULPS * UNIT_ROUNDOFF


def kcrit_jump_side(
    ba: float, eps: float, perturbation: str, log_size: float, size: float | None = None
) -> int:
    """Side of the critical trajectory for a named jump at kappa = kappa_crit, v_o > 0.

    Returns -1 (U < 0: closed orbit, stable), +1 (U > 0: open orbit, runaway for eps < 1)
    or 0 (within the rounding of the closed form: undecidable in double precision).
    Velocity jump (log_size = d): the sign of U at the start is the sign of the closed
    form's own residual h(d) (:func:`vjump_kcrit_acc`; psi - psi_crit = (b/a) h(d), and U
    increases with psi at fixed phi), certain where |h| > 8u S, so a jump d_crit (1 -/+ 10
    rel_accuracy) is always decided; U itself, a difference of O(1) terms, would not
    resolve it.  Load-point jump (log_size = ln(1 + dv), or size = dv when given): stable
    iff dv < dv_crit = 1/(kappa_crit (1 - eps)) (4u), compared in dv with a margin of 8u
    dv_crit, or in the logarithm with 4u dv/(1 + dv) + 2u ln(1 + dv_crit) (the rounding
    of ln(1 + dv_crit)).  At eps = 1 every orbit is closed: -1.
    """
    if eps >= 1.0:
        return -1
    if perturbation == "velocity-jump":
        kc = ba - 1.0
        D = ba * (1.0 - eps) + eps
        q = (1.0 - eps) * kc / D
        h, _, S = _h_kcrit(log_size, eps, kc, D, q)
        if abs(h) <= 8.0 * UNIT_ROUNDOFF * S:
            return 0
        return -1 if h < 0.0 else 1
    dvc, lc, _ = ljump_kcrit_acc(ba, eps)
    if size is not None and math.isfinite(size):
        if abs(size - dvc) <= 8.0 * UNIT_ROUNDOFF * dvc:
            return 0
        return -1 if size < dvc else 1
    w = -math.expm1(-lc)  # dv/(1 + dv) at dv_crit
    if abs(log_size - lc) <= UNIT_ROUNDOFF * (4.0 * w + 2.0 * abs(lc)):
        return 0
    return -1 if log_size < lc else 1


def velocity_jump_crit_vo0(ba: float, kappa: float, eps: float) -> float:
    """Critical velocity jump for v_o = 0 (`eq: analytical phi crit`).

    d_crit = (1/eps) ln(1/(1 - eps kappa/kappa_crit)) = L*.

    Equals L*; +inf when eps kappa >= kappa_crit.  Relative accuracy <= 6.7e-16 (tested
    upper bound, :func:`L_star_acc`), including x = eps kappa/kappa_crit -> 1.
    """
    p = Params(ba=ba, kappa=kappa, eps=eps, vo=0.0)
    return float(L_star_acc(p.kappa, p.kappa_crit, p.eps)[0])


def velocity_jump_crit_slip_law(ba: float) -> float:
    """Exact slip-law (eps = 0) critical velocity jump at kappa = kappa_crit, v_o > 0.

    `eq: asymptotic solution critical velocity jump slip law`: 1 + W0((a/b - 1)/e) with
    the principal branch of Lambert W (the root of b/a phi = b/a - kappa_crit e^(-phi)).
    Evaluated as the cancellation-free root of :func:`vjump_kcrit_acc` at eps = 0: the
    direct 1 + W0(z) loses digits as b/a grows, z tending to the branch point -1/e
    (measured against mpmath: 3.2e-13 at b/a = 1e4, 3.4e-11 at b/a = 1e6).  Relative
    accuracy: the bound of :func:`velocity_jump_crit_kcrit_acc` at eps = 0 (<= 1.8e-15).
    """
    ba = Params(ba=ba, kappa=0.0, eps=0.0).ba
    return float(vjump_kcrit_acc(ba, 0.0)[0])


def velocity_jump_crit_aging_asymptote(ba: float, eps: float) -> float:
    """Leading-order asymptote as eps -> 1.

    `eq: asymptotic solution critical velocity jump aging law`.

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
def _em(d: float) -> float:
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
def _lmr(eps: float, R: float, d: float, kc: float, D: float) -> float:
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


def velocity_jump_crit_kcrit(ba: float, eps: float) -> float:
    """Critical velocity jump at kappa = kappa_crit, v_o > 0 (intersection of psi = phi with U = 0).

    Solves psi_crit_kcrit(d) = d (`eq: limiting trajectory 1` with psi = phi) with the
    compiled, cancellation-free :func:`vjump_kcrit_acc` (safeguarded Newton); the root is
    unique because psi_crit - phi is decreasing.  +inf at eps = 1.  Independent of v_o by
    the scaling invariance; at eps = 0 it equals the Lambert-W form of
    :func:`velocity_jump_crit_slip_law`.  Relative accuracy: ~1e-15 for moderate b/a, but
    ill-conditioned as eps -> 1 with large b/a (9.1e-13 measured at b/a = 6.7e5,
    eps = 0.986); :func:`velocity_jump_crit_kcrit_acc` returns the tested bound.
    """
    ba, eps = _check_ba_eps(ba, eps)
    return float(vjump_kcrit_acc(ba, eps)[0])


def velocity_jump_crit_kcrit_acc(ba: float, eps: float) -> tuple[float, float]:
    """(d_crit, rel_accuracy) of :func:`velocity_jump_crit_kcrit`; rel_accuracy: tested bound."""
    ba, eps = _check_ba_eps(ba, eps)
    d, acc = vjump_kcrit_acc(ba, eps)
    return float(d), float(acc)


def load_point_jump_crit_kcrit(ba: float, eps: float) -> float:
    """Critical relative load-point jump (dv/v_o)_crit at kappa = kappa_crit.

    dv_crit = 1/(kappa_crit (1 - eps)).

    Derived from `eq: trajectories 1`: the jump v_o -> v_o(1 + dv) from steady state
    puts the system, in the new load point's frame, at phi = -ln(1+dv),
    psi = (b/a - 1) ln(1+dv), where (1 - b/a) phi - psi = 0, so U = 0 reduces to
    e^(-ln(1+dv)) = kappa_crit (1 - eps)/D with D = (b/a)(1 - eps) + eps, i.e.
    1 + dv = D/(kappa_crit (1 - eps)).  +inf at eps = 1.  Relative accuracy <= 4.4e-16
    (three roundings; tested against mpmath).
    """
    ba, eps = _check_ba_eps(ba, eps)
    return float(ljump_kcrit_acc(ba, eps)[0])


# ----------------------------------------------------------------------------------------
@dataclass(frozen=True)
class ClosedFormResult:
    """A closed-form critical size with a tested accuracy bound.

    Attributes:
        kind: "zero" | "finite" | "infinite" (as in rsfcore.critical).
        critical_size: d (velocity jump, ln V units) or dv (load-point jump, relative to
            v_o); 0.0 for "zero", inf for "infinite".
        log_critical_size: d for a velocity jump, ln(1 + dv) for a load-point jump
            (finite even where dv itself would not be); inf for "infinite".
        rel_accuracy: upper bound on |critical_size - exact|/exact, where exact is the
            same closed form evaluated exactly at the given (double) inputs; derived
            from the conditioning of the formula (see each kernel), tested against
            50-digit mpmath.  0 for exact decisions.
        accuracy_met: rel_accuracy <= the requested rtol.
        reason: why the accuracy is not met ("" when it is).
        equation: the paper's equation label of the closed form.
    """

    kind: str
    critical_size: float
    log_critical_size: float
    rel_accuracy: float
    accuracy_met: bool
    reason: str
    equation: str


def closed_form_critical(
    params: Params, perturbation: str = "velocity-jump", *, rtol: float = 1e-10
) -> ClosedFormResult:
    """Closed-form critical size where one exists, with its accuracy bound against ``rtol``.

    Applies to (a) v_o = 0, velocity jump: d_crit = L* (`eq: analytical phi crit`);
    (b) kappa = kappa_crit exactly, v_o > 0: velocity jump from `eq: limiting trajectory 1`
    with psi = phi, load-point jump dv = 1/(kappa_crit (1 - eps)) (`eq: trajectories 1`).
    Elsewhere ParameterError (use rsfcore.critical.critical_perturbation).
    ``rtol`` in (0, 1): accuracy_met is rel_accuracy <= rtol; when not met, ``reason``
    says that the formula's conditioning at these inputs limits it in double precision.
    """
    if not isinstance(params, Params):
        raise ParameterError("params", params, "an rsfcore.Params")
    rtol = check_range("rtol", rtol, 0.0, 1.0, lo_open=True, hi_open=True)
    if perturbation not in ("velocity-jump", "load-point-jump"):
        raise ParameterError("perturbation", perturbation, "one of velocity-jump, load-point-jump")
    kc = params.kappa_crit
    if params.vo == 0.0:
        if perturbation != "velocity-jump":
            raise ParameterError(
                "vo", params.vo, "> 0 for a load-point jump (relative jump of a moving load point)"
            )
        v, acc = L_star_acc(params.kappa, kc, params.eps)
        eq = "eq: analytical phi crit"
        lv = v
    elif params.kappa == kc:
        if perturbation == "velocity-jump":
            v, acc = vjump_kcrit_acc(params.ba, params.eps)
            lv = v
            eq = "eq: limiting trajectory 1 (psi = phi)"
        else:
            v, lv, acc = ljump_kcrit_acc(params.ba, params.eps)
            eq = "eq: trajectories 1 (U = 0 at the load-point jump start)"
    else:
        raise ParameterError(
            "params",
            params.as_dict(),
            "v_o = 0 or kappa = kappa_crit (b/a - 1) exactly for a closed form",
        )
    v, lv, acc = float(v), float(lv), float(acc)
    kind = "infinite" if math.isinf(v) else ("zero" if v == 0.0 else "finite")
    met = acc <= rtol
    reason = (
        ""
        if met
        else (
            f"the closed form is ill-conditioned here: rounding in double precision limits its"
            f" relative accuracy to {acc:.2g} (> rtol {rtol:.2g})"
        )
    )
    return ClosedFormResult(kind, v, lv, acc, met, reason, eq)


def delta_tau(slip_over_Dc: ArrayLike, v2_over_v1: float, eps: float) -> NDArray[np.float64]:
    """Stress transient after an imposed velocity step V1 -> V2 (`eq: delta tau`), units b sigma.

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
