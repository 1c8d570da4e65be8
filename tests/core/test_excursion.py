"""The fast-slip leg in closed form (rsfcore.excursion) against independent references.

* (leg 3) J(L) - J(L_in) against 50-digit mpmath quadrature of dL/(r + G(L));
* (leg 1) the peak of phi against 50-digit quadrature of d phi/dL = (kappa + (b/a) G) /
  (kappa + kc G) itself (not through J);
* the engine with legs against the engine stepping through them (method="integrate") where
  stepping is accurate (peaks phi ~ 1e2 .. 1e6), each within the sum of the two claimed
  accuracies;
* the b/a -> 1 case of the stress benchmark that stepping could not resolve.
"""

from __future__ import annotations

import functools
import math
import random

import mpmath as mp
import numpy as np
import pytest

import rsfcore
from rsfcore import Params
from rsfcore.excursion import LEG_MIN_RISE, leg, leg_dJ
from rsfcore.laws import G, L_star
from rsfcore.trajectory import DECIDED_OUTCOME_BUDGET

U = 2.220446049250313e-16


def _G_mp(L: mp.mpf, eps: float) -> mp.mpf:
    e = mp.mpf(eps)
    return -L if eps == 0.0 else mp.expm1(-e * L) / e


def _Lstar_mp(r: float, eps: float) -> mp.mpf:
    x = mp.mpf(eps) * mp.mpf(r)
    if x >= 1:
        return mp.inf
    return mp.mpf(r) if eps == 0.0 else -mp.log1p(-x) / mp.mpf(eps)


def _cases(seed: int, n: int) -> list[tuple[float, float, float, float]]:
    """(r, eps, L_in, L) with L < L_in < L* and the exponent of G unclipped."""
    rng = random.Random(seed)
    out = []
    while len(out) < n:
        r = 10 ** rng.uniform(-2, 1.5)
        eps = rng.choice([0.0, 1.0, rng.random(), 10 ** rng.uniform(-12, -1), 1.0 / r])
        if eps > 1.0:
            continue
        ls = _Lstar_mp(r, eps)
        L_in = (
            float(min(ls - mp.mpf(10) ** rng.uniform(-3, 1), 20))
            if ls != mp.inf
            else rng.uniform(-5, 20)
        )
        L = L_in - 10 ** rng.uniform(-3, 1.5)
        if eps * L < -600 or not r + G(L_in, eps) > 0:
            continue
        out.append((r, eps, L_in, L))
    return out


@pytest.mark.parametrize("case", _cases(3, 120))
def test_leg_dJ_against_50_digit_quadrature(case: tuple[float, float, float, float]) -> None:
    r, eps, L_in, L = case
    mp.mp.dps = 50
    rg_in = r + G(L_in, eps)
    got = leg_dJ(L, L_in, r, eps, rg_in)
    ref = mp.quad(lambda t: 1 / (mp.mpf(r) + _G_mp(t, eps)), [mp.mpf(L_in), mp.mpf(L)])
    # the closed form is exact; its rounding is a few ulp times the conditioning of
    # r + G(L_in) (r + G -> 0 at L*, and L_in itself rounded): measured <= 1.3 u cond over
    # 300 random cases (eps = 0, 1, tiny, 1/r where q = 0, L_in up to 1e-3 from L*); 8x margin
    cond = 1.0 + (r + abs(G(L_in, eps)) + abs(L_in) * math.exp(-eps * L_in)) / rg_in
    assert abs((got - ref) / ref) <= 10.0 * U * cond


