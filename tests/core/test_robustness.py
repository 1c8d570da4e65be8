"""Numerical robustness on purpose: eps -> 0 and 1, b/a -> 1, large kappa, huge and tiny
perturbations, v_o = 0, starts hugging the separatrix, exponent overflow.

Every call must return an answer with a finite accuracy (no NaN, no hang, no exception
other than a clear ParameterError); outcomes are checked against what is known
independently (kind of the parameter point, closed forms).
"""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest

from rsfcore import Params, TrajectoryResult, classify, simulate
from rsfcore.analytic import U_kcrit, velocity_jump_crit_kcrit
from rsfcore.laws import L_star

EPS = [0.0, 1e-300, 1e-12, 0.5, 1.0]
BA = [1 + 1e-6, 1.01, 100.0]
KAPPA_RATIO = [0.0, 0.5, 1.0, 1.5, 1e4]
SIZES = [1e-12, 1.0, 700.0]


#: Step budget of the fast matrices: the largest load-point case outside the stiff corner
#: needs 2.0e5 steps (b/a = 1 + 1e-6, kappa = kappa_crit/2, dv = 1e-12; measured), so 4e5
#: leaves 2x; a case needing more raises BudgetExceeded instead of hitting a time limit.
MATRIX_BUDGET = 400_000


#: The matrices check robustness (no NaN, no hang, a certified outcome), and that
#: rel_accuracy is a number in (0, 1].  It is not asserted small: the second run at
#: rtol/10 (rsfcore.simulate) reports ill-conditioned times honestly in these corners,
#: where the sum of local errors claimed ~1e-9 (measured, rtol 1e-10 against 1e-13):
#: d = 1e-12 above L* (within the integration's resolution of the repelling line or the
#: separatrix: blow-up time 11620 vs 11438 at b/a = 1.01, kappa = kappa_crit/2), v_o = 0
#: peaks after a long creep (phi 2746 vs 2737 at b/a = 1.01, eps = 1e-12), and orbits at
#: eps = 1, d = 700 whose peak phi is ~1e19.  Accuracy as a bound is tested in
#: test_trajectory.py (delivered error <= rel_accuracy against tighter runs).
ACCURACY_MAX = 1.0
#: Since NUMERICS_VERSION 5 the claim is no longer capped at 1 (the cap hid a peak time 17x
#: off while claiming 1).  A claim above ACCURACY_MAX (no digit) must still be a bound:
#: _claim_bounds checks it against an rtol 1e-13 run.  One corner of the matrix has one: the
#: time of the plateau-like peak of the load-point jump dv = 700 at eps = 1, b/a = 100,
#: kappa/kappa_crit = 1e4 (phi stays within 1e-10 of its maximum 6.5526 from T = 5.2e-8 to
#: ~1e-6; at rtol 1e-10 the peak time is 1.31e-7, 1.5 off the 5.20e-8 of rtol 1e-12/1e-13).
#: NUMERICS_VERSION 5 claimed 1.2 .. 2.8 there, below the error at rtol 1e-9 (4.0), and this
#: test allowed claims up to 4; since 6 the claim is checked against the tightest run
#: (rsfcore.trajectory.NOISE_PROBE_TIGHTEN) and bounds it (7.6 at rtol 1e-10).


def _claim_bounds(r: TrajectoryResult, ref: TrajectoryResult, ctx: object) -> None:
    """Every time and peak of r within its rel_accuracy (+ the reference's own claim) of the
    reference run (relative to the reference's value)."""
    assert r.outcome == ref.outcome, ctx
    for name in ("blowup_time", "return_time", "peak_time", "peak_phi"):
        a, b = getattr(r, name), getattr(ref, name)
        if a is None or b is None or not (math.isfinite(a) and math.isfinite(b)):
            continue
        scale = max(abs(b), 1.0) if name == "peak_phi" else abs(b)
        assert abs(a - b) <= (r.rel_accuracy + ref.rel_accuracy) * scale, (name, a, b, ctx)


def _finite_or_none(*vals: float | None) -> bool:
    return all(v is None or math.isfinite(v) for v in vals)


