"""Compiled integrator for the spring-slider system: DOP853 with dense output and events.

The system is `eq:psi_T` / `eq:phi_T`, written with the state y = (phi, ln theta, T, s, s_o)
where ln theta = (psi - phi)/(b/a) is the log of the dimensionless state variable
V_* theta/Dc, s = delta/Dc the slip and s_o = delta_o/Dc the load-point displacement,
so that psi = phi + (b/a) ln theta and L = ln(V theta/Dc) = phi + ln theta.

Formulation (nothing overflows; see References): the independent
variable is a bounded "hybrid" time tau with

    d tau = D(y) (c + e^phi) dT,     c = v_o if v_o > 0 else 1,
    D(y) = hypot(1, (b/a) G(L) a_phi),   a_phi = e^phi/(c + e^phi) = sigmoid(phi - ln c),

so that every right-hand side below is bounded by max(kappa (1 + v_o/c), 1) + 1:

    d phi/dtau     = [kappa (v_o (1 - a_phi)/c - a_phi) - (b/a) G(L) a_phi] / D
    d ln theta/dtau = G(L) a_phi / D
    d(cT)/dtau     = (1 - a_phi)/D       (the engine carries c T internally)
    ds/dtau        = a_phi / D
    ds_o/dtau      = v_o (1 - a_phi)/(c D)

G(L) = expm1(-eps L)/eps is the evolution law (`eq: intermediate state evolution law`),
with its exponent clipped at 600 (a regime where the rescaling D has already saturated
the state rate).  The time change D makes the equations bounded when L -> -inf after a
huge excursion near eps*kappa -> kappa_crit.

Integrator: the explicit Runge-Kutta pair of Dormand & Prince of order 8(5,3) (Hairer,
Norsett & Wanner, Solving ODEs I, Sec. II.10) with its 7th-order dense output.  The
tableau is this project's copy of the published coefficients (rsfcore.ode.dop853_tableau);
stages, error norm, step-size controller, dense output, the Illinois root finder (events) and
the Newton inversion of the time component (samples at given T) are the shared kernels of
rsfcore.ode.rk; stiff phases take implicit steps: Radau IIA of order 5 (rsfcore.ode.radau5,
the default since NUMERICS_VERSION 9, with its collocation polynomial as dense output),
or the Rosenbrock methods RODASP (NUMERICS_VERSION 8) and RODAS4 (rsfcore.ode.rodasp,
rsfcore.ode.rodas4, also used by the separatrix integrator; :class:`StiffMethod`); this
module holds the right-hand side, its Jacobian and the driver with its events.

The right-hand side's numerators are differences of terms up to ~kappa that nearly
cancel on the slow manifold of a stiff machine; they are formed so that their rounding
is relative to what is left (:func:`_terms`), because the steps' error estimates see that
rounding times h, and where it was ~u kappa it, not the truncation error, set the steps
at tight rtol (issue 22: 43,137 DOP853 steps at rtol 1e-13 for a load-point jump at
b/a = kappa = 1e6, 956 now).

Events located on every accepted step with the dense output:
  * runaway certificate: L = phi + ln theta > L* (absorbing; see laws.py);
  * return certificate: phi crosses ln v_o downward after having been at or above it;
  * local maxima of phi (d phi/dtau = 0) and of psi (d psi/dtau = 0, where V = V_o),
    giving the true peaks of slip rate and friction, never sampled ones;
  * optional stop at a given T;
  * blow-up: phi - ln c > phi_stop, after which the remaining time is < e^-phi_stop
    (blowup_tail).

References: Ciardo & Viesca (the system, `eq:psi_T`, `eq:phi_T`); E. Hairer, S. P. Norsett,
G. Wanner, Solving Ordinary Differential Equations I, 2nd ed., Springer 1993 (DOP853,
Sec. II.10); docs/core-api.md (hybrid time and its measured cost).
"""

from __future__ import annotations

import math
import sys
from enum import IntEnum
from typing import NamedTuple

import numba as nb
import numpy as np
from numpy.typing import NDArray

from .excursion import LEG_MIN_RISE, PHI_LEG
from .excursion import descent_leg as _descent_leg
from .excursion import fast_leg as _fast_leg
from .laws import EXP_CLIP, G_clipped, two_prod
from .ode import radau5, rk, rodas4, rodasp

__all__ = [
    "Status",
    "Integrator",
    "StiffMethod",
    "EngineOptions",
    "EngineResult",
    "run",
    "integrate",
    "replay_samples",
    "replay_samples_T",
    "LOG_TAU",
    "LOG_H",
    "LOG_STIFF",
    "LOG_XLIM",
    "LOG_NEWTON",
    "LOG_Y",
    "blowup_tail",
    "STATUS",
    "TIME_LIMIT",
    "PHI_SUBNORMAL",
    "NSTATE",
]

NSTATE = 5
_EMPTY = np.empty(0)
_EMPTY2 = np.empty((0, NSTATE))
#: columns of a step log row: hybrid time at the step's start, signed step, the method
#: (0.0 DOP853, 1.0 RODAS4, 2.0 RODASP, 3.0 Radau IIA: 1 + StiffMethod), the usable
#: fraction of the step (< 1 at a stop), the Newton iterations of a Radau IIA step (0
#: otherwise: replay_samples takes the same number), then the internal state (phi, L,
#: c T[, s, s_o]) at the step's start
LOG_TAU, LOG_H, LOG_STIFF, LOG_XLIM, LOG_NEWTON, LOG_Y = 0, 1, 2, 3, 4, 5
_EMPTY_LOG = np.empty((0, LOG_Y + NSTATE))
_I_PHI, _I_LTH, _I_T, _I_S, _I_SO = 0, 1, 2, 3, 4
_NS = rk.N_STAGES  # stages of the step proper
_NSE = rk.N_STAGES_EXTENDED  # stages with the dense-output extension


class Status(IntEnum):
    """Why :func:`integrate` stopped (the kernel returns the int; :func:`run` wraps it)."""

    #: reached the requested final time T
    T_END = 0
    #: L > L*: certain finite-time instability; integrated to blow-up
    RUNAWAY = 1
    #: phi fell back below ln v_o after an excursion
    RETURNED = 2
    #: v_o = 0 (or kappa = 0) and phi is past its (unique) maximum
    PEAK_PASSED = 3
    #: step budget exhausted without a certificate
    BUDGET = 4
    #: the step size failed down to ~0 (non-finite states)
    STEP_UNDERFLOW = 5
    #: within eq_tol of the steady state (monotone approach)
    CONVERGED = 6
    #: c T or the hybrid time passed TIME_LIMIT (the end of the double range): the state
    #: no longer moves at any representable time (v_o = 0 after a velocity drop to
    #: phi = -6000, where e^phi underflows to 0, stepped to T ~ 1e308 and then took
    #: infinite steps until its budget: 30 s for a trajectory)
    TIME_LIMIT = 7
    #: phi - ln c fell below EngineOptions.phi_floor (PHI_SUBNORMAL: e^(phi - ln c), the
    #: slip rate and every rate proportional to it, is subnormal there and carries fewer
    #: than 53 bits, 0 below -745; the run does not follow the model beyond)
    PHI_FLOOR = 8

    @property
    def text(self) -> str:
        """Lower-case name, as in messages ("step_underflow")."""
        return self.name.lower()


#: Status texts by code (for callers of the raw kernel).
STATUS: dict[int, str] = {int(s): s.text for s in Status}
_STATUS_OF: dict[int, Status] = {int(s): s for s in Status}

