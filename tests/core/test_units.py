"""SI <-> dimensionless conversions (rsfcore.units): hand values, round trips, validation,
and equality of SI and dimensionless critical/classify answers."""

from __future__ import annotations

import json
import math
from fractions import Fraction

import numpy as np
import pytest

from rsfcore.critical import critical_perturbation
from rsfcore.params import ParameterError, Params, PhysicalParams
from rsfcore.trajectory import classify
from rsfcore.units import (
    PHYSICAL_FIELDS,
    PhysicalInputs,
    classify_si,
    critical_si,
    kappa_from_lab_stiffness,
    lab_stiffness_from_kappa,
    lab_stiffness_to_Pa_per_m,
    load_point_jump_si,
    load_point_jump_size,
    velocity_jump_si,
    velocity_jump_size,
)

# The example lab set (sigma = 100 MPa, k = 1 GPa/m) with V_* = 1 um/s, V_load = 10 um/s.
LAB = dict(
    a=0.01, b=0.015, Dc_m=1e-5, sigma_Pa=1e8, k_Pa_per_m=1e9, V_star_m_s=1e-6, V_load_m_s=1e-5
)


def _rel(x: float, y: float) -> float:
    return abs(x - y) / abs(y)


def test_hand_computed_groups() -> None:
    """b/a = 0.015/0.01 = 1.5; kappa = 1e9 * 1e-5 / (0.01 * 1e8) = 1e4/1e6 = 0.01;
    v_o = 1e-5/1e-6 = 10; Dc/V_* = 10 s; a sigma = 1 MPa; k_crit = sigma (b - a)/Dc =
    1e8 * 0.005 / 1e-5 = 5e10 Pa/m.  Each is a couple of correctly rounded operations:
    4 ulp (1e-15 relative) covers them."""
    ph = PhysicalInputs(**LAB)
    p = ph.to_params(0.3)
    for got, want in (
        (p.ba, 1.5),
        (p.kappa, 0.01),
        (p.vo, 10.0),
        (p.eps, 0.3),
        (ph.kappa_crit, 0.5),
        (ph.time_scale_s, 10.0),
        (ph.stress_scale_Pa, 1e6),
        (ph.k_crit_Pa_per_m, 5e10),
    ):
        assert _rel(got, want) <= 1e-15
    # answers back: T = 2 -> 20 s; psi = 3 -> 3 MPa and friction change 0.03; phi = ln 5 -> 5 um/s
    assert _rel(ph.time_s(2.0), 20.0) <= 1e-15
    assert _rel(ph.shear_stress_change_Pa(3.0), 3e6) <= 1e-15
    assert _rel(ph.friction_change(3.0), 0.03) <= 1e-15
    assert _rel(ph.slip_rate_m_s(math.log(5.0)), 5e-6) <= 4e-16 * 4
    assert _rel(ph.slip_m(7.0), 7e-5) <= 1e-15


def test_default_load_velocity_is_V_star() -> None:
    ph = PhysicalInputs(**{k: v for k, v in LAB.items() if k != "V_load_m_s"})
    assert ph.V_load_m_s == LAB["V_star_m_s"] and ph.vo == 1.0
    assert ph.to_dict()["V_load_m_s"] == LAB["V_star_m_s"]


def test_perturbations_hand_computed() -> None:
    """Velocity jump from steady sliding at V_load = 10 um/s to 100 um/s: d = ln 10;
    as a factor 10 the same.  Load-point jump to 30 um/s: dv = 30/10 - 1 = 2."""
    ph = PhysicalInputs(**LAB)
    assert velocity_jump_size(ph, new_slip_rate_m_s=1e-4) == pytest.approx(
        math.log(10.0), rel=1e-15
    )
    assert velocity_jump_size(ph, factor=10.0) == math.log(10.0)
    assert load_point_jump_size(ph, new_load_point_velocity_m_s=3e-5) == pytest.approx(
        2.0, rel=1e-15
    )
    assert load_point_jump_size(ph, factor=3.0) == 2.0
    vj = velocity_jump_si(ph, math.log(10.0))
    assert _rel(vj.factor, 10.0) <= 4e-16 and _rel(vj.new_slip_rate_m_s, 1e-4) <= 1e-15
    lj = load_point_jump_si(ph, 2.0)
    assert lj.factor == 3.0 and _rel(lj.new_load_point_velocity_m_s, 3e-5) <= 1e-15
    # stationary load point: the jump starts from V_* (the origin phi = 0)
    ph0 = PhysicalInputs(**{**LAB, "V_load_m_s": 0.0})
    assert ph0.slip_rate_before_m_s == LAB["V_star_m_s"]
    assert velocity_jump_size(ph0, new_slip_rate_m_s=1e-5) == pytest.approx(
        math.log(10.0), rel=1e-15
    )
    with pytest.raises(ParameterError) as e:
        load_point_jump_size(ph0, new_load_point_velocity_m_s=1e-6)
    assert e.value.field == "physical.V_load_m_s"