@pytest.mark.parametrize("seed", range(12))
def test_leg_peak_against_quadrature_of_dphi_dL(seed: int) -> None:
    rng = random.Random(100 + seed)
    kc = 10 ** rng.uniform(-12, -3)
    r = 10 ** rng.uniform(0, 1.2)
    eps = rng.choice([0.0, 1.0, rng.random()])
    ba = 1.0 + kc
    kc = ba - 1.0  # the kappa_crit the engine uses (1 + kc rounds kc to ~1e-16/kc)
    kappa = r * kc
    ls = float(L_star(kappa, kc, eps))
    L_in = min(ls - 0.3, 3.0) if math.isfinite(ls) else 3.0
    phi_in = 60.0
    res = leg(phi_in, L_in - phi_in, ba, kappa, eps)
    assert res.ok
    mp.mp.dps = 50
    L_pk = mp.findroot(lambda t: kappa + ba * _G_mp(t, eps), mp.mpf(float(L_star(kappa, ba, eps))))

    def dphi(t: mp.mpf) -> mp.mpf:
        g = _G_mp(t, eps)
        return (kappa + ba * g) / (kappa + kc * g)

    rise = mp.quad(dphi, [mp.mpf(L_in), L_pk])
    # phi_peak - phi_in ~ 1/kc (1e3 .. 1e12): the closed form gives it to a few ulp of
    # (b/a)|dL| / kc (the O(1) difference (leg 1) divided by kc); 64 ulp of margin
    tol = 64.0 * U * (abs(L_in - float(L_pk)) + 1.0) / kc
    assert abs(res.phi_peak - phi_in - float(rise)) <= tol
    assert float(rise) > LEG_MIN_RISE
    # the exit is where phi is back at phi_in: the quadrature from L_in to L_exit is ~0
    back = mp.quad(dphi, [mp.mpf(L_in), L_pk, mp.mpf(res.L_exit)])
    assert abs(float(back)) <= tol


def _leg_cases() -> list[tuple[Params, str, float]]:
    rng = random.Random(5)
    out: list[tuple[Params, str, float]] = []
    while len(out) < 10:
        kc = 10 ** rng.uniform(-6, -3)
        r = 10 ** rng.uniform(0.1, 1.0)
        p = Params(1.0 + kc, r * kc, rng.choice([0.0, 1.0, rng.random()]), 10 ** rng.uniform(-2, 2))
        kind = rng.choice(["velocity-jump", "load-point-jump"])
        c = rsfcore.critical_perturbation(p, kind)
        if c.kind != "finite" or not c.log_critical_size:
            continue
        out.append((p, kind, c.log_critical_size * rng.choice([0.5, 0.9, 0.99])))
    # v_o = 0 (the load term vanishes; L is monotone and the run stops past the peak)
    out.append((Params(1.0 + 1e-5, 2e-5, 0.3, 0.0), "velocity-jump", 3.0))
    out.append((Params(1.0 + 1e-4, 5e-4, 0.0, 0.0), "velocity-jump", 4.0))  # L* = 5
    return out


@pytest.mark.parametrize("case", _leg_cases())
def test_engine_legs_agree_with_stepping(case: tuple[Params, str, float]) -> None:
    """Peaks phi 1e2 .. 1e6: stepping is accurate there (its L blur ~ u |phi| <= 1e-10)."""
    p, kind, lg = case
    a = rsfcore.classify(p, kind, log_size=lg, rtol=1e-11)
    b = rsfcore.classify(p, kind, log_size=lg, rtol=1e-11, method="integrate")
    assert a.outcome == b.outcome == "stable"
    assert a.n_steps <= b.n_steps
    for name in ("return_time", "peak_time", "peak_phi"):
        x, y = getattr(a, name), getattr(b, name)
        if x is None and y is None:
            continue
        assert x is not None and y is not None
        # each run's rel_accuracy is a checked bound (second run at rtol/10): the two may
        # differ by at most the sum
        assert abs(x - y) <= (a.rel_accuracy + b.rel_accuracy) * max(abs(y), 1.0), name


