"""The intermediate (aging-to-slip) state evolution law family and the Nagata law mapping.

With L = ln(V theta / Dc) the intermediate law `eq: intermediate state evolution law` reads

    d theta/dt = G(L) e^L,      G(L) = ((e^L)^(-eps) - 1)/eps = expm1(-eps L)/eps,

G -> -L as eps -> 0 (slip law `eq: slip law`) and G = e^(-L) - 1 at eps = 1 (aging law
`eq: aging law`).  In the dimensionless variables L = phi + (psi - phi)/(b/a).

Everything here is evaluated without cancellation for any eps in [0, 1], including
eps = 0 exactly and subnormal eps (a short series is used for |eps L| < 1e-4, whose
truncation error is below (eps L)^4/120 < 1e-18 relative).

The slip-parametrised form used throughout the package (slip s, ds = e^phi dT) is

    dL/ds = kappa v_o e^(-phi) + g(L),     g(L) = -kappa - kappa_crit G(L),

and g has the single root L* = -log1p(-x)/eps with x = eps kappa / kappa_crit (L* =
kappa/kappa_crit at eps = 0), which exists only while x < 1.  L > L* is absorbing and
leads to a finite-time runaway; for v_o = 0 dL/ds = g(L) exactly.
"""

from __future__ import annotations

import math

import numba as nb

__all__ = [
    "G",
    "G_clipped",
    "state_rate",
    "L_star",
    "runaway_possible",
    "x_param",
    "nagata_to_intermediate",
    "intermediate_to_nagata",
    "EXP_CLIP",
    "two_prod",
]

#: Largest exponent used inside G: exp(600) ~ 4e260, so (b/a) G stays finite for b/a <= 1e6.
EXP_CLIP = 600.0

_SERIES = 1.0e-4


@nb.njit(cache=True, nogil=True, error_model="numpy")
def G(L: float, eps: float) -> float:
    """G(L) = expm1(-eps L)/eps of `eq: intermediate state evolution law`.

    Valid for eps in [0, 1] and any finite L with eps*L > -709 (else +inf).
    Relative accuracy: a few ulp (expm1), or the series' < 1e-18 truncation when
    |eps L| < 1e-4; exact slip-law limit G = -L at eps = 0.
    """
    x = eps * L
    if abs(x) < _SERIES:
        # -L (1 - x/2 + x^2/6 - x^3/24): exact at eps = 0, no division by eps.
        return -L * (1.0 - x * (0.5 - x * (1.0 / 6.0 - x * (1.0 / 24.0))))
    return math.expm1(-x) / eps


@nb.njit(cache=True, nogil=True, error_model="numpy")
def G_clipped(L: float, eps: float) -> float:
    """G(L) with the exponent -eps L clipped at EXP_CLIP, so it never overflows.

    Differs from G only where G > e^600/eps, i.e. for theta e^phi < e^(-600/eps):
    there the engine's time rescaling has already made the state rate saturate.
    """
    if eps * L < -EXP_CLIP:
        return math.expm1(EXP_CLIP) / eps
    return G(L, eps)


def state_rate(V: float, theta: float, Dc: float, eps: float) -> float:
    """d theta/dt [s/s] of `eq: intermediate state evolution law` in physical units.

    V [m/s] > 0, theta [s] > 0, Dc [m] > 0, eps in [0, 1].  Returns G(L) V theta/Dc with
    L = ln(V theta/Dc); eps = 1 gives 1 - V theta/Dc (aging) and eps = 0 gives
    -(V theta/Dc) ln(V theta/Dc) (slip), both exactly up to rounding.
    """
    omega = V * theta / Dc
    return G(math.log(omega), eps) * omega


@nb.njit(cache=True, nogil=True, error_model="numpy")
def x_param(kappa: float, kappa_crit: float, eps: float) -> float:
    """x = eps kappa / kappa_crit; a finite runaway exists only while x < 1."""
    return eps * kappa / kappa_crit


@nb.njit(cache=True, nogil=True, error_model="numpy")
def runaway_possible(kappa: float, kappa_crit: float, eps: float, tol: float) -> bool:
    """True when x = eps kappa/kappa_crit < 1 - tol (`eq: critical trajectory condition`)."""
    return eps * kappa < kappa_crit * (1.0 - tol)


@nb.njit(cache=True, nogil=True, error_model="numpy")
def two_prod(a: float, b: float) -> tuple[float, float]:
    """(p, e) with p = fl(a b) and p + e = a b exactly (Dekker/Veltkamp, no FMA needed).

    Valid for |a|, |b| < 1e290 and products far from underflow.
    """
    p = a * b
    c = 134217729.0 * a  # 2^27 + 1
    ah = c - (c - a)
    al = a - ah
    c = 134217729.0 * b
    bh = c - (c - b)
    bl = b - bh
    e = ((ah * bh - p) + ah * bl + al * bh) + al * bl
    return p, e