def test_lab_stiffness() -> None:
    """k = 2e3 /m (friction per metre) at sigma = 1e8 Pa is 2e11 Pa/m; kappa = k Dc/a =
    2e3 * 1e-5 / 0.01 = 2 whichever way it is computed."""
    assert lab_stiffness_to_Pa_per_m(2e3, 1e8) == 2e11
    kap = kappa_from_lab_stiffness(2e3, 1e-5, 0.01)
    assert _rel(kap, 2.0) <= 4e-16
    ph = PhysicalInputs(**{**LAB, "k_Pa_per_m": 2e11})
    assert _rel(ph.kappa, kap) <= 4e-16
    assert _rel(lab_stiffness_from_kappa(kap, 1e-5, 0.01), 2e3) <= 1e-15
    assert kappa_from_lab_stiffness(math.inf, 1e-5, 0.01) == math.inf


def _random_inputs(rng: np.random.Generator) -> PhysicalInputs:
    a = 10 ** rng.uniform(-4, -0.5)
    ba = 1 + 10 ** rng.uniform(-6, 3)
    Dc = 10 ** rng.uniform(-8, -1)
    sigma = 10 ** rng.uniform(4, 9)
    kappa = 10 ** rng.uniform(-4, 5)
    Vs = 10 ** rng.uniform(-12, 0)
    vo = 10 ** rng.uniform(-6, 6)
    return PhysicalInputs(
        a=a,
        b=ba * a,
        Dc_m=Dc,
        sigma_Pa=sigma,
        k_Pa_per_m=kappa * a * sigma / Dc,
        V_star_m_s=Vs,
        V_load_m_s=vo * Vs,
    )


def test_round_trips() -> None:
    """SI -> dimensionless -> SI and back, over 500 random sets spanning the valid ranges.
    Each direction is <= 3 roundings, so the round trip is within ~6 ulp = 1.3e-15;
    asserted at 1e-14 (the issue's bound)."""
    rng = np.random.default_rng(15)
    worst = 0.0
    for _ in range(500):
        ph = _random_inputs(rng)
        eps = float(rng.uniform(0, 1))
        p = ph.to_params(eps)
        back = PhysicalInputs.from_params(
            p, a=ph.a, Dc_m=ph.Dc_m, sigma_Pa=ph.sigma_Pa, V_star_m_s=ph.V_star_m_s
        )
        for name in PHYSICAL_FIELDS:
            worst = max(
                worst,
                _rel(
                    getattr(back, name if name != "V_load_m_s" else "V_load"),
                    getattr(ph, "V_load" if name == "V_load_m_s" else name),
                ),
            )
        p2 = back.to_params(eps)
        for name in ("ba", "kappa", "vo"):
            worst = max(worst, _rel(getattr(p2, name), getattr(p, name)))
        # variables
        T, psi, phi, s = (float(x) for x in rng.uniform(-50, 50, 4))
        T = abs(T)
        worst = max(worst, _rel(ph.T_from_time(ph.time_s(T)), T))
        worst = max(
            worst, _rel(ph.psi_from_shear_stress_change(ph.shear_stress_change_Pa(psi)), psi)
        )
        worst = max(
            worst, abs(ph.phi_from_slip_rate(ph.slip_rate_m_s(phi)) - phi) / max(1.0, abs(phi))
        )
        # perturbations
        d = float(rng.uniform(-30, 30))
        vj = velocity_jump_si(ph, d)
        worst = max(
            worst,
            abs(velocity_jump_size(ph, new_slip_rate_m_s=vj.new_slip_rate_m_s) - d)
            / max(1.0, abs(d)),
        )
        # dv -> V_load (1 + dv) -> V_new/V_load - 1 is conditioned by (1 + dv)/dv (the
        # SI value cannot hold dv better than ulp(1 + dv)): scaled accordingly.
        dv = float(10 ** rng.uniform(-3, 3))
        lj = load_point_jump_si(ph, dv)
        dv_back = load_point_jump_size(
            ph, new_load_point_velocity_m_s=lj.new_load_point_velocity_m_s
        )
        worst = max(worst, _rel(dv_back, dv) * dv / (1.0 + dv))
        # and against PhysicalParams, the older SI container
        pp = ph.to_physical_params(eps)
        q = pp.to_dimensionless()
        for name in ("ba", "kappa", "vo"):
            worst = max(worst, _rel(getattr(q, name), getattr(p, name)))
    assert worst <= 1e-14, worst