@pytest.mark.parametrize("vo", [1.0, 0.0])
def test_matrix_velocity_jumps(vo: float) -> None:
    """Every (eps, b/a, kappa/kappa_crit, d), bounded by a step budget (MATRIX_BUDGET)."""
    for eps, ba, kr, d in itertools.product(EPS, BA, KAPPA_RATIO, SIZES):
        p = Params.from_ratio(ba, kr, eps, vo)
        r = classify(p, "velocity-jump", d, max_steps=MATRIX_BUDGET)
        ctx = (eps, ba, kr, d, vo, r.certificate)
        assert r.outcome in ("stable", "unstable"), ctx
        assert _finite_or_none(r.blowup_time, r.return_time, r.peak_time, r.rel_accuracy), ctx
        assert not math.isnan(r.peak_phi) and 0 < r.rel_accuracy <= ACCURACY_MAX, ctx
        Ls = L_star(p.kappa, p.kappa_crit, p.eps)
        if vo == 0.0 or kr == 0.0:
            # exact: dL/ds = g(L), L0 = d
            assert r.outcome == ("unstable" if d >= Ls else "stable"), ctx
        elif kr < 1.0:
            assert r.outcome == "unstable", ctx  # kind "zero"
        elif not math.isfinite(Ls):
            assert r.outcome == "stable", ctx  # kind "infinite"
        elif d > Ls:
            assert (
                r.outcome == "unstable"
                and r.certificate.endswith("Lstar")
                or r.certificate.startswith("U_")
            ), ctx
        if r.outcome == "unstable" and r.blowup_time is not None:
            assert r.blowup_time >= 0


def _check_load_point_jump(
    r: TrajectoryResult, eps: float, ba: float, kr: float, dv: float
) -> None:
    ctx = (eps, ba, kr, dv, r.certificate)
    assert r.outcome in ("stable", "unstable"), ctx
    assert _finite_or_none(r.blowup_time, r.return_time, r.peak_time), ctx
    assert not math.isnan(r.peak_phi) and 0 < r.rel_accuracy < math.inf, ctx
    if r.rel_accuracy > ACCURACY_MAX:
        p = Params.from_ratio(ba, kr, eps, 1.0)
        ref = classify(p, "load-point-jump", dv, rtol=1e-13, max_steps=MATRIX_BUDGET)
        _claim_bounds(r, ref, ctx)
    assert r.complete or r.certificate == "linear_instability", ctx  # (no blow-up time: by design)
    if 0.0 < kr < 1.0:
        assert r.outcome == "unstable", ctx  # kind "zero": every perturbation grows


def test_matrix_load_point_jumps() -> None:
    """Every (eps, b/a, kappa/kappa_crit, dv), with a step budget (not a time limit): a
    case that needed more would raise BudgetExceeded.  The stiff corner kappa = 1e6 (b/a =
    100, kappa/kappa_crit = 1e4) took DOP853 alone up to 2.1e6 steps (3-27 s per case, the
    test once hit pytest-timeout); with the switch to a Rosenbrock method (RODAS4, RODASP
    since NUMERICS_VERSION 8) it takes <= 1.1e3 steps."""
    for eps, ba, kr, dv in itertools.product(EPS, BA, KAPPA_RATIO, [1e-12, 1.0, 700.0]):
        p = Params.from_ratio(ba, kr, eps, 1.0)
        r = classify(p, "load-point-jump", dv, max_steps=MATRIX_BUDGET)
        _check_load_point_jump(r, eps, ba, kr, dv)


def test_negative_and_tiny_perturbations() -> None:
    p = Params(2, 2, 0.25, 1)
    for d in (-700.0, -5.0, -1e-12, 1e-12):
        r = classify(p, "velocity-jump", d)
        assert r.outcome == "stable" and _finite_or_none(r.return_time, r.peak_time)
    r = classify(p, "load-point-jump", -0.999999)
    assert r.outcome == "stable"


@pytest.mark.parametrize("eps", [0.0, 0.3, 0.9])
@pytest.mark.parametrize("ba", [1.25, 2.0, 10.0])
def test_starts_hugging_the_separatrix_kcrit(eps: float, ba: float) -> None:
    """kappa = kappa_crit: starts 1e-10 (relative) either side of the critical trajectory,
    classified by integration alone (the closed form is the independent check)."""
    dc = velocity_jump_crit_kcrit(ba, eps)
    p = Params(ba, ba - 1, eps, 1.0)
    lo = classify(p, "velocity-jump", dc * (1 - 1e-10), rtol=1e-13, method="integrate")
    hi = classify(p, "velocity-jump", dc * (1 + 1e-10), rtol=1e-13, method="integrate")
    assert (lo.outcome, hi.outcome) == ("stable", "unstable")
    assert (
        float(U_kcrit(lo.start[0], lo.start[1], ba, eps))
        < 0
        < float(U_kcrit(hi.start[0], hi.start[1], ba, eps))
    )


