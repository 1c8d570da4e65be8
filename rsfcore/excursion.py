"""The fast-slip leg of an excursion in closed form (huge slip rates, b/a -> 1).

Near b/a -> 1 with kappa ~ kappa_crit a perturbation that does not run away can still
drive phi = ln(V/V_*) to 1e5 .. 1e12 before it returns (`eq:psi_T` / `eq:phi_T`; e.g. b/a =
1 + 3.5e-12, kappa/kappa_crit = 3.9, d = 2.6: peak phi = 4.2e11).  An explicit integration
of (phi, ln theta) then needs ~1e5 steps and cannot even represent L = phi + ln theta better
than ~1e-16 |phi| (4e-5 at that peak), which decides where the excursion ends.

Above phi - ln c = :data:`PHI_LEG` the hybrid-time equations of rsfcore.engine lose every
term of the load point: a_phi = sigmoid(phi - ln c) = 1 - O(e^-50) rounds to 1, so

    d phi/dtau      = -(kappa + (b/a) G(L)) / D,
    d ln theta/dtau = G(L) / D,
    dL/dtau         = -(kappa + kc G(L)) / D,         kc = b/a - 1 = kappa_crit,

and L alone moves the state.  Below L* (where kappa + kc G > 0) L decreases monotonically,
phi rises while kappa + (b/a) G(L) < 0 (L above L_peak, the root of kappa + (b/a) G), peaks
at L_peak and falls again.  Along the leg phi is a function of L (divide the equations):

    d phi/dL = 1 + G/(kappa + kc G),     ds/dL = -1/(kappa + kc G),

so with r = kappa/kc and J(L) = integral dL/(r + G(L)), exactly,

    kc (phi(L) - phi_in) = (b/a)(L - L_in) - r (J(L) - J(L_in))        (leg 1)
    s(L) - s_in          = -(J(L) - J(L_in)) / kc                        (leg 2)

and J has a closed form: with u = e^(-eps L), r + G = (q + u)/eps, q = eps r - 1, so
dL/(r + G) = -du/(u (q + u)) integrates to ln(1 + q e^(eps L))/q.  Written without
cancellation for every eps in [0, 1] (eps = 0 included) and every q:

    J(L) - J(L_in) = l(z) E / (r + G(L_in)),   E = expm1(eps dL)/eps,  dL = L - L_in,
    z = q E / (r + G(L_in)),                   l(z) = log1p(z)/z        (leg 3)

(at eps = 0: -ln((r - L)/(r - L_in)), the slip law).  The leg ends where phi is back at
phi_in, the root L_exit < L_peak of (leg 1) = 0; (leg 1) is a difference of O(|dL|) terms
whose second, r (J(L) - J(L_in)), carries the rounding of r + G(L_in) (~ulp(r)) relative to
r + G(L_in), so L_exit carries an absolute error below max(1, c) ulp(|dL|) with the
conditioning factor c = r/(r + G(L_in)) (large where the leg starts near L*), however high
the peak: measured <= 0.18 max(1, c) ulp(|dL|) over 281 random legs against 60-digit
mpmath roots of (leg 1) (up to 4.2e6 ulp at c ~ 1e8; tests/core/test_excursion.py).  The time
spent on the leg is T-wise e^-(phi_in - ln c) (1/|rate_in| + 1/|rate_exit|)/c with
rate = kappa + (b/a) G(L) (the integral of d(cT) = e^-(phi - ln c) d phi/rate over the
two flanks), below 1e-21 of the time scale at PHI_LEG = 50.

A start high above ln c that falls (a velocity jump d > 150, or the exit of a leg there)
takes its falling flank down to phi - ln c = PHI_LEG the same way (:func:`descent_leg`: L_exit
the root of (leg 1) = kc (phi_exit - phi_in), within 2 ulp of L plus its conditioning,
measured against 60-digit roots), instead of ~5 steps per unit of phi at rtol 1e-13 while
c T grows as e^-(phi - ln c); c T spent there is e^-PHI_LEG/rate_exit - e^-(phi_in - ln
c)/rate_in to first order.

Derived here from the system `eq:psi_T` / `eq:phi_T` (the paper treats these excursions
only through the separatrix asymptote, `eq: limiting trajectory2`).  Checked in
tests/core/test_excursion.py against 50-digit quadrature of d phi/dL (leg 1, 3) and
against the full explicit integration where that is accurate (peaks phi ~ 1e2 .. 1e6).
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numba as nb

from .laws import EXP_CLIP, G, L_star, two_prod

__all__ = [
    "PHI_LEG",
    "LEG_MIN_RISE",
    "LegResult",
    "leg",
    "fast_leg",
    "descent_leg",
    "leg_dJ",
    "leg_phi",
]

#: phi - ln c above which the leg is taken in closed form: a_phi = 1 - e^-50 = 1 - 2e-22
#: rounds to 1, so the reduced equations are the engine's own to rounding.
PHI_LEG = 50.0
#: Legs whose peak rises less than this above the entry are left to the integrator (few
#: steps there; the closed form is used where it saves work and resolves what steps cannot).
LEG_MIN_RISE = 100.0

_U = 2.220446049250313e-16


@nb.njit(cache=True, nogil=True, error_model="numpy")
def _log1p_ratio(z: float) -> float:
    """log1p(z)/z for z > -1, 1 at z = 0 (series below 1e-8: truncation < 1e-24)."""
    if abs(z) < 1e-8:
        return 1.0 - z * (0.5 - z / 3.0)
    return math.log1p(z) / z


@nb.njit(cache=True, nogil=True, error_model="numpy")
def _leg_dJ_q(L: float, L_in: float, r: float, eps: float, rg_in: float, q: float) -> float:
    """:func:`leg_dJ` with q = eps r - 1 given (fast_leg forms it as -(1 - x) exactly)."""
    dL = L - L_in
    E = G(-dL, eps)  # expm1(eps dL)/eps, -> dL at eps = 0, series for small eps dL
    z = q * E / rg_in
    if z < -0.5:
        # 1 + z = e^(eps dL) (r + G(L))/rg_in is small: log1p(z) would amplify the rounding
        # of z by 1/(1 + z); its two factors are taken separately (no cancellation: the
        # sum is log1p(z) < -0.69)
        if eps * L < -EXP_CLIP:
            # G(L) overflows beyond eps L < -709: ln(r + G(L)) = -eps L - ln(eps) +
            # log1p(q e^(eps L)) exactly (z < -0.5 needs q > 0, so eps > 0), and eps dL -
            # eps L = -eps L_in (no cancellation of the two large terms)
            lq = math.log1p(q * math.exp(eps * L))
            return (-eps * L_in - math.log(eps * rg_in) + lq) / q
        return (eps * dL + math.log((r + G(L, eps)) / rg_in)) / q
    return _log1p_ratio(z) * E / rg_in


@nb.njit(cache=True, nogil=True, error_model="numpy")
def leg_dJ(L: float, L_in: float, r: float, eps: float, rg_in: float) -> float:
    """J(L) - J(L_in) of (leg 3); ``rg_in`` = r + G(L_in) > 0.

    Valid while r + G > 0 on [L, L_in] and eps L_in > -EXP_CLIP (L itself may lie beyond
    the double range of G, where J saturates); relative accuracy a few ulp
    plus the conditioning of rg_in and of q = eps r - 1 (tests/core/test_excursion.py:
    <= 2e-15 against 50-digit quadrature).
    """
    return _leg_dJ_q(L, L_in, r, eps, rg_in, eps * r - 1.0)


@nb.njit(cache=True, nogil=True, error_model="numpy")
def _leg_phi_q(
    L: float, L_in: float, ba: float, r: float, eps: float, rg_in: float, q: float
) -> float:
    return ba * (L - L_in) - r * _leg_dJ_q(L, L_in, r, eps, rg_in, q)


@nb.njit(cache=True, nogil=True, error_model="numpy")
def leg_phi(L: float, L_in: float, ba: float, r: float, eps: float, rg_in: float) -> float:
    """kc (phi(L) - phi_in) of (leg 1): (b/a)(L - L_in) - r (J(L) - J(L_in))."""
    return _leg_phi_q(L, L_in, ba, r, eps, rg_in, eps * r - 1.0)


@nb.njit(cache=True, nogil=True, error_model="numpy")
def _leg_entry(
    phi_in: float, L_in: float, kappa: float, kc: float, eps: float
) -> tuple[float, float, float, float, bool]:
    """A leg's entry terms, shared by :func:`fast_leg` and :func:`descent_leg`: r =
    kappa/kc, G(L_in), q = eps r - 1 = -(1 - x) with 1 - x to a few ulp (eps kappa = p + e
    exactly; Sterbenz near x = 1), r + G(L_in) (from e^(-eps L_in) - (1 - x) where x >=
    1/2) and whether r + G(L_in) is clear of its own rounding and of the rounding of L
    (dG/dL = -e^(-eps L)): else the side of L* (and the exit) is not resolved here.

    Returns (r, G(L_in), q, r + G(L_in), resolved)."""
    r = kappa / kc
    g_in = G(L_in, eps)
    p, e = two_prod(eps, kappa)
    omx = ((kc - p) - e) / kc
    q = -omx
    if eps > 0.0 and omx <= 0.5:
        ex = math.exp(-eps * L_in)
        rg_in = (ex - omx) / eps
        rg_round = 64.0 * _U * (ex * (1.0 + abs(eps * L_in)) + omx) / eps
    else:
        rg_in = r + g_in
        rg_round = 64.0 * _U * (r + abs(g_in))
    blur = 64.0 * _U * (abs(phi_in) + abs(L_in)) * math.exp(-eps * L_in)
    return r, g_in, q, rg_in, bool(rg_in > blur + rg_round)


@nb.njit(cache=True, nogil=True, error_model="numpy")
def _leg_root_below(
    top: float,
    step: float,
    target: float,
    L_in: float,
    ba: float,
    r: float,
    eps: float,
    rg_in: float,
    q: float,
) -> tuple[bool, float]:
    """The root below ``top`` of kc (phi(L) - phi_in) = ``target`` on a flank where (leg 1)
    increases with L (shared by :func:`fast_leg` and :func:`descent_leg`): bracketed by
    steps doubling from ``step`` below ``top`` (at most 80), then bisected to adjacent
    doubles (at most 200 halvings).  Returns (found, L) with L the upper end of the last
    bracket, the side where (leg 1) >= target."""
    lo = top - step
    found = False
    for _ in range(80):
        if _leg_phi_q(lo, L_in, ba, r, eps, rg_in, q) < target:
            found = True
            break
        step *= 2.0
        lo = top - step
    if not found:
        return False, math.nan
    hi = top
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        if mid <= lo or mid >= hi:
            break
        if _leg_phi_q(mid, L_in, ba, r, eps, rg_in, q) < target:
            lo = mid
        else:
            hi = mid
    return True, hi


@nb.njit(cache=True, nogil=True, error_model="numpy")
def fast_leg(
    phi_in: float, L_in: float, ba: float, kappa: float, eps: float
) -> tuple[bool, float, float, float, float, float]:
    """The leg from (phi_in, L_in) at phi_in - ln c >= PHI_LEG back to phi_in (the engine
    carries L = phi + ln theta itself, rsfcore.engine).

    Returns (ok, L_exit, phi_peak, dJ_exit, rate_in, rate_exit).  ``ok`` is False (and the
    integrator should go on stepping) where the closed form does not apply or gains
    nothing: kappa or kappa_crit not positive, an entry in the clipped range of G (eps L_in
    < -EXP_CLIP), L_in at or above L* (the runaway side) or within its own rounding of it,
    phi not rising (L_in <= L_peak), or a rise below LEG_MIN_RISE.  An exit in the clipped
    range is taken (the engine's G is clipped there, but its rates are saturated).

    q = eps r - 1 = -(1 - x) and, for x >= 1/2, r + G(L_in) = (e^(-eps L_in) - (1 - x))/eps
    are formed from 1 - x of the input doubles (eps kappa = p + e exactly, as in
    rsfcore.laws.L_star): near x -> 1 both are differences of nearly equal terms, and from
    r = kappa/kc and G(L_in) rounded they lost 1/(1 - x) and r/(r + G(L_in)) ulps (a peak
    phi = 1.3e6 was 3e-6 relative off at b/a = 1e5, x = 1 - 1e-12, against a 60-digit
    evaluation of (leg 1)).
    """
    kc = ba - 1.0
    bad = (False, math.nan, math.nan, math.nan, math.nan, math.nan)
    if not (kc > 0.0 and kappa > 0.0 and math.isfinite(L_in)):
        return bad
    if eps * L_in < -EXP_CLIP:
        return bad
    r, g_in, q, rg_in, resolved = _leg_entry(phi_in, L_in, kappa, kc, eps)
    if not resolved:
        return bad
    L_pk = L_star(kappa, ba, eps)  # root of kappa + (b/a) G(L): the peak of phi
    if not (L_in > L_pk):
        return bad
    rise = _leg_phi_q(L_pk, L_in, ba, r, eps, rg_in, q)  # kc (phi_peak - phi_in)
    if not (rise > kc * LEG_MIN_RISE):
        return bad
    # bracket the exit below the peak: leg_phi increases with L there
    # (an exit in the clipped range of the engine's G, eps L < -EXP_CLIP, is taken too:
    # (leg 1, 3) stay exact there, J saturating as L -> -inf, and past the exit the
    # engine's rates are saturated by its time change D, so the clipping changes them
    # by < e^-500 relative; refused, such legs were stepped through: 3.4e3 steps to a
    # peak phi = 1.3e6 at b/a = 1e5, x = 1 - 1e-12, classify's check run out of budget)
    found, L_exit = _leg_root_below(L_pk, max(L_in - L_pk, 1.0), 0.0, L_in, ba, r, eps, rg_in, q)
    if not found:
        return bad
    # (phi(L_exit) >= phi_in by at most the resolution of L)
    dJ = _leg_dJ_q(L_exit, L_in, r, eps, rg_in, q)
    rate_in = -(kappa + ba * g_in)
    # (+inf beyond the double range of G: the exit flank then takes no time)
    rate_exit = kappa + ba * G(L_exit, eps) if eps * L_exit > -EXP_CLIP else math.inf
    return (True, L_exit, phi_in + rise / kc, dJ, rate_in, rate_exit)


@nb.njit(cache=True, nogil=True, error_model="numpy")
def descent_leg(
    phi_in: float, L_in: float, ba: float, kappa: float, eps: float, drop: float
) -> tuple[bool, float, float, float, float]:
    """The falling flank from (phi_in, L_in), phi_in - ln c >= PHI_LEG + drop, down to
    phi_in - drop (the engine passes drop = phi_in - ln c - PHI_LEG: the end of the
    region where (leg 1 - 3) are the engine's equations to rounding).

    A start high above ln c (a velocity jump d > 150, or the exit of a rising leg there)
    falls at d phi/dtau ~ -1 while c T grows as e^-(phi - ln c): the relative control of T
    holds DOP853 to steps of ~0.2 in tau, ~3.3e3 steps from phi - ln c = 700 to 50 at
    rtol 1e-13 (issue 22: three runs of a trajectory after d = 782, 10.3 ms), in ~e^-50
    of the time of what follows.  Along the flank phi(L) is (leg 1) with phi falling with
    L (kappa + (b/a) G > 0 and r + G > 0: both rates positive), so its end L_exit is the
    root of kc (phi(L) - phi_in) = -kc drop below L_in, taken on the side where phi >=
    phi_in - drop (the resolution of L, as for :func:`fast_leg`'s exit).

    Returns (ok, L_exit, dJ_exit, rate_in, rate_exit), rate = kappa + (b/a) G.  ``ok`` is
    False where the closed form does not apply or gains nothing: kappa or kappa_crit not
    positive, an entry in the clipped range of G, L_in at or within its rounding of L*,
    phi not falling (L_in >= L_peak, or the rate at the entry not positive), or a drop
    below LEG_MIN_RISE.
    """
    kc = ba - 1.0
    bad = (False, math.nan, math.nan, math.nan, math.nan)
    if not (kc > 0.0 and kappa > 0.0 and math.isfinite(L_in) and drop >= LEG_MIN_RISE):
        return bad
    if eps * L_in < -EXP_CLIP:
        return bad
    r, g_in, q, rg_in, resolved = _leg_entry(phi_in, L_in, kappa, kc, eps)
    if not resolved:
        return bad
    rate_in = kappa + ba * g_in
    if not (L_in < L_star(kappa, ba, eps) and rate_in > 0.0):
        return bad
    target = -kc * drop  # kc (phi(L_exit) - phi_in)
    # bracket the exit below L_in: leg_phi increases with L on the falling flank
    found, L_exit = _leg_root_below(L_in, 1.0, target, L_in, ba, r, eps, rg_in, q)
    if not found:
        return bad
    dJ = _leg_dJ_q(L_exit, L_in, r, eps, rg_in, q)
    rate_exit = kappa + ba * G(L_exit, eps) if eps * L_exit > -EXP_CLIP else math.inf
    if not (rate_exit > 0.0):
        return bad
    return (True, L_exit, dJ, rate_in, rate_exit)


class LegResult(NamedTuple):
    """:func:`fast_leg` named (for Python callers and tests).

    Attributes: ok, L_exit, phi_peak, dJ_exit (J(L_exit) - J(L_in) of (leg 3)),
    rate_in, rate_exit (|kappa + (b/a) G| at entry and exit).
    """

    ok: bool
    L_exit: float
    phi_peak: float
    dJ_exit: float
    rate_in: float
    rate_exit: float


def leg(phi_in: float, lth_in: float, ba: float, kappa: float, eps: float) -> LegResult:
    """:func:`fast_leg` as a :class:`LegResult`."""
    res = fast_leg(phi_in, phi_in + lth_in, ba, kappa, eps)
    return LegResult(bool(res[0]), *(float(v) for v in res[1:]))