# ints for the compiled kernel (numba freezes module-level ints as constants).
# The kernels of rsfcore.ode.rk, rsfcore.ode.rodas4, rsfcore.ode.rodasp and
# rsfcore.ode.radau5 are inlined into integrate(); numba's cache does not see edits there,
# so touch this file (or clear NUMBA_CACHE_DIR) after changing rk.py, rodas4.py,
# rodasp.py or radau5.py.
_T_END = int(Status.T_END)
_RUNAWAY = int(Status.RUNAWAY)
_RETURNED = int(Status.RETURNED)
_PEAK_PASSED = int(Status.PEAK_PASSED)
_BUDGET = int(Status.BUDGET)
_STEP_UNDERFLOW = int(Status.STEP_UNDERFLOW)
_CONVERGED = int(Status.CONVERGED)
_TIME_LIMIT = int(Status.TIME_LIMIT)
_PHI_FLOOR = int(Status.PHI_FLOOR)
#: ln of the smallest normal double (-708.40): below phi - ln c = PHI_SUBNORMAL, e^(phi -
#: ln c) is subnormal (Status.PHI_FLOOR)
PHI_SUBNORMAL = math.log(sys.float_info.min)
#: c T and the hybrid time beyond which a run stops (Status.TIME_LIMIT)
TIME_LIMIT = 1e300
#: A stiff phase hands back to DOP853 after 20 Rosenbrock steps in a row with h |lambda|
#: below this (lambda: the largest eigenvalue of the stiff 2 x 2 block).  RODAS4: 2 (well
#: inside DOP853's stability interval, ~6).  RODASP: 1, because on stiff relaxations at
#: tight rtol DOP853 then takes accuracy-limited steps of h |lambda| ~ 1 at twice the cost
#: of a Rosenbrock step (12 right-hand sides against 6): at b/a = 4.9e4, kappa = 6.1e4,
#: dv = 8e45, rtol 1e-13 the trajectory took 40.6 ms CPU with 2, 20.3 ms with 1 (0.5, 0.25,
#: 0.1: 19.0 - 19.5 ms), and eight other stiff and soft queries at rtol 1e-8 .. 1e-13 moved
#: by less than the timing noise (bench/bench_speed.py's cases).
#: Radau IIA: 1, as RODASP (measured the same way, 0.5 and 2 were not faster).
_EXIT_HL_RODAS4 = 2.0
_EXIT_HL_RODASP = 1.0
_EXIT_HL_RADAU5 = 1.0
#: With Radau IIA a DOP853 phase also hands over where it resolves a decayed fast mode:
#: the 2 x 2 block of the Jacobian has real eigenvalues, the fast one negative and 10x the
#: slow one (:func:`_decayed_fast_rate`), and the steps, limited by accuracy, have h
#: |lambda_fast| > 0.5 (rtol/1e-13)^(1/9) (rk.STIFF_THRESHOLD at most: 1.1 at rtol 1e-10,
#: 3.0 at 1e-6, 6.1 from 1e-4 on), counted like Hairer's test (15 steps, where Hairer's
#: own indicator is above that too).  At tight rtol DOP853 follows such a slow manifold at
#: h |lambda| ~ 0.5 - 1.3 (an explicit method's error carries powers of h lambda), below
#: Hairer's 6.1, while Radau IIA follows the slow solution at 5 - 10 right-hand sides a
#: step against 12.  Fast dynamics that DOP853 resolves itself (a spiral's complex pair,
#: a growing slip) do not count; Hairer's indicator alone also fired on a slow spiral
#: near its fixed point (b/a = 1.01, kappa = 0.5 kappa_crit, eps = 0.5, dv = 1e-12, rtol
#: 1e-10: 367 Radau IIA steps, 1,457 steps in all against 1,121), where it estimates
#: h |lambda| from state differences at the rounding level.
_ENTRY_HL_1E13 = 0.5
#: the slow eigenvalue must be this many times smaller than the fast one
_SLOW_FAST_RATIO = 0.1


class Integrator(IntEnum):
    """Which method :func:`integrate` uses (the kernel takes the int)."""

    #: DOP853 throughout (the reference for the explicit method)
    EXPLICIT = 0
    #: DOP853, switching to the stiff method (:class:`StiffMethod`) in stiff phases and
    #: back (the default)
    AUTO = 1
    #: the stiff method (:class:`StiffMethod`, Radau IIA by default) throughout (for tests
    #: and comparison)
    IMPLICIT = 2
    #: the historical name of IMPLICIT (up to NUMERICS_VERSION 8 the stiff method was a
    #: Rosenbrock method); an alias, same value
    ROSENBROCK = 2


class StiffMethod(IntEnum):
    """Which implicit method takes the stiff steps of :func:`integrate` (the kernel takes
    the int; rsfcore.ode.rodas4, rsfcore.ode.rodasp, rsfcore.ode.radau5).

    RODAS4 and RODASP are 6-stage L-stable Rosenbrock methods of order 4(3) with the same
    step kernel; on the engine's stiff relaxations (a machine relaxing along its slow
    manifold after a large load-point jump) RODAS4 loses order (1.5e5 steps at rtol 1e-13
    against 1.5e3 at 1e-8) where RODASP keeps it.  Radau IIA (order 5, 3 stages,
    simplified Newton; the default since NUMERICS_VERSION 9) keeps order 5 there and
    takes 3-6x fewer steps at tight tolerances for ~8 right-hand sides per step against
    6: at b/a = 4.9e4, kappa = 6.1e4, eps = 1, dv = 9.2e65 (the stiff phase alone, same
    controller) 517 / 1,634 / 2,933 steps at rtol 1e-10 / 1e-12 / 1e-13 against RODASP's
    2,217 / 8,854 / 17,364 (2.7 against 11.0 ms CPU at 1e-13).  tests/core/test_stiff.py
    checks each against scipy's Radau.
    """

    #: Hairer & Wanner's RODAS4 (the engine's stiff method up to NUMERICS_VERSION 7)
    RODAS4 = 0
    #: Steinebach's RODASP, with its own continuous extension (NUMERICS_VERSION 8)
    RODASP = 1
    #: Radau IIA of order 5 with its collocation polynomial as dense output (the default)
    RADAU5 = 2


class EngineResult(NamedTuple):
    """Result of one :func:`integrate` run (dimensionless; T = V_* t/Dc).

    Attributes:
        status: why the run stopped.
        y_end: final state (phi, ln theta, T[, s, s_o]).
        tau_end: final hybrid time (over the integrated steps: a closed-form fast-slip
            leg, n_legs > 0, adds none).
        T_cert: T of the runaway certificate L > L* (nan if none).
        T_return: T of the return certificate (nan if none).
        peak_phi, peak_T: largest phi reached (located on the dense output) and its T.
        peak_psi, peak_psi_T: largest psi = phi + (b/a) ln theta and its T.
        n_steps, n_rhs, n_rejected: accepted steps, right-hand-side evaluations, rejections.
        err_sum: sum over accepted steps of rtol times the normalised local error estimate.
        n_filled: number of sample rows written.
        n_stiff_steps: accepted Rosenbrock steps (stiff phases); n_jacobians: Jacobians.
        n_legs: fast-slip legs and falling flanks taken in closed form (rsfcore.excursion;
            fast_leg=True).
        n_logged: rows written to ``steplog`` (one per accepted step; -1 when it was too
            short, 0 when none was given): :func:`replay_samples` reads them.
    """

    status: Status
    y_end: NDArray[np.float64]
    tau_end: float
    T_cert: float
    T_return: float
    peak_phi: float
    peak_T: float
    peak_psi: float
    peak_psi_T: float
    n_steps: int
    n_rhs: int
    n_rejected: int
    err_sum: float
    n_filled: int
    n_stiff_steps: int = 0
    n_jacobians: int = 0
    n_legs: int = 0
    n_logged: int = 0


class EngineOptions(NamedTuple):
    """How one :func:`integrate` run goes: tolerances, certificates, stops, budget, method.

    One named structure instead of a dozen positional arguments; numba types it as a
    named tuple, so the compiled kernel reads the fields by name.  Every field must have
    its declared type (float64, bool, int64) when it reaches the kernel, or numba compiles
    another specialisation: :func:`run` coerces with :meth:`typed`.

    Attributes:
        rtol, atol: local error tolerances (DOP853 8(5,3) norm / RODAS4 norm) on phi and
            L; T is controlled in relative terms only.  Validated by the caller
            (rsfcore.limits.RTOL: [1e-13, 1e-3]).
        Lstar: L* of laws.L_star (inf when no runaway is possible).
        check_runaway: stop the stability question at L > L* (then integrate to blow-up).
        stop_on_return: stop when phi crosses ln v_o downward after being above it
            (v_o > 0), or, for v_o = 0 or kappa = 0, once phi has passed its maximum.
        t_end: stop at this T (inf for none).
        phi_stop: blow-up threshold on phi - ln c (remaining time < e^-phi_stop).
        max_steps: budget of accepted + rejected steps.
        eq_tol: with stop_on_return and v_o > 0, also stop (Status.CONVERGED) once both
            |phi - ln v_o| and |L| fall below eq_tol without a crossing (0: never).
        integrator: an :class:`Integrator` code (0 DOP853, 1 automatic, 2 Rosenbrock).
        fast_leg: take fast-slip legs and falling flanks in closed form (rsfcore.excursion).
        stiff_method: a :class:`StiffMethod` code (0 RODAS4, 1 RODASP, 2 Radau IIA, the
            default): the implicit method of stiff phases.
        phi_floor: stop (Status.PHI_FLOOR) once phi - ln c < phi_floor (-inf: never).
    """

    rtol: float
    atol: float
    Lstar: float = math.inf
    check_runaway: bool = False
    stop_on_return: bool = False
    t_end: float = math.inf
    phi_stop: float = 40.0
    max_steps: int = 10_000_000
    eq_tol: float = 0.0
    integrator: int = 1
    fast_leg: bool = False
    stiff_method: int = int(StiffMethod.RADAU5)
    phi_floor: float = -math.inf

    def typed(self) -> EngineOptions:
        """The same options with every field coerced to its declared type."""
        return EngineOptions(
            float(self.rtol),
            float(self.atol),
            float(self.Lstar),
            bool(self.check_runaway),
            bool(self.stop_on_return),
            float(self.t_end),
            float(self.phi_stop),
            int(self.max_steps),
            float(self.eq_tol),
            int(self.integrator),
            bool(self.fast_leg),
            int(self.stiff_method),
            float(self.phi_floor),
        )


