"""Critical perturbation sizes: velocity jumps and load-point jumps (Ciardo & Viesca).

For given (b/a, kappa, eps, v_o) the critical size of a perturbation is the smallest size
that makes the slip rate run away in finite time.  Its *kind* is

* ``zero``: every perturbation, however small, grows (kappa < kappa_crit, v_o > 0; linear
  instability, Ruina 1983; or kappa = 0, v_o = 0);
* ``infinite``: no perturbation of that kind ever runs away (eps kappa >= kappa_crit,
  `eq: critical trajectory condition`; in particular the aging law at kappa = kappa_crit);
* ``finite``: sizes above ``critical_size`` run away, smaller ones return.

Sizes: a velocity jump of size d moves (phi, psi) by (d, d) from steady sliding (slip rate
times e^d at constant state); a load-point jump of size dv changes v_o to v_o (1 + dv).
Both critical sizes are independent of v_o > 0 (the system is invariant under
phi -> phi + ln v_o, psi -> psi + (1 - b/a) ln v_o, T -> v_o T).

Methods, in the order they are tried:

1. exact decisions: zero / infinite as above (O(1));
2. closed forms: v_o = 0 velocity jump, d_crit = L* (`eq: analytical phi crit`);
   kappa = kappa_crit velocity jump, the intersection of psi = phi with the critical
   trajectory U = 0 (`eq: limiting trajectory 1`, solved by safeguarded Newton to 1e-15;
   Lambert W at eps = 0); kappa = kappa_crit load-point jump, dv = 1/(kappa_crit (1 - eps));
3. otherwise (kappa > kappa_crit, x = eps kappa/kappa_crit < 1, v_o > 0) the *separatrix*
   method: with s_theta = ln theta = (psi - phi)/(b/a) and u = L = phi + s_theta, the
   trajectory that separates return from runaway is the one with L -> L* as phi -> +inf.
   Along it s_theta is monotone while L > 0, and it solves the scalar ODE

       du/ds_theta = kappa expm1(s_theta - u)/G(u) - kappa_crit,        (A)

   which is integrated from its asymptotic expansion far out (phi ~ L* - s_theta >= 30),

       u = L* - c1 z - c2 z^2 + O(z^3),   z = e^(s_theta - L*),
       c1 = kappa/(lambda + mu),  lambda = kappa_crit - eps kappa,  mu = kappa/kappa_crit,
       c2 = kappa_crit c1 [1 + (1 - x) c1/mu - ((1 - x)^2/mu^2 + eps (1 - x)/(2 mu)) c1^2 ... ]

   (see :func:`asymptotic_start`), towards increasing s_theta, where the separatrix
   attracts its neighbours, so errors decay.  The velocity-jump start points are the line
   s_theta = 0 (there u = L = d), so d_crit = u(0).  The load-point jump start, in the
   v_o = 1 frame, is (phi, psi) = (-l, (b/a - 1) l), l = ln(1 + dv): s_theta = l and L = 0.
   The separatrix reaches L = 0 where s_theta has its maximum (d s_theta/ds = G(L) = 0),
   so (A) is singular there; near it the roles are swapped and

       d s_theta/du = G(u) / (kappa expm1(s_theta - u) - kappa_crit G(u))      (B)

   is integrated down to u = 0 exactly; then dv = expm1(s_theta).  Both are run by a
   compiled scalar DOP853 (Dormand-Prince 8(5,3); rsfcore.separatrix drives the shared
   kernels of rsfcore.ode.rk, the same ones as the trajectory engine).  Where kappa is
   large the separatrix attracts its neighbours at a rate ~kappa and DOP853's steps
   become stability-limited: it then hands over to RODAS4 (L-stable Rosenbrock, analytic
   Jacobian), whose local tolerance is relaxed where the contraction still to come damps
   the errors; a velocity jump whose end lies near the turning point (slope
   |du/ds_theta| > 1 before s_theta = 0) is finished in (B), locating s_theta = 0
   (rsfcore.separatrix, docs/accuracy.md "The stiff corner").  The separatrix method finds
   the crossing nearest to infinity; whenever its assumptions fail (u reaches 0 before
   s_theta = 0 for a velocity jump, u stops decreasing before L = 0 for a load-point
   jump, step-size underflow) it reports failure and :func:`bisect_critical` is used.
4. :func:`bisect_critical`: bisection on the certified outcomes of
   :func:`rsfcore.trajectory.classify` (independent cross-check and fallback).

Delivered accuracy: DOP853's embedded local error estimate under-estimates the true local
error of this scalar problem by up to ~100x on long steps, so steps are capped (0.5 in
s_theta, 0.1 in u) and the internal tolerance is calibrated (0.02 rtol for velocity jumps,
0.1 rtol for load-point jumps): over 2 x 1000 random points (b/a in [1.01, 50],
kappa/kappa_crit in [1.01, 6], eps up to x = 0.99) and rtol in {1e-6, 1e-8, 1e-10} the
delivered error was at most 0.23 rtol (velocity) and 0.52 rtol (load point).
``rel_accuracy`` reports max(rtol, propagated a-posteriori estimate); the estimate
propagates local errors with the analytic Jacobian of (A)/(B).  Stiff runs whose estimate
misses rtol are repeated at 0.1x and 0.01x the tolerance; over the stiff corner the
estimate bounds the error measured against the explicit method (where it converges) and
bisection on classify (tests/core/test_critical_stiff.py).  The truncation of the
asymptotic start is ~1e-3 rtol (z0 chosen from rtol; measured to scale as z0^3).
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass, replace
from typing import Any

import numba as nb
import numpy as np

from . import limits as lim
from .asymptote import (
    ASYM_B_MAX,
    ASYM_DIRECT_LSTAR,
    ASYM_LSTAR_MIN,
    ASYM_R_MIN,
    load_jump_asymptote,
)
from .batchloop import stored_value
from .decision import (
    BOUNDARY_RTOL,
    FLAG_FALLBACK,
    FLAG_LOG_VALUE,
    FLAG_ON_KCRIT,
    FLAG_ON_X1,
    KIND_FINITE,
    KIND_INFINITE,
    KIND_ZERO,
    KINDS,
    M_ASYMPTOTE,
    M_BISECTION,
    M_CF_LJUMP_KCRIT,
    M_CF_VJUMP_KCRIT,
    M_CF_VO0,
    M_FINITE_BEYOND_RANGE,
    M_INF_NO_RUNAWAY,
    M_INF_NO_SPRING,
    M_SEPARATRIX,
    M_ZERO_LINEAR,
    M_ZERO_VO0,
    METHODS,
    PERTURBATIONS,
    Decision,
    DecisionFlag,
    Kind,
    Method,
    boundary_gaps,
    critical_point,
    first_decision,
    pert_code,
)
from .errors import UndecidedError
from .laws import L_star
from .limits import DEFAULT_RTOL, RTOL_RANGE
from .params import ParameterError, Params
from .separatrix import N_WORK, asym_coeffs, separatrix_critical, separatrix_explicit

__all__ = [
    "CriticalResult",
    "critical_perturbation",
    "accuracy_verdict",
    "bisect_critical",
    "load_jump_asymptote",
    "asymptotic_start",
    "separatrix_raw",
    "PERTURBATIONS",
    "KINDS",
    "METHODS",
    "BOUNDARY_RTOL",
    "DEFAULT_RTOL",
    "RTOL_RANGE",
    "ASYM_R_MIN",
    "ASYM_B_MAX",
    "ASYM_LSTAR_MIN",
    "ASYM_DIRECT_LSTAR",
    "Decision",
    "DecisionFlag",
    "Kind",
    "Method",
    "first_decision",
    "KIND_ZERO",
    "KIND_FINITE",
    "KIND_INFINITE",
    "FLAG_ON_X1",
    "FLAG_ON_KCRIT",
    "FLAG_FALLBACK",
    "FLAG_LOG_VALUE",
    "M_ZERO_LINEAR",
    "M_INF_NO_RUNAWAY",
    "M_INF_NO_SPRING",
    "M_CF_VJUMP_KCRIT",
    "M_CF_LJUMP_KCRIT",
    "M_CF_VO0",
    "M_SEPARATRIX",
    "M_BISECTION",
    "M_ZERO_VO0",
    "M_FINITE_BEYOND_RANGE",
    "M_ASYMPTOTE",
    "critical_batch",
]


def critical_batch(ba, kappa, eps, vo, pert, rtol, kind, value, rel_acc, method, flags):  # type: ignore[no-untyped-def]
    """Deprecated (to be removed): use :func:`rsfcore.batch.critical_points`, the one batch
    path (it also finishes the FLAG_FALLBACK points by bisection and checks its inputs).

    Compiled loop over 1-D arrays ba, kappa, eps (same length) at one v_o and one
    perturbation code: fills the outputs kind, value, rel_acc, method, flags per point
    (no input check) and returns the number of right-hand-side evaluations.  Points with
    FLAG_FALLBACK set in ``flags`` need :func:`bisect_critical`.
    """
    warnings.warn(
        "rsfcore.critical.critical_batch is deprecated and will be removed; use"
        " rsfcore.batch.critical_points",
        DeprecationWarning,
        stacklevel=2,
    )
    return int(
        _critical_batch_loop(ba, kappa, eps, vo, pert, rtol, kind, value, rel_acc, method, flags)
    )


@nb.njit(cache=True, nogil=True)
def _critical_batch_loop(ba, kappa, eps, vo, pert, rtol, kind, value, rel_acc, method, flags):
    """The loop of the deprecated :func:`critical_batch` (the kernel and stored value of
    rsfcore.batchloop)."""
    K = np.empty(N_WORK)
    n_total = 0
    for i in range(ba.shape[0]):
        k, v, a, m, fl, nr = critical_point(ba[i], kappa[i], eps[i], vo, pert, rtol, K)
        kind[i] = k
        value[i] = stored_value(v, fl)
        rel_acc[i] = a
        method[i] = m
        flags[i] = fl
        n_total += nr
    return n_total


def separatrix_raw(
    params: Params,
    perturbation: str = "velocity-jump",
    rtol: float = DEFAULT_RTOL,
    *,
    explicit: bool = False,
) -> tuple[int, float, float, int]:
    """Run the separatrix method alone: (status, value, absolute error estimate, n_rhs).

    Requires kappa > kappa_crit, eps kappa < kappa_crit and v_o > 0 (else ParameterError).
    status 0 = success; otherwise value is nan (see the S_* codes).  For tests and study.
    explicit=True: DOP853 alone at the strict tolerance (no RODAS4 switch, no relaxed
    tolerance), the method as it was before the stiff corner was handled; a reference
    where its step budget (2e5 steps) suffices, status 4 (budget) where not.
    """
    pert = pert_code(perturbation)
    if not (
        params.vo > 0.0
        and params.kappa >= params.kappa_crit
        and boundary_gaps(params.ba, params.kappa, params.eps)[1] > 0.0
    ):
        raise ParameterError(
            "params", params.as_dict(), "kappa >= kappa_crit, eps*kappa < kappa_crit, v_o > 0"
        )
    run = separatrix_explicit if explicit else separatrix_critical
    st, v, e, nr = run(params.kappa, params.kappa_crit, params.eps, pert, rtol, np.empty(N_WORK))
    return int(st), float(v), float(e), int(nr)


def asymptotic_start(params: Params, s0: float) -> dict[str, float]:
    """The separatrix's asymptotic start at s_theta = s0: {'L_star', 'c1', 'c2', 'z', 'u', 'phi'}.

    u = L* - c1 z - c2 z^2 with z = e^(s0 - L*); the neglected terms are O((c1 z)^3).
    """
    Ls, c1, c2 = asym_coeffs(params.kappa, params.kappa_crit, params.eps)
    z = math.exp(s0 - Ls)
    u = Ls - z * (c1 + c2 * z)
    return {
        "L_star": float(Ls),
        "c1": float(c1),
        "c2": float(c2),
        "z": z,
        "u": float(u),
        "phi": float(u - s0),
    }


# ----------------------------------------------------------------------------------------
@dataclass(frozen=True)
class CriticalResult:
    """Critical perturbation of one kind at one parameter point.

    Attributes:
        kind: "zero" | "finite" | "infinite".
        critical_size: d_crit (velocity jump, in ln V units: the jump multiplies V by e^d)
            or (dv/v_o)_crit (load-point jump); 0.0 for "zero", None for "infinite".
        rel_accuracy: estimated relative accuracy of critical_size (0 for exact decisions).
        method: how it was obtained (one of METHODS).
        perturbation: "velocity-jump" | "load-point-jump".
        params: the parameters.
        on_boundary: the point lies on x = eps kappa/kappa_crit = 1 or kappa = kappa_crit
            up to rounding (BOUNDARY_RTOL), where the kind may flip.
        log_critical_size: d (velocity jump) or l = ln(1 + dv) (load-point jump); finite for
            every "finite" and "zero" result, also where dv exceeds the double range
            (critical_size is then inf; classify(..., log_size=l) checks it); None for
            "infinite", and for a finite size beyond reach (accuracy_met False, see reason:
            load-point jumps at b/a -> 1 with kappa/kappa_crit >~ 3e4).
        accuracy_met: rel_accuracy <= the requested rtol (always True for exact decisions).
        reason: why the requested rtol is not met ("" when it is).
    """

    kind: str
    critical_size: float | None
    rel_accuracy: float
    method: str
    perturbation: str
    params: Params
    on_boundary: bool = False
    n_rhs: int = 0
    log_critical_size: float | None = None
    accuracy_met: bool = True
    reason: str = ""

    def __post_init__(self) -> None:
        if self.log_critical_size is None and self.critical_size is not None:
            cs = float(self.critical_size)
            lg = cs if self.perturbation == PERTURBATIONS[0] else math.log1p(cs)
            object.__setattr__(self, "log_critical_size", lg)

    def to_dict(self) -> dict[str, Any]:
        """JSON-safe dict (no inf/nan: a size beyond the double range is null, its log kept)."""
        cs = self.critical_size
        return {
            "kind": self.kind,
            "critical_size": cs if cs is None or math.isfinite(cs) else None,
            "log_critical_size": self.log_critical_size,
            "rel_accuracy": float(self.rel_accuracy),
            "accuracy_met": bool(self.accuracy_met),
            "reason": self.reason,
            "method": self.method,
            "perturbation": self.perturbation,
            "params": self.params.as_dict(),
            "on_boundary": bool(self.on_boundary),
        }


def accuracy_verdict(kind: str, method: str, rel_accuracy: float, rtol: float) -> tuple[bool, str]:
    """(accuracy_met, reason) of a critical size against the requested ``rtol``.

    Shared by :func:`critical_perturbation` and the batch paths, so both say the same.
    Exact decisions (kind zero/infinite) always meet it; otherwise the reason names what
    limits the accuracy (the closed form's conditioning, the separatrix integration's
    error estimate, or the bisection bracket).
    """
    if kind != "finite" or rel_accuracy <= rtol:
        return True, ""
    how = method.split(":")[0]
    why = {
        "closed form": "the closed form is ill-conditioned here: rounding in double precision"
        " limits it to",
        "separatrix": "the separatrix integration's propagated error estimate (with, for a"
        " load-point jump, the rounding of l = ln(1 + dv) over its steps) is",
        "bisection on certified classify() outcomes": "the bisection bracket (classify could"
        " not decide closer to the separatrix) is",
        "asymptote": "the asymptote's error bound (its third order in 1/r and b, plus the"
        " rounding of l = ln(1 + dv)) is",
    }.get(how, f"{how} reaches")
    return False, f"{why} {rel_accuracy:.2g} relative, above the requested rtol {rtol:.2g}"


def _with_accuracy(res: CriticalResult, rtol: float) -> CriticalResult:
    """Set accuracy_met / reason of a result against the requested rtol (a result that
    already says why it cannot meet any, e.g. a size beyond reach, keeps its reason)."""
    if not res.accuracy_met and res.reason:
        return res
    met, reason = accuracy_verdict(res.kind, res.method, res.rel_accuracy, rtol)
    return replace(res, accuracy_met=met, reason=reason)


def critical_perturbation(
    params: Params, perturbation: str = "velocity-jump", *, rtol: float = DEFAULT_RTOL
) -> CriticalResult:
    """Critical size of a velocity jump or load-point jump (module docstring for methods).

    Args:
        params: Params(ba, kappa, eps, vo); any ba in (1, 1e6], kappa >= 0, eps in [0, 1],
            vo = 0 or > 0.
        perturbation: "velocity-jump" (size d: (phi, psi) += (d, d)) or "load-point-jump"
            (size dv: v_o -> v_o (1 + dv); needs vo > 0, else ParameterError).
        rtol: requested relative accuracy of a numerical result, [1e-13, 1e-3].

    Returns a CriticalResult.  Never returns nan: if the separatrix method cannot be
    applied, bisection on classify() is used (slower, same accuracy target).
    """
    if (
        isinstance(params, Params)
        and perturbation == PERTURBATIONS[1]
        and params.vo > 0.0
        and float(L_star(params.kappa, params.kappa_crit, params.eps)) >= ASYM_DIRECT_LSTAR
    ):
        # beyond the separatrix integration's budget for certain: skip its failed attempt
        # (0.1-0.3 s) and answer by the asymptote
        x = params.eps * params.kappa / params.kappa_crit
        res = _asymptote_result(params, perturbation, abs(x - 1.0) <= BOUNDARY_RTOL)
        if res is not None:
            return _with_accuracy(res, lim.RTOL.check(rtol))
    dec = first_decision(params, perturbation, rtol)
    if dec.flags & DecisionFlag.FALLBACK:
        res = bisect_critical(params, perturbation, rtol=dec.rtol)
        return replace(res, on_boundary=dec.on_boundary)
    log = dec.value if dec.flags & DecisionFlag.LOG_VALUE else None
    res = _make_result(dec, perturbation, params, log)
    return _with_accuracy(res, dec.rtol)


def _make_result(
    dec: Decision, perturbation: str, params: Params, log: float | None = None
) -> CriticalResult:
    """The CriticalResult of a decision; log: l = ln(1 + dv) when dv is beyond the double
    range (size inf, kind finite)."""
    size: float | None
    if dec.kind == Kind.INFINITE:
        size = None
    elif dec.kind == Kind.ZERO:
        size = 0.0
    else:
        size = math.inf if log is not None else dec.value
    return CriticalResult(
        dec.kind.text,
        size,
        dec.rel_accuracy,
        dec.method.text,
        perturbation,
        params,
        dec.on_boundary,
        dec.n_rhs,
        log,
    )


def _asymptote_result(params: Params, perturbation: str, on_b: bool) -> CriticalResult | None:
    """The load-point critical size by :func:`load_jump_asymptote`, or None outside it."""
    asym = load_jump_asymptote(params)
    if asym is None:
        return None
    lg, err = asym
    size = math.expm1(lg) if lg < 709.0 else math.inf
    return CriticalResult(
        "finite", size, err, METHODS[M_ASYMPTOTE], perturbation, params, on_b, 0, lg
    )


def bisect_critical(
    params: Params,
    perturbation: str = "velocity-jump",
    rtol: float = DEFAULT_RTOL,
    *,
    integrate_only: bool = False,
) -> CriticalResult:
    """Critical size by bisection on certified :func:`rsfcore.trajectory.classify` outcomes.

    The exact decisions (zero: kappa < kappa_crit with v_o > 0; infinite: eps kappa >=
    kappa_crit) are taken as in :func:`critical_perturbation`; every finite value, closed
    forms included, is recomputed by bisection.  Velocity jump: bracket [0, L*] (L >= L* is
    absorbing).  Load-point jump: bracket grown by factors of 4 in dv until a runaway, then
    bisection in ln(1 + dv).  Stops when the bracket is below rtol relative; rel_accuracy
    is the final bracket width relative to the result (plus the classify tolerance).
    If classify cannot decide a midpoint (UndecidedError: step underflow within ~1e-10
    of the separatrix when excursions reach phi ~ 1e7), the bisection stops there and
    rel_accuracy reports the bracket reached.

    integrate_only=True asks classify to certify by integration alone (ignoring its
    closed-form shortcuts at kappa = kappa_crit and v_o = 0), to check closed forms.
    Otherwise a load-point jump whose size lies beyond both methods (kappa/kappa_crit >=
    ASYM_R_MIN, L* >= ASYM_LSTAR_MIN) is answered by :func:`load_jump_asymptote`.

    With v_o > 0 the classifications run at v_o = 1: critical sizes are v_o-invariant
    (module docstring), so the answer is too, exactly (issue 13 measured 1.3 % between
    v_o = 1 and 1e-12 at b/a = kappa = 1e6 when each v_o was integrated).
    """
    res = _bisect_critical(params, perturbation, rtol, integrate_only)
    return _with_accuracy(res, lim.RTOL.check(rtol))


def _bisect_critical(
    params: Params, perturbation: str, rtol: float, integrate_only: bool
) -> CriticalResult:
    from .trajectory import classify

    dec = first_decision(params, perturbation, rtol)
    rtol, on_b = dec.rtol, dec.on_boundary
    p_run = params.with_(vo=1.0) if params.vo > 0.0 else params
    if dec.kind != Kind.FINITE:
        return _make_result(dec._replace(n_rhs=0), perturbation, params)
    if pert_code(perturbation) == 1 and not integrate_only:
        res = _asymptote_result(params, perturbation, on_b)
        if res is not None:
            return res

    crtol = max(1e-13, min(1e-10, rtol))
    kw: dict[str, Any] = {"method": "integrate"} if integrate_only else {}
    n_rhs = 0

    def unstable(size: float) -> bool:
        nonlocal n_rhs
        r = classify(
            p_run,
            perturbation,
            size,
            rtol=crtol,
            check_accuracy=False,
            separatrix_side=False,  # independent of the separatrix method
            **kw,
        )
        n_rhs += r.n_rhs
        return r.outcome == "unstable"

    if pert_code(perturbation) == 0:
        from .trajectory import SIZE_MAX

        Ls = float(L_star(params.kappa, params.kappa_crit, params.eps))
        lo, hi = 0.0, min(Ls * (1.0 + 1e-12) + 1e-300, SIZE_MAX)
        if not unstable(hi):
            raise UndecidedError(
                f"velocity jump of size {hi} (L* = {Ls}) not classified unstable; classify accepts"
                f" |d| <= {SIZE_MAX:g} (params {params.as_dict()})"
            )
        while hi - lo > rtol * 0.25 * hi:
            mid = 0.5 * (lo + hi)
            try:
                u = unstable(mid)
            except UndecidedError:
                # within ~1e-10 of the separatrix with excursions to phi ~ 1e7 and more
                # the engine's step can underflow: stop with the bracket reached so far
                break
            if u:
                hi = mid
            else:
                lo = mid
        value = 0.5 * (lo + hi)
        width = (hi - lo) / value
    else:
        # bisection on l = ln(1 + dv)
        l_lo, l_hi = 0.0, math.log(2.0)
        l_max = math.log1p(1e300)  # the largest load point classify takes, at v_o = 1
        while not unstable(math.expm1(l_hi)):
            l_lo = l_hi
            if l_hi >= l_max:
                Ls = float(L_star(params.kappa, params.kappa_crit, params.eps))
                if math.isfinite(Ls):
                    # L* finite: a large enough jump (t = l far above the separatrix's
                    # turning point) runs away, so the size is finite; it is beyond both
                    # methods here (b/a -> 1 with kappa/kappa_crit >~ 3e4, where
                    # ln(1 + dv_crit) ~ L* - ln(kappa_crit), measured to ~1/(kappa/kappa_crit)
                    # at eps = 0 where the separatrix integration reaches)
                    guess = Ls - math.log(params.kappa_crit)
                    return CriticalResult(
                        "finite",
                        None,
                        1.0,
                        METHODS[M_BISECTION] + " (beyond reach)",
                        perturbation,
                        params,
                        on_b,
                        n_rhs,
                        None,
                        False,
                        "the critical size is finite (L* is finite) but beyond what rsfcore"
                        f" computes: ln(1 + dv_crit) > {l_max:.4g} (the separatrix"
                        " integration ran out of budget); its asymptote suggests"
                        f" ln(1 + dv_crit) ~ L* - ln(kappa_crit) = {guess:.6g} (unverified)",
                    )
                return CriticalResult(
                    "infinite",
                    None,
                    0.0,
                    METHODS[M_BISECTION] + " (no runaway up to the largest v_o)",
                    perturbation,
                    params,
                    on_b,
                    n_rhs,
                )
            l_hi = min(l_hi + math.log(4.0), l_max)
        while math.expm1(l_hi) - math.expm1(l_lo) > rtol * 0.25 * math.expm1(l_hi):
            mid = 0.5 * (l_lo + l_hi)
            try:
                u = unstable(math.expm1(mid))
            except UndecidedError:
                break
            if u:
                l_hi = mid
            else:
                l_lo = mid
        lo, hi = math.expm1(l_lo), math.expm1(l_hi)
        value = 0.5 * (lo + hi)
        width = (hi - lo) / value
    return CriticalResult(
        "finite", value, max(width, crtol), METHODS[M_BISECTION], perturbation, params, on_b, n_rhs
    )
