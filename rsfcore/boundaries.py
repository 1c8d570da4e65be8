"""Stability boundaries of the rate-and-state spring-slider (Ciardo & Viesca) as functions.

All quantities are dimensionless (`eq: characteristic scales`): ba = b/a, kappa =
k Dc/(a sigma), eps the evolution-law parameter (0 slip law, 1 aging law), phi =
ln(V/V_*), psi = (tau - tau_*)/(a sigma).  Every function validates its inputs
(rsfcore.ParameterError) and is exact up to rounding (a few ulp; expm1/log1p and short
series keep eps -> 0 exact).

The central quantity is x = eps kappa/kappa_crit.  While x < 1 the line L = L* (L =
ln(V theta/Dc), L* = -log1p(-x)/eps) exists and L > L* is absorbing and runs away; when
x >= 1 no trajectory runs away, for a moving or a stationary load point alike
(`eq: critical trajectory condition`).  Hence eps_crit, (a/b)_crit and
max_unstable_kappa below are the same boundary x = 1 solved for eps, a/b and kappa.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .critical import BOUNDARY_RTOL
from .jsonsafe import finite_or_none

# (numba's cache does not track callees in other modules: this file was touched when
# rsfcore.laws.L_star began deciding x >= 1 on the exact 1 - x, NUMERICS_VERSION 5)
from .laws import L_star
from .params import BA_MAX, KAPPA_MAX, ParameterError, Params, check_range

__all__ = [
    "kappa_crit",
    "eps_crit",
    "ab_crit",
    "acceleration_line",
    "acceleration_possible",
    "acceleration_L",
    "max_unstable_kappa",
    "boundaries_summary",
]


def _ba(ba: float) -> float:
    return check_range("ba", ba, 1.0, BA_MAX, lo_open=True)


def _kappa(kappa: float) -> float:
    return check_range("kappa", kappa, 0.0, KAPPA_MAX)


def _eps(eps: float) -> float:
    return check_range("eps", eps, 0.0, 1.0)


def kappa_crit(ba: float) -> float:
    """Critical stiffness of linear stability, kappa_crit = b/a - 1.

    `eq: dimensionless critical stiffness` (the dimensionless form of `eq: critical
    stiffness`, k_crit = sigma (b - a)/Dc, divided by a sigma/Dc).  ba in (1, 1e6];
    exact up to one rounding.  Below it (with a moving load point) every perturbation
    grows; above it small perturbations decay.
    """
    return _ba(ba) - 1.0


def eps_crit(ba: float, kappa: float) -> float:
    """Critical evolution-law parameter eps_crit = kappa_crit/kappa (`eq: critical epsilon`).

    For eps > eps_crit (x = eps kappa/kappa_crit > 1) no perturbation runs away; for
    eps < eps_crit sufficiently large perturbations do.  At eps = eps_crit exactly x = 1
    and nothing runs away either (the critical size diverges as eps -> eps_crit-).

    Semantics when kappa <= kappa_crit: the returned value is >= 1, i.e. no eps in [0, 1)
    is unconditionally stable; at kappa = kappa_crit only the aging law eps = 1 is
    (eps_crit = 1); for kappa < kappa_crit every eps in [0, 1] admits a runaway
    (eps_crit > 1 is outside the law family).  kappa = 0 returns math.inf.
    ba in (1, 1e6], kappa in [0, 1e6].  Exact up to one rounding.
    """
    b = _ba(ba)
    k = _kappa(kappa)
    if k == 0.0:
        return math.inf
    return (b - 1.0) / k


def ab_crit(kappa: float, eps: float) -> float:
    """Critical a/b = 1/(kappa eps + 1) (`eq: critical ab`).

    For a/b above it (b/a below 1 + kappa eps, i.e. x > 1) no perturbation runs away; for
    a/b below it sufficiently large perturbations do.  kappa in [0, 1e6] (absolute
    dimensionless stiffness k Dc/(a sigma)), eps in [0, 1]; eps = 0 or kappa = 0 gives 1
    (every rate-weakening a/b < 1 can run away).  Exact up to one rounding.
    """
    k = _kappa(kappa)
    e = _eps(eps)
    return 1.0 / (k * e + 1.0)


def acceleration_possible(ba: float, kappa: float, eps: float) -> bool:
    """True iff eps kappa/(b/a) < 1 (`eq: acceleration condition`, stationary load point).

    Then the acceleration line exists and trajectories that cross it accelerate
    transiently (d phi/dT > 0 above it); dimensionally k < b sigma/(Dc eps).
    """
    b = _ba(ba)
    k = _kappa(kappa)
    e = _eps(eps)
    return e * k < b


def acceleration_L(ba: float, kappa: float, eps: float) -> float:
    """L_a = -log1p(-eps kappa/(b/a))/eps, the value of L = ln(V theta/Dc) on the acceleration line.

    Exact limit kappa/(b/a) at eps = 0 (series for eps kappa/(b/a) < 1e-4, truncation
    < 1e-17 relative).  Raises ParameterError when the line does not exist.
    """
    b = _ba(ba)
    k = _kappa(kappa)
    e = _eps(eps)
    y = e * k / b
    if not y < 1.0:
        raise ParameterError(
            "kappa", kappa, f"eps*kappa < b/a = {b!r} (eq: acceleration condition)"
        )
    r = k / b
    if y < 1.0e-4:
        return r * (1.0 + y * (0.5 + y * (1.0 / 3.0 + y * 0.25)))
    return -math.log1p(-y) / e


def acceleration_line(
    ba: float, kappa: float, eps: float, phi: ArrayLike
) -> NDArray[np.float64] | float:
    """psi on the acceleration line of a stationary load point (`eq: acceleration line`).

        psi_a(phi) = (1 - b/a) phi + (b/a) ln[(1 - eps kappa/(b/a))^(-1/eps)]
                   = (1 - b/a) phi + (b/a) L_a,

    where d phi/dT = 0 for v_o = 0 (above the line the slip rate increases).  Parallel to
    the steady-state line psi = (1 - b/a) phi.  eps -> 0 gives psi_a = (1 - b/a) phi +
    kappa.  Exists iff eps kappa/(b/a) < 1 (`eq: acceleration condition`), else
    ParameterError.  phi: scalar or array (returned with the same shape; a float for a
    scalar).  Accuracy: a few ulp of the terms.
    """
    b = _ba(ba)
    La = acceleration_L(b, kappa, eps)
    ph = np.asarray(phi, dtype=np.float64)
    if not np.all(np.isfinite(ph)):
        raise ParameterError("phi", phi, "finite real numbers")
    out = (1.0 - b) * ph + b * La
    if out.ndim == 0:
        return float(out)
    return out


def max_unstable_kappa(ba: float, eps: float) -> float:
    """kappa_crit/eps: the supremum of stiffnesses that can still run away (any v_o).

    For kappa >= kappa_crit/eps (x >= 1) no perturbation of any size runs away, with a
    moving (v_o > 0) or a stationary load point; for kappa_crit <= kappa < kappa_crit/eps
    sufficiently large perturbations do (conditional stability); below kappa_crit with a
    moving load point every perturbation grows.  math.inf at eps = 0 (slip law: every
    stiffness can run away).  ba in (1, 1e6], eps in [0, 1]; at eps = 1 it equals
    kappa_crit (aging law: unconditional stability above kappa_crit, Ranjith & Rice).
    Exact up to one rounding.
    """
    b = _ba(ba)
    e = _eps(eps)
    if e == 0.0:
        return math.inf
    return (b - 1.0) / e


def boundaries_summary(ba: float, kappa: float, eps: float, vo: float = 1.0) -> dict[str, Any]:
    """All boundaries at one parameter point, JSON-safe (None where infinite/non-existent).

    Keys: params, kappa_crit, kappa_ratio, x (= eps kappa/kappa_crit), L_star (None when
    x >= 1), eps_crit, a_over_b, ab_crit, max_unstable_kappa, acceleration_possible,
    acceleration_L and acceleration_intercept (psi_a at phi = 0; None when the line does
    not exist), regime ("unconditionally unstable" | "conditionally stable" |
    "unconditionally stable"), on_boundary ({"x_equals_1", "kappa_equals_kappa_crit"}, up
    to the rounding band critical.BOUNDARY_RTOL) and equation labels.
    """
    p = Params(ba=ba, kappa=kappa, eps=eps, vo=vo)
    kc = p.kappa_crit
    r = p.kappa / kc
    x = p.eps * r
    on_x1 = abs(x - 1.0) <= BOUNDARY_RTOL
    on_kc = abs(r - 1.0) <= BOUNDARY_RTOL
    if x >= 1.0 - BOUNDARY_RTOL:
        regime = "unconditionally stable"
    elif p.vo > 0.0 and r < 1.0 and not on_kc or p.vo == 0.0 and p.kappa == 0.0:
        regime = "unconditionally unstable"
    else:
        regime = "conditionally stable"
    acc = acceleration_possible(p.ba, p.kappa, p.eps)
    La = acceleration_L(p.ba, p.kappa, p.eps) if acc else math.inf
    Ls = float(L_star(p.kappa, kc, p.eps))
    return {
        "params": p.as_dict(),
        "kappa_crit": kc,
        "kappa_ratio": r,
        "x": x,
        "L_star": finite_or_none(Ls) if x < 1.0 else None,
        "eps_crit": finite_or_none(eps_crit(p.ba, p.kappa)),
        "a_over_b": 1.0 / p.ba,
        "ab_crit": ab_crit(p.kappa, p.eps),
        "max_unstable_kappa": finite_or_none(max_unstable_kappa(p.ba, p.eps)),
        "acceleration_possible": bool(acc),
        "acceleration_L": finite_or_none(La) if acc else None,
        "acceleration_intercept": (p.ba * La) if acc else None,
        "regime": regime,
        "on_boundary": {"x_equals_1": bool(on_x1), "kappa_equals_kappa_crit": bool(on_kc)},
        "equations": {
            "kappa_crit": "eq: dimensionless critical stiffness",
            "eps_crit": "eq: critical epsilon",
            "ab_crit": "eq: critical ab",
            "acceleration": "eq: acceleration line / eq: acceleration condition (v_o = 0)",
            "existence": "eq: critical trajectory condition (x < 1)",
        },
    }