def test_leg_resolves_what_stepping_cannot() -> None:
    """bench_stress: b/a = 1 + 3.5e-12, kappa/kappa_crit = 3.9, d = d_crit/2.  Stepping took
    290,938 steps (1.2 s) and returned at T = 0.01377 after a peak phi = 4.18e11 with
    rel_accuracy 1 (its two runs disagreed: at phi ~ 4e11 L = phi + ln theta is blurred by
    ~1e-4).  With the leg: ~50 steps, and the answer is the same at every rtol."""
    p = Params(1.0000000000034857, 1.3682027670983518e-11, 0.11733657384331686, 16.050232785451595)
    res = [
        rsfcore.classify(p, "velocity-jump", log_size=2.6302518027188104, rtol=rt)
        for rt in (1e-8, 1e-10, 1e-13)
    ]
    ref = res[-1]
    assert all(r.outcome == "stable" and r.certificate == "returned_to_steady_state" for r in res)
    assert res[1].n_steps < 1000
    for r in res[:2]:
        for name in ("return_time", "peak_time", "peak_phi"):
            x, y = getattr(r, name), getattr(ref, name)
            assert abs(x - y) <= r.rel_accuracy * abs(y), name
    assert res[1].rel_accuracy < 1e-6
    assert 3e11 < ref.peak_phi < 5e11
    # its trajectory in tau ends at the return too: the sample grid comes from a run in
    # the trajectory's own frame (the classification's tau_end, from the v_o = 1 frame,
    # entered the leg elsewhere and cut the samples off at the peak, T = 0.00199)
    for sampling in ("tau", "time"):
        tr = rsfcore.simulate(
            p, "velocity-jump", log_size=2.6302518027188104, n_points=200, sampling=sampling
        )
        assert tr.trajectory is not None and tr.return_time is not None
        assert tr.trajectory.T[-1] == pytest.approx(tr.return_time, rel=1e-8)


@pytest.mark.parametrize("sampling", ["tau", "time"])
def test_trajectory_samples_skip_the_leg(sampling: str) -> None:
    """A leg advances neither T nor tau: the samples step from its entry to its exit (equal
    phi, ~ln v_o + 50), the run takes the leg's few steps, and the trajectory ends where
    the classification says; samples on either side agree with stepping (method
    "integrate") at the same T, where stepping is accurate (peak ~1e5)."""
    p = Params(1.0 + 1e-5, 3e-5, 0.0, 1.0)
    c = rsfcore.critical_perturbation(p, "velocity-jump")
    d = 0.9 * c.critical_size
    cl = rsfcore.classify(p, "velocity-jump", d, rtol=1e-11)
    tr = rsfcore.simulate(p, "velocity-jump", d, rtol=1e-11, n_points=400, sampling=sampling)
    assert cl.peak_phi > 1e4 and tr.peak_phi == cl.peak_phi  # a leg was taken
    assert tr.trajectory is not None and len(tr.trajectory.T) == 400
    T, phi = tr.trajectory.T, tr.trajectory.phi
    # T is non-decreasing up to the dense output's error, rtol |T| (T hardly moves at phi ~
    # 36 .. 50, where samples 1e-17 apart in T came out up to 2.5e-14 |T| the wrong way)
    assert np.all(np.diff(T) >= -1e-11 * T[1:])
    assert phi.max() < 60.0  # nothing sampled on the leg (its entry is at phi = 50 + steps)
    assert T[-1] == pytest.approx(cl.return_time, rel=10 * cl.rel_accuracy)
    # where phi < 5 (d phi/dT <= e^5 |...|, so an error of rtol |T| in T moves phi by
    # < 1e-9): samples against stepping at rtol 1e-12 (its blur of L ~1e-16 * 1e5) at the
    # same T, before and after the leg
    slow = np.where(phi < 5.0)[0][::3]
    ref = rsfcore.simulate(p, "velocity-jump", d, rtol=1e-12, times=T[slow], method="integrate")
    assert ref.trajectory is not None and len(slow) >= 8 and T[slow[-1]] > T[np.argmax(phi)]
    dphi = np.abs(ref.trajectory.phi - phi[slow])
    assert np.all(dphi <= 1e-8 * (1.0 + np.abs(phi[slow]))), dphi.max()


def test_slow_spiral_outcome_without_its_times() -> None:
    """kappa < kappa_crit near b/a -> 1: the outcome is certain (every perturbation grows)
    but blow-up is > 5e5 steps away; classify stops after DECIDED_OUTCOME_BUDGET steps
    (was 5e5 steps, 0.33 s) and says the times are missing."""
    p = Params(1.0000000000390448, 3.8653600331900095e-11, 0.38753867831264943, 45.27932586413081)
    r = rsfcore.classify(p, "velocity-jump", -0.01495176963773283)
    assert r.outcome == "unstable" and r.certificate == "linear_instability"
    assert r.blowup_time is None and not r.complete
    assert r.n_steps <= DECIDED_OUTCOME_BUDGET


