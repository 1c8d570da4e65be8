"""rsfcore.batch.critical_points: the array form of critical_perturbation."""

from __future__ import annotations

import math

import numpy as np
import pytest

from rsfcore import batch
from rsfcore import critical as crit
from rsfcore.diagram import stability_diagram
from rsfcore.params import ParameterError, Params
from rsfcore.trajectory import classify


def _random_points(n: int, seed: int) -> tuple[np.ndarray, ...]:
    rng = np.random.default_rng(seed)
    ba = 1.0 + 10 ** rng.uniform(-1.5, 1.5, n)
    ratio = rng.uniform(0.5, 5.0, n)
    ratio[::7] = 1.0  # kappa = kappa_crit: closed forms
    eps = rng.uniform(0.0, 0.99, n)
    vo = rng.choice([0.0, 1e-3, 1.0, 7.5], n)
    return ba, ratio * (ba - 1.0), eps, vo


@pytest.mark.parametrize("pert", ["velocity-jump", "load-point-jump"])
def test_matches_critical_perturbation_point_by_point(pert: str) -> None:
    ba, kappa, eps, vo = _random_points(200, 1 if pert == "velocity-jump" else 2)
    if pert == "load-point-jump":
        vo = np.where(vo == 0.0, 2.0, vo)
    res = batch.critical_points(ba, kappa, eps, vo, perturbation=pert, rtol=1e-10)
    kinds = set()
    for i in range(ba.size):
        ref = crit.critical_perturbation(Params(ba[i], kappa[i], eps[i], vo[i]), pert, rtol=1e-10)
        kinds.add(ref.kind)
        assert crit.KINDS[res.kind[i]] == ref.kind
        assert not res.failed[i]
        if ref.kind == "finite":
            # Same compiled kernel and same fallback: equal up to rounding (1e-12 is the
            # agreement the service promises; the numbers are in fact identical).
            assert res.critical_size[i] == pytest.approx(ref.critical_size, rel=1e-12)
            assert res.rel_accuracy[i] == pytest.approx(ref.rel_accuracy, rel=1e-12)
        elif ref.kind == "zero":
            assert res.critical_size[i] == 0.0
        else:
            assert math.isinf(res.critical_size[i])
    assert kinds == {"zero", "finite", "infinite"}  # the sample covers every kind


def test_vo_independence_is_what_the_kernel_does() -> None:
    """Critical sizes do not depend on v_o > 0 (the invariance the batch relies on)."""
    p = dict(ba=3.0, kappa=5.0, eps=0.3)
    a = crit.critical_perturbation(Params(vo=1e-6, **p), rtol=1e-10).critical_size
    b = crit.critical_perturbation(Params(vo=1e6, **p), rtol=1e-10).critical_size
    assert a == b


def test_outcome_agrees_with_stability_diagram() -> None:
    kr = np.linspace(0.5, 4.0, 9)
    ep = np.linspace(0.0, 0.9, 7)
    d = stability_diagram("kappa_ratio", kr, "eps", ep, ba=2.0, vo=1.0, size=0.8)
    K, E = np.meshgrid(kr, ep, indexing="ij")
    res = batch.critical_points(2.0, (K * 1.0).ravel(), E.ravel(), 1.0, size=0.8)
    assert res.outcome is not None and d.outcome is not None
    assert np.array_equal(res.outcome, d.outcome.ravel())
    assert np.array_equal(res.outcome_uncertain, d.outcome_uncertain.ravel())
    assert np.array_equal(res.critical_size, d.critical_size.ravel())


def test_negative_size_is_classified() -> None:
    res = batch.critical_points([2.0, 2.0], [3.0, 0.5], [0.2, 0.2], 1.0, size=[-0.5, -0.5])
    for i, k in enumerate([3.0, 0.5]):
        ref = classify(Params(2.0, k, 0.2, 1.0), "velocity-jump", -0.5)
        assert res.outcome[i] == (1 if ref.outcome == "unstable" else 0)


def test_failure_isolated(monkeypatch: pytest.MonkeyPatch) -> None:
    """A point whose fallback raises is recorded; the others are kept."""
    orig = crit.critical_batch

    def flagging(ba, kappa, eps, vo, pert, rtol, kind, value, acc, meth, flags):
        orig(ba, kappa, eps, vo, pert, rtol, kind, value, acc, meth, flags)
        flags[eps == 0.5] |= crit.FLAG_FALLBACK

    def failing(params, *a, **kw):
        raise FloatingPointError(f"boom at {params.eps}")

    monkeypatch.setattr(crit, "critical_batch", flagging)
    monkeypatch.setattr(crit, "bisect_critical", failing)
    eps = np.array([0.1, 0.5, 0.2, 0.5])
    res = batch.critical_points(2.0, 3.0, eps, 1.0)
    assert res.failed.tolist() == [False, True, False, True]
    assert set(res.errors) == {1, 3} and "boom at 0.5" in res.errors[1]
    assert np.isnan(res.critical_size[[1, 3]]).all() and (res.kind[[1, 3]] == -1).all()
    ref = crit.critical_perturbation(Params(2.0, 3.0, 0.2, 1.0)).critical_size
    assert res.critical_size[2] == ref


@pytest.mark.parametrize(
    "kw, field",
    [
        (dict(ba=[2.0, 0.5], kappa=1.0, eps=0.1, vo=1.0), "ba[1]"),
        (dict(ba=[2.0, 2.0], kappa=1.0, eps=[0.1, 0.2, 0.3], vo=1.0), "ba"),
        (dict(ba=[2.0, 2.0, 2.0], kappa=1.0, eps=[0.1, 0.2, 1.5], vo=1.0), "eps[2]"),
        (
            dict(ba=[2.0, 2.0], kappa=1.0, eps=0.1, vo=[1.0, 0.0], perturbation="load-point-jump"),
            "vo[1]",
        ),
        (dict(ba=[2.0, 2.0], kappa=[1.0, np.nan], eps=0.1, vo=1.0), "kappa[1]"),
    ],
)
def test_bad_input_names_element(kw: dict, field: str) -> None:
    with pytest.raises(ParameterError) as e:
        batch.critical_points(**kw)
    assert e.value.field == field