@nb.njit(cache=True, nogil=True, error_model="numpy")
def _kahan(s, comp, x):
    """Kahan-compensated s + x: returns (new sum, new compensation)."""
    yk = x - comp
    t = s + yk
    return t, (t - s) - yk


#: eps L above which kappa + k G(L) is formed as ((eps kappa - k) + k e^(-eps L))/eps
#: where that is the more accurate form (:func:`_terms`): below, G(L) is not yet near its
#: limit -1/eps and the direct sum is as accurate
_SATURATED_EPS_L = 0.25


@nb.njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _terms(y, ba, kappa, eps, vo, c, lnc):
    """The pieces of the right-hand side shared by :func:`_rhs` and :func:`_jacobian`:
    (ap, om, apom, load, g, z, inv_d, n0, n1) with a_phi = ap, 1 - a_phi = om, a_phi
    (1 - a_phi) = apom, load = v_o om/c, g = G(L), z = (b/a) g a_phi, inv_d = 1/D and the
    numerators n0 = kappa (load - ap) - z of d phi/dtau and n1 = kappa (load - ap) -
    (b/a - 1) g ap of dL/dtau.

    Each numerator is a difference of terms up to ~kappa that nearly cancel on the slow
    manifold of a stiff machine; it is formed so that its rounding is relative to what is
    left, because that rounding is noise that the steps' error estimates see (h times it;
    at rtol 1e-13 it, not the truncation error, set the step: issue 22):

    * load - ap, which is om - a_phi = -tanh((phi - ln c)/2) when v_o > 0, from expm1
      (full relative accuracy near phi = ln c; formed from om and ap it is off by ~1 ulp
      of 1/2, which kappa = 1e6 makes ~1e-10 in d phi/dtau);
    * where eps L > _SATURATED_EPS_L, G(L) = (e^(-eps L) - 1)/eps nears -1/eps and
      kappa + k G(L) (k = b/a, b/a - 1) cancels down to its L-dependent part: formed as
      ((eps kappa - k) + k e^(-eps L))/eps with eps kappa - k exact (two_prod), it keeps
      relative accuracy (b/a = kappa = 1e6, eps = 1, L = 476: 1e6 e^-476 ~ 1e-201, against
      0 +- 1e-10 directly), and n = kappa load - ap (kappa + k G(L)) is taken where its
      rounding bound is the smaller one.  This covers the former special cases near L*
      with x = eps kappa/(b/a - 1) -> 1, where kappa + (b/a - 1) G is a difference of
      terms 1/(1 - x) times larger (x = 1 - 1e-11: rounded to u kappa it moved L by
      1e-12 on the way to a fast-slip leg whose peak depends on it 6.7e5x), and the long
      slip at phi - ln c ~ 20 with x -> 1 (tests/core/test_slip_balance.py).
    """
    zz = y[0] - lnc
    a = abs(zz)
    if a < 1.0:
        em = math.expm1(-a)
        e = 1.0 + em
    else:
        e = math.exp(-a)
        em = e - 1.0
    inv = 1.0 / (1.0 + e)
    # a_phi = sigmoid(zz) and om = 1 - a_phi, each to full relative precision; their
    # difference om - ap = -tanh(zz/2) = sign(zz) expm1(-|zz|)/(1 + e) too
    if zz >= 0.0:
        ap = inv
        om = e * inv
        d = em * inv
    else:
        ap = e * inv
        om = inv
        d = -em * inv
    apom = e * inv * inv  # a_phi (1 - a_phi) = d a_phi / d phi, without cancellation
    if vo == c:
        load = om
        lmap = d
    else:
        load = vo * om / c
        lmap = load - ap
    L = y[1]
    xl = eps * L
    saturated = eps > 0.0 and xl > _SATURATED_EPS_L
    if saturated:
        t = math.exp(-xl)
        g = (t - 1.0) / eps  # (t - 1 in (-1, -0.22): a few ulp, as expm1)
    else:
        t = 0.0
        g = G_clipped(L, eps)
    z = ba * g * ap
    az = abs(z)
    # D = hypot(1, z) without hypot's cost; |z| alone where z*z would overflow
    inv_d = 1.0 / math.sqrt(1.0 + z * z) if az < 1e150 else 1.0 / az
    kl = kappa * lmap
    kc = ba - 1.0
    zc = kc * g * ap
    n0 = kl - z
    n1 = kl - zc
    if saturated:
        kload = kappa * load
        p, e2 = two_prod(eps, kappa)
        # kappa + k G = (a_k + k t)/eps with a_k = eps kappa - k; rounding bound of
        # kload - ap (a_k + k t)/eps against that of kl - k g ap
        a0 = (p - ba) + e2
        if eps * kload + ap * (abs(a0) + ba * t) < eps * (abs(kl) + az):
            n0 = kload - ap * ((a0 + ba * t) / eps)
        a1 = (p - kc) + e2
        if eps * kload + ap * (abs(a1) + kc * t) < eps * (abs(kl) + abs(zc)):
            n1 = kload - ap * ((a1 + kc * t) / eps)
    return ap, om, apom, load, g, z, inv_d, n0, n1


@nb.njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _stiff_step_scales(y, ynew, fnew, n, rtol, atol, sc):
    """A stiff (Radau IIA or Rosenbrock) step's end state and slope are finite in all n
    components: then the error scales of (phi, L, T) are set in sc (atol on phi and L,
    none on T) and True; else False (the step is rejected)."""
    for j in range(n):
        if not (math.isfinite(ynew[j]) and math.isfinite(fnew[j])):
            return False
    for j in range(3):
        sc[j] = rk.error_scale(y[j], ynew[j], rtol, atol if j < 2 else 1e-300, math.inf)
    return True


@nb.njit(cache=True, nogil=True, error_model="numpy")
def _rhs(y, out, ba, kappa, eps, vo, c, lnc):
    """Hybrid-time right-hand side (module docstring) of the internal state
    y = (phi, L, c T[, s, s_o]), its numerators formed without avoidable cancellation
    (:func:`_terms`). Writes into ``out``."""
    ap, om, apom, load, g, z, inv_d, n0, n1 = _terms(y, ba, kappa, eps, vo, c, lnc)
    out[0] = n0 * inv_d
    # dL/dtau = d phi/dtau + d ln theta/dtau, written without the cancellation of the two
    out[1] = n1 * inv_d
    out[2] = om * inv_d  # d(c T)/dtau: the engine carries c T, which is O(tau) for any v_o
    if out.shape[0] > 3:  # slip and load point only when the full state is carried
        out[3] = ap * inv_d
        out[4] = load * inv_d


@nb.njit(cache=True, nogil=True, error_model="numpy")
def _decayed_fast_rate(J):
    """|lambda_fast| of the 2 x 2 block J[:2, :2] where its eigenvalues are real, the fast
    one negative and |lambda_slow| < _SLOW_FAST_RATIO |lambda_fast| (a decayed fast mode
    around a slow manifold); else 0."""
    tr = J[0, 0] + J[1, 1]
    det = J[0, 0] * J[1, 1] - J[0, 1] * J[1, 0]
    disc = 0.25 * tr * tr - det
    if not (disc > 0.0):
        return 0.0
    r = math.sqrt(disc)
    # the fast eigenvalue has the sign of the trace; the slow one det/fast (no cancellation)
    fast = 0.5 * tr - r if tr < 0.0 else 0.5 * tr + r
    if not (fast < 0.0):
        return 0.0
    slow = det / fast
    if abs(slow) < _SLOW_FAST_RATIO * abs(fast):
        return -fast
    return 0.0


@nb.njit(cache=True, nogil=True, error_model="numpy")
def _initial_h(y, f, tmp, ftmp, rtol, atol, ba, kappa, eps, vo, c, lnc):
    """Starting step from y with slope f (Hairer, Norsett & Wanner II.4 heuristic, order 8),
    normed over the error norm's components (phi, ln theta, T); one right-hand side."""
    h0, d1 = rk.initial_step_trial(y, f, rtol, atol, 3)
    for j in range(y.shape[0]):
        tmp[j] = y[j] + h0 * f[j]
    _rhs(tmp, ftmp, ba, kappa, eps, vo, c, lnc)
    return rk.initial_step(h0, d1, y, f, ftmp, rtol, atol, 3)


@nb.njit(cache=True, nogil=True, error_model="numpy")
def _stage(K, y, h, s, tmp, ftmp, ba, kappa, eps, vo, c, lnc):
    """Stage s of the tableau: K[s] = f(y + h sum_m A[s, m] K[m]) (K (16, n), y (n,))."""
    n = y.shape[0]
    rk.stage_state(K, y, h, s, tmp)
    _rhs(tmp, ftmp, ba, kappa, eps, vo, c, lnc)
    for j in range(n):
        K[s, j] = ftmp[j]