def test_leg_exit_error_within_its_conditioning() -> None:
    # the docstring bound of L_exit (rsfcore.excursion): an absolute error below
    # max(1, c) ulp(|dL|), c = r/(r + G(L_in)), against 60-digit mpmath roots of (leg 1)
    # with J in closed form; measured <= 0.18 max(1, c) ulp over 281 legs (issue 22: the
    # former "a few ulp of |dL|" missed c, measured up to 1.6e4 .. 4e6 ulp)
    from rsfcore.excursion import fast_leg

    def resid(L: mp.mpf, B: mp.mpf, E: mp.mpf, R: mp.mpf, Li: mp.mpf) -> mp.mpf:
        # (leg 1) with J(L) - J(L_in) of (leg 3) in closed form
        if E == 0:
            dj = -mp.log((R - L) / (R - Li))
        else:
            q = E * R - 1
            dj = mp.log((1 + q * mp.e ** (E * L)) / (1 + q * mp.e ** (E * Li))) / q
        return B * (L - Li) - R * dj

    rng = np.random.default_rng(5)
    n = 0
    with mp.workdps(60):
        for _ in range(40):
            kc = 10 ** rng.uniform(-12, -1)
            ba = 1 + kc
            r = 10 ** rng.uniform(0.0005, 1.5)
            kappa = r * kc
            eps = float(rng.choice([0.0, rng.uniform(0, 1)]))
            if eps * r >= 1:
                eps = rng.uniform(0, 0.99) / r
            ls = float(L_star(kappa, ba - 1.0, eps))
            L_in = ls * (1 - 10 ** rng.uniform(-8, -1))
            ok, L_exit = fast_leg(50.0, L_in, ba, kappa, eps)[:2]
            if not ok:
                continue
            B, E, Li = mp.mpf(ba), mp.mpf(eps), mp.mpf(L_in)
            R = mp.mpf(kappa) / (B - 1)
            root = mp.findroot(functools.partial(resid, B=B, E=E, R=R, Li=Li), mp.mpf(L_exit))
            dl = abs(float(root - Li))
            g_in = mp.expm1(-E * Li) / E if eps > 0 else -Li
            c = float(R / (R + g_in))
            assert c > 0
            assert abs(L_exit - float(root)) <= max(1.0, c) * math.ulp(dl), (L_in, c)
            n += 1
    assert n >= 30


def test_leg_dJ_beyond_the_double_range_of_G() -> None:
    """J(L) - J(L_in) where G(L) overflows (eps L = -1000, the clipped range of the engine's
    G), on both branches of (leg 3): q < 0 (x < 1, log1p form) and q > 0 with z < -0.5 (the
    logarithm of r + G(L), formed without G), against J = ln(1 + q e^(eps L))/q in 50 digits."""
    mp.mp.dps = 50
    for r, eps, L_in in ((1.5, 0.5, 2.0), (3.0, 0.5, 2.0), (0.5, 1.0, -3.0)):
        L = -1000.0 / eps
        q = mp.mpf(eps) * mp.mpf(r) - 1

        def J(t: float, q: mp.mpf = q, eps: float = eps) -> mp.mpf:
            return mp.log(1 + q * mp.e ** (mp.mpf(eps) * mp.mpf(t))) / q

        ref = J(L) - J(L_in)
        got = leg_dJ(L, L_in, r, eps, r + G(L_in, eps))
        assert math.isfinite(got)
        assert abs((got - ref) / ref) <= 1e-14, (r, eps, got, ref)


