"""The first decision on a critical size: its kind, and the value where a method decides it.

Shared by rsfcore.critical (critical_perturbation, critical_batch, bisect_critical) and
rsfcore.trajectory (the side of the separatrix of a perturbation), so that neither
imports the other for it.  The compiled kernel :func:`critical_point` returns ints (numba);
:func:`first_decision` names them: :class:`Kind`, :class:`Method`, :class:`DecisionFlag`
in a :class:`Decision`.  The plain int constants (KIND_*, M_*, FLAG_*) are the same codes
for compiled code and numpy arrays (rsfcore.critical re-exports them).

The kind follows the exact signs of kappa - kappa_crit and 1 - x, x = eps kappa/kappa_crit,
of the input doubles (:func:`boundary_gaps`, double-double arithmetic): the critical size is
``zero`` for kappa < kappa_crit with v_o > 0, ``infinite`` for x >= 1, finite otherwise.
"""

from __future__ import annotations

import math
from enum import IntEnum, IntFlag
from typing import NamedTuple

import numba as nb
import numpy as np
from numpy.typing import NDArray

from . import limits as lim
from .analytic import L_star_acc, ljump_kcrit_acc, vjump_kcrit_acc
from .laws import two_prod
from .params import ParameterError, Params
from .separatrix import N_WORK, S_OK, S_OVERFLOW, separatrix_critical

__all__ = [
    "PERTURBATIONS",
    "KINDS",
    "METHODS",
    "BOUNDARY_RTOL",
    "Kind",
    "Method",
    "DecisionFlag",
    "Decision",
    "boundary_gaps",
    "critical_point",
    "first_decision",
    "pert_code",
    "KIND_ZERO",
    "KIND_FINITE",
    "KIND_INFINITE",
    "FLAG_ON_X1",
    "FLAG_ON_KCRIT",
    "FLAG_FALLBACK",
    "FLAG_LOG_VALUE",
    "M_ZERO_LINEAR",
    "M_INF_NO_RUNAWAY",
    "M_CF_VJUMP_KCRIT",
    "M_CF_LJUMP_KCRIT",
    "M_CF_VO0",
    "M_SEPARATRIX",
    "M_BISECTION",
    "M_ZERO_VO0",
    "M_FINITE_BEYOND_RANGE",
    "M_ASYMPTOTE",
    "M_INF_NO_SPRING",
]

PERTURBATIONS: tuple[str, ...] = ("velocity-jump", "load-point-jump")
#: kind codes used by the compiled kernels and by rsfcore.diagram
KIND_ZERO, KIND_FINITE, KIND_INFINITE = 0, 1, 2
KINDS: tuple[str, ...] = ("zero", "finite", "infinite")

# method codes (index into METHODS)
M_ZERO_LINEAR = 0
M_INF_NO_RUNAWAY = 1
M_CF_VJUMP_KCRIT = 2
M_CF_LJUMP_KCRIT = 3
M_CF_VO0 = 4
M_SEPARATRIX = 5
M_BISECTION = 6
M_ZERO_VO0 = 7
M_FINITE_BEYOND_RANGE = 8
METHODS: tuple[str, ...] = (
    "zero: kappa < kappa_crit with a moving load point (linear instability)",
    "infinite: eps*kappa >= kappa_crit, no runaway possible (eq: critical trajectory condition)",
    "closed form: eq: limiting trajectory 1 with psi = phi (kappa = kappa_crit)",
    "closed form: load-point jump at kappa = kappa_crit, dv = 1/(kappa_crit (1 - eps))"
    " (eq: trajectories 1)",
    "closed form: eq: analytical phi crit (v_o = 0), d_crit = L*",
    "separatrix: backward integration of the separatrix from its asymptote (compiled DOP853,"
    " RODAS4 where stiff)",
    "bisection on certified classify() outcomes",
    "zero: kappa = 0 with a stationary load point (L* = 0)",
    "separatrix: finite beyond the double range, ln(1 + dv) > 709 (dv > 8e307): reported by"
    " log_critical_size = ln(1 + dv)",
    "asymptote: ln(1 + dv) = L* - ln(kappa_crit) + ln((r - 1)/(r - x)) + O(kappa_crit/r) for"
    " r = kappa/kappa_crit >> 1 (derived in docs/derivations/load_jump_asymptote.md)",
    "infinite: kappa = 0, no spring: the load point does not act on the slider",
)
M_ASYMPTOTE = 9
M_INF_NO_SPRING = 10