@nb.njit(cache=True, nogil=True, error_model="numpy")
def _dop853_step(K, y, f, h, ynew, fnew, tmp, ftmp, ba, kappa, eps, vo, c, lnc):
    """One DOP853 step of size h from (y, f = rhs(y)): stages 1-12 into K, the new state
    into ynew, its right-hand side into fnew and K[_NS] (12 right-hand sides)."""
    n = y.shape[0]
    for j in range(n):
        K[0, j] = f[j]
    for s in range(1, _NS):
        _stage(K, y, h, s, tmp, ftmp, ba, kappa, eps, vo, c, lnc)
    rk.step_state(K, y, h, ynew)
    _rhs(ynew, fnew, ba, kappa, eps, vo, c, lnc)
    for j in range(n):
        K[_NS, j] = fnew[j]


@nb.njit(cache=True, nogil=True, error_model="numpy")
def _dense_coeffs(K, y0, y1, f0, f1, h, F, ba, kappa, eps, vo, c, lnc, tmp, ftmp):
    """Fill F (7, n) with the DOP853 dense-output polynomial of the last step.

    Evaluates the three extra stages 14-16 (3 right-hand sides), then rk.dense_coeffs."""
    for s in range(_NS + 1, _NSE):
        _stage(K, y0, h, s, tmp, ftmp, ba, kappa, eps, vo, c, lnc)
    rk.dense_coeffs(K, y0, y1, f0, f1, h, F)


@nb.njit(cache=True, nogil=True, error_model="numpy")
def _root(F, y0, idx, target, x0, x1, g0, g1, tmp, ftmp, ba, kappa, eps, vo, c, lnc, poly_h=0.0):
    """Root in (x0, x1) on the dense output, bracketed by g0 = g(x0), g1 = g(x1) (Illinois).

    idx >= 0: g(x) = y_idx(x) - target (an event on a state component);
    idx = -1: g(x) = d phi/dtau at y(x) (a local maximum of phi);
    idx = -2: g(x) = d psi/dtau at y(x) (a local maximum of psi = phi + (b/a) ln theta).
    With poly_h > 0 (a stiff step of length poly_h, with a cubic dense output: the Hermite
    interpolant of a Rosenbrock step, the collocation polynomial of a Radau IIA step) the
    slopes are those of the polynomial, divided by poly_h: evaluating f at interpolated
    states would multiply the interpolation error by the stiffness |lambda|.  The Hermite
    interpolant's equal f at the step ends, so the bracket g0, g1 is the same; the
    collocation polynomial's are f(Y_3) = f(y1) at the end and within its O(h^4) of f(y0)
    at the start (a bracket whose sign there differs ends the search at that end).
    At most 80 trial points; stops when g = 0 or the bracket is below 1e-15.
    """
    if g0 == 0.0:
        return x0
    if g1 == 0.0:
        return x1
    side = 0
    xm = x0
    for _ in range(80):
        xm = rk.illinois_point(x0, x1, g0, g1)
        rk.dense_eval(F, y0, xm, tmp)
        if idx >= 0:
            gm = tmp[idx] - target
        elif poly_h > 0.0:
            w1 = 1.0 - 2.0 * xm
            w2 = xm * (2.0 - 3.0 * xm)
            gm = (F[0, 0] + w1 * F[1, 0] + w2 * F[2, 0]) / poly_h
            if idx == -2:
                gl = (F[0, 1] + w1 * F[1, 1] + w2 * F[2, 1]) / poly_h
                gm = ba * gl - (ba - 1.0) * gm
        else:
            _rhs(tmp, ftmp, ba, kappa, eps, vo, c, lnc)
            gm = ftmp[0] if idx == -1 else ba * ftmp[1] - (ba - 1.0) * ftmp[0]
        if gm == 0.0 or abs(x1 - x0) < 1e-15:
            break
        x0, x1, g0, g1, side = rk.illinois_update(x0, x1, g0, g1, side, xm, gm)
    return xm


# ------------------------------------------------------------------------------------------
# Stiff phases: the analytic Jacobian for the Rosenbrock method RODAS4 (rsfcore.ode.rodas4)


@nb.njit(cache=True, nogil=True, error_model="numpy")
def _jacobian(y, J, ba, kappa, eps, vo, c, lnc):
    """J[i, 0] = d f_i/d phi, J[i, 1] = d f_i/d L of the hybrid-time RHS (_rhs) in the
    internal state (phi, L, c T[, s, s_o]).

    The right-hand side depends on (phi, L) only (T, s, s_o are quadratures), so these
    two columns are the whole Jacobian.  Exact derivatives of every branch of _rhs
    (sigmoid, clipped G, the time change D = hypot(1, z) or |z|); checked against finite
    differences in tests/core/test_stiff.py.  J has shape (n, 2), n = len(y).
    """
    ap, om, apom, load, g, z, inv_d, n0, n1 = _terms(y, ba, kappa, eps, vo, c, lnc)
    L = y[1]
    gL = 0.0 if eps * L < -EXP_CLIP else -math.exp(-eps * L)  # G'(L)
    kc = ba - 1.0
    az = abs(z)
    z_p = ba * g * apom
    z_l = ba * gL * ap
    # d inv_d = -(z/(1 + z^2)) inv_d dz, or -(dz/z) inv_d on the |z| branch; grouped so
    # that nothing underflows for |z| up to the double range
    if az < 1e150:
        q = z * inv_d * inv_d
        id_p = -q * (inv_d * z_p)  # d inv_d / d phi
        id_l = -q * (inv_d * z_l)  # d inv_d / d L
    else:
        id_p = -(z_p / z) * inv_d
        id_l = -(z_l / z) * inv_d
    load_p = -vo * apom / c
    kl_p = kappa * (load_p - apom)
    J[0, 0] = (kl_p - z_p) * inv_d + n0 * id_p
    J[0, 1] = -z_l * inv_d + n0 * id_l
    J[1, 0] = (kl_p - kc * g * apom) * inv_d + n1 * id_p
    J[1, 1] = -kc * gL * ap * inv_d + n1 * id_l
    J[2, 0] = -apom * inv_d + om * id_p
    J[2, 1] = om * id_l
    if y.shape[0] > 3:
        J[3, 0] = apom * inv_d + ap * id_p
        J[3, 1] = ap * id_l
        J[4, 0] = load_p * inv_d + load * id_p
        J[4, 1] = load * id_l