def test_leg_with_its_exit_beyond_the_clipped_range() -> None:
    """b/a = 1e5, x = eps kappa/kappa_crit = 1 - 1e-12, d = 0.9 d_crit: the excursion climbs
    to phi = 1.3e6 and its leg exits at L = -1.3e6 (eps L = -6.5e5), where the engine's G is
    clipped.  The leg was refused there and stepped through: 3,436 steps, and classify's
    check run ran out of its budget (31 ms); and q, r + G(L_in) rounded from r = kappa/kc
    lost 1/(1 - x) ulps (the peak was 3e-6 off).  Now ~20 steps, and the peak is the
    60-digit value of (leg 1) from the exact start (phi_in = d < 50, where the load terms
    are below e^-49 of the rates, so the leg's invariant holds from the start)."""
    ba, kappa, eps, d = 100000.0, 199997.9999998, 0.5, 49.7358063025455
    mp.mp.dps = 60
    B, K, E, D = mp.mpf(ba), mp.mpf(kappa), mp.mpf(eps), mp.mpf(d)
    kc = B - 1
    R = K / kc
    q = E * R - 1

    def J(t: mp.mpf) -> mp.mpf:
        return mp.log(1 + q * mp.e ** (E * t)) / q

    L_pk = -mp.log(1 - E * K / B) / E  # root of kappa + (b/a) G
    peak = D + (B * (L_pk - D) - R * (J(L_pk) - J(D))) / kc
    lg = leg(d, 0.0, ba, kappa, eps)
    assert lg.ok and eps * lg.L_exit < -600.0
    assert abs(lg.phi_peak - float(peak)) <= 1e-14 * float(peak)
    for rtol in (1e-3, 1e-10, 1e-13):
        res = rsfcore.classify(Params(ba, kappa, eps, 1.0), "velocity-jump", log_size=d, rtol=rtol)
        assert res.outcome == "stable" and res.complete
        assert res.n_steps < 100
        assert abs(res.peak_phi - float(peak)) <= res.rel_accuracy * float(peak)


def test_descent_leg_exit_against_60_digit_root() -> None:
    """The falling flank's end (rsfcore.excursion.descent_leg) against 60-digit mpmath roots
    of (leg 1) = -kc drop (J in closed form): within 2 ulp of L (bisection on doubles, as
    L itself is carried) plus 4x the conditioning u ((b/a)|dL| + |(b/a) dL - target|) /
    |d(leg 1)/dL| (measured <= 1.27 of the larger over 296 random flanks, b/a - 1 in
    [1e-12, 1], r in [1e-2, 1e3], drops 100 .. 700)."""
    from rsfcore.excursion import descent_leg

    def resid(L: mp.mpf, B: mp.mpf, E: mp.mpf, R: mp.mpf, Li: mp.mpf, tgt: mp.mpf) -> mp.mpf:
        if E == 0:
            dj = -mp.log((R - L) / (R - Li))
        else:
            q = E * R - 1
            dj = mp.log((1 + q * mp.e ** (E * L)) / (1 + q * mp.e ** (E * Li))) / q
        return B * (L - Li) - R * dj - tgt

    rng = np.random.default_rng(7)
    n = 0
    with mp.workdps(60):
        for _ in range(60):
            kc = 10 ** rng.uniform(-12, 0)
            ba, r = 1.0 + kc, 10 ** rng.uniform(-2, 3)
            kappa = r * kc
            eps = float(rng.choice([0.0, 1.0, rng.uniform(0, 1)]))
            top = min(float(L_star(kappa, ba, eps)), float(L_star(kappa, ba - 1.0, eps)))
            L_in = (top if math.isfinite(top) else 50.0) - 10 ** rng.uniform(-3, 3)
            if eps * L_in < -600:
                continue
            drop = float(rng.uniform(100, 700))
            ok, L_exit = descent_leg(50.0 + drop, L_in, ba, kappa, eps, drop)[:2]
            assert ok, (kc, r, eps, L_in)
            B, E, Li = mp.mpf(ba), mp.mpf(eps), mp.mpf(L_in)
            R, tgt = mp.mpf(kappa) / (B - 1), -(B - 1) * mp.mpf(drop)
            fr = functools.partial(resid, B=B, E=E, R=R, Li=Li, tgt=tgt)
            dlt = mp.mpf(1e-9) * (abs(L_exit - L_in) + 1)
            root = mp.findroot(fr, (mp.mpf(L_exit) - dlt, mp.mpf(L_exit) + dlt), solver="illinois")
            h = mp.mpf(1e-20) * (abs(root) + 1)
            der = abs((fr(root + h) - fr(root - h)) / (2 * h))
            cond = float(U / 2 * (B * abs(root - Li) + abs(B * (root - Li) - tgt)) / der)
            assert abs(L_exit - float(root)) <= 2 * math.ulp(L_exit) + 4 * cond, (kc, r, eps)
            n += 1
    assert n >= 50