@pytest.mark.parametrize("eps", [0.0, 0.3, 0.9])
def test_starts_hugging_the_separatrix_vo0(eps: float) -> None:
    p = Params(2.0, 1.0, eps, 0.0)
    dc = float(L_star(1.0, 1.0, eps))
    for f, want in ((1 - 1e-10, "stable"), (1 + 1e-10, "unstable")):
        r = classify(p, "velocity-jump", dc * f, method="integrate")
        assert r.outcome == want


def test_huge_excursion_without_overflow() -> None:
    """Aging law, kappa = kappa_crit, d = 10: the closed orbit reaches phi ~ 22017 (e^phi
    is far beyond double range).  From `eq: trajectories 1-2` the peak satisfies
    e^L = b/a/(b/a - kappa), so for b/a = 2, kappa = 1:
    phi_peak = U/(b/a) - 2 + 2 ln 2 up to e^-phi terms, U/(b/a) = (1 + e^10) - 10."""
    expected = (1 + math.exp(10)) - 10 - 2 + 2 * math.log(2)
    for rtol in (1e-10, 1e-13):
        r = classify(Params(2.0, 1.0, 1.0, 1.0), "velocity-jump", 10.0, rtol=rtol)
        # Along an excursion to phi ~ 2e4 errors are amplified: the delivered error was
        # 5x the reported rel_accuracy at rtol 1e-10 and 2.6x at 1e-13; 10x covers it
        # (recorded as a known limit of the local-error estimate).
        assert r.outcome == "stable"
        assert r.peak_phi == pytest.approx(expected, rel=10 * r.rel_accuracy)
    assert r.return_time is not None and math.isfinite(r.return_time)


def test_eps_kappa_near_kappa_crit_huge_return() -> None:
    """eps*kappa -> kappa_crit: after a large excursion L goes very negative (G would
    overflow at eps L < -709 without the time change and clipping)."""
    for x in (0.999, 0.999999):
        p = Params(2.0, x / 0.5, 0.5, 1.0)
        for d in (5.0, 50.0):
            r = classify(p, "velocity-jump", d)
            assert _finite_or_none(r.return_time, r.blowup_time, r.peak_time)


def test_large_kappa_trajectory_is_finite() -> None:
    r = simulate(Params(2.0, 1e4, 0.5, 1.0), "velocity-jump", 3.0, n_points=50)
    assert r.outcome == "stable" and np.all(np.isfinite(r.trajectory.phi))


def test_vo_far_from_one() -> None:
    # scaling invariance phi -> phi + ln vo, psi -> psi + (1 - b/a) ln vo, T -> vo T
    a = classify(Params(2, 2, 0.25, 1.0), "velocity-jump", 2.5)
    for vo in (1e-200, 1e-5, 1e7, 1e250):
        b = classify(Params(2, 2, 0.25, vo), "velocity-jump", 2.5)
        assert b.outcome == a.outcome
        assert b.return_time * vo == pytest.approx(a.return_time, rel=1e-8)
        assert b.peak_phi - math.log(vo) == pytest.approx(a.peak_phi, rel=1e-8, abs=1e-8)


@pytest.mark.parametrize(
    "ba, kr, eps, pert",
    [
        (2.0, 2.0, 0.25, "velocity-jump"),
        (2.0, 1.5, 0.05, "load-point-jump"),
        (10.0, 3.0, 0.0, "velocity-jump"),
    ],
)
def test_starts_hugging_the_separatrix_general_kappa(
    ba: float, kr: float, eps: float, pert: str
) -> None:
    """kappa != kappa_crit: sizes 1e-10 (relative) either side of the separatrix method's
    critical size (computed at rtol 1e-13, delivered error <= ~1e-13), classified by
    integration at rtol 1e-13."""
    from rsfcore.critical import critical_perturbation

    p = Params.from_ratio(ba, kr, eps, 1.0)
    dc = critical_perturbation(p, pert, rtol=1e-13).critical_size
    lo = classify(p, pert, dc * (1 - 1e-10), rtol=1e-13)
    hi = classify(p, pert, dc * (1 + 1e-10), rtol=1e-13)
    assert (lo.outcome, hi.outcome) == ("stable", "unstable")
    # it really hugged the separatrix: the excursion is far larger than 1 % below critical
    assert lo.peak_phi > classify(p, pert, dc * 0.99, rtol=1e-13).peak_phi + 1.0