@nb.njit(cache=True, nogil=True, error_model="numpy")
def integrate(y0, ba, kappa, eps, vo, opts, sample_tau, sample_T_in, samples, steplog):
    """Integrate from y0 = (phi, ln theta, T, s, s_o) until a certificate or a stop.

    Args:
        y0: initial state (5,) = (phi, ln theta, T, s, s_o), or (3,) without slip and
            load point (classification only: ~25% cheaper); T usually 0.
        ba, kappa, eps, vo: parameters (validated by the caller).
        opts: an :class:`EngineOptions` (fields of their declared types: see
            :meth:`EngineOptions.typed`).  Its ``integrator``: 0 = DOP853 only;
            1 = automatic (DOP853, switching to the implicit method of ``stiff_method``,
            Radau IIA by default, when Hairer's stiffness test fires 15 times (h |lambda|
            > 6.1; with Radau IIA also h |lambda_fast| > 0.5 (rtol/1e-13)^(1/9) on a
            decayed fast mode: _ENTRY_HL_1E13), and back when h |lambda| < 1 (RODAS4: 2)
            for 20 steps); 2 = the implicit method only.
            Its ``fast_leg``: take the fast-slip leg of an excursion above
            phi - ln c = PHI_LEG in closed form (rsfcore.excursion) instead of stepping
            through it, and the falling flank of a state above PHI_LEG + LEG_MIN_RISE down
            to PHI_LEG; tau does not advance over either, so no hybrid-time sample falls
            inside one (samples in T do not either: both last < e^-50 of the time scale).
        sample_tau: sorted hybrid-time values at which to record the state (may be empty).
        sample_T: sorted physical-time values T at which to record the state (may be empty).
        samples: output array (len(sample_tau) + len(sample_T), 5) filled in order.
        steplog: (m, LOG_Y + len(y0)) array that receives one row per accepted step
            (LOG_* columns), so that samples in hybrid time can be taken afterwards by
            :func:`replay_samples` without a second run; (0, k): no log.  A run of more
            than m accepted steps stops logging and reports n_logged = -1.

    Returns:
        (status, y_end, tau_end, T_cert, T_return, peak_phi, peak_T, peak_psi, peak_psi_T,
         n_steps, n_rhs, n_rejected, err_sum, n_filled, n_stiff_steps, n_jacobians,
         n_legs, n_logged) where
        T_cert is the T of the runaway certificate (nan if none) and err_sum the sum over
        accepted steps of the normalised local error estimate times rtol (an a-posteriori
        accuracy indicator).
    """
    rtol = opts.rtol
    atol = opts.atol
    Lstar = opts.Lstar
    check_runaway = opts.check_runaway
    stop_on_return = opts.stop_on_return
    t_end = opts.t_end
    phi_stop = opts.phi_stop
    max_steps = opts.max_steps
    eq_tol = opts.eq_tol
    integrator = opts.integrator
    fast_leg = opts.fast_leg
    stiff_method = opts.stiff_method
    phi_floor = opts.phi_floor
    n = y0.shape[0]  # 5, or 3 = (phi, ln theta, T) when slip and load point are not wanted
    c = vo if vo > 0.0 else 1.0
    lnc = math.log(c)
    # With v_o = 0 or kappa = 0, dL/ds = g(L) exactly: L is monotone and the outcome
    # is fixed at the start; the only stop needed is past the (unique) maximum of phi.
    fixed_L = vo == 0.0 or kappa == 0.0
    phi_ss = math.log(vo) if not fixed_L else -math.inf

    # Internally the time component is c T (so that it stays O(tau) for any v_o);
    # inputs and outputs are in T.
    t_end = t_end * c
    sample_T = sample_T_in * c

    K = np.empty((_NSE, n))
    F = np.empty((7, n))
    # internal state (phi, L, c T[, s, s_o]): L = phi + ln theta is carried itself, so
    # that it keeps its own accuracy (rtol |L| + atol) however large |phi| grows; from
    # (phi, ln theta) it would be blurred by rtol |phi| per step and by the rounding of
    # phi + ln theta (0.016 at phi = 1e14), which decides L > L* (issue 22)
    kc = ba - 1.0
    y = y0.copy()
    y[1] = y0[0] + y0[1]
    y[2] *= c
    ynew = np.empty(n)
    tmp = np.empty(n)
    ftmp = np.empty(n)
    f = np.empty(n)
    fnew = np.empty(n)
    ye = np.empty(n)  # state and slope at the end of the usable part of a step
    fe = np.empty(n)
    R = np.empty((rodas4.N_STAGES, n))  # RODAS4 stage increments
    J = np.empty((n, 2))  # Jacobian columns d f/d phi, d f/d L
    rbuf = np.empty(n)
    Z = np.empty((radau5.N_STAGES, n))  # Radau IIA stage increments and slopes
    FZ = np.empty((radau5.N_STAGES, n))
    n_newton = 0  # Newton iterations of the last Radau IIA step
    args = (ba, kappa, eps, vo, c, lnc)  # of _rhs after (state, out), for rodas4.step

    _rhs(y, f, ba, kappa, eps, vo, c, lnc)
    h = _initial_h(y, f, tmp, ftmp, rtol, atol, ba, kappa, eps, vo, c, lnc)
    n_rhs = 2

    tau = 0.0
    tau_c = 0.0
    status = _BUDGET
    sc = np.empty(3)  # error weights of (phi, ln theta, T)
    T_cert = math.nan
    T_return = math.nan
    peak_phi = y[0]
    peak_T = y[2]
    peak_psi = ba * y[1] - kc * y[0]
    peak_psi_T = y[2]
    above = (not fixed_L) and y[0] >= phi_ss
    runaway = False
    err_sum = 0.0
    n_steps = 0
    n_rej = 0
    i_tau = 0
    i_T = 0
    n_tau = sample_tau.shape[0]
    n_T = sample_T.shape[0]
    n_filled = 0
    n_log = 0
    log_cap = steplog.shape[0]

    # Samples at tau = 0 / T = T0.
    while i_tau < n_tau and sample_tau[i_tau] <= 0.0:
        for j in range(n):
            samples[n_filled, j] = y[j]
        n_filled += 1
        i_tau += 1
    while i_T < n_T and sample_T[i_T] <= y[2]:
        for j in range(n):
            samples[n_filled, j] = y[j]
        n_filled += 1
        i_T += 1

    if y[2] >= t_end:
        y[2] /= c
        y[1] -= y[0]
        for i in range(n_filled):
            samples[i, 2] /= c
            samples[i, 1] -= samples[i, 0]
        return (
            _T_END,
            y,
            tau,
            T_cert,
            T_return,
            peak_phi,
            peak_T / c,
            peak_psi,
            peak_psi_T / c,
            0,
            n_rhs,
            0,
            0.0,
            n_filled,
            0,
            0,
            0,
            0,
        )
    if check_runaway and y[1] > Lstar:
        runaway = True
        T_cert = y[2]
        peak_phi = math.inf

    rejected_last = False
    h_acc_prev = 0.0
    err_acc_prev = 1.0
    # stiffness switching (Hairer's test on DOP853 steps; spectral radius on RODAS4 steps)
    stiff = integrator == 2
    n_stiff_hits = 0  # consecutive accepted DOP853 steps with h |lambda| > STIFF_THRESHOLD
    n_nonstiff = 0
    n_easy = 0  # consecutive accepted Rosenbrock steps with h |lambda| < the exit threshold
    stiff_entry = rk.STIFF_THRESHOLD
    if stiff_method == 2:
        stiff_entry = min(rk.STIFF_THRESHOLD, _ENTRY_HL_1E13 * (rtol / 1e-13) ** (1.0 / 9.0))
        exit_hl = _EXIT_HL_RADAU5
    elif stiff_method == 1:
        exit_hl = _EXIT_HL_RODASP
    else:
        exit_hl = _EXIT_HL_RODAS4
    n_stiff_steps = 0
    n_jac = 0
    n_legs = 0
    while n_steps + n_rej < max_steps:
        if tau > TIME_LIMIT or y[2] > TIME_LIMIT:
            status = _TIME_LIMIT
            break
        if y[0] - lnc < phi_floor:
            status = _PHI_FLOOR
            break
        if stiff and stiff_method == 2:
            # ---- one Radau IIA step (stiff phase) --------------------------------------
            _jacobian(y, J, ba, kappa, eps, vo, c, lnc)
            n_jac += 1
            for j in range(2):  # Newton's weights
                sc[j] = atol + rtol * abs(y[j])
            st, n_r, n_newton = radau5.step(
                _rhs, args, y, f, h, J, sc, Z, FZ, tmp, ftmp, ynew, fnew, 0
            )
            n_rhs += n_r
            err = math.inf
            if st == 0 and _stiff_step_scales(y, ynew, fnew, n, rtol, atol, sc):
                err, n_r = radau5.error_norm(
                    _rhs, args, y, f, h, J, Z, sc, 3, rejected_last, tmp, ftmp, rbuf
                )
                n_rhs += n_r
            if not (err <= 1.0):
                n_rej += 1
                # (Newton failed: half the step, as RADAU5)
                h *= rodas4.reject_factor(err) if st == 0 else 0.5
                rejected_last = True
                if not (h > 1e-300):
                    status = _STEP_UNDERFLOW
                    break
                continue
            radau5.dense_coeffs(Z, F)
            n_stiff_steps += 1
        elif stiff:
            # ---- one Rosenbrock step (stiff phase: RODASP, or RODAS4) -------------
            _jacobian(y, J, ba, kappa, eps, vo, c, lnc)
            n_jac += 1
            if stiff_method == 1:
                ok = rodasp.step(_rhs, args, y, f, h, J, R, tmp, ftmp, rbuf, ynew, fnew)
            else:
                ok = rodas4.step(_rhs, args, y, f, h, J, R, tmp, ftmp, rbuf, ynew, fnew)
            n_rhs += 6
            err = math.inf
            if ok and _stiff_step_scales(y, ynew, fnew, n, rtol, atol, sc):
                if stiff_method == 1:
                    err = rodasp.error_norm(R, f, fnew, h, sc, 0, 3, True)
                else:
                    err = rodas4.error_norm(R, f, fnew, h, sc, 0, 3, True)
            if not (err <= 1.0):
                n_rej += 1
                h *= rodas4.reject_factor(err)
                rejected_last = True
                if not (h > 1e-300):
                    status = _STEP_UNDERFLOW
                    break
                continue
            rodas4.hermite_coeffs(y, ynew, f, fnew, h, F)
            n_stiff_steps += 1
        else:
            # ---- one DOP853 step --------------------------------------------------
            _dop853_step(K, y, f, h, ynew, fnew, tmp, ftmp, ba, kappa, eps, vo, c, lnc)
            n_rhs += _NS

            finite = True
            for j in range(n):
                if not math.isfinite(ynew[j]):
                    finite = False
            # Error norm over (phi, ln theta, T) only, so that the 3- and 5-component runs
            # take identical steps (slip and load point are quadratures of the same accuracy).
            # phi, ln theta: mixed absolute/relative; T (a non-decreasing integral from 0):
            # purely relative, so that short blow-up times keep their relative accuracy.
            for j in range(3):
                sc[j] = rk.error_scale(y[j], ynew[j], rtol, atol if j < 2 else 1e-300, math.inf)
            err = rk.error_norm(K, h, sc, 3) if finite else math.inf

            if not (err <= 1.0):
                n_rej += 1
                h *= rk.reject_factor(err)
                rejected_last = True
                # The system is autonomous, so a step far below the spacing of tau is still
                # meaningful (excursions to phi ~ 1e7 at b/a -> 1 need them); only a step that
                # keeps failing down to ~0 (non-finite states) ends the run.  Also catches NaN.
                if not (h > 1e-300):
                    status = _STEP_UNDERFLOW
                    break
                continue
            # Hairer's stiffness test: h |lambda| from the last two stages (both at c = 1;
            # tmp still holds the argument of stage 12)
            if integrator == 1:
                hl = rk.stiffness_ratio(K, ynew, tmp, h, 2)
                slaved = False
                if stiff_entry < hl <= rk.STIFF_THRESHOLD:
                    # a decayed fast mode (Radau IIA only): test the Jacobian at the start
                    _jacobian(y, J, ba, kappa, eps, vo, c, lnc)
                    n_jac += 1
                    slaved = h * _decayed_fast_rate(J) > stiff_entry
                if hl > rk.STIFF_THRESHOLD or slaved:
                    n_stiff_hits += 1
                    n_nonstiff = 0
                else:
                    n_nonstiff += 1
                    if n_nonstiff >= 6:
                        n_stiff_hits = 0

        # ---- accepted: events on [tau, tau + x_end h] ----------------------------
        n_steps += 1
        err_sum += err * rtol
        dense_ready = stiff  # a stiff step has its dense output already
        stop_x = 2.0  # fraction of the step where integration stops (2 = none)
        stop_status = -1

        # A requested final time inside this step is located first, so that no event
        # (peak, certificate) is taken from beyond it.
        x_end = 1.0
        if ynew[2] >= t_end:
            if not dense_ready:
                _dense_coeffs(K, y, ynew, f, fnew, h, F, ba, kappa, eps, vo, c, lnc, tmp, ftmp)
                n_rhs += 3
                dense_ready = True
            x_end = _root(
                F,
                y,
                2,
                t_end,
                0.0,
                1.0,
                y[2] - t_end,
                ynew[2] - t_end,
                tmp,
                ftmp,
                ba,
                kappa,
                eps,
                vo,
                c,
                lnc,
            )
            rk.dense_eval(F, y, x_end, ye)
            _rhs(ye, fe, ba, kappa, eps, vo, c, lnc)
            n_rhs += 1
            stop_x = x_end
            stop_status = _T_END
        else:
            for j in range(n):
                ye[j] = ynew[j]
                fe[j] = fnew[j]

        # maximum of psi (friction), tracked on every step like that of phi
        gp0 = ba * f[1] - kc * f[0]
        gp1 = ba * fe[1] - kc * fe[0]
        if gp0 > 0.0 and gp1 <= 0.0:
            if not dense_ready:
                _dense_coeffs(K, y, ynew, f, fnew, h, F, ba, kappa, eps, vo, c, lnc, tmp, ftmp)
                n_rhs += 3
                dense_ready = True
            xp = _root(
                F,
                y,
                -2,
                0.0,
                0.0,
                x_end,
                gp0,
                gp1,
                tmp,
                ftmp,
                ba,
                kappa,
                eps,
                vo,
                c,
                lnc,
                h if stiff else 0.0,
            )
            rk.dense_eval(F, y, xp, tmp)
            if ba * tmp[1] - kc * tmp[0] > peak_psi:
                peak_psi = ba * tmp[1] - kc * tmp[0]
                peak_psi_T = tmp[2]
        if ba * ye[1] - kc * ye[0] > peak_psi:
            peak_psi = ba * ye[1] - kc * ye[0]
            peak_psi_T = ye[2]

        # runaway certificate (checked at the step end: L is absorbing above L*)
        if check_runaway and not runaway and ye[1] > Lstar:
            runaway = True
            T_cert = ye[2]

        if not runaway:
            # local maximum of phi inside the step
            if f[0] > 0.0 and fe[0] <= 0.0:
                if not dense_ready:
                    _dense_coeffs(K, y, ynew, f, fnew, h, F, ba, kappa, eps, vo, c, lnc, tmp, ftmp)
                    n_rhs += 3
                    dense_ready = True
                xm = _root(
                    F,
                    y,
                    -1,
                    0.0,
                    0.0,
                    x_end,
                    f[0],
                    fe[0],
                    tmp,
                    ftmp,
                    ba,
                    kappa,
                    eps,
                    vo,
                    c,
                    lnc,
                    h if stiff else 0.0,
                )
                rk.dense_eval(F, y, xm, tmp)
                if tmp[0] > peak_phi:
                    peak_phi = tmp[0]
                    peak_T = tmp[2]
            if ye[0] > peak_phi:
                peak_phi = ye[0]
                peak_T = ye[2]
            # return certificate
            if stop_on_return:
                if not fixed_L:
                    if above and ye[0] < phi_ss:
                        if not dense_ready:
                            _dense_coeffs(
                                K, y, ynew, f, fnew, h, F, ba, kappa, eps, vo, c, lnc, tmp, ftmp
                            )
                            n_rhs += 3
                            dense_ready = True
                        xr = _root(
                            F,
                            y,
                            0,
                            phi_ss,
                            0.0,
                            x_end,
                            y[0] - phi_ss,
                            ye[0] - phi_ss,
                            tmp,
                            ftmp,
                            ba,
                            kappa,
                            eps,
                            vo,
                            c,
                            lnc,
                        )
                        rk.dense_eval(F, y, xr, tmp)
                        T_return = tmp[2]
                        stop_x = xr
                        stop_status = _RETURNED
                    if ye[0] >= phi_ss:
                        above = True
                    if stop_status < 0 and abs(ye[0] - phi_ss) < eq_tol and abs(ye[1]) < eq_tol:
                        # within eq_tol of the (asymptotically stable) steady state
                        # (phi = ln v_o, L = 0) without crossing it, from below or above:
                        # a node, not a focus (stiff machines approach from above)
                        stop_x = x_end
                        stop_status = _CONVERGED
                elif fe[0] < 0.0 and stop_status < 0:
                    # v_o = 0 or kappa = 0: L decreases monotonically below L*, so once d phi/ds < 0
                    # it stays negative and the maximum is behind us.
                    stop_x = x_end
                    stop_status = _PEAK_PASSED
        elif ye[0] - lnc > phi_stop and stop_status < 0:
            stop_x = x_end
            stop_status = _RUNAWAY

        # samples inside this step (up to the stop point)
        x_lim = min(stop_x, 1.0)
        tau_lim = tau + x_lim * h
        T_lim = ynew[2]
        if log_cap > 0 and n_log >= 0:
            if n_log < log_cap:
                steplog[n_log, LOG_TAU] = tau
                steplog[n_log, LOG_H] = h
                steplog[n_log, LOG_STIFF] = (1.0 + stiff_method) if stiff else 0.0
                steplog[n_log, LOG_XLIM] = x_lim
                steplog[n_log, LOG_NEWTON] = n_newton if stiff and stiff_method == 2 else 0
                for j in range(n):
                    steplog[n_log, LOG_Y + j] = y[j]
                n_log += 1
            else:
                n_log = -1
        if (i_tau < n_tau and sample_tau[i_tau] <= tau_lim) or (
            i_T < n_T and sample_T[i_T] <= ynew[2]
        ):
            if not dense_ready:
                _dense_coeffs(K, y, ynew, f, fnew, h, F, ba, kappa, eps, vo, c, lnc, tmp, ftmp)
                n_rhs += 3
                dense_ready = True
            while i_tau < n_tau and sample_tau[i_tau] <= tau_lim:
                rk.dense_eval(F, y, (sample_tau[i_tau] - tau) / h, tmp)
                for j in range(n):
                    samples[n_filled, j] = tmp[j]
                n_filled += 1
                i_tau += 1
            if i_T < n_T:
                if x_lim < 1.0:
                    rk.dense_eval(F, y, x_lim, ftmp)
                    T_lim = ftmp[2]
                i_T, n_filled = _samples_in_step_T(
                    F, y, x_lim, T_lim, sample_T, i_T, samples, n_filled, tmp
                )

        if stop_status >= 0:
            # samples at the stop time itself (lost to rounding of the located stop)
            if i_T < n_T:
                if x_lim < 1.0:
                    if not dense_ready:
                        _dense_coeffs(
                            K, y, ynew, f, fnew, h, F, ba, kappa, eps, vo, c, lnc, tmp, ftmp
                        )
                        n_rhs += 3
                        dense_ready = True
                    rk.dense_eval(F, y, x_lim, ftmp)
                else:
                    for j in range(n):
                        ftmp[j] = ynew[j]
                while i_T < n_T and sample_T[i_T] <= ftmp[2] * (1.0 + 1e-12):
                    for j in range(n):
                        samples[n_filled, j] = ftmp[j]
                    n_filled += 1
                    i_T += 1
            if stop_x < 1.0:
                rk.dense_eval(F, y, stop_x, tmp)
                for j in range(n):
                    y[j] = tmp[j]
                tau, tau_c = _kahan(tau, tau_c, stop_x * h)
            else:
                for j in range(n):
                    y[j] = ynew[j]
                tau, tau_c = _kahan(tau, tau_c, h)
            status = stop_status
            break

        # advance (compensated sum: tau stays exact to rounding over millions of tiny steps)
        tau, tau_c = _kahan(tau, tau_c, h)
        for j in range(n):
            y[j] = ynew[j]
            f[j] = fnew[j]
        if stiff:
            # rodas.f's controller with Gustafsson's predictive correction
            fac, err_c = rodas4.accept_factor(err, h, h_acc_prev, err_acc_prev, rejected_last)
            h_acc_prev = h
            err_acc_prev = err_c
            rejected_last = False
            h *= fac
            if integrator == 1:
                # back to DOP853 once the step is well inside its stability region
                n_easy = n_easy + 1 if h * rodas4.spectral_radius(J) < exit_hl else 0
                if n_easy >= 20:
                    stiff = False
                    n_stiff_hits = 0
                    n_nonstiff = 0
                    h_acc_prev = 0.0
                    err_acc_prev = 1.0
        else:
            # elementary controller with Gustafsson's predictive correction (Hairer &
            # Wanner IV.8): when the error constant changes steadily from step to step
            # (approaching a sharp peak), extrapolate the trend instead of retrying a step
            # that fails.
            fac, err_c = rk.accept_factor(err, h, h_acc_prev, err_acc_prev, rejected_last)
            h_acc_prev = h
            err_acc_prev = err_c
            rejected_last = False
            h *= fac
            if n_stiff_hits >= 15:
                # stability, not accuracy, limits the step: continue with RODAS4
                stiff = True
                n_easy = 0
                h_acc_prev = 0.0
                err_acc_prev = 1.0

        # ---- fast-slip leg in closed form (rsfcore.excursion) ---------------------
        # (v_o = 0 too: the load term is 0 there, and kappa = 0 has no leg: fast_leg checks)
        if fast_leg and not runaway and y[0] - lnc >= PHI_LEG:
            leg = _fast_leg(y[0], y[1], ba, kappa, eps)
            if leg[0]:
                L_exit, phi_pk, dJ, rate_in, rate_exit = leg[1], leg[2], leg[3], leg[4], leg[5]
                # c T spent on the two flanks (the top takes < e^-phi of it)
                e_in = math.exp(-(y[0] - lnc))
                dcT_up = e_in / rate_in
                dcT = dcT_up + e_in / rate_exit
                if y[2] + dcT < t_end and not (i_T < n_T and sample_T[i_T] <= y[2] + dcT):
                    if phi_pk > peak_phi:
                        peak_phi = phi_pk
                        peak_T = y[2] + dcT_up
                    if n > 3:
                        y[3] += -dJ / (ba - 1.0)
                        y[4] += dcT
                    y[2] += dcT
                    y[1] = L_exit  # phi is back at its entry value
                    _rhs(y, f, ba, kappa, eps, vo, c, lnc)
                    n_rhs += 1
                    n_legs += 1
                    # restart the step size (the exit flank is not the entry's)
                    h = _initial_h(y, f, tmp, ftmp, rtol, atol, ba, kappa, eps, vo, c, lnc)
                    n_rhs += 1
                    h_acc_prev = 0.0
                    err_acc_prev = 1.0
        # ---- the falling flank high above ln c in closed form (excursion.descent_leg):
        # from a start (or a leg's exit) at phi - ln c >= PHI_LEG + LEG_MIN_RISE down to
        # PHI_LEG, where stepping costs ~5 steps per unit of phi at rtol 1e-13 (c T grows as
        # e^-(phi - ln c)) for ~e^-50 of the time that follows
        if fast_leg and not runaway and y[0] - lnc >= PHI_LEG + LEG_MIN_RISE:
            dleg = _descent_leg(y[0], y[1], ba, kappa, eps, y[0] - lnc - PHI_LEG)
            if dleg[0]:
                L_exit, dJ, rate_in, rate_exit = dleg[1], dleg[2], dleg[3], dleg[4]
                # c T spent on the flank: integral of e^-(phi - ln c) d phi / rate, ~e^-50 of
                # the time scale, taken to first order (the rate's change over the last unit
                # of phi, O(1) of it, is below 1e-21 of the time that follows)
                dcT = math.exp(-PHI_LEG) / rate_exit - math.exp(-(y[0] - lnc)) / rate_in
                dcT = max(dcT, 0.0)
                if y[2] + dcT < t_end and not (i_T < n_T and sample_T[i_T] <= y[2] + dcT):
                    if n > 3:
                        y[3] += -dJ / (ba - 1.0)
                        y[4] += dcT
                    y[2] += dcT
                    y[0] = lnc + PHI_LEG
                    y[1] = L_exit
                    _rhs(y, f, ba, kappa, eps, vo, c, lnc)
                    n_rhs += 1
                    n_legs += 1
                    h = _initial_h(y, f, tmp, ftmp, rtol, atol, ba, kappa, eps, vo, c, lnc)
                    n_rhs += 1
                    h_acc_prev = 0.0
                    err_acc_prev = 1.0

    if status == _BUDGET and runaway:
        status = _RUNAWAY if y[0] - lnc > phi_stop else _BUDGET
    y[2] /= c
    y[1] -= y[0]  # back to ln theta = L - phi
    for i in range(n_filled):
        samples[i, 2] /= c
        samples[i, 1] -= samples[i, 0]
    return (
        status,
        y,
        tau,
        T_cert / c,
        T_return / c,
        peak_phi,
        peak_T / c,
        peak_psi,
        peak_psi_T / c,
        n_steps,
        n_rhs,
        n_rej,
        err_sum,
        n_filled,
        n_stiff_steps,
        n_jac,
        n_legs,
        n_log,
    )


