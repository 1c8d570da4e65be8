"""classify_points agrees with classify, point by point (issue 13, item 6).

The reference is rsfcore.trajectory.classify(params, start=(phi0, psi0)) for each point
(integration with certificates), independent of the traced separatrix.  Samples: random
starts over a box around steady sliding, starts offset from the traced separatrix by
1e-6 and 1e-9 (1 + |t| + |u|) on both sides (the latter inside the safety margin, so they
must be integrated), velocity jumps of size d_crit (1 -/+ 1e-9) and load-point jumps of
size dv_crit (1 -/+ 1e-6), and every regime of the module docstring.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from rsfcore import Params, classify
from rsfcore.critical import critical_perturbation
from rsfcore.errors import ParameterError
from rsfcore.phase import (
    CURVE_ERR_FACTOR,
    MARGIN_FACTOR,
    Outcome,
    PointMethod,
    Separatrix,
    classify_points,
    trace_separatrix,
)

RTOL = 1e-10


def _reference(p: Params, phi: np.ndarray, psi: np.ndarray, rtol: float = RTOL) -> np.ndarray:
    out = np.empty(phi.size, dtype=np.int8)
    for i, (a, b) in enumerate(zip(phi.ravel(), psi.ravel(), strict=True)):
        r = classify(p, start=(float(a), float(b)), rtol=rtol)
        out[i] = Outcome.STABLE if r.outcome == "stable" else Outcome.UNSTABLE
    return out.reshape(phi.shape)


def _box(p: Params, n: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """Random starts around steady sliding (phi in ln v_o + [-4, 6], L in [-4, L* + 1])."""
    rng = np.random.default_rng(seed)
    lnvo = math.log(p.vo) if p.vo > 0 else 0.0
    phi = lnvo + rng.uniform(-4.0, 6.0, n)
    lth = -lnvo + rng.uniform(-5.0, 4.0, n)
    return phi, phi + p.ba * lth


def _from_tu(p: Params, t: np.ndarray, u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    lth = t - (math.log(p.vo) if p.vo > 0 else 0.0)
    phi = u - lth
    return phi, phi + p.ba * lth


SEPARATRIX_CASES = [
    Params(2.0, 1.5, 0.3),
    Params(1.25, 0.5, 0.0),
    Params(10.0, 20.0, 0.4, 1e-3),
    Params(2.0, 1.2, 0.8),
    Params(1.01, 0.015, 0.5, 1e6),
]


@pytest.mark.parametrize("p", SEPARATRIX_CASES, ids=str)
def test_random_starts_agree_with_classify(p: Params) -> None:
    phi, psi = _box(p, 400, seed=1)
    r = classify_points(p, phi, psi, rtol=RTOL)
    assert np.array_equal(r.outcome, _reference(p, phi, psi))
    # the separatrix (or u >= L*) decides almost all of them: few random starts fall in
    # the margin, and many are decided by the curve itself
    assert np.count_nonzero(r.method == PointMethod.INTEGRATED) <= 20
    assert np.count_nonzero(r.method == PointMethod.SEPARATRIX) >= 100
    assert {"stable", "unstable"} <= set(r.outcome_names())


@pytest.mark.parametrize("p", SEPARATRIX_CASES[:4], ids=str)
@pytest.mark.parametrize("delta", [1e-6, 1e-9])
def test_starts_near_the_separatrix(p: Params, delta: float) -> None:
    # offsets of delta (1 + |t| + |u|) in u on branch A and in t on branch B, both sides:
    # 1e-6 is outside the margin (100 rtol = 1e-8) and decided by the curve, 1e-9 inside
    # it and integrated; both must agree with classify
    sep = trace_separatrix(p, RTOL)
    assert sep is not None
    rng = np.random.default_rng(7)
    tA = rng.uniform(sep.s0 - 3.0, sep.t_switch - 1e-3, 20)
    uA = sep.u_of_t(tA)
    uB = rng.uniform(max(sep.u_end, -20.0), sep.u_switch, 20)
    tB = sep.t_of_u(uB)
    sgn = np.tile([-1.0, 1.0], 10)
    uA = uA + sgn * delta * (1 + np.abs(tA) + np.abs(uA))
    tB = tB + sgn * delta * (1 + np.abs(tB) + np.abs(uB))
    phi, psi = _from_tu(p, np.concatenate([tA, tB]), np.concatenate([uA, uB]))
    r = classify_points(p, phi, psi, rtol=RTOL)
    expected_side = np.where(np.concatenate([sgn, sgn]) > 0, Outcome.UNSTABLE, Outcome.STABLE)
    assert np.array_equal(r.outcome, _reference(p, phi, psi))
    assert np.array_equal(r.outcome, expected_side)
    if delta < MARGIN_FACTOR * RTOL:
        assert np.all(r.method == PointMethod.INTEGRATED)
    else:  # (near the asymptote u -> L* an offset of 1e-6 can put u above L*)
        assert np.all(np.isin(r.method, [PointMethod.SEPARATRIX, PointMethod.ABOVE_LSTAR]))


@pytest.mark.parametrize("p", SEPARATRIX_CASES, ids=str)
def test_traced_curve_reproduces_critical_sizes(p: Params) -> None:
    # independent of classify: the separatrix method of rsfcore.critical (itself checked
    # against bisection) gives the same crossing points of the traced curve, to 1e-9
    vj = critical_perturbation(p, "velocity-jump", rtol=1e-12)
    lj = critical_perturbation(p, "load-point-jump", rtol=1e-12)
    sep = trace_separatrix(p, 1e-12)
    assert sep is not None
    # velocity jump: start t = 0 (ln theta = -ln v_o), u = d
    d = float(sep.u_of_t(0.0)[0]) if sep.t_switch > 0.0 else None
    if d is not None:
        assert d == pytest.approx(vj.critical_size, rel=1e-9)
    # load-point jump: start u = 0, t = ln(1 + dv)
    assert float(sep.t_of_u(0.0)[0]) == pytest.approx(math.log1p(lj.critical_size), rel=1e-9)


@pytest.mark.parametrize("p", SEPARATRIX_CASES[:3], ids=str)
def test_perturbations_at_the_critical_size(p: Params) -> None:
    vj = critical_perturbation(p, "velocity-jump").critical_size
    lj = critical_perturbation(p, "load-point-jump").critical_size
    lnvo = math.log(p.vo)
    phi, psi = [], []
    for f in (1 - 1e-9, 1 + 1e-9, 0.5, 1.5):
        phi.append(lnvo + f * vj)
        psi.append((1 - p.ba) * lnvo + f * vj)
    r = classify_points(p, np.array(phi), np.array(psi), rtol=RTOL)
    assert list(r.outcome) == [Outcome.STABLE, Outcome.UNSTABLE, Outcome.STABLE, Outcome.UNSTABLE]
    assert r.method[0] == r.method[1] == PointMethod.INTEGRATED
    # a load-point jump dv from steady state at v_o: the same start (ln v_o, (1 - b/a) ln v_o)
    # with the load point at v_o (1 + dv)
    for f, want in ((1 - 1e-6, Outcome.STABLE), (1 + 1e-6, Outcome.UNSTABLE)):
        q = p.with_(vo=p.vo * (1.0 + f * lj))
        r = classify_points(q, np.array([lnvo]), np.array([(1 - p.ba) * lnvo]), rtol=RTOL)
        assert r.outcome[0] == want, (f, r)


@pytest.mark.parametrize(
    "p, method",
    [
        (Params(2.0, 1.0, 0.3), PointMethod.U_SIGN),  # kappa = kappa_crit
        (Params(2.0, 1.0, 1.0), PointMethod.U_SIGN),  # aging law: every orbit closed
        (Params(2.0, 1.0, 0.3, 1e-6), PointMethod.U_SIGN),  # U far from v_o = 1
        (Params(2.0, 0.5, 0.3), PointMethod.LINEAR),  # kappa < kappa_crit
        (Params(2.0, 3.0, 0.5), PointMethod.NO_RUNAWAY),  # eps kappa >= kappa_crit
        (Params(2.0, 1.5, 0.3, 0.0), PointMethod.FIXED_L),  # v_o = 0
        (Params(2.0, 0.0, 0.3, 1.0), PointMethod.FIXED_L),  # kappa = 0
        (Params(2.0, 3.0, 0.5, 0.0), PointMethod.NO_RUNAWAY),  # v_o = 0, no L*
    ],
    ids=str,
)
def test_regimes_without_separatrix(p: Params, method: PointMethod) -> None:
    phi, psi = _box(p, 150, seed=3)
    r = classify_points(p, phi, psi, rtol=RTOL)
    assert np.array_equal(r.outcome, _reference(p, phi, psi))
    decided = r.method != PointMethod.INTEGRATED
    assert np.all(r.method[decided] == method) or method == PointMethod.FIXED_L


def test_equilibrium_and_on_lstar() -> None:
    p = Params(2.0, 1.5, 0.3, 4.0)
    lnvo = math.log(4.0)
    r = classify_points(p, np.array([lnvo]), np.array([(1 - 2.0) * lnvo]))
    assert r.outcome[0] == Outcome.STABLE and r.method[0] == PointMethod.EQUILIBRIUM
    # v_o = 0 on the line L = L* itself: unstable (classify's vo0_L_on_Lstar)
    q = Params(2.0, 0.5, 0.0, 0.0)
    r = classify_points(q, np.array([0.5]), np.array([0.5]))  # L = 0.5 = L*
    assert r.outcome[0] == Outcome.UNSTABLE
    assert classify(q, start=(0.5, 0.5)).outcome == "unstable"


def test_shape_and_result_fields() -> None:
    p = Params(2.0, 1.5, 0.3)
    phi, psi = np.meshgrid(np.linspace(-3, 5, 7), np.linspace(-4, 4, 5))
    r = classify_points(p, phi, psi)
    assert r.outcome.shape == r.method.shape == (5, 7)
    d = r.to_dict()
    assert len(d["outcome"]) == 35 and d["params"]["ba"] == 2.0
    assert r.unstable.dtype == bool


def test_invalid_inputs() -> None:
    p = Params(2.0, 1.5, 0.3)
    with pytest.raises(ParameterError) as e:
        classify_points(p, np.zeros(3), np.zeros(4))
    assert e.value.field == "psi0"
    with pytest.raises(ParameterError) as e:
        classify_points(p, np.array([0.0, np.nan]), np.zeros(2))
    assert e.value.field == "phi0[1]"
    with pytest.raises(ParameterError) as e:
        classify_points(p, np.zeros(2), np.array([0.0, 1e9]))
    assert e.value.field == "psi0[1]"
    with pytest.raises(ParameterError) as e:
        classify_points(p, np.zeros(2), np.zeros(2), rtol=1.0)
    assert e.value.field == "rtol"


@pytest.mark.slow
def test_random_parameter_sets() -> None:
    # 150 random parameter sets over the valid range (b/a 1 + 1e-3 .. 1e3, kappa/kappa_crit
    # 0.5 .. 20, eps 0 .. 1, v_o 1e-6 .. 1e6, a tenth with v_o = 0), 100 starts each
    rng = np.random.default_rng(11)
    for _ in range(150):
        ba = 1.0 + 10.0 ** rng.uniform(-3.0, 3.0)
        kc = ba - 1.0
        kappa = min(kc * 10.0 ** rng.uniform(-0.3, 1.3), 1e6)
        eps = float(rng.choice([0.0, rng.uniform(0.0, 1.0), 1.0]))
        vo = 0.0 if rng.random() < 0.1 else 10.0 ** rng.uniform(-6.0, 6.0)
        p = Params(ba, kappa, eps, vo)
        phi, psi = _box(p, 100, seed=int(rng.integers(1 << 30)))
        r = classify_points(p, phi, psi, rtol=RTOL)
        assert np.array_equal(r.outcome, _reference(p, phi, psi)), p


# ---------------------------------------------------------------------------------------
# the stiff corner: the tracing hands over to RODAS4 (issue 22, item 3)
STIFF_CASES = [Params(1e4, 1.0001e4, 0.0), Params(1e5, 1.1e5, 0.0), Params(1e6, 1e6, 0.0)]
STIFF_RTOL = 1e-8


def _band(sep: Separatrix, t: float, u: float, rtol: float) -> float:
    """The stated error band of a side decision at (t, u): the margin of classify_points
    (without the rounding term, which is below 1e-13 here)."""
    return MARGIN_FACTOR * rtol * (1 + abs(t) + abs(u)) + CURVE_ERR_FACTOR * sep.curve_error(t, u)


@pytest.mark.parametrize("rtol", [STIFF_RTOL, 1e-12, 1e-13])
@pytest.mark.parametrize("p", STIFF_CASES, ids=str)
def test_stiff_corner_traces_the_separatrix(p: Params, rtol: float) -> None:
    # before RODAS4 took over the stiff part these were not traced (DOP853 filled its 4e4
    # rows before the end of branch A) and every start was integrated; at rtol <= 1e-12
    # RODAS4 at rtol filled them too (its tolerance is now floored at 1e-10)
    sep = trace_separatrix(p, rtol)
    assert sep is not None and sep.n_stiff > 0
    # independent of the tracing: critical sizes by the separatrix method of
    # rsfcore.critical lie on the curve (velocity jump: (t, u) = (0, d_crit), on branch B
    # here; load-point jump: (ln(1 + dv_crit), 0)), within the stated band plus their own
    # claimed accuracy
    vj = critical_perturbation(p, "velocity-jump", rtol=1e-10)
    lj = critical_perturbation(p, "load-point-jump", rtol=1e-10)
    d, l_ = vj.critical_size, math.log1p(lj.critical_size)
    assert 0.0 < d < sep.u_switch and sep.t_switch < 0.0
    miss_v = float(sep.t_of_u(d)[0])
    miss_l = float(sep.t_of_u(0.0)[0]) - l_
    assert abs(miss_v) <= _band(sep, 0.0, d, rtol) + vj.rel_accuracy * d
    assert abs(miss_l) <= _band(sep, l_, 0.0, rtol) + lj.rel_accuracy * l_


@pytest.mark.parametrize("p", STIFF_CASES, ids=str)
def test_stiff_corner_agrees_with_classify(p: Params) -> None:
    # random starts, and starts 3x the stated band off the curve on both sides (decided by
    # the curve) and 0.1x inside it (integrated): every outcome is classify's, point by
    # point, and the side of the offset
    sep = trace_separatrix(p, STIFF_RTOL)
    assert sep is not None
    phi, psi = _box(p, 40, seed=3)
    r = classify_points(p, phi, psi, rtol=STIFF_RTOL)
    assert np.array_equal(r.outcome, _reference(p, phi, psi, STIFF_RTOL))
    # (L* ~ 1 here: most of the others have u >= L*)
    assert np.count_nonzero(r.method == PointMethod.SEPARATRIX) >= 15
    assert np.count_nonzero(r.method == PointMethod.INTEGRATED) <= 2
    rng = np.random.default_rng(11)
    tA = rng.uniform(sep.s0 - 2.0, sep.t_switch - 1e-3, 6)
    uA = sep.u_of_t(tA)
    uB = rng.uniform(max(sep.u_end, -10.0), sep.u_switch, 6)
    tB = sep.t_of_u(uB)
    sgn = np.tile([-1.0, 1.0], 3)
    for factor, method in ((3.0, PointMethod.SEPARATRIX), (0.1, PointMethod.INTEGRATED)):
        bA = np.array([_band(sep, t, u, STIFF_RTOL) for t, u in zip(tA, uA, strict=True)])
        bB = np.array([_band(sep, t, u, STIFF_RTOL) for t, u in zip(tB, uB, strict=True)])
        phi, psi = _from_tu(
            p,
            np.concatenate([tA, tB + sgn * factor * bB]),
            np.concatenate([uA + sgn * factor * bA, uB]),
        )
        r = classify_points(p, phi, psi, rtol=STIFF_RTOL)
        side = np.where(np.concatenate([sgn, sgn]) > 0, Outcome.UNSTABLE, Outcome.STABLE)
        assert np.array_equal(r.outcome, side), (factor, r.outcome, side)
        assert np.array_equal(r.outcome, _reference(p, phi, psi, STIFF_RTOL)), factor
        assert np.all(np.isin(r.method, [method, PointMethod.ABOVE_LSTAR])), factor


@pytest.mark.slow
@pytest.mark.parametrize("p", STIFF_CASES, ids=str)
def test_stiff_corner_agrees_with_classify_at_tight_rtol(p: Params) -> None:
    # rtol 1e-12: the RODAS4 part of the tracing runs at 1e-10 (its floor) and the curve's
    # estimate widens the band; starts 3x the band off on both sides are decided by the
    # curve and agree with classify at 1e-12 point by point, and random starts too
    rtol = 1e-12
    sep = trace_separatrix(p, rtol)
    assert sep is not None and sep.n_stiff > 0
    rng = np.random.default_rng(12)
    tA = rng.uniform(sep.s0 - 2.0, sep.t_switch - 1e-3, 3)
    uA = sep.u_of_t(tA)
    uB = rng.uniform(max(sep.u_end, -10.0), sep.u_switch, 3)
    tB = sep.t_of_u(uB)
    sgn = np.array([-1.0, 1.0, -1.0])
    bA = np.array([_band(sep, t, u, rtol) for t, u in zip(tA, uA, strict=True)])
    bB = np.array([_band(sep, t, u, rtol) for t, u in zip(tB, uB, strict=True)])
    phi, psi = _from_tu(
        p,
        np.concatenate([tA, tB + sgn * 3.0 * bB]),
        np.concatenate([uA + sgn * 3.0 * bA, uB]),
    )
    r = classify_points(p, phi, psi, rtol=rtol)
    side = np.where(np.concatenate([sgn, sgn]) > 0, Outcome.UNSTABLE, Outcome.STABLE)
    assert np.array_equal(r.outcome, side)
    assert np.all(np.isin(r.method, [PointMethod.SEPARATRIX, PointMethod.ABOVE_LSTAR]))
    assert np.array_equal(r.outcome, _reference(p, phi, psi, rtol))
    phi, psi = _box(p, 12, seed=5)
    r = classify_points(p, phi, psi, rtol=rtol)
    assert np.array_equal(r.outcome, _reference(p, phi, psi, rtol))