@nb.njit(cache=True, nogil=True, error_model="numpy")
def L_star(kappa: float, kappa_crit: float, eps: float) -> float:
    """Root L* of g(L) = -kappa - kappa_crit G(L): L* = -log1p(-x)/eps, x = eps kappa/kappa_crit.

    Returns +inf when x >= 1 (no runaway possible), decided on the exact 1 - x of the input
    doubles (a computed x = 1.0 can hide 1 - x = 5e-17, where L* = 37/eps is finite).  For v_o = 0 this is
    `eq: analytical phi crit`; `eq: limiting trajectory2` is the line L = L*.
    Relative accuracy <= 6u = 6.7e-16 for all inputs with x < 1 (derivation in
    rsfcore.analytic.L_star_acc, tested against 50-digit mpmath): series for x < 1e-4,
    log1p(-x) for x < 1/2, and for x >= 1/2 the difference 1 - x formed exactly as
    ((kappa_crit - p) - e)/kappa_crit with p + e = eps kappa (the naive log1p(-x) lost
    1/((1 - x)|ln(1 - x)|) ulps: 2.7e-5 relative at x = 1 - 1.3e-13).
    """
    r = kappa / kappa_crit
    x = eps * r
    if x < _SERIES:
        return r * (1.0 + x * (0.5 + x * (1.0 / 3.0 + x * 0.25)))
    if x < 0.5:
        return -math.log1p(-x) / eps
    p, e = two_prod(eps, kappa)
    omx = ((kappa_crit - p) - e) / kappa_crit
    if not (omx > 0.0):
        return math.inf
    return -math.log(omx) / eps


def nagata_to_intermediate(aN: float, bN: float, DcN: float, cN: float) -> dict[str, float]:
    """Map Nagata-law parameters to the intermediate law.

    (`eq: mapping Nagata and intermediate evolution law`)

    Nagata et al. (2012), `eq: Nagata law`:
        f = f_* + aN ln(V/V_*) + bN ln(V_* theta/DcN),
        d theta/dt = 1 - V theta/DcN - cN theta/(sigma bN) d tau/dt.
    Returns {'a', 'b', 'Dc', 'eps'} with a = aN/(1+cN), eps = 1 - aN cN/((1+cN) bN),
    b = eps bN and Dc = DcN (1+cN).  Requires aN > 0, bN > 0, DcN > 0, cN >= 0 and
    aN cN < (1 + cN) bN (eps > 0).

    Correction to the paper: the printed mapping has Dc = DcN/(1+cN).  With
    Theta' = ln theta + gamma ln V, gamma = aN cN/((1+cN) bN), the Nagata law becomes
    d Theta'/dt = (1/theta - V/DcN)/(1 + cN), i.e. the intermediate law with the slip
    distance DcN (1 + cN): the stress-rate term slows the state evolution.  Integrating
    both laws (tests/test_nagata.py) the corrected map reproduces the Nagata friction to
    ~1e-11, the printed one is off by ~1e-2.
    """
    from .params import ParameterError, check_range

    aN = check_range("aN", aN, 0.0, None, lo_open=True)
    bN = check_range("bN", bN, 0.0, None, lo_open=True)
    DcN = check_range("DcN", DcN, 0.0, None, lo_open=True)
    cN = check_range("cN", cN, 0.0, None)
    eps = 1.0 - aN * cN / ((1.0 + cN) * bN)
    if not eps > 0.0:
        raise ParameterError("cN", cN, "aN*cN/((1+cN)*bN) < 1 (eps > 0)")
    return {"a": aN / (1.0 + cN), "b": eps * bN, "Dc": DcN * (1.0 + cN), "eps": eps}


def intermediate_to_nagata(a: float, b: float, Dc: float, eps: float) -> dict[str, float]:
    """Inverse of :func:`nagata_to_intermediate`.

    cN = (1 - eps) b/(a eps), aN = a(1+cN), bN = b/eps, DcN = Dc/(1+cN).

    Requires eps in (0, 1]; the slip law (eps = 0) has no Nagata equivalent (cN -> inf).
    """
    from .params import check_range

    a = check_range("a", a, 0.0, None, lo_open=True)
    b = check_range("b", b, 0.0, None, lo_open=True)
    Dc = check_range("Dc", Dc, 0.0, None, lo_open=True)
    eps = check_range("eps", eps, 0.0, 1.0, lo_open=True)
    cN = (1.0 - eps) * b / (a * eps)
    return {"aN": a * (1.0 + cN), "bN": b / eps, "DcN": Dc / (1.0 + cN), "cN": cN}