@nb.njit(cache=True, nogil=True, error_model="numpy")
def _samples_in_step_T(F, y, x_lim, T_lim, sample_T, i_T, samples, n_filled, tmp):
    """Samples at the times sample_T[i_T:] (internal c T, sorted) that lie in one step, up
    to its c T at x_lim (T_lim), from its dense output (coefficients F, start y): c T
    increases along the step, so each is found by safeguarded Newton on the T component,
    bracketed below by the previous sample and started from the previous sample's slope
    (or the secant across the step).  Used by :func:`integrate` and
    :func:`replay_samples_T` (the same inversion, so their samples are the same bits).
    Returns the next (i_T, n_filled)."""
    n = y.shape[0]
    n_T = sample_T.shape[0]
    x_lo = 0.0
    T_lo = y[2]
    slope = 0.0
    while i_T < n_T and sample_T[i_T] <= T_lim:
        tgt = sample_T[i_T]
        if slope > 0.0:
            xg = x_lo + (tgt - T_lo) / slope
        elif T_lim > T_lo:
            xg = x_lo + (x_lim - x_lo) * (tgt - T_lo) / (T_lim - T_lo)
        else:
            xg = 0.5 * (x_lo + x_lim)
        xs, slope = rk.dense_invert(F, y[2], 2, tgt, x_lo, x_lim, T_lo - tgt, T_lim - tgt, xg)
        rk.dense_eval(F, y, xs, tmp)
        for j in range(n):
            samples[n_filled, j] = tmp[j]
        n_filled += 1
        i_T += 1
        x_lo = xs
        T_lo = tgt
    return i_T, n_filled


