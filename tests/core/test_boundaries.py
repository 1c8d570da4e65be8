"""Tests of rsfcore.boundaries: each boundary checked numerically, plus the reference values."""

from __future__ import annotations

import json
import math
from fractions import Fraction

import numpy as np
import pytest

from rsfcore import ParameterError, Params, classify
from rsfcore import boundaries as bd
from rsfcore.critical import critical_perturbation
from rsfcore.laws import G

from .reference import reference_case


def _reference(case_id: str) -> dict:
    return reference_case(case_id)


def test_reference_eps_crit_and_ab_crit():
    """Factor 1 on trusted_rel_tol (1e-15): both are a single division, exact to 1 ulp."""
    c = _reference("vo0_eps_crit_ba2_k1.5")
    v = bd.eps_crit(c["inputs"]["ba"], c["inputs"]["kappa"])
    assert abs(v - c["value"]) <= c["trusted_rel_tol"] * c["value"]
    c = _reference("vo0_ab_crit_k1_eps0.5")
    v = bd.ab_crit(c["inputs"]["kappa"], c["inputs"]["eps"])
    assert abs(v - c["value"]) <= c["trusted_rel_tol"] * c["value"]


def _phi_dot_vo0(phi: float, psi: float, ba: float, kappa: float, eps: float) -> float:
    """d phi/dT of `eq:phi_T` with v_o = 0, divided by e^phi: -kappa - ba G(L)."""
    L = phi + (psi - phi) / ba
    return -kappa - ba * G(L, eps)


@pytest.mark.parametrize(
    "ba,kappa,eps",
    [
        (2.0, 0.5, 0.0),
        (2.0, 0.5, 0.6),
        (2.0, 1.5, 0.3),
        (2.0, 4.0, 0.4),
        (10.0, 3.0, 1.0),
        (2.0, 1.0, 1e-300),
    ],
)
def test_acceleration_line_has_zero_phi_rate(ba, kappa, eps):
    assert bd.acceleration_possible(ba, kappa, eps)
    phi = np.linspace(-5.0, 5.0, 11)
    psi = bd.acceleration_line(ba, kappa, eps, phi)
    for f, s in zip(phi, psi, strict=True):
        assert abs(_phi_dot_vo0(f, s, ba, kappa, eps)) <= 1e-12 * (kappa + ba)
        assert _phi_dot_vo0(f, s + 1e-3, ba, kappa, eps) > 0.0  # above: accelerating
        assert _phi_dot_vo0(f, s - 1e-3, ba, kappa, eps) < 0.0
    # the slip-law limit printed in the paper: psi_a = (1 - b/a) phi + kappa
    if eps < 1e-100:
        assert np.allclose(psi, (1 - ba) * phi + kappa, rtol=0, atol=1e-14)
    assert isinstance(bd.acceleration_line(ba, kappa, eps, 0.0), float)


def test_acceleration_condition():
    assert not bd.acceleration_possible(2.0, 4.0, 0.5)  # eps kappa/(b/a) = 1
    with pytest.raises(ParameterError):
        bd.acceleration_line(2.0, 4.0, 0.5, 0.0)
    assert bd.acceleration_possible(2.0, 4.0, 0.5 * (1 - 1e-9))
    # paper (Suppl. Fig. 5): kappa = 4, b/a = 2: acceleration only for eps < 0.5
    assert bd.acceleration_possible(2.0, 4.0, 0.49) and not bd.acceleration_possible(2.0, 4.0, 0.51)


@pytest.mark.parametrize("vo", [0.0, 1.0])
@pytest.mark.parametrize("ba,kappa", [(2.0, 1.5), (2.0, 4.0), (5.0, 10.0)])
def test_eps_crit_separates_finite_from_infinite(ba, kappa, vo):
    ec = bd.eps_crit(ba, kappa)
    below = critical_perturbation(Params(ba, kappa, ec * (1 - 1e-6), vo))
    above = critical_perturbation(Params(ba, kappa, min(1.0, ec * (1 + 1e-6)), vo))
    at = critical_perturbation(Params(ba, kappa, ec, vo))
    assert below.kind == "finite"
    assert above.kind == "infinite" and at.on_boundary
    # at the double eps_crit the kind follows the exact sign of 1 - x of the input doubles
    # (issue 22: x = 1 - 5.6e-17 is finite, L* = 56), referee exact rationals
    omx = 1 - Fraction(ec) * Fraction(kappa) / (Fraction(ba) - 1)
    assert at.kind == ("finite" if omx > 0 else "infinite")
    # direct integration above eps_crit: a large jump stays stable
    assert (
        classify(Params(ba, kappa, min(1.0, ec * 1.01), vo), "velocity-jump", 30.0).outcome
        == "stable"
    )
    # and below it that jump runs away (it exceeds L*)
    assert classify(Params(ba, kappa, ec * 0.5, vo), "velocity-jump", 30.0).outcome == "unstable"