# flag bits of the compiled kernel (_critical_point, critical_batch; they call the separatrix
# driver, whose shared rk kernels numba's cache does not track: touch this file after
# editing rsfcore/separatrix.py or rsfcore/ode/rk.py, or clear NUMBA_CACHE_DIR)
FLAG_ON_X1 = 1  # eps*kappa/kappa_crit = 1 up to rounding
FLAG_ON_KCRIT = 2  # kappa = kappa_crit up to rounding
FLAG_FALLBACK = 4  # separatrix method failed: use bisection
#: _critical_point only: value is l = ln(1 + dv) (dv beyond the double range); critical_batch
#: writes inf (kind finite) there
FLAG_LOG_VALUE = 8

#: Relative band around x = eps kappa/kappa_crit = 1 and kappa = kappa_crit within which a
#: point is flagged ``on_boundary`` (~450 ulp).  The kind itself follows the exact signs
#: of 1 - x and kappa - kappa_crit of the input doubles (:func:`boundary_gaps`); only
#: kappa in [kappa_crit, kappa_crit (1 + BOUNDARY_RTOL)] is snapped, to the closed forms at
#: kappa = kappa_crit, whose claim adds the snap times the measured sensitivity.
BOUNDARY_RTOL = 1.0e-13
# DEFAULT_RTOL and RTOL_RANGE: rsfcore.limits (re-exported here for old import paths)


@nb.njit(cache=True, nogil=True)
def critical_point(
    ba: float,
    kappa: float,
    eps: float,
    vo: float,
    pert: int,
    rtol: float,
    K: NDArray[np.float64],
) -> tuple[int, float, float, int, int, int]:
    """Decision logic for one point.  Returns (kind, value, rel_acc, method, flags, n_rhs).

    value is 0 for zero, inf for infinite; on FLAG_FALLBACK value is nan.
    """
    kc = ba - 1.0
    rm1, omx = boundary_gaps(ba, kappa, eps)
    flags = 0
    if abs(rm1) <= BOUNDARY_RTOL:
        flags |= FLAG_ON_KCRIT
    if abs(omx) <= BOUNDARY_RTOL:
        flags |= FLAG_ON_X1
    if pert == 1 and kappa == 0.0:
        # no spring: the load point does not act on the slider, a load-point jump
        # changes nothing (classify: at_equilibrium)
        return KIND_INFINITE, math.inf, 0.0, M_INF_NO_SPRING, flags, 0
    # the kind follows the exact signs of kappa - kappa_crit and 1 - x of the input doubles
    if vo > 0.0 and rm1 < 0.0:
        return KIND_ZERO, 0.0, 0.0, M_ZERO_LINEAR, flags, 0
    if not (omx > 0.0):
        return KIND_INFINITE, math.inf, 0.0, M_INF_NO_RUNAWAY, flags, 0
    on_kc = rm1 <= BOUNDARY_RTOL
    if vo == 0.0:
        # velocity jump only (the caller rejects load-point jumps with v_o = 0)
        Ls, acc = L_star_acc(kappa, kc, eps)
        if Ls == 0.0:
            return KIND_ZERO, 0.0, 0.0, M_ZERO_VO0, flags, 0
        return KIND_FINITE, Ls, acc, M_CF_VO0, flags, 0
    if on_kc:
        # closed forms evaluated at kappa = kappa_crit, with their tested rounding bounds
        # (rsfcore.analytic, derived from each formula's conditioning); inside the rounding
        # band add |r - 1| times the sensitivity d ln(size)/d r at r = 1, measured
        # (separatrix at r = 1 + h) to stay below 20 + 2/(1 - eps) + 2 sqrt(b/a)
        sens = (20.0 + 2.0 / (1.0 - eps) + 2.0 * math.sqrt(ba)) * abs(rm1)
        if pert == 0:
            d, acc = vjump_kcrit_acc(ba, eps)
            return KIND_FINITE, d, acc + sens, M_CF_VJUMP_KCRIT, flags, 0
        dv, _, acc = ljump_kcrit_acc(ba, eps)
        return KIND_FINITE, dv, acc + sens, M_CF_LJUMP_KCRIT, flags, 0
    st, val, aerr, nr = separatrix_critical(kappa, kc, eps, pert, rtol, K)
    if st == S_OVERFLOW and pert == 1:
        # val = l = ln(1 + dv) > 709, aerr its absolute error = the relative error of dv
        return KIND_FINITE, val, max(aerr, rtol), M_FINITE_BEYOND_RANGE, flags | FLAG_LOG_VALUE, nr
    if st != S_OK:
        return KIND_FINITE, math.nan, math.nan, M_SEPARATRIX, flags | FLAG_FALLBACK, nr
    # reported accuracy: the requested rtol (met by calibration, see _TOL_FACTOR_V) or the
    # propagated a-posteriori estimate when that is larger
    return KIND_FINITE, val, max(aerr / val, rtol), M_SEPARATRIX, flags, nr


