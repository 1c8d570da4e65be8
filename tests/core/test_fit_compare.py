"""The law comparison's shared and shortened work (rsfcore.fit.compare_laws): laws stopped
once their rejection is certain (``complete``) against the same laws fitted completely,
and that the best law's fit does not depend on it."""

from __future__ import annotations

import math

import numpy as np
import pytest

from rsfcore.fit import FitStatus, attach_stability, compare_laws, synthetic_record

TRUE = {"mu0": 0.6, "a": 0.01, "b": 0.015, "Dc_m": 1e-5, "k_per_m": 1000.0}


def _record(noise: float, eps: float = 1.0, n: int = 3000):  # type: ignore[no-untyped-def]
    t = np.linspace(0.0, 60.0, n)
    v = np.where(t < 20.0, 1e-6, np.where(t < 40.0, 1e-5, 3e-6))
    return synthetic_record(t, v, **TRUE, eps=eps, noise=noise, seed=5, rtol=1e-12)


@pytest.fixture(scope="module")
def noisy_pair():  # type: ignore[no-untyped-def]
    rec = _record(1e-4)
    laws = ("aging", "slip", "nagata", "eps")
    full = compare_laws(rec, laws, uncertainty_samples=20)
    short = compare_laws(rec, laws, complete=(), uncertainty_samples=20)
    return full, short


def test_stopped_laws_keep_the_verdict_and_bound_the_polished_fit(noisy_pair) -> None:  # type: ignore[no-untyped-def]
    full, short = noisy_pair
    assert full.best == short.best == "aging"
    stopped = [k for k, f in short.fits.items() if f.stopped_early]
    assert set(stopped) == {"slip", "nagata"}  # rejected by thousands of AIC units
    s_full = {s.law: s for s in full.scores}
    s_short = {s.law: s for s in short.scores}
    for law in stopped:
        f, g = short.fits[law], full.fits[law]
        assert g.status is FitStatus.REJECTED and f.status is FitStatus.REJECTED
        assert s_short[law].status == "rejected"
        # the certainty claim, checked against the completely fitted law: its misfit lies
        # between the stopped iterate's and the stated lower bound
        assert f.rss_lower_bound is not None
        assert f.rss_lower_bound <= g.rss <= f.rss * (1 + 1e-12)
        assert s_short[law].delta_aic >= s_full[law].delta_aic > 10.0
        # labelled: not converged, no standard errors, no stability answer
        assert not f.converged and all(v is None for v in f.stderr.values())
        assert "at least" in f.message and "not polished" in f.message
        assert math.isnan(f.model_accuracy)
        assert attach_stability(f, uncertainty_samples=10) is None
        d = f.to_dict(series=False)
        assert d["stopped_early"] is True and d["status"] == "rejected"


def test_best_law_is_the_same_fit_either_way(noisy_pair) -> None:  # type: ignore[no-untyped-def]
    full, short = noisy_pair
    a, b = full.fits["aging"], short.fits["aging"]
    assert not b.stopped_early and b.ok
    # the same start and the same iterations: identical to the last bit
    assert a.params == b.params and a.stderr == b.stderr
    assert a.stability is not None and b.stability is not None
    assert a.stability.to_dict() == b.stability.to_dict()


def test_requested_law_is_fitted_completely() -> None:
    rec = _record(1e-4, n=1500)
    cmp = compare_laws(rec, ("aging", "slip"), complete=("slip",), uncertainty_samples=10)
    slip = cmp.fits["slip"]
    assert not slip.stopped_early and slip.converged
    assert slip.status is FitStatus.REJECTED and slip.stderr["a"] is not None


def test_noise_free_records_are_never_stopped() -> None:
    """The misfit floor decides there (best rms ~1e-12 < 1000 x floor): every law is
    fitted completely, as without ``complete``."""
    cmp = compare_laws(_record(0.0, n=1500), ("aging", "slip"), complete=(), stability=False)
    assert not any(f.stopped_early for f in cmp.fits.values())
    assert cmp.best == "aging" and cmp.fits["slip"].status is FitStatus.REJECTED