def test_groups_correctly_rounded_against_exact_arithmetic() -> None:
    """b/a, kappa and v_o against exact rational arithmetic rounded once: within 2 ulp."""
    rng = np.random.default_rng(7)
    for _ in range(300):
        ph = _random_inputs(rng)
        F = Fraction
        exact = {
            "ba": F(ph.b) / F(ph.a),
            "kappa": F(ph.k_Pa_per_m) * F(ph.Dc_m) / (F(ph.a) * F(ph.sigma_Pa)),
            "vo": F(ph.V_load) / F(ph.V_star_m_s),
        }
        p = ph.to_params(0.5)
        for name, val in exact.items():
            x = float(val)
            assert abs(getattr(p, name) - x) <= 2 * math.ulp(x), name


def test_si_and_dimensionless_answers_equal_exactly() -> None:
    """Inputs chosen so that every group is exact in binary: a = 1/4, b = 3/4 (b/a = 3),
    Dc = 2^-16 m, sigma = 2^20 Pa, k = 3 2^34 Pa/m (kappa = 3 2^34 2^-16/(2^-2 2^20) = 3),
    V_* = 2^-20 m/s, V_load = 2^-18 m/s (v_o = 4).  The SI route must then give bit-identical
    critical sizes and classify outcomes/times to the dimensionless Params(3, 3, 0.5, 4)
    (kappa/kappa_crit = 1.5, x = eps kappa/kappa_crit = 0.75: both sizes finite)."""
    ph = PhysicalInputs(
        a=0.25,
        b=0.75,
        Dc_m=2.0**-16,
        sigma_Pa=2.0**20,
        k_Pa_per_m=3.0 * 2.0**34,
        V_star_m_s=2.0**-20,
        V_load_m_s=2.0**-18,
    )
    p = Params(ba=3.0, kappa=3.0, eps=0.5, vo=4.0)
    assert ph.to_params(0.5) == p
    for pert in ("velocity-jump", "load-point-jump"):
        c_si = critical_si(ph, 0.5, pert)
        c = critical_perturbation(p, pert)
        assert c_si.kind == c.kind == "finite"
        assert c_si.critical_size == c.critical_size
        assert c_si.rel_accuracy == c.rel_accuracy
    c = critical_perturbation(p, "velocity-jump").critical_size
    vj = critical_si(ph, 0.5, "velocity-jump").velocity_jump
    assert vj is not None and vj.new_slip_rate_m_s == 2.0**-18 * math.exp(c)
    # classify from SI: factor 2^k is exact, so the size is exactly ln(factor)
    for factor in (2.0, 64.0):
        r_si = classify_si(ph, 0.5, "velocity-jump", factor=factor)
        r = classify(p, "velocity-jump", math.log(factor))
        assert r_si.outcome == r.outcome and r_si.certificate == r.certificate
        T = r.return_time if r.return_time is not None else r.blowup_time
        t = r_si.return_time_s if r_si.return_time_s is not None else r_si.blowup_time_s
        assert t == T * 2.0**-16 / 2.0**-20
    r_si = classify_si(
        ph, 0.5, "load-point-jump", new_load_point_velocity_m_s=2.0**-15
    )  # dv = 7 exactly
    r = classify(p, "load-point-jump", 7.0)
    assert r_si.size == 7.0 and r_si.outcome == r.outcome