class Kind(IntEnum):
    """Kind of a critical size (codes of the compiled kernels; names as in KINDS)."""

    ZERO = KIND_ZERO
    FINITE = KIND_FINITE
    INFINITE = KIND_INFINITE

    @property
    def text(self) -> str:
        """ "zero" | "finite" | "infinite"."""
        return KINDS[int(self)]


class Method(IntEnum):
    """How a critical size was decided (index into METHODS)."""

    ZERO_LINEAR = M_ZERO_LINEAR
    INF_NO_RUNAWAY = M_INF_NO_RUNAWAY
    CF_VJUMP_KCRIT = M_CF_VJUMP_KCRIT
    CF_LJUMP_KCRIT = M_CF_LJUMP_KCRIT
    CF_VO0 = M_CF_VO0
    SEPARATRIX = M_SEPARATRIX
    BISECTION = M_BISECTION
    ZERO_VO0 = M_ZERO_VO0
    FINITE_BEYOND_RANGE = M_FINITE_BEYOND_RANGE
    ASYMPTOTE = M_ASYMPTOTE
    INF_NO_SPRING = M_INF_NO_SPRING

    @property
    def text(self) -> str:
        """The description in METHODS."""
        return METHODS[int(self)]


class DecisionFlag(IntFlag):
    """Flag bits of the compiled decision."""

    #: x = eps kappa/kappa_crit within BOUNDARY_RTOL of 1
    ON_X1 = FLAG_ON_X1
    #: kappa within BOUNDARY_RTOL of kappa_crit
    ON_KCRIT = FLAG_ON_KCRIT
    #: the separatrix method failed: use bisection
    FALLBACK = FLAG_FALLBACK
    #: value is l = ln(1 + dv) (dv beyond the double range)
    LOG_VALUE = FLAG_LOG_VALUE


class Decision(NamedTuple):
    """The compiled decision for one point, named (:func:`first_decision`).

    Attributes:
        rtol: the validated tolerance.
        kind: zero / finite / infinite.
        value: the size (0 for zero, inf for infinite, nan on FALLBACK, l = ln(1 + dv)
            with LOG_VALUE).
        rel_accuracy: relative accuracy of value (0 for exact decisions).
        method: how it was decided.
        flags: :class:`DecisionFlag` bits.
        n_rhs: right-hand sides evaluated.
        on_boundary: ON_X1 or ON_KCRIT.
    """

    rtol: float
    kind: Kind
    value: float
    rel_accuracy: float
    method: Method
    flags: DecisionFlag
    n_rhs: int
    on_boundary: bool


@nb.njit(cache=True, nogil=True)
def boundary_gaps(ba: float, kappa: float, eps: float) -> tuple[float, float]:
    """(kappa/kappa_crit - 1, 1 - x) of the input doubles, x = eps kappa/kappa_crit, with
    kappa_crit the double b/a - 1 (Params.kappa_crit: exact for b/a <= 2, Sterbenz), each
    with its exact sign and a relative accuracy of a few ulp (eps kappa = p + e exactly;
    kc - p and kappa - kc are exact by Sterbenz near the boundary; rsfcore.laws.L_star
    forms 1 - x the same way).  The kind of a critical size follows these signs; a ratio
    computed in doubles can be off by 3 ulp either way."""
    kc = ba - 1.0
    rm1 = (kappa - kc) / kc
    p, e = two_prod(eps, kappa)
    omx = ((kc - p) - e) / kc
    return rm1, omx


def pert_code(perturbation: str) -> int:
    """Index of ``perturbation`` in PERTURBATIONS, or ParameterError naming the field."""
    if perturbation not in PERTURBATIONS:
        raise ParameterError("perturbation", perturbation, "one of " + ", ".join(PERTURBATIONS))
    return PERTURBATIONS.index(perturbation)


def first_decision(params: Params, perturbation: str, rtol: float) -> Decision:
    """Validate the inputs and run the compiled decision for one point (:class:`Decision`)."""
    if not isinstance(params, Params):
        raise ParameterError("params", params, "an rsfcore.Params")
    pert = pert_code(perturbation)
    rtol = lim.RTOL.check(rtol)
    if pert == 1 and params.vo == 0.0:
        raise ParameterError(
            "vo", params.vo, "> 0 for a load-point jump (relative jump of a moving load point)"
        )
    kind, val, acc, meth, flags, nr = critical_point(
        params.ba, params.kappa, params.eps, params.vo, pert, rtol, np.empty(N_WORK)
    )
    fl = DecisionFlag(int(flags))
    return Decision(
        rtol,
        Kind(int(kind)),
        float(val),
        float(acc),
        Method(int(meth)),
        fl,
        int(nr),
        bool(fl & (DecisionFlag.ON_X1 | DecisionFlag.ON_KCRIT)),
    )