@nb.njit(cache=True, nogil=True)
def _replay_workspace(n):
    """The arrays :func:`_replay_step` works in, for a state of n components."""
    return (
        np.empty((_NSE, n)),  # K
        np.empty((7, n)),  # F
        np.empty((rodas4.N_STAGES, n)),  # R
        np.empty((n, 2)),  # J
        np.empty(n),  # y
        np.empty(n),  # ynew
        np.empty(n),  # f
        np.empty(n),  # fnew
        np.empty(n),  # tmp
        np.empty(n),  # ftmp
        np.empty(n),  # rbuf
        np.empty((radau5.N_STAGES, n)),  # Z
        np.empty((radau5.N_STAGES, n)),  # FZ
        np.ones(2),  # sc (Newton's weights: unused with a fixed number of iterations)
    )


@nb.njit(cache=True, nogil=True)
def _start_row(samples, row, y0, c):
    """samples[row] <- the start y0 in the internal form (L = phi + ln theta, c T)."""
    samples[row, 0] = y0[0]
    samples[row, 1] = y0[0] + y0[1]
    samples[row, 2] = y0[2] * c
    for j in range(3, y0.shape[0]):
        samples[row, j] = y0[j]


@nb.njit(cache=True, nogil=True, error_model="numpy")
def _replay_step(steplog, k, ba, kappa, eps, vo, c, lnc, K, F, R, J, y, ynew, f, fnew,
                 tmp, ftmp, rbuf, Z, FZ, sc):  # fmt: skip
    """Take logged step k of a step log again from its logged start (the same state, step
    and method give the same stages): y <- its start, ynew <- its end, F <- the dense
    output's coefficients (as :func:`integrate` forms them)."""
    n = y.shape[0]
    args = (ba, kappa, eps, vo, c, lnc)
    h = steplog[k, LOG_H]
    for j in range(n):
        y[j] = steplog[k, LOG_Y + j]
    _rhs(y, f, ba, kappa, eps, vo, c, lnc)
    if steplog[k, LOG_STIFF] == 3.0:
        # Radau IIA: the same Newton iterations from the same start give the same stages
        _jacobian(y, J, ba, kappa, eps, vo, c, lnc)
        radau5.step(
            _rhs, args, y, f, h, J, sc, Z, FZ, tmp, ftmp, ynew, fnew,
            int(steplog[k, LOG_NEWTON]),
        )  # fmt: skip
        radau5.dense_coeffs(Z, F)
    elif steplog[k, LOG_STIFF] != 0.0:
        _jacobian(y, J, ba, kappa, eps, vo, c, lnc)
        if steplog[k, LOG_STIFF] == 2.0:
            rodasp.step(_rhs, args, y, f, h, J, R, tmp, ftmp, rbuf, ynew, fnew)
        else:
            rodas4.step(_rhs, args, y, f, h, J, R, tmp, ftmp, rbuf, ynew, fnew)
        rodas4.hermite_coeffs(y, ynew, f, fnew, h, F)
    else:
        _dop853_step(K, y, f, h, ynew, fnew, tmp, ftmp, ba, kappa, eps, vo, c, lnc)
        _dense_coeffs(K, y, ynew, f, fnew, h, F, ba, kappa, eps, vo, c, lnc, tmp, ftmp)