def test_si_and_dimensionless_answers_agree_general() -> None:
    """For arbitrary SI inputs the only difference to a dimensionless query is the rounding
    of the groups (<= 2 ulp, previous test); critical sizes have condition number O(1) in
    the groups here, so the SI and dimensionless answers agree to 1e-12 (the issue's bound)."""
    rng = np.random.default_rng(3)
    n = 0
    while n < 20:
        a = 10 ** rng.uniform(-3, -1)
        ba = float(rng.uniform(1.2, 5))
        ratio = float(rng.uniform(1.1, 4))
        Dc, sigma, Vs = 1e-5, 5e7, 1e-6
        F = Fraction
        kappa_exact = F(ratio) * (F(ba) - 1)
        b = ba * a
        k = float(kappa_exact * F(a) * F(sigma) / F(Dc))
        ph = PhysicalInputs(a=a, b=b, Dc_m=Dc, sigma_Pa=sigma, k_Pa_per_m=k, V_star_m_s=Vs)
        p_dimless = Params(
            ba=float(F(b) / F(a)), kappa=float(F(k) * F(Dc) / (F(a) * F(sigma))), eps=0.4
        )
        c1 = critical_si(ph, 0.4, "velocity-jump")
        c2 = critical_perturbation(p_dimless, "velocity-jump")
        if c2.kind != "finite":
            continue
        n += 1
        assert abs(c1.critical_size - c2.critical_size) <= 1e-12 * abs(c2.critical_size)


@pytest.mark.parametrize(
    "changes, field",
    [
        (dict(a=0.0), "physical.a"),
        (dict(a=1.5), "physical.a"),
        (dict(b=0.01), "physical.b"),  # b = a: not rate weakening
        (dict(b=0.005), "physical.b"),
        (dict(b=1e5), "physical.b"),  # b/a > 1e6
        (dict(Dc_m=0.0), "physical.Dc_m"),
        (dict(Dc_m=float("nan")), "physical.Dc_m"),
        (dict(sigma_Pa=-1.0), "physical.sigma_Pa"),
        (dict(k_Pa_per_m=-1.0), "physical.k_Pa_per_m"),
        (dict(k_Pa_per_m=1e18), "physical.k_Pa_per_m"),  # kappa = 1e7 > 1e6
        (dict(V_star_m_s=0.0), "physical.V_star_m_s"),
        (dict(V_load_m_s=-1e-6), "physical.V_load_m_s"),
        (dict(V_load_m_s="fast"), "physical.V_load_m_s"),
    ],
)
def test_validation_names_field_and_range(changes: dict, field: str) -> None:
    with pytest.raises(ParameterError) as e:
        PhysicalInputs(**{**LAB, **changes})
    assert e.value.field == field
    assert "valid range" in str(e.value) and e.value.valid


def test_b_must_exceed_a_message() -> None:
    with pytest.raises(ParameterError) as e:
        PhysicalInputs(**{**LAB, "b": 0.009})
    assert "b > a" in e.value.valid


def test_from_dict() -> None:
    ph = PhysicalInputs.from_dict(LAB)
    assert ph == PhysicalInputs(**LAB)
    # the "new user" payload uses other names: refused with the valid names listed
    with pytest.raises(ParameterError) as e:
        PhysicalInputs.from_dict({"a": 0.01, "b": 0.015, "k": 1e9, "Dc": 1e-5, "sigma": 1e8})
    assert e.value.field == "physical.k" and "k_Pa_per_m" in e.value.valid
    with pytest.raises(ParameterError) as e:
        PhysicalInputs.from_dict({k: v for k, v in LAB.items() if k != "Dc_m"})
    assert e.value.field == "physical.Dc_m"
    with pytest.raises(ParameterError) as e:
        PhysicalInputs.from_dict({**LAB, "b": 0.001}, prefix="items[3].physical")
    assert e.value.field == "items[3].physical.b"


