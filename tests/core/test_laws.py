"""Evolution-law family: exact slip limit, no cancellation for tiny eps, L*, Nagata mapping."""

from __future__ import annotations

import math

import mpmath as mp
import pytest

from rsfcore.laws import (
    G,
    G_clipped,
    L_star,
    intermediate_to_nagata,
    nagata_to_intermediate,
    state_rate,
)
from rsfcore.params import ParameterError

mp.mp.dps = 50


def _G_exact(L: float, eps: float) -> float:
    if eps == 0:
        return -L
    e = mp.mpf(eps)
    return float(mp.expm1(-e * mp.mpf(L)) / e)


@pytest.mark.parametrize("eps", [0.0, 5e-324, 1e-300, 1e-12, 1e-5, 0.25, 0.5, 1.0])
@pytest.mark.parametrize("L", [-50.0, -3.0, -1e-8, 0.0, 1e-8, 0.7, 5.0, 200.0])
def test_G_matches_high_precision(eps: float, L: float) -> None:
    # 4 ulp: expm1 and the 4-term series are each accurate to a couple of ulp.
    assert G(L, eps) == pytest.approx(_G_exact(L, eps), rel=4 * 2.2e-16, abs=1e-300)


def test_G_limits() -> None:
    assert G(1.3, 0.0) == -1.3  # slip law exactly
    assert G(1.3, 1.0) == pytest.approx(math.exp(-1.3) - 1.0, rel=1e-15)  # aging law
    assert math.isfinite(G_clipped(-1e6, 1.0)) and G_clipped(-1e6, 1.0) > 1e200


@pytest.mark.parametrize("eps", [0.0, 1e-300, 1e-12, 1e-6, 0.3, 0.999999])
@pytest.mark.parametrize("r", [0.1, 1.0, 2.5])
def test_L_star_high_precision(eps: float, r: float) -> None:
    kc = 1.0
    x = eps * r
    if x >= 1:
        assert L_star(r, kc, eps) == math.inf
        return
    exact = r if eps == 0 else float(-mp.log1p(-mp.mpf(eps) * r) / mp.mpf(eps))
    assert L_star(r, kc, eps) == pytest.approx(exact, rel=4e-16)
    # L* is the root of g(L) = -kappa - kappa_crit G(L)
    assert -r - kc * G(L_star(r, kc, eps), eps) == pytest.approx(0.0, abs=1e-14 * max(1.0, r))


def test_L_star_naive_form_would_fail() -> None:
    # numerics.md: -log(1-x)/eps is off by ~2e-5 at eps = 1e-12; ours is not.
    eps, r = 1e-12, 1.0
    naive = -math.log(1 - eps * r) / eps
    assert abs(naive - 1.0) > 1e-6
    assert L_star(r, 1.0, eps) == pytest.approx(1.0, rel=1e-15)
    assert L_star(2.0, 1.0, 0.5) == math.inf  # x = 1: no runaway


def test_state_rate_end_members() -> None:
    V, th, Dc = 2e-6, 3.0, 1e-5
    om = V * th / Dc
    assert state_rate(V, th, Dc, 1.0) == pytest.approx(1 - om, rel=1e-14)
    assert state_rate(V, th, Dc, 0.0) == pytest.approx(-om * math.log(om), rel=1e-14)


def test_nagata_mapping_round_trip_and_errors() -> None:
    m = nagata_to_intermediate(aN=0.012, bN=0.016, DcN=2e-5, cN=2.0)
    assert m["eps"] == pytest.approx(1 - 0.012 * 2 / (3 * 0.016))
    back = intermediate_to_nagata(m["a"], m["b"], m["Dc"], m["eps"])
    assert back["aN"] == pytest.approx(0.012) and back["bN"] == pytest.approx(0.016)
    assert back["DcN"] == pytest.approx(2e-5) and back["cN"] == pytest.approx(2.0)
    assert nagata_to_intermediate(0.01, 0.015, 1e-5, 0.0)["eps"] == 1.0  # cN = 0: aging law
    with pytest.raises(ParameterError) as e:
        intermediate_to_nagata(0.01, 0.015, 1e-5, 0.0)
    assert e.value.field == "eps"
    with pytest.raises(ParameterError):
        nagata_to_intermediate(aN=0.1, bN=0.01, DcN=1e-5, cN=100.0)