@nb.njit(cache=True, nogil=True, error_model="numpy")
def replay_samples(steplog, n_log, y0, ba, kappa, eps, vo, sample_tau, samples):
    """Samples at the hybrid times ``sample_tau`` (sorted) from the step log of a finished
    :func:`integrate` run from y0 (its rows [0, n_log), LOG_* columns), without a second
    run: each step that holds a sample is taken again from its logged start (the same
    state, step and method give the same stages, so the same dense output: DOP853's
    7th-order polynomial, the collocation polynomial of a Radau IIA step (taken with the
    logged number of Newton iterations), or the cubic Hermite interpolant of a RODASP or
    RODAS4 step), and the samples are read from it exactly as :func:`integrate` reads
    them.  The result is bit-identical to
    a run with ``sample_tau`` given (tests/core/test_trajectory.py).  Fills ``samples``
    (len(sample_tau), len(y0)) in the output form (phi, ln theta, T[, s, s_o]); returns
    the number of rows filled.
    """
    n = y0.shape[0]
    c = vo if vo > 0.0 else 1.0
    lnc = math.log(c)
    K, F, R, J, y, ynew, f, fnew, tmp, ftmp, rbuf, Z, FZ, sc = _replay_workspace(n)
    n_tau = sample_tau.shape[0]
    i_tau = 0
    n_filled = 0
    # samples at tau = 0: the start (internal form: L = phi + ln theta, c T)
    while i_tau < n_tau and sample_tau[i_tau] <= 0.0:
        _start_row(samples, n_filled, y0, c)
        n_filled += 1
        i_tau += 1
    for k in range(n_log):
        if i_tau >= n_tau:
            break
        tau = steplog[k, LOG_TAU]
        h = steplog[k, LOG_H]
        tau_lim = tau + steplog[k, LOG_XLIM] * h
        if not sample_tau[i_tau] <= tau_lim:
            continue
        _replay_step(steplog, k, ba, kappa, eps, vo, c, lnc, K, F, R, J, y, ynew, f, fnew,
                     tmp, ftmp, rbuf, Z, FZ, sc)  # fmt: skip
        while i_tau < n_tau and sample_tau[i_tau] <= tau_lim:
            rk.dense_eval(F, y, (sample_tau[i_tau] - tau) / h, tmp)
            for j in range(n):
                samples[n_filled, j] = tmp[j]
            n_filled += 1
            i_tau += 1
    for i in range(n_filled):
        samples[i, 2] /= c
        samples[i, 1] -= samples[i, 0]
    return n_filled


@nb.njit(cache=True, nogil=True, error_model="numpy")
def replay_samples_T(steplog, n_log, y0, ba, kappa, eps, vo, sample_T_in, stopped, samples):
    """Samples at the times ``sample_T_in`` (T, sorted ascending) from the step log of a
    finished :func:`integrate` run from y0 (its rows [0, n_log)), without a second run:
    c T increases along the run, so each sample lies in the logged step whose c T range
    holds it; that step is taken again from its logged start (:func:`_replay_step`, as
    :func:`replay_samples`) and the sample's point in it is found by the same safeguarded
    Newton on the T component of its dense output (rk.dense_invert), with the same start
    and bracket, as :func:`integrate` does, so the samples are bit-identical to those of a
    run with ``sample_T`` given that takes the same steps (tests/core/test_replay_time.py).
    ``stopped``: the run ended at a stop located inside its last step (T_END, RUNAWAY,
    RETURNED, PEAK_PASSED, CONVERGED): samples up to 1e-12 past the stop's c T are the
    stop state, as in :func:`integrate`.

    A closed-form leg (fast slip, descent) advances c T between two logged steps without a
    step: a sample inside it is not in the log (a run with that sample integrates the
    leg instead), and the function returns -1; the caller then takes a second run.
    Otherwise fills ``samples`` (len(sample_T_in), len(y0)) in the output form (phi,
    ln theta, T[, s, s_o]) and returns the rows filled (fewer than asked where the run
    ended before the last time).
    """
    n = y0.shape[0]
    c = vo if vo > 0.0 else 1.0
    lnc = math.log(c)
    sample_T = sample_T_in * c
    K, F, R, J, y, ynew, f, fnew, tmp, ftmp, rbuf, Z, FZ, sc = _replay_workspace(n)
    n_T = sample_T.shape[0]
    i_T = 0
    n_filled = 0
    # samples at the start (internal form: L = phi + ln theta, c T)
    while i_T < n_T and sample_T[i_T] <= y0[2] * c:
        _start_row(samples, n_filled, y0, c)
        n_filled += 1
        i_T += 1
    for k in range(n_log):
        if i_T >= n_T:
            break
        # c T where the next logged step starts: the end of this one, unless a leg
        # follows it (then beyond it)
        T_next = steplog[k + 1, LOG_Y + 2] if k + 1 < n_log else math.inf
        if sample_T[i_T] > T_next:
            continue
        _replay_step(steplog, k, ba, kappa, eps, vo, c, lnc, K, F, R, J, y, ynew, f, fnew,
                     tmp, ftmp, rbuf, Z, FZ, sc)  # fmt: skip
        x_lim = steplog[k, LOG_XLIM]
        T_lim = ynew[2]
        if x_lim < 1.0:
            rk.dense_eval(F, y, x_lim, ftmp)
            T_lim = ftmp[2]
        # (integrate's inversion, step for step)
        i_T, n_filled = _samples_in_step_T(
            F, y, x_lim, T_lim, sample_T, i_T, samples, n_filled, tmp
        )
        if k + 1 == n_log and stopped and i_T < n_T:
            # samples at the stop time itself (lost to rounding of the located stop)
            if x_lim >= 1.0:
                for j in range(n):
                    ftmp[j] = ynew[j]
            while i_T < n_T and sample_T[i_T] <= ftmp[2] * (1.0 + 1e-12):
                for j in range(n):
                    samples[n_filled, j] = ftmp[j]
                n_filled += 1
                i_T += 1
        if i_T < n_T and sample_T[i_T] < T_next:
            return -1  # inside a closed-form leg after this step
    for i in range(n_filled):
        samples[i, 2] /= c
        samples[i, 1] -= samples[i, 0]
    return n_filled


def blowup_tail(phi: float, L: float, ba: float, kappa: float, eps: float) -> float:
    """Dimensionless time left to blow-up after the engine stopped at phi - ln c > phi_stop.

    For phi >> ln v_o, d phi/dT = e^phi r with r = -(b/a) G(L) - kappa > 0 on a runaway,
    so the remaining time is e^-phi / r, with L held at its value at the stop.  L is not
    fixed: dL/dphi = (r + G(L))/r is O(1), so this tail is only good to O(1) of itself
    (measured 0.1 of it at b/a = 8478, kappa = 2e5), and the caller must stop far enough
    above the start that the tail is negligible (rsfcore.trajectory stops PHI_STOP above
    both ln c and the start: tail < e^-40 of the blow-up time).
    """
    from .laws import G

    rate = -ba * G(L, eps) - kappa
    if rate <= 0.0 or phi > 700.0:
        return 0.0
    return math.exp(-phi) / rate


def run(
    y0: NDArray[np.float64],
    ba: float,
    kappa: float,
    eps: float,
    vo: float,
    opts: EngineOptions,
    sample_tau: NDArray[np.float64] = _EMPTY,
    sample_T: NDArray[np.float64] = _EMPTY,
    samples: NDArray[np.float64] = _EMPTY2,
    steplog: NDArray[np.float64] = _EMPTY_LOG,
) -> EngineResult:
    """:func:`integrate` with its result as an :class:`EngineResult` (status a :class:`Status`).

    Same arguments as :func:`integrate` (validated by the caller: rsfcore.trajectory,
    rsfcore.protocols, rsfcore.fit); ``opts`` is coerced to its declared field types
    (:meth:`EngineOptions.typed`).  The compiled kernel itself returns a plain tuple of
    ints and floats; this thin wrapper names it.
    """
    res = integrate(y0, ba, kappa, eps, vo, opts.typed(), sample_tau, sample_T, samples, steplog)
    # the kernel already returns Python ints and floats: only the status is wrapped
    return EngineResult(_STATUS_OF[res[0]], *res[1:])
