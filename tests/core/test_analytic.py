"""Closed forms checked against direct integration and their own limits.

U must stay constant along computed trajectories.  The integrator controls the local
error relative to each state component (phi, psi up to ~6 on these orbits), and U contains
e^phi terms, so the relative drift of U over one orbit is a small multiple of rtol: measured
at most 19 rtol (rtol = 1e-10), 28 rtol (1e-11) and 31 rtol (1e-12), the worst case being the
slip-law orbit from d = 0.8 that reaches phi = 5.7.  The asserted bound is 50 rtol, i.e.
5e-9 at rtol = 1e-10, for these single short orbits only: the general law (linear in the
number of oscillations, relative drift ~ 1/(1 - d/d_crit) near the separatrix) is in
docs/accuracy.md and tests/core/test_u_drift.py.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from rsfcore import Params, classify, simulate
from rsfcore.analytic import (
    U_kcrit,
    U_vo0,
    delta_tau,
    load_point_jump_crit_kcrit,
    psi_crit_kcrit,
    psi_crit_vo0,
    velocity_jump_crit_aging_asymptote,
    velocity_jump_crit_kcrit,
    velocity_jump_crit_slip_law,
    velocity_jump_crit_vo0,
)
from rsfcore.params import ParameterError

from .reference import perturbation_of, reference_cases

RTOL = 1e-10
U_DRIFT_BOUND = 50 * RTOL


@pytest.mark.parametrize("eps", [0.0, 1e-300, 1e-12, 0.3, 0.6, 0.99, 1.0])
@pytest.mark.parametrize("d", [0.3, 0.8])
def test_U_kcrit_conserved(eps: float, d: float) -> None:
    ba = 1.25
    r = simulate(Params(ba, ba - 1, eps, 1.0), "velocity-jump", d, n_points=400, rtol=RTOL)
    t = r.trajectory
    U = U_kcrit(t.phi, t.psi, ba, eps)
    assert np.all(np.isfinite(U))
    assert np.max(np.abs(U - U[0])) <= U_DRIFT_BOUND * abs(U[0])
    assert r.outcome == "stable"
    if eps < 1.0:  # at eps = 1 `eq: trajectories 1-2` has another normalisation (all orbits closed)
        assert U[0] < 0


@pytest.mark.parametrize("vo", [0.3, 1.0, 7.0])
def test_U_kcrit_conserved_other_vo(vo: float) -> None:
    ba, eps = 2.0, 0.25
    r = simulate(Params(ba, 1.0, eps, vo), "velocity-jump", 0.6, n_points=300)
    t = r.trajectory
    U = U_kcrit(t.phi, t.psi, ba, eps, vo)
    assert np.max(np.abs(U - U[0])) <= U_DRIFT_BOUND * abs(U[0])


@pytest.mark.parametrize("eps", [0.0, 1e-12, 0.3, 1.0])
@pytest.mark.parametrize("kappa, d", [(0.5, 0.3), (0.5, 2.0), (1.5, 1.0), (3.0, 0.5)])
def test_U_vo0_conserved(eps: float, kappa: float, d: float) -> None:
    ba = 2.0
    if eps * kappa == ba - 1:
        pytest.skip("U singular on eps*kappa = kappa_crit")
    r = simulate(Params(ba, kappa, eps, 0.0), "velocity-jump", d, n_points=300)
    t = r.trajectory
    U = U_vo0(t.phi, t.psi, ba, kappa, eps)
    assert np.max(np.abs(U - U[0])) <= U_DRIFT_BOUND * abs(U[0])


def test_U_slip_limit_is_continuous() -> None:
    phi = np.linspace(-2, 2, 9)
    psi = np.linspace(-1, 3, 9)
    u0 = U_kcrit(phi, psi, 1.25, 0.0)
    # U is smooth in eps: the eps = 1e-9 value differs from the limit by O(eps)
    assert np.allclose(U_kcrit(phi, psi, 1.25, 1e-9), u0, rtol=1e-7, atol=1e-8)
    assert np.array_equal(U_kcrit(phi, psi, 1.25, 1e-300), u0)
    # exact slip-law form written independently
    kc = 0.25
    assert np.allclose(
        u0, np.exp(psi - phi) * (kc - np.exp(phi) * ((1 - 1.25) * phi - psi + 1.25)), rtol=1e-14
    )


def test_U_vo0_slip_limit() -> None:
    phi, psi = np.array([0.1, 0.5]), np.array([0.2, -0.4])
    assert np.allclose(U_vo0(phi, psi, 2.0, 0.5, 1e-10), U_vo0(phi, psi, 2.0, 0.5, 0.0), rtol=1e-8)
    with pytest.raises(ParameterError):
        U_vo0(phi, psi, 2.0, 2.0, 0.5)  # eps kappa = kappa_crit


@pytest.mark.parametrize("eps", [0.0, 1e-12, 0.3, 0.6, 0.9])
def test_critical_trajectory_is_U_zero(eps: float) -> None:
    phi = np.linspace(-1.0, 4.0, 11)
    psi = psi_crit_kcrit(phi, 1.25, eps)
    ok = np.isfinite(psi)
    U = U_kcrit(phi[ok], psi[ok], 1.25, eps)
    scale = np.abs(1.25 * np.exp((psi[ok] - phi[ok]) * (1 - eps * 0.2)) * 0.25)
    assert np.all(np.abs(U) <= 1e-12 * scale + 1e-14)


def test_printed_slip_law_critical_trajectory_has_a_typo() -> None:
    # `eq: limiting trajectory 1b` printed with e^{+phi}: its intersection with psi = phi
    # is 0.626 for b/a = 1.25 (reference README), ours (e^{-phi}) gives the reference 0.92032.
    ba, kc = 1.25, 0.25
    from scipy.optimize import brentq

    printed = brentq(lambda p: 1 - kc * (math.exp(p) - 1) - p * (ba - 1) - p, 0, 3)
    assert printed == pytest.approx(0.626, abs=1e-3)
    assert velocity_jump_crit_kcrit(ba, 0.0) == pytest.approx(0.9203218394885235, rel=1e-14)


def test_vo0_critical_line_and_jump() -> None:
    phi = np.array([-1.0, 0.0, 2.0])
    psi = psi_crit_vo0(phi, 2.0, 1.0, 0.3)
    assert np.allclose(U_vo0(phi, psi, 2.0, 1.0, 0.3), 0.0, atol=1e-13)
    assert velocity_jump_crit_vo0(2.0, 1.0, 0.3) == pytest.approx(-math.log(0.7) / 0.3, rel=1e-15)
    assert velocity_jump_crit_vo0(2.0, 0.5, 0.0) == 0.5  # slip-law minimum kappa/kappa_crit
    assert velocity_jump_crit_vo0(2.0, 1.5, 1.0) == math.inf  # eps > eps_crit


@pytest.mark.parametrize("ba", [1.01, 1.25, 2.0, 10.0, 100.0])
def test_slip_law_lambert_w_is_exact(ba: float) -> None:
    d = velocity_jump_crit_slip_law(ba)
    kc = ba - 1
    assert ba * d == pytest.approx(ba - kc * math.exp(-d), rel=1e-14)


def test_aging_asymptote_approaches_numerical() -> None:
    # `eq: asymptotic solution critical velocity jump aging law` is leading-order as eps -> 1.
    errs = [
        abs(velocity_jump_crit_aging_asymptote(1.25, e) - velocity_jump_crit_kcrit(1.25, e))
        / velocity_jump_crit_kcrit(1.25, e)
        for e in (0.9, 0.99, 0.999)
    ]
    assert errs[0] > errs[1] > errs[2] and errs[2] < 1e-2


def test_reference_kcrit_values() -> None:
    for c in reference_cases():
        i = c["inputs"]
        if c["kind"] != "finite" or "eps" not in i or "kappa" not in i or "ba" not in i:
            continue
        if not math.isclose(i["kappa"], i["ba"] - 1, rel_tol=1e-15) or i.get("vo", 1.0) == 0.0:
            continue
        tol = max(
            10 * c["trusted_rel_tol"], 4e-15
        )  # 10x the methods' agreement, floored at a few ulp
        if perturbation_of(c) == "load-point-jump":
            v = load_point_jump_crit_kcrit(i["ba"], i["eps"])
        else:
            v = velocity_jump_crit_kcrit(i["ba"], i["eps"])
        assert v == pytest.approx(c["value"], rel=tol), c["id"]


@pytest.mark.parametrize("ba, eps", [(2.0, 0.25), (2.0, 0.0), (1.25, 0.6), (5.0, 0.9)])
def test_load_point_closed_form_against_integration(ba: float, eps: float) -> None:
    dv = load_point_jump_crit_kcrit(ba, eps)
    p = Params(ba, ba - 1, eps, 1.0)
    lo = classify(p, "load-point-jump", dv * (1 - 1e-7), method="integrate", rtol=1e-12)
    hi = classify(p, "load-point-jump", dv * (1 + 1e-7), method="integrate", rtol=1e-12)
    assert (lo.outcome, hi.outcome) == ("stable", "unstable")


@pytest.mark.parametrize("eps", [1e-300, 1e-12, 0.5, 1.0])
def test_delta_tau_limits(eps: float) -> None:
    s = np.array([0.0, 0.5, 3.0, 50.0])
    v = delta_tau(s, 10.0, eps)
    assert v[0] == pytest.approx(math.log(10.0), rel=1e-14)  # start: ln(theta1/theta2)
    assert abs(v[-1]) < 1e-20  # new steady state
    if eps == 1.0:  # aging law closed form: ln(1 + (r - 1) e^-s)
        assert np.allclose(v, np.log1p(9.0 * np.exp(-s)), rtol=1e-14)
    assert np.allclose(delta_tau(s, 10.0, 0.0), math.log(10.0) * np.exp(-s), rtol=1e-14)


def test_delta_tau_matches_state_integration() -> None:
    # Integrate d theta/d delta at constant V2 (infinitely stiff machine) with scipy: independent.
    from scipy.integrate import solve_ivp

    from rsfcore.laws import G

    for eps in (0.0, 0.3, 1.0):
        for r in (1e-3, 10.0, 1e4):
            # x = ln(V2 theta/Dc) with theta_1 = Dc/V1: x0 = ln(V2/V1); dx/d(delta/Dc) = G(x)
            sol = solve_ivp(
                lambda s, x, eps=eps: [G(x[0], eps)],
                (0, 6),
                [math.log(r)],
                rtol=1e-12,
                atol=1e-14,
                dense_output=True,
            )
            s = np.linspace(0, 6, 13)
            assert np.allclose(delta_tau(s, r, eps), sol.sol(s)[0], rtol=1e-8, atol=1e-10)
