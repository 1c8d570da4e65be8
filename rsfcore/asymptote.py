"""The critical load-point jump for kappa/kappa_crit >> 1 by its derived asymptote.

Used by rsfcore.critical (in place of, or as the fallback of, the separatrix method where
ln(1 + dv_crit) is beyond its reach) and by rsfcore.trajectory (the side of the
separatrix of a large load-point jump).  Derivation: docs/derivations/load_jump_asymptote.md.
"""

from __future__ import annotations

import math

from .laws import L_star
from .params import Params

__all__ = [
    "ASYM_R_MIN",
    "ASYM_LSTAR_MIN",
    "ASYM_DIRECT_LSTAR",
    "ASYM_B_MAX",
    "load_jump_asymptote",
]

#: The load-point asymptote is used where kappa/kappa_crit >= this and L* >= ASYM_LSTAR_MIN
#: (ln(1 + dv_crit) >~ 1e4, beyond the starts classify integrates), as a fallback of the
#: separatrix method or (ASYM_DIRECT_LSTAR) in its place.
ASYM_R_MIN = 1.0e3
ASYM_LSTAR_MIN = 1.0e4
#: From this L* on critical_perturbation answers by the asymptote at once: its error there
#: is ~8 ulp(l) (3 b (1/r + b)^2 < 1e-12 for r >= 2e4), ~1 us, where the separatrix
#: method (which now reaches L* ~ 1e8) carries a rounding floor of 2 sqrt(steps) ulp(l).
ASYM_DIRECT_LSTAR = 2.0e4
#: b = kappa_crit (1 - x)/r up to which the remainder bound of the asymptote is tested
#: (its series in b has radius ~1)
ASYM_B_MAX = 0.3
_ZETA2_M1 = math.pi**2 / 6.0 - 1.0
_ZETA3 = 1.2020569031595942  # zeta(3) (Apery's constant)


def load_jump_asymptote(
    params: Params, lstar_min: float = ASYM_LSTAR_MIN
) -> tuple[float, float] | None:
    """(l, abs error of l) of the critical load-point jump, l = ln(1 + dv_crit), for
    r = kappa/kappa_crit >> 1, or None outside its range (r < ASYM_R_MIN, b =
    kappa_crit (1 - x)/r > ASYM_B_MAX, L* < ``lstar_min``, or L* infinite; a smaller
    ``lstar_min`` is for testing it where the separatrix method runs too).

    Derived in docs/derivations/load_jump_asymptote.md (inner variables of the
    separatrix ODE (B) near u = L*; every step checked in
    tests/core/test_asymptote_derivation.py), with x = eps r and b as above:

        l = L* - ln(kappa_crit) + ln((r - 1)/(r - x)) + b (zeta(2) - 1)
            + (b/r) [(zeta(3) - 1)(2 - x) + (zeta(3) - 3/2) kappa_crit (1 - x)] + R3,

    |R3| <= 3 b (1/r + b)^2 (10x the largest remainder measured against the numerical
    inner solution, b <= 0.3).  The first order is the formerly fitted
    -(1 - x)(1 - (pi^2/6 - 1) kappa_crit)/r exactly.  The returned error is that bound
    plus 8 ulp of l; tested against the separatrix method wherever both run
    (tests/core/test_critical_agreement.py): e.g. 2.3e-10 at r = 1e3, kappa_crit = 1
    (the fitted first-order form erred 3.9e-7 there)."""
    kc, kappa, eps = params.kappa_crit, params.kappa, params.eps
    r = kappa / kc
    if not r >= ASYM_R_MIN:
        return None
    ls = float(L_star(kappa, kc, eps))
    if not (math.isfinite(ls) and ls >= lstar_min):
        return None
    x = eps * r
    b = kc * (1.0 - x) / r
    if not b <= ASYM_B_MAX:
        return None
    delta = math.log1p(-(1.0 - x) / (r - x)) + b * (
        _ZETA2_M1 + ((_ZETA3 - 1.0) * (2.0 - x) + (_ZETA3 - 1.5) * kc * (1.0 - x)) / r
    )
    lg = ls - math.log(kc) + delta
    return lg, 3.0 * b * (1.0 / r + b) ** 2 + 8.0 * math.ulp(lg)
