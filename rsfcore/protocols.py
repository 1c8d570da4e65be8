"""Laboratory loading protocols in physical (SI) units: load histories, velocity steps,
slide-hold-slide tests.

These are the forward models rate-and-state lab users run, here for the whole
aging-to-slip family of `eq: intermediate state evolution law` (eps in [0, 1]) and with
exact peaks.  The spring-slider obeys `eq: rate and state friction`, `eq: MC criterion`
and `eq: equation of motion2` (quasi-static, d tau/dt = k (V_o - V)); every segment is
integrated with the compiled DOP853 engine (rsfcore.engine.integrate) in the
dimensionless variables of `eq: characteristic scales`:

    psi = (tau - tau_*)/(a sigma),  phi = ln(V/V_*),  T = V_* t/Dc,  v_o = V_o/V_*.

Units: times t [s], velocities [m/s], slip and load-point displacement [m], state
theta [s], shear stress change tau - tau_* [Pa], friction f = f_* + a psi (-).

Peaks (never read off the output grid):

* peak slip rate of a segment: the engine's event-located maximum of phi (a root of
  d phi/dtau on the 7th-order dense output of every accepted step);
* peak friction of a segment: psi is maximal where d psi/dT = kappa (v_o - e^phi) changes
  sign from + to - (V crossing V_o upward); the engine locates that root on the dense
  output of every step in the same way.  Segment end points are candidates too (e.g.
  during a hold, V_o = 0, friction only decreases).

Accuracy delivered (default rtol 1e-10; tests/test_protocols.py): peaks agree with runs
at rtol 1e-12 and 10x the samples to 3e-12 in f (3e-10 in psi), 4e-10 relative in peak V
and 7e-11 s in peak times.  Reported peaks are >= every output sample up to the accuracy
of the dense output (in a random sweep of 300 histories the largest excess was 3.7x
``rel_accuracy``, in psi and ln V; it occurs only for flat maxima, V within ~1e-8 of V_o
on a slow approach to steady state).  The time of such a flat maximum is ill-conditioned
(the value is not); pronounced peaks have well-defined times.  V errors are friction
errors divided by a: judge accuracy in ln V, not only in f.

Runaway: when L = ln(V theta/Dc) exceeds L* (rsfcore.laws.L_star) slip is certain to
run away in finite time (the region is absorbing for every v_o >= 0); the engine then
integrates to phi - ln c = 40 (remaining time < e^-40 of the time scale).  The history
stops there and the result reports the segment index, the time of the certificate and
the blow-up time; no NaN or inf is ever returned.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from . import limits as lim
from .analytic import delta_tau
from .engine import EngineOptions, EngineResult, Status, blowup_tail, run
from .errors import IntegrationBudgetError
from .jsonsafe import finite_list, finite_or_none
from .laws import L_star
from .params import VO_MAX, ParameterError, PhysicalParams, check_range

__all__ = [
    "ProtocolResult",
    "SegmentSummary",
    "Runaway",
    "VelocityStepResult",
    "SlideHoldSlideResult",
    "IntegrationBudgetError",
    "load_history",
    "velocity_step",
    "slide_hold_slide",
    "steady_state_friction",
]

#: Blow-up threshold on phi - ln c (remaining time after it < e^-40 time scales).
PHI_STOP = 40.0
#: Budget of accepted + rejected steps per segment.
MAX_STEPS = 5_000_000

_EMPTY = np.empty(0)
_EMPTY2 = np.empty((0, 5))


def steady_state_friction(phys: PhysicalParams, V: float) -> float:
    """Steady-state friction f_ss = f_* + (a - b) ln(V/V_*) at slip rate V > 0 [m/s].

    (`eq: steady state`)"""
    V = check_range("V", V, 0.0, None, lo_open=True)
    return phys.f_star + (phys.a - phys.b) * math.log(V / phys.V_star)


# ---------------------------------------------------------------------------------------
# Result types
# ---------------------------------------------------------------------------------------
@dataclass
class Runaway:
    """Certified unstable slip (finite-time runaway of V).

    Attributes:
        segment: index of the segment in which L > L* was first reached.
        t_certificate_s: time [s] at which L = ln(V theta/Dc) was found above L* (from
            then on the runaway is certain, whatever the load point does); the end of the
            integration step in which L crossed L* (an upper bound within one step), or
            the segment end if the crossing was in that segment's last step.
        blowup_segment: segment in which V reached V_o e^40 (None if the history ended first).
        t_blowup_s: time [s] at which V -> infinity (time at V = c e^40 V_* plus the
            analytic tail, < e^-40 Dc/V_*), or None if the history ended before.
    """

    segment: int
    t_certificate_s: float
    blowup_segment: int | None
    t_blowup_s: float | None

    def to_dict(self) -> dict[str, Any]:
        return {
            "segment": self.segment,
            "t_certificate_s": finite_or_none(self.t_certificate_s),
            "blowup_segment": self.blowup_segment,
            "t_blowup_s": finite_or_none(self.t_blowup_s),
        }


@dataclass
class SegmentSummary:
    """One constant-V_o segment and its true peaks.

    Attributes:
        index: segment index (0-based).
        duration_s: requested duration [s].
        Vo_m_s: load-point velocity [m/s] (0 = hold).
        t_start_s, t_end_s: start and actual end time [s] (end < start + duration only
            after a runaway).
        status: "completed", "runaway" (L > L* inside or before this segment) or
            "not_run" (after a blow-up).
        peak_friction: maximum of f over the segment (-), with its time
            peak_friction_time_s [s] and peak_friction_where in {"start", "end",
            "interior"} ("interior": located at the V = V_o crossing).
        peak_V_m_s: maximum slip rate [m/s] over the segment with its time
            peak_V_time_s [s]; None when the segment runs away (V -> infinity).
    """

    index: int
    duration_s: float
    Vo_m_s: float
    t_start_s: float
    t_end_s: float | None = None
    status: str = "not_run"
    peak_friction: float | None = None
    peak_friction_time_s: float | None = None
    peak_friction_where: str | None = None
    peak_V_m_s: float | None = None
    peak_V_time_s: float | None = None
    n_steps: int = 0

    def to_dict(self) -> dict[str, Any]:
        return {
            "index": self.index,
            "duration_s": float(self.duration_s),
            "Vo_m_s": float(self.Vo_m_s),
            "t_start_s": finite_or_none(self.t_start_s),
            "t_end_s": finite_or_none(self.t_end_s),
            "status": self.status,
            "peak_friction": finite_or_none(self.peak_friction),
            "peak_friction_time_s": finite_or_none(self.peak_friction_time_s),
            "peak_friction_where": self.peak_friction_where,
            "peak_V_m_s": finite_or_none(self.peak_V_m_s),
            "peak_V_time_s": finite_or_none(self.peak_V_time_s),
            "n_steps": int(self.n_steps),
        }


@dataclass
class ProtocolResult:
    """Output of :func:`load_history` (all arrays share one time axis, SI units).

    Arrays (length n, first point = start of the history, junctions not repeated):
        t_s: time [s]; friction: f = f_* + a psi (-); tau_change_Pa: tau - tau_* [Pa]
        (tau_* = f_* sigma); V_m_s: slip rate [m/s]; theta_s: state theta [s];
        slip_m: slip since the start [m]; load_point_m: load-point displacement since
        the start [m] (= sum of V_o dt exactly, up to rtol); segment: segment index of
        each point; Vo_m_s: load-point velocity of that segment [m/s].  A junction between
        segments is sampled once and belongs to the segment that starts there, so
        ``Vo_m_s[j]`` is the load-point velocity on [t_j, t_j+1): the step-time convention
        of a fit record (rsfcore.fit.read_record reads this output unchanged).

    Samples come from the integrator's 7th-order dense output (same accuracy as the
    steps).  Per-segment true peaks are in ``segments``; ``runaway`` is set when slip
    became unstable.  ``rel_accuracy`` is the engine's a-posteriori indicator (sum of
    local error estimates, floored at rtol): the relative accuracy of psi, ln(V/V_*)
    and ln theta.
    """

    t_s: NDArray[np.float64]
    friction: NDArray[np.float64]
    tau_change_Pa: NDArray[np.float64]
    V_m_s: NDArray[np.float64]
    theta_s: NDArray[np.float64]
    slip_m: NDArray[np.float64]
    load_point_m: NDArray[np.float64]
    segment: NDArray[np.int64]
    Vo_m_s: NDArray[np.float64]
    segments: list[SegmentSummary]
    runaway: Runaway | None
    params: PhysicalParams
    rtol: float
    rel_accuracy: float
    psi: NDArray[np.float64] = field(repr=False, default_factory=lambda: np.empty(0))
    phi: NDArray[np.float64] = field(repr=False, default_factory=lambda: np.empty(0))
    ln_theta: NDArray[np.float64] = field(repr=False, default_factory=lambda: np.empty(0))

    @property
    def unstable(self) -> bool:
        return self.runaway is not None

    def to_dict(self) -> dict[str, Any]:
        """JSON-safe dict (no NaN/inf: non-finite values, which never occur, would be null)."""
        p = self.params
        return {
            "params": {
                "a": p.a,
                "b": p.b,
                "Dc_m": p.Dc,
                "sigma_Pa": p.sigma,
                "k_Pa_per_m": p.k,
                "V_star_m_s": p.V_star,
                "eps": p.eps,
                "f_star": p.f_star,
            },
            "rtol": self.rtol,
            "rel_accuracy": finite_or_none(self.rel_accuracy),
            "unstable": self.unstable,
            "runaway": None if self.runaway is None else self.runaway.to_dict(),
            "segments": [s.to_dict() for s in self.segments],
            "t_s": finite_list(self.t_s),
            "friction": finite_list(self.friction),
            "tau_change_Pa": finite_list(self.tau_change_Pa),
            "V_m_s": finite_list(self.V_m_s),
            "theta_s": finite_list(self.theta_s),
            "slip_m": finite_list(self.slip_m),
            "load_point_m": finite_list(self.load_point_m),
            "segment": [int(i) for i in self.segment],
            "Vo_m_s": finite_list(self.Vo_m_s),
        }


# ---------------------------------------------------------------------------------------
# Segment integration and peak location
# ---------------------------------------------------------------------------------------
@dataclass
class _Ctx:
    ba: float
    kappa: float
    eps: float
    vo: float
    rtol: float
    Ls: float


def _run(
    y0: NDArray[np.float64],
    c: _Ctx,
    t_end: float,
    sample_T: NDArray[np.float64] = _EMPTY,
    sample_tau: NDArray[np.float64] = _EMPTY,
) -> tuple[EngineResult, NDArray[np.float64]]:
    n = sample_T.shape[0] + sample_tau.shape[0]
    samples = np.empty((n, 5)) if n else _EMPTY2
    opts = EngineOptions(
        rtol=c.rtol,
        atol=c.rtol,
        Lstar=c.Ls,
        check_runaway=True,
        t_end=t_end,
        phi_stop=PHI_STOP,
        max_steps=MAX_STEPS,
    )
    y = np.ascontiguousarray(y0, dtype=np.float64)
    res = run(y, c.ba, c.kappa, c.eps, c.vo, opts, sample_tau, sample_T, samples)
    return res, samples[: res.n_filled]


# ---------------------------------------------------------------------------------------
# Public protocols
# ---------------------------------------------------------------------------------------
def load_history(
    phys: PhysicalParams,
    segments: Sequence[tuple[float, float]],
    *,
    n_points_per_segment: int = 200,
    rtol: float = 1e-10,
    start: str | tuple[float, float] = "steady",
) -> ProtocolResult:
    """Spring-slider response to a piecewise-constant load-point velocity history.

    Args:
        phys: physical parameters (a, b, Dc [m], sigma [Pa], k [Pa/m], V_* [m/s], eps,
            f_*).  ``phys.Vo`` is not used: the segments set the load-point velocity.
        segments: list of (duration_s > 0, Vo_m_s >= 0) pairs; Vo = 0 is a hold.
            Vo/V_* <= 1e300.
        n_points_per_segment: output samples per segment, evenly spaced in time
            (both ends included), [2, 100000].
        rtol: relative (and absolute) local tolerance of the DOP853 engine, [1e-13, 1e-3].
        start: "steady" (steady state at the first segment's V_o, or at V_* if that V_o
            is 0: V = V_o, theta = Dc/V_o, f = f_ss(V_o), `eq: steady state`) or an
            explicit (V_m_s > 0, theta_s > 0) with tau on the friction law
            `eq: rate and state friction`.

    Each segment is integrated by rsfcore.engine.integrate with v_o = V_o/V_*, chained
    through the full state (phi, ln theta, T, slip, load point; the last three are
    cumulative) and stopped at the segment's end time, which the engine locates on its
    dense output.  Returns a :class:`ProtocolResult` with arrays against t [s] and the
    true per-segment peaks (module docstring).  On a runaway (L > L*, unstable slip) the
    history stops at blow-up and ``result.runaway`` names the segment and the times.
    Raises ParameterError for invalid input and IntegrationBudgetError if a segment
    needs more than 5e6 steps.
    """
    if not isinstance(phys, PhysicalParams):
        raise ParameterError("phys", phys, "a PhysicalParams instance")
    rtol = lim.RTOL.check(rtol)
    npts = lim.N_POINTS.check_int(n_points_per_segment, "n_points_per_segment")
    segs: list[tuple[float, float]] = []
    try:
        seg_list = list(segments)
    except TypeError:
        raise ParameterError("segments", segments, "a list of (duration_s, Vo_m_s) pairs") from None
    if not seg_list:
        raise ParameterError("segments", segments, "a non-empty list of (duration_s, Vo_m_s) pairs")
    for i, sg in enumerate(seg_list):
        try:
            d, v = sg
        except (TypeError, ValueError):
            raise ParameterError(f"segments[{i}]", sg, "a (duration_s, Vo_m_s) pair") from None
        d = check_range(f"segments[{i}].duration_s", d, 0.0, None, lo_open=True)
        v = check_range(f"segments[{i}].Vo_m_s", v, 0.0, phys.V_star * VO_MAX)
        if d / phys.time_scale > 1e15:
            raise ParameterError(
                f"segments[{i}].duration_s", d, f"<= 1e15 Dc/V_* = {1e15 * phys.time_scale:g} s"
            )
        segs.append((d, v))

    p = phys
    ba = p.b / p.a
    kappa = p.k * p.Dc / (p.a * p.sigma)
    kc = ba - 1.0
    Ls = float(L_star(kappa, kc, p.eps))
    ts = p.time_scale

    # initial state
    if isinstance(start, str):
        if start != "steady":
            raise ParameterError("start", start, "'steady' or (V_m_s, theta_s)")
        v0 = segs[0][1] / p.V_star
        phi0 = math.log(v0) if v0 > 0.0 else 0.0
        lth0 = -phi0
    else:
        try:
            V0, th0 = start
        except (TypeError, ValueError):
            raise ParameterError("start", start, "'steady' or (V_m_s, theta_s)") from None
        V0 = check_range("start.V_m_s", V0, 0.0, None, lo_open=True)
        th0 = check_range("start.theta_s", th0, 0.0, None, lo_open=True)
        phi0 = math.log(V0 / p.V_star)
        lth0 = math.log(th0 / ts)
        if abs(phi0) > 690.0 or abs(lth0) > 690.0:
            raise ParameterError("start", start, "|ln(V/V_*)| and |ln(theta V_*/Dc)| <= 690")
    y = np.array([phi0, lth0, 0.0, 0.0, 0.0])

    summaries = [
        SegmentSummary(index=i, duration_s=d, Vo_m_s=v, t_start_s=math.nan)
        for i, (d, v) in enumerate(segs)
    ]
    chunks: list[NDArray[np.float64]] = []
    seg_idx: list[NDArray[np.int64]] = []
    runaway: Runaway | None = None
    err_total = 0.0
    T_now = 0.0
    for i, (dur, Vo) in enumerate(segs):
        sm = summaries[i]
        sm.t_start_s = T_now * ts
        vo = Vo / p.V_star
        ctx = _Ctx(ba, kappa, p.eps, vo, rtol, Ls)
        T_end = T_now + dur / ts
        y_start = y.copy()
        sT = np.linspace(T_now, T_end, npts)
        sT[0] = T_now
        sT[-1] = T_end
        res, samp = _run(y_start, ctx, T_end, sample_T=sT)
        status, T_cert = res.status, res.T_cert
        peak_phi, peak_T, peak_psi, peak_psi_T = (
            res.peak_phi,
            res.peak_T,
            res.peak_psi,
            res.peak_psi_T,
        )
        y_end = np.asarray(res.y_end).copy()
        sm.n_steps = res.n_steps + res.n_rejected
        err_total += res.err_sum
        # (the engine takes no event from beyond t_end, so a certificate is within the segment)
        ran_away = not math.isnan(T_cert)
        unfinished = status in (Status.BUDGET, Status.STEP_UNDERFLOW)
        if unfinished and not ran_away:
            raise IntegrationBudgetError(
                f"segment {i} (Vo={Vo:g} m/s, {dur:g} s) did not finish: engine status "
                f"{status.text} "
                f"after {sm.n_steps} steps at t={float(y_end[2]) * ts:g} s"
            )
        blew_up = status == Status.RUNAWAY or (ran_away and unfinished)
        if blew_up:
            # append the blow-up state so that the runaway shows in the output
            samp = (
                np.vstack([samp, y_end[None, :]])
                if samp.shape[0] == 0 or samp[-1, 2] < y_end[2]
                else samp
            )
        if i > 0 and samp.shape[0] > 0 and chunks and samp[0, 2] <= chunks[-1][-1, 2]:
            # the junction is sampled once, labelled with the new segment: Vo_m_s[j] is the
            # load-point velocity on [t_j, t_j+1) (the fit record's step-time convention)
            samp = samp[1:]
            if seg_idx[-1].shape[0]:
                seg_idx[-1][-1] = i
        chunks.append(samp)
        seg_idx.append(np.full(samp.shape[0], i, dtype=np.int64))

        # -- peaks: located by the engine on every step (start, interior maxima, end) ------
        sm.peak_friction = p.f_star + p.a * float(peak_psi)
        sm.peak_friction_time_s = float(peak_psi_T) * ts
        if float(peak_psi_T) <= T_now:
            sm.peak_friction_where = "start"
        elif float(peak_psi_T) >= float(y_end[2]):
            sm.peak_friction_where = "end"
        else:
            sm.peak_friction_where = "interior"
        # slip rate: the engine's event-located maximum (start, interior maxima, end)
        if ran_away:
            sm.peak_V_m_s = None
            sm.peak_V_time_s = None
        else:
            sm.peak_V_m_s = p.V_star * math.exp(float(peak_phi))
            sm.peak_V_time_s = float(peak_T) * ts

        if ran_away:
            sm.status = "runaway"
            if runaway is None:
                runaway = Runaway(
                    segment=i,
                    t_certificate_s=float(T_cert) * ts,
                    blowup_segment=None,
                    t_blowup_s=None,
                )
        else:
            sm.status = "completed"
        y = y_end
        T_now = float(y_end[2])
        sm.t_end_s = T_now * ts
        if blew_up:
            assert runaway is not None
            runaway.blowup_segment = i
            runaway.t_blowup_s = (
                T_now + blowup_tail(float(y_end[0]), float(y_end[0] + y_end[1]), ba, kappa, p.eps)
            ) * ts
            break

    s = np.vstack(chunks) if chunks else np.empty((0, 5))
    idx = np.concatenate(seg_idx) if seg_idx else np.empty(0, dtype=np.int64)
    phi, lth = s[:, 0], s[:, 1]
    psi = phi + ba * lth
    with np.errstate(over="ignore", under="ignore"):
        V = p.V_star * np.exp(np.minimum(phi, 709.0))
        theta = ts * np.exp(np.clip(lth, -745.0, 709.0))
    return ProtocolResult(
        t_s=s[:, 2] * ts,
        friction=p.f_star + p.a * psi,
        tau_change_Pa=p.a * p.sigma * psi,
        V_m_s=V,
        theta_s=theta,
        slip_m=s[:, 3] * p.Dc,
        load_point_m=s[:, 4] * p.Dc,
        segment=idx,
        Vo_m_s=np.array([segs[i][1] for i in idx], dtype=np.float64),
        segments=summaries,
        runaway=runaway,
        params=phys,
        rtol=rtol,
        rel_accuracy=max(rtol, err_total),
        psi=psi,
        phi=phi.copy(),
        ln_theta=lth.copy(),
    )


def _with_steady_sample(res: ProtocolResult, V1: float) -> ProtocolResult:
    """The velocity step's history with the steady state at V1 one sample interval before
    the step prepended (t_s = -dt, segment -1, Vo_m_s = V1): the output then starts in
    steady sliding at the old velocity and steps at t = 0, as a fit record does."""
    p = res.params
    dt = float(res.t_s[1] - res.t_s[0]) if res.t_s.shape[0] > 1 else p.Dc / V1
    phi = math.log(V1 / p.V_star)
    lth = -phi
    psi = phi + (p.b / p.a) * lth

    def pre(arr: NDArray[Any], value: float) -> NDArray[Any]:
        return np.concatenate((np.array([value], dtype=arr.dtype), arr))

    res.t_s = pre(res.t_s, -dt)
    res.friction = pre(res.friction, p.f_star + p.a * psi)
    res.tau_change_Pa = pre(res.tau_change_Pa, p.a * p.sigma * psi)
    res.V_m_s = pre(res.V_m_s, V1)
    res.theta_s = pre(res.theta_s, p.Dc / V1)
    res.slip_m = pre(res.slip_m, -V1 * dt)
    res.load_point_m = pre(res.load_point_m, -V1 * dt)
    res.segment = pre(res.segment, -1)
    res.Vo_m_s = pre(res.Vo_m_s, V1)
    res.psi = pre(res.psi, psi)
    res.phi = pre(res.phi, phi)
    res.ln_theta = pre(res.ln_theta, lth)
    return res


@dataclass
class VelocityStepResult:
    """Load-point velocity step V1 -> V2 from steady state at V1, with `eq: delta tau`.

    Attributes:
        protocol: the full :class:`ProtocolResult` (one segment at V2), its first sample
            the steady state at V1 one sample interval before the step (t_s < 0, segment
            -1, Vo_m_s = V1), so that the output is a fit record as written.
        V1_m_s, V2_m_s: velocities before and after the step [m/s].
        slip_since_step_m: slip since the step [m] at the output points (< 0 before it).
        delta_tau_over_b_sigma: simulated (tau - tau_ss(V2))/(b sigma) (-).
        analytic_over_b_sigma: `eq: delta tau` (infinitely stiff machine) at the same
            slip (rsfcore.analytic.delta_tau).
        slip_after_m: deviations are measured where slip >= slip_after_m (the elastic
            boundary layer of width ~ a sigma/k = Dc/kappa, where V climbs from V1 to V2,
            is excluded; default 20 a sigma/k).
        max_deviation: max |simulated - analytic| over slip >= slip_after_m (-), in
            units of b sigma.  It is O(1/kappa) (a finite machine lags the imposed
            velocity; measured in tests/test_protocols.py), not an integration error.
        kappa: k Dc/(a sigma).
    """

    protocol: ProtocolResult
    V1_m_s: float
    V2_m_s: float
    slip_since_step_m: NDArray[np.float64]
    delta_tau_over_b_sigma: NDArray[np.float64]
    analytic_over_b_sigma: NDArray[np.float64]
    slip_after_m: float
    max_deviation: float
    kappa: float

    def to_dict(self) -> dict[str, Any]:
        return {
            "V1_m_s": self.V1_m_s,
            "V2_m_s": self.V2_m_s,
            "kappa": self.kappa,
            "slip_after_m": self.slip_after_m,
            "max_deviation": finite_or_none(self.max_deviation),
            "slip_since_step_m": finite_list(self.slip_since_step_m),
            "delta_tau_over_b_sigma": finite_list(self.delta_tau_over_b_sigma),
            "analytic_over_b_sigma": finite_list(self.analytic_over_b_sigma),
            "protocol": self.protocol.to_dict(),
        }


def velocity_step(
    phys: PhysicalParams,
    V1: float,
    V2: float,
    *,
    slip_after_m: float | None = None,
    slip_total_m: float | None = None,
    n_points: int = 400,
    rtol: float = 1e-10,
) -> VelocityStepResult:
    """Load-point velocity step V1 -> V2 [m/s] from steady state at V1, against `eq: delta tau`.

    Args:
        phys: physical parameters; needs k > 0.
        V1, V2: load-point velocities before/after the step [m/s], > 0.
        slip_after_m: start of the comparison window [m] (default 20 a sigma/k).
        slip_total_m: load-point displacement after the step [m] (default 10 Dc;
            `eq: delta tau` has then decayed to e^-10 of its initial value).
        n_points: output samples (evenly spaced in time), [2, 100000].
        rtol: engine tolerance, [1e-13, 1e-3].

    `eq: delta tau` holds for an infinitely stiff machine (V = V2 right after the step);
    the simulated curve converges to it as kappa -> infinity with max deviation O(1/kappa)
    outside the elastic boundary layer.  A runaway (kappa < kappa_crit) is reported in
    ``protocol.runaway`` and the deviation is then computed on the part before blow-up.
    """
    V1 = check_range("V1", V1, 0.0, None, lo_open=True)
    V2 = check_range("V2", V2, 0.0, None, lo_open=True)
    if not phys.k > 0.0:
        raise ParameterError("k", phys.k, "> 0 for a velocity step (the spring transmits the step)")
    kappa = phys.k * phys.Dc / (phys.a * phys.sigma)
    layer = 20.0 * phys.a * phys.sigma / phys.k
    s_after = (
        layer if slip_after_m is None else check_range("slip_after_m", slip_after_m, 0.0, None)
    )
    s_tot = (
        10.0 * phys.Dc
        if slip_total_m is None
        else check_range("slip_total_m", slip_total_m, 0.0, None, lo_open=True)
    )
    res = _with_steady_sample(
        load_history(
            phys,
            [(s_tot / V2, V2)],
            n_points_per_segment=n_points,
            rtol=rtol,
            start=(V1, phys.Dc / V1),
        ),
        V1,
    )
    slip = res.slip_m
    psi_ss2 = (1.0 - phys.b / phys.a) * math.log(V2 / phys.V_star)
    sim = phys.a * (res.psi - psi_ss2) / phys.b
    ana = np.array(delta_tau(np.maximum(slip, 0.0) / phys.Dc, V2 / V1, phys.eps), dtype=np.float64)
    ana[0] = sim[0]  # before the step (t < 0): steady at V1 on either machine
    mask = slip >= s_after
    if res.runaway is not None:
        mask &= res.phi < math.log(max(V1, V2) / phys.V_star) + 5.0
    dev = float(np.max(np.abs(sim[mask] - ana[mask]))) if np.any(mask) else 0.0
    return VelocityStepResult(
        protocol=res,
        V1_m_s=V1,
        V2_m_s=V2,
        slip_since_step_m=slip,
        delta_tau_over_b_sigma=sim,
        analytic_over_b_sigma=np.asarray(ana, dtype=np.float64),
        slip_after_m=s_after,
        max_deviation=dev,
        kappa=kappa,
    )


@dataclass
class SlideHoldSlideResult:
    """Slide-hold-slide test: slide at V, hold (V_o = 0), reslide at V.

    Attributes:
        protocol: the full :class:`ProtocolResult` (segments 0 slide, 1 hold, 2 reslide).
        V_m_s, hold_s: sliding velocity [m/s] and hold time [s].
        f_ss: steady-state friction at V before the hold (-) (`eq: steady state`).
        peak_friction: true peak friction on reslide (-), at peak_time_s [s] (absolute)
            = reslide start + peak_time_after_reslide_s [s].
        healing_delta_f: peak_friction - f_ss (-), the lab "Delta mu" (None if the
            reslide ran away or was not reached).
        relaxation_delta_f: f_ss - friction at the end of the hold (-) ("Delta mu_c").
        peak_V_reslide_m_s: true peak slip rate on reslide [m/s].
        accuracy: relative ~rtol on psi at the peak (see module docstring).
    """

    protocol: ProtocolResult
    V_m_s: float
    hold_s: float
    f_ss: float
    peak_friction: float | None
    peak_time_s: float | None
    peak_time_after_reslide_s: float | None
    healing_delta_f: float | None
    relaxation_delta_f: float | None
    peak_V_reslide_m_s: float | None

    def to_dict(self) -> dict[str, Any]:
        return {
            "V_m_s": self.V_m_s,
            "hold_s": self.hold_s,
            "f_ss": self.f_ss,
            "peak_friction": finite_or_none(self.peak_friction),
            "peak_time_s": finite_or_none(self.peak_time_s),
            "peak_time_after_reslide_s": finite_or_none(self.peak_time_after_reslide_s),
            "healing_delta_f": finite_or_none(self.healing_delta_f),
            "relaxation_delta_f": finite_or_none(self.relaxation_delta_f),
            "peak_V_reslide_m_s": finite_or_none(self.peak_V_reslide_m_s),
            "protocol": self.protocol.to_dict(),
        }


def slide_hold_slide(
    phys: PhysicalParams,
    V: float,
    hold_s: float,
    *,
    slide_before_s: float,
    slide_after_s: float,
    n_points_per_segment: int = 200,
    rtol: float = 1e-10,
) -> SlideHoldSlideResult:
    """Slide at V [m/s] for slide_before_s [s] from steady state, hold (V_o = 0) for
    hold_s [s], reslide at V for slide_after_s [s]; report the healing Delta f.

    All durations > 0.  The peak friction on reslide is the true maximum (located at the
    V = V_o crossing, module docstring), relative accuracy ~rtol in psi.  Aging law
    (eps = 1): healing grows ~ b ln(hold) for long holds; slip law (eps -> 0): state only
    evolves with slip, so on a stiff machine healing stays small.
    """
    V = check_range("V", V, 0.0, None, lo_open=True)
    hold_s = check_range("hold_s", hold_s, 0.0, None, lo_open=True)
    res = load_history(
        phys,
        [(slide_before_s, V), (hold_s, 0.0), (slide_after_s, V)],
        n_points_per_segment=n_points_per_segment,
        rtol=rtol,
        start="steady",
    )
    f_ss = steady_state_friction(phys, V)
    rs = res.segments[2]
    hold = res.segments[1]
    relax = None
    if hold.status == "completed":
        # the hold's end is the junction sample, labelled with the reslide (segment 2)
        sel = np.flatnonzero(res.segment == 1)
        if sel.size:
            j = int(sel[-1]) + 1
            if not (j < res.segment.shape[0] and res.segment[j] == 2):
                j = int(sel[-1])
            relax = f_ss - float(res.friction[j])
    pk = rs.peak_friction if rs.status == "completed" else None
    return SlideHoldSlideResult(
        protocol=res,
        V_m_s=V,
        hold_s=hold_s,
        f_ss=f_ss,
        peak_friction=pk,
        peak_time_s=rs.peak_friction_time_s if pk is not None else None,
        peak_time_after_reslide_s=(rs.peak_friction_time_s - rs.t_start_s)
        if pk is not None and rs.peak_friction_time_s is not None
        else None,
        healing_delta_f=(pk - f_ss) if pk is not None else None,
        relaxation_delta_f=relax,
        peak_V_reslide_m_s=rs.peak_V_m_s if rs.status == "completed" else None,
    )