def test_eps_crit_semantics():
    assert bd.eps_crit(2.0, 1.0) == 1.0  # kappa = kappa_crit: only the aging law
    assert bd.eps_crit(2.0, 0.5) == 2.0  # > 1: every eps admits a runaway
    assert bd.eps_crit(2.0, 0.0) == math.inf
    assert critical_perturbation(Params(2.0, 0.5, 1.0, 0.0)).kind == "finite"


@pytest.mark.parametrize("kappa,eps", [(1.0, 0.5), (3.0, 0.2), (0.5, 1.0)])
def test_ab_crit_separates_finite_from_infinite(kappa, eps):
    ab = bd.ab_crit(kappa, eps)
    ba_c = 1.0 / ab  # = 1 + kappa eps
    assert abs(ba_c - (1 + kappa * eps)) <= 4e-16 * ba_c
    assert critical_perturbation(Params(ba_c * (1 + 1e-6), kappa, eps, 0.0)).kind == "finite"
    assert critical_perturbation(Params(ba_c * (1 - 1e-6), kappa, eps, 0.0)).kind == "infinite"
    assert bd.ab_crit(kappa, 0.0) == 1.0


@pytest.mark.parametrize("vo", [0.0, 1.0])
def test_max_unstable_kappa(vo):
    for ba, eps in ((2.0, 0.25), (10.0, 0.5), (1.5, 1.0)):
        km = bd.max_unstable_kappa(ba, eps)
        assert abs(km - (ba - 1) / eps) <= 4e-16 * km
        # below it something runs away ("zero" at eps = 1, where km = kappa_crit, v_o > 0)
        assert critical_perturbation(Params(ba, km * (1 - 1e-6), eps, vo)).kind in (
            "finite",
            "zero",
        )
        assert critical_perturbation(Params(ba, km * (1 + 1e-6), eps, vo)).kind == "infinite"
    assert bd.max_unstable_kappa(2.0, 0.0) == math.inf
    assert bd.max_unstable_kappa(2.0, 1.0) == bd.kappa_crit(2.0)


def test_kappa_crit():
    assert bd.kappa_crit(2.0) == 1.0
    assert bd.kappa_crit(1.25) == 0.25
    with pytest.raises(ParameterError) as e:
        bd.kappa_crit(1.0)
    assert e.value.field == "ba"


def test_eps_to_zero_exact():
    assert bd.acceleration_L(2.0, 1.0, 0.0) == 0.5
    assert bd.acceleration_L(2.0, 1.0, 1e-300) == 0.5
    assert abs(bd.acceleration_L(2.0, 1.0, 1e-12) - 0.5) <= 1e-12


def test_summary_json_safe_and_regimes():
    s = bd.boundaries_summary(2.0, 1.5, 0.3)
    json.dumps(s, allow_nan=False)
    assert s["regime"] == "conditionally stable" and s["eps_crit"] == pytest.approx(2 / 3)
    assert bd.boundaries_summary(2.0, 0.5, 0.3)["regime"] == "unconditionally unstable"
    assert bd.boundaries_summary(2.0, 0.5, 0.3, vo=0.0)["regime"] == "conditionally stable"
    s = bd.boundaries_summary(2.0, 5.0, 0.25)
    assert s["regime"] == "unconditionally stable" and s["L_star"] is None
    json.dumps(s, allow_nan=False)
    s = bd.boundaries_summary(2.0, 25.0 / 9.0, 0.36)
    assert s["on_boundary"]["x_equals_1"] and s["regime"] == "unconditionally stable"
    s = bd.boundaries_summary(2.0, 1.0, 0.0)
    assert s["max_unstable_kappa"] is None and s["on_boundary"]["kappa_equals_kappa_crit"]
    json.dumps(s, allow_nan=False)


def test_invalid():
    with pytest.raises(ParameterError):
        bd.eps_crit(2.0, -1.0)
    with pytest.raises(ParameterError):
        bd.ab_crit(1.0, 1.5)
    with pytest.raises(ParameterError):
        bd.acceleration_line(2.0, 1.0, 0.3, [0.0, math.nan])