def test_perturbation_validation() -> None:
    ph = PhysicalInputs(**LAB)
    with pytest.raises(ParameterError) as e:
        velocity_jump_size(ph)
    assert e.value.field == "perturbation"
    with pytest.raises(ParameterError) as e:
        velocity_jump_size(ph, factor=2.0, new_slip_rate_m_s=1e-5)
    assert e.value.field == "perturbation"
    with pytest.raises(ParameterError) as e:
        velocity_jump_size(ph, new_slip_rate_m_s=-1.0)
    assert e.value.field == "perturbation.new_slip_rate_m_s"
    with pytest.raises(ParameterError) as e:
        velocity_jump_size(ph, factor=0.0)
    assert e.value.field == "perturbation.factor"
    with pytest.raises(ParameterError) as e:
        load_point_jump_size(ph, new_load_point_velocity_m_s=0.0)
    assert e.value.field == "perturbation.new_load_point_velocity_m_s"
    with pytest.raises(ParameterError) as e:
        classify_si(ph, 0.5, "velocity-jump", new_load_point_velocity_m_s=1.0)
    assert e.value.field == "perturbation.new_load_point_velocity_m_s"


def test_extreme_answers_json_safe() -> None:
    """Sizes beyond double range come back as None in SI, never inf/NaN."""
    ph = PhysicalInputs(**LAB)
    vj = velocity_jump_si(ph, 5000.0)
    assert vj.factor is None and vj.new_slip_rate_m_s is None
    json.dumps(vj.to_dict(), allow_nan=False)
    lj = load_point_jump_si(PhysicalInputs(**{**LAB, "V_load_m_s": 10.0}), 1e308)  # 1e309 m/s
    assert lj.new_load_point_velocity_m_s is None and lj.factor == 1e308
    json.dumps(lj.to_dict(), allow_nan=False)
    # infinite critical size (aging law at kappa >= kappa_crit / eps): null in JSON
    ph_stiff = PhysicalInputs(**{**LAB, "k_Pa_per_m": 1e11})  # kappa = 1 >= kappa_crit = 0.5
    c = critical_si(ph_stiff, 1.0, "velocity-jump")
    assert c.kind == "infinite" and c.velocity_jump is None
    json.dumps(c.to_dict(), allow_nan=False)
    assert PhysicalInputs(**LAB).slip_rate_m_s(800.0) is None


def test_physical_params_interop() -> None:
    pp = PhysicalParams(
        a=0.01,
        b=0.015,
        Dc_m=1e-5,
        sigma_Pa=1e7,
        k_Pa_per_m=5e9,
        V_star_m_s=1e-6,
        V_load_m_s=3e-6,
        eps=0.3,
    )
    ph = PhysicalInputs.from_physical_params(pp)
    assert ph.to_params(0.3) == pp.to_dimensionless()
    assert ph.to_physical_params(0.3) == pp


def test_answers_beyond_double_range_by_their_logarithm() -> None:
    """A critical size beyond the double range (d or l = ln(1 + dv) > 709) converts to SI
    by its logarithm: the factor and the new velocity are None, their log10 follow from
    the definitions (independent arithmetic here); no error names a field 'd'."""
    ph = PhysicalInputs(**LAB)
    vj = velocity_jump_si(ph, 2.0e4).to_dict()
    assert vj["factor"] is None and vj["new_slip_rate_m_s"] is None
    assert vj["log10_new_slip_rate_m_s"] == pytest.approx(
        math.log10(ph.slip_rate_before_m_s) + 2.0e4 / math.log(10.0), rel=1e-15
    )
    lj = load_point_jump_si(ph, None, log_factor=3.0e4).to_dict()
    assert lj["dv"] is None and lj["factor"] is None and lj["new_load_point_velocity_m_s"] is None
    assert lj["log_factor"] == 3.0e4
    assert lj["log10_new_load_point_velocity_m_s"] == pytest.approx(
        math.log10(ph.V_load) + 3.0e4 / math.log(10.0), rel=1e-15
    )
    # a representable size given both ways: the same numbers as from dv alone
    both = load_point_jump_si(ph, 2.0, log_factor=math.log1p(2.0)).to_dict()
    assert both == load_point_jump_si(ph, 2.0).to_dict()
    json.dumps([vj, lj], allow_nan=False)
