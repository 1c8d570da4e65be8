"""Parameter validation and physical <-> dimensionless conversion (`eq: characteristic scales`)."""

from __future__ import annotations

import math

import pytest

from rsfcore import ParameterError, Params, PhysicalParams


@pytest.mark.parametrize(
    "kwargs, field",
    [
        (dict(ba=1.0, kappa=1.0, eps=0.5), "ba"),
        (dict(ba=0.5, kappa=1.0, eps=0.5), "ba"),
        (dict(ba=2.0, kappa=-1.0, eps=0.5), "kappa"),
        (dict(ba=2.0, kappa=1.0, eps=1.5), "eps"),
        (dict(ba=2.0, kappa=1.0, eps=-1e-3), "eps"),
        (dict(ba=2.0, kappa=1.0, eps=0.5, vo=-1.0), "vo"),
        (dict(ba=float("nan"), kappa=1.0, eps=0.5), "ba"),
        (dict(ba=2.0, kappa=float("inf"), eps=0.5), "kappa"),
        (dict(ba=2.0, kappa=1e7, eps=0.5), "kappa"),
    ],
)
def test_invalid_params_name_field_and_range(kwargs: dict, field: str) -> None:
    with pytest.raises(ParameterError) as e:
        Params(**kwargs)
    assert e.value.field == field
    assert field in str(e.value) and "valid range" in str(e.value)


def test_physical_round_trip() -> None:
    ph = PhysicalParams(
        a=0.01,
        b=0.015,
        Dc_m=1e-5,
        sigma_Pa=1e7,
        k_Pa_per_m=5e9,
        V_star_m_s=1e-6,
        V_load_m_s=3e-6,
        eps=0.3,
    )
    p = ph.to_dimensionless()
    assert p.ba == pytest.approx(1.5, rel=1e-15)
    assert p.kappa == pytest.approx(5e9 * 1e-5 / (0.01 * 1e7), rel=1e-15)
    assert p.vo == pytest.approx(3.0, rel=1e-15)
    back = PhysicalParams.from_dimensionless(p, a=0.01, Dc_m=1e-5, sigma_Pa=1e7, V_star_m_s=1e-6)
    for name in ("a", "b", "Dc", "sigma", "k", "V_star", "Vo", "eps"):
        assert getattr(back, name) == pytest.approx(getattr(ph, name), rel=1e-14)
    # k_crit = sigma (b - a)/Dc  <->  kappa_crit = b/a - 1 (`eq: critical stiffness`)
    assert ph.k_crit * ph.Dc / (ph.a * ph.sigma) == pytest.approx(p.kappa_crit, rel=1e-14)
    assert ph.time(1.0) == pytest.approx(10.0)
    assert ph.velocity(math.log(2.0)) == pytest.approx(2e-6)


@pytest.mark.parametrize(
    "kwargs, field",
    [
        (dict(a=0.0), "a"),
        (dict(b=0.005), "b"),
        (dict(Dc_m=0.0), "Dc_m"),
        (dict(sigma_Pa=-1.0), "sigma_Pa"),
        (dict(V_star_m_s=0.0), "V_star_m_s"),
        (dict(V_load_m_s=-1e-6), "V_load_m_s"),
        (dict(eps=2.0), "eps"),
    ],
)
def test_invalid_physical(kwargs: dict, field: str) -> None:
    base = dict(
        a=0.01,
        b=0.015,
        Dc_m=1e-5,
        sigma_Pa=1e7,
        k_Pa_per_m=5e9,
        V_star_m_s=1e-6,
        V_load_m_s=1e-6,
        eps=0.3,
    )
    base.update(kwargs)
    with pytest.raises(ParameterError) as e:
        PhysicalParams(**base)
    assert e.value.field == field


def test_from_ratio() -> None:
    p = Params.from_ratio(2.0, 1.5, 0.1)
    assert p.kappa == 1.5 and p.kappa_ratio == 1.5 and p.kappa_crit == 1.0


def test_physical_params_si_names_and_deprecated_keywords() -> None:
    """PhysicalParams is spelled as HTTP and the CLI (Dc_m, sigma_Pa, k_Pa_per_m,
    V_star_m_s, V_load_m_s; V_load defaults to V_*, eps to the one default 0.25); the
    older keywords still build the same machine, with a DeprecationWarning, and the older
    attribute names read the same values."""
    new = PhysicalParams(a=0.01, b=0.015, Dc_m=1e-5, sigma_Pa=1e7, k_Pa_per_m=5e9, V_star_m_s=1e-6)
    assert new.V_load_m_s == 1e-6 and new.eps == 0.25 and new.f_star == 0.6
    with pytest.warns(DeprecationWarning, match="Dc -> Dc_m"):
        old = PhysicalParams(
            a=0.01, b=0.015, Dc=1e-5, sigma=1e7, k=5e9, V_star=1e-6, Vo=1e-6, eps=0.25
        )
    assert old == new
    assert (old.Dc, old.sigma, old.k, old.V_star, old.Vo) == (1e-5, 1e7, 5e9, 1e-6, 1e-6)
    with pytest.raises(TypeError):
        PhysicalParams(a=0.01, b=0.015, Dc_m=1e-5, sigma_Pa=1e7, k_Pa_per_m=5e9)
    with pytest.raises(ParameterError) as e:
        PhysicalParams(a=0.01, b=0.015, Dc_m=1e-5, sigma_Pa=1e7, k_Pa_per_m=1e20, V_star_m_s=1)
    assert e.value.field == "k_Pa_per_m"