def _descent_cases() -> list[tuple[Params, float]]:
    # velocity jumps far above ln v_o that return without a rising leg (x >= 1, or eps = 0
    # with L* = kappa/kappa_crit above d), where stepping is accurate (L blur u |phi| ~ 1e-13)
    return [
        (Params(1.1, 1.0, 1.0, 1.0), 782.0),
        (Params(1.1, 1.0, 1.0, 1.0), 3000.0),
        (Params(1.5, 0.75, 1.0, 3e-5), 400.0),
        (Params(1.1, 60.0, 0.0, 2e4), 300.0),
    ]


@pytest.mark.parametrize("case", _descent_cases())
def test_engine_descent_agrees_with_stepping(case: tuple[Params, float]) -> None:
    """The falling flank from phi - ln v_o = d down to 50 in closed form against stepping
    through it (method="integrate", ~5 steps per unit of phi at rtol 1e-12): same outcome,
    times and peak within the sum of the two claimed accuracies, and a fraction of the
    steps (at b/a = 1.1, d = 782, rtol 1e-13: 273 steps against 3,109; scipy's DOP853 on a
    40-digit right-hand side gives the same return time to 1.8e-13 and peak to 3e-16)."""
    p, d = case
    a = rsfcore.classify(p, "velocity-jump", d, rtol=1e-12)
    b = rsfcore.classify(p, "velocity-jump", d, rtol=1e-12, method="integrate")
    assert a.outcome == b.outcome == "stable"
    assert 3 * a.n_steps < b.n_steps, (a.n_steps, b.n_steps)
    for name in ("return_time", "peak_time", "peak_phi"):
        x, y = getattr(a, name), getattr(b, name)
        if x is None or y is None:
            continue
        assert abs(x - y) <= (a.rel_accuracy + b.rel_accuracy) * max(abs(y), 1.0), name


def test_trajectory_samples_skip_the_descent() -> None:
    """The flank advances tau by nothing and T by ~e^-50: samples in tau step from the
    start (phi = d) to phi <= ln v_o + 50 + (one step), T stays non-decreasing and the
    trajectory ends at the return the classification gives."""
    p, d = Params(1.1, 1.0, 1.0, 1.0), 782.0
    cl = rsfcore.classify(p, "velocity-jump", d, rtol=1e-11)
    tr = rsfcore.simulate(p, "velocity-jump", d, rtol=1e-11, n_points=200)
    assert tr.trajectory is not None and cl.return_time is not None
    T, phi = tr.trajectory.T, tr.trajectory.phi
    assert np.all(np.diff(T) >= -1e-11 * T[1:])
    assert not np.any((phi > 60.0) & (phi < 700.0))  # nothing sampled on the flank
    assert T[-1] == pytest.approx(cl.return_time, rel=10 * cl.rel_accuracy)


@pytest.mark.parametrize(
    ("p", "d", "kw"),
    [
        (Params(1.000000000001, 0.01, 0.0, 1.0), 782.0, {"t_end": 1e-250, "n_points": 20}),
        (Params(2.0, 3.0, 0.5, 1e-200), 9000.0, {"n_points": 50}),
    ],
)
def test_sampled_times_are_never_negative(p: Params, d: float, kw: dict[str, float]) -> None:
    """T starts at 0 and never decreases; the dense output of c T at subnormal values came
    out as -5.6e-313 .. -6.9e-311 (and -5.4e-123 in T at v_o = 1e-200, c T = -5e-323)."""
    tr = rsfcore.simulate(p, "velocity-jump", d, rtol=1e-13, **kw).trajectory  # type: ignore[arg-type]
    assert tr is not None and np.all(tr.T >= 0.0), tr.T[tr.T < 0.0]
