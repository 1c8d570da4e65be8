"""Drift of the conserved U along computed trajectories: the documented law (issue 13, item 4).

U of `eq: trajectories 1` (kappa = kappa_crit, v_o > 0) and of `eq: trajectories 2`
(v_o = 0) is constant along exact trajectories.  The integrator controls each step's
local error relative to the state, so U drifts.  The law stated in docs/accuracy.md and in
the docstrings of rsfcore.analytic.U_kcrit / U_vo0 is

    |U(T) - U(0)| <= A rtol M(T) (1 + Y(T)) (1 + V(T)),     A = 10,

with M the largest U-scale (sum of the magnitudes of U's terms, U_kcrit_scale /
U_vo0_scale) met so far, Y the largest |phi| or |ln theta| so far (the error control is
relative: each step's error in phi, ln theta is ~rtol (1 + |y|)), and V the total
variation of phi so far (2 x amplitude per oscillation: the drift is systematic and grows
linearly with the number of oscillations, not like its square root).

Why A = 10: the largest measured ratio |U(T) - U(0)| / (rtol M (1 + Y)(1 + V)) was 2.6
(kappa = kappa_crit; b/a 1.001 .. 1e4, eps 0 .. 1, d/d_crit 0.3 .. 1 - 1e-8, v_o 1e-6 .. 1e3,
rtol 1e-6 .. 1e-12, up to 2300 oscillations) and 3.8 (v_o = 0, rtol 1e-12); A = 10 leaves
a margin of 2.6x over the worst case seen.  V is taken from the 1e5 dense samples, a lower
bound of the true variation, which makes the assertion stricter, not looser.

The old claim "relative drift <= 50 rtol" is false in general: relative drift is this
absolute law divided by |U(0)|, which vanishes like 1 - d/d_crit at the separatrix
(measured 2.4e8 rtol relative at d = (1 - 1e-8) d_crit, while the absolute drift stays
~0.03 rtol M), and it grows linearly with the number of oscillations (7e3 rtol after
1478 oscillations at b/a = 1.25, eps = 0, d = 0.9 d_crit).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pytest

from rsfcore import Params, simulate
from rsfcore.analytic import (
    L_star_acc,
    U_kcrit,
    U_kcrit_scale,
    U_vo0,
    U_vo0_scale,
    velocity_jump_crit_kcrit,
)
from rsfcore.limits import STEP_BUDGET

A_LAW = 10.0


@dataclass
class Drift:
    ratio: float  # max over the path of |dU| / (rtol M (1 + Y)(1 + V)); the law says <= A_LAW
    n_osc: int  # upward crossings of ln v_o
    U0: float
    M: float
    abs_drift: float  # max |U(T) - U(0)| / (rtol M)
    rel_drift: float  # max |U(T) - U(0)| / (rtol |U(0)|)
    abs_at: dict[int, float]  # max |dU| / (rtol M) up to the k-th oscillation
    crossed: bool  # the drift reached |U(0)|: the path may have left its level set there


def drift(p: Params, d: float, rtol: float, t_end: float | None) -> Drift:
    # (thousands of oscillations: beyond the ~10 ms that SAMPLE_BUDGET allows a query)
    r = simulate(
        p, "velocity-jump", d, rtol=rtol, t_end=t_end, n_points=100_000, sample_steps=STEP_BUDGET
    )
    assert t_end is None or "samples end" not in r.reason  # (the whole extent asked)
    t = r.trajectory
    assert t is not None
    if p.vo == 0.0:
        U = U_vo0(t.phi, t.psi, p.ba, p.kappa, p.eps)
        Ms = U_vo0_scale(t.phi, t.psi, p.ba, p.kappa, p.eps)
    else:
        U = U_kcrit(t.phi, t.psi, p.ba, p.eps, p.vo)
        Ms = U_kcrit_scale(t.phi, t.psi, p.ba, p.eps, p.vo)
    # Where the drift reaches |U(0)| the computed path may cross U = 0 (the separatrix)
    # and leave its level set for good (d within the law's reach of d_crit at a loose
    # rtol, e.g. (1 - 1e-8) d_crit at rtol 1e-6, which then runs away): the law is
    # checked up to there and ``crossed`` reports it.
    dU = np.abs(U - U[0])
    bad = ~(np.isfinite(U) & np.isfinite(Ms)) | (dU >= abs(U[0]))
    n = int(np.argmax(bad)) if bad.any() else len(U)
    crossed = n < len(U)
    U, Ms, dU = U[:n], Ms[:n], dU[:n]
    M = np.maximum.accumulate(Ms)
    phi, lth = t.phi[:n], t.ln_theta[:n]
    Y = np.maximum.accumulate(np.maximum(np.abs(phi), np.abs(lth)))
    V = np.concatenate([[0.0], np.cumsum(np.abs(np.diff(phi)))])
    lnvo = math.log(p.vo) if p.vo > 0.0 else 0.0
    up = np.flatnonzero((phi[:-1] < lnvo) & (phi[1:] >= lnvo)) if p.vo > 0.0 else np.empty(0, int)
    at = {
        k: float(np.max(dU[: up[k] + 1]) / (rtol * M[up[k]]))
        for k in (1, 10, 100, 1000)
        if len(up) > k
    }
    return Drift(
        ratio=float(np.max(dU / (rtol * M * (1.0 + Y) * (1.0 + V)))),
        n_osc=len(up),
        U0=float(U[0]),
        M=float(M[-1]),
        abs_drift=float(dU.max() / (rtol * M[-1])),
        rel_drift=float(dU.max() / (rtol * abs(U[0]))),
        abs_at=at,
        crossed=crossed,
    )


def _dc(ba: float, eps: float) -> float:
    return velocity_jump_crit_kcrit(ba, eps) if eps < 1.0 else 1.0


def test_drift_grows_linearly_with_oscillations() -> None:
    # b/a = 1.25, eps = 0.5, d = 0.9 d_crit, ~2300 oscillations: the absolute drift after
    # 1000 oscillations is ~10x that after 100 (measured 775 vs 78 rtol M): linear growth
    # (a random walk would give ~3x).  [5, 20] brackets 10 with room for the
    # oscillation-to-oscillation scatter of a single orbit.
    p = Params(1.25, 0.25, 0.5, 1.0)
    r = drift(p, 0.9 * _dc(1.25, 0.5), 1e-10, 3.0e4)
    assert r.n_osc >= 1000 and not r.crossed
    assert 5.0 <= r.abs_at[1000] / r.abs_at[100] <= 20.0
    assert r.rel_drift > 50.0  # the old "<= 50 rtol" claim does not hold here
    assert r.ratio <= A_LAW


def test_relative_drift_near_separatrix() -> None:
    # |U(0)| vanishes like (1 - d/d_crit) while the absolute drift does not, so the
    # relative drift grows like 1/(1 - d/d_crit).  Measured over the first oscillation
    # (b/a = 1.25, eps = 0): 8.0e2, 3.2e5, 3.0e6, 3.1e8 rtol at 1 - d/d_crit = 1e-2, 1e-4,
    # 1e-6, 1e-8, while the absolute drift stays 1.2 .. 13 rtol M.  Asserted: U(0)/(1 -
    # d/d_crit) converges (within 1e-3 from 1e-6 to 1e-8), the relative drift grows by
    # >= 1e3 over the six decades (1e6 for exact proportionality; the absolute drift of a
    # single oscillation scatters by ~10x), and the absolute law holds throughout.
    ba, eps = 1.25, 0.0
    p = Params(ba, ba - 1.0, eps, 1.0)
    out = {}
    for k in (2, 6, 8):
        f = 1.0 - 10.0**-k
        out[k] = drift(p, f * _dc(ba, eps), 1e-10, 300.0)
        assert out[k].ratio <= A_LAW
    rel1 = {k: o.abs_at[1] * o.M / abs(o.U0) for k, o in out.items()}
    assert abs((out[6].U0 / 1e-6) / (out[8].U0 / 1e-8) - 1.0) < 1e-3
    assert rel1[8] >= 1e3 * rel1[2]
    assert rel1[6] > 1e6  # the "1.2e7 rtol at 0.9999 d_crit" of issue 13 is this law


@pytest.mark.parametrize(
    "ba, eps, frac, vo, rtol",
    [
        (1.25, 0.0, 0.3, 1.0, 1e-10),
        (1.25, 0.9, 0.9999, 1.0, 1e-12),  # peak phi ~ 320
        (2.0, 0.3, 0.9, 1e-6, 1e-12),  # the largest ratio measured (2.6)
        (10.0, 0.5, 0.99, 1e3, 1e-8),
        (2.0, 1.0, 5.0, 1.0, 1e-10),  # aging law, `eq: trajectories 1-2`
    ],
)
def test_drift_law_kcrit(ba: float, eps: float, frac: float, vo: float, rtol: float) -> None:
    p = Params(ba, ba - 1.0, eps, vo)
    d = frac * _dc(ba, eps)
    r0 = simulate(p, "velocity-jump", d, rtol=rtol)
    assert r0.return_time is not None
    # 600 first-return times: hundreds of oscillations for moderate orbits; near the
    # separatrix the slow leg of an orbit (phi down to -72 at 0.9999 d_crit) is so long
    # that the run ends inside the first one
    r = drift(p, d, rtol, 600.0 * r0.return_time)
    assert not r.crossed and r.ratio <= A_LAW, r


@pytest.mark.parametrize(
    "ba, kappa, eps, frac, rtol, t_end",
    [
        (2.0, 0.5, 0.0, 0.3, 1e-12, 1e3),  # the largest ratio measured (3.8)
        (2.0, 1.5, 0.3, 0.9999, 1e-10, None),
        (1.25, 0.2, 0.9, 1 - 1e-6, 1e-10, 1e3),  # peak phi ~ 146
    ],
)
def test_drift_law_vo0(
    ba: float, kappa: float, eps: float, frac: float, rtol: float, t_end: float | None
) -> None:
    Ls = L_star_acc(kappa, ba - 1.0, eps)[0]
    r = drift(Params(ba, kappa, eps, 0.0), frac * Ls, rtol, t_end)
    assert not r.crossed and r.ratio <= A_LAW, r


#: (d/d_crit, rtol) pairs of the sweep: loose tolerances only away from the separatrix,
#: where the drift cannot reach |U(0)| (at (1 - 1e-8) d_crit and rtol 1e-6 the computed
#: path crosses U = 0, as the law allows, and then runs away: 30-40 s each, not useful)
_SWEEP_KCRIT = [
    (0.3, 1e-6),
    (0.9, 1e-6),
    (0.3, 1e-12),
    (0.9, 1e-12),
    (0.9999, 1e-9),
    (0.9999, 1e-12),
    (1 - 1e-8, 1e-12),
]


@pytest.mark.slow
def test_drift_law_sweep() -> None:
    worst = 0.0
    cases = [
        (1.001, 0.5),
        (1.25, 0.0),
        (1.25, 0.9),
        (2.0, 0.3),
        (10.0, 0.5),
        (100.0, 0.5),
        (1.25, 1.0),
        (2.0, 1.0),
    ]
    for ba, eps in cases:
        aging = [(f, r) for f in (0.3, 2.0, 5.0) for r in (1e-6, 1e-12)]
        pairs = _SWEEP_KCRIT if eps < 1.0 else aging
        for frac, rtol in pairs:
            for vo in (1.0, 1e-6, 1e3):
                p = Params(ba, ba - 1.0, eps, vo)
                d = frac * _dc(ba, eps)
                r0 = simulate(p, "velocity-jump", d, rtol=rtol)
                assert r0.return_time is not None
                r = drift(p, d, rtol, 600.0 * r0.return_time)
                # crossings happen only where the law allows them: within its reach
                assert not r.crossed or frac > 0.999, (ba, eps, frac, vo, rtol)
                assert r.ratio <= A_LAW, (ba, eps, frac, vo, rtol, r)
                worst = max(worst, r.ratio)
    for ba, kappa, eps in [
        (2.0, 0.5, 0.0),
        (2.0, 1.5, 0.3),
        (1.25, 0.2, 0.9),
        (10.0, 30.0, 0.2),
        (1e3, 1e4, 0.05),
    ]:
        Ls = L_star_acc(kappa, ba - 1.0, eps)[0]
        for frac in (0.3, 0.9, 0.9999, 1 - 1e-6):
            for rtol in (1e-6, 1e-12):
                r = drift(Params(ba, kappa, eps, 0.0), frac * Ls, rtol, 1e3)
                assert r.ratio <= A_LAW, (ba, kappa, eps, frac, rtol, r)
                worst = max(worst, r.ratio)
    assert worst > 0.5  # the law is not vacuous: within 20x of the worst case
