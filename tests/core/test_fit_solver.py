"""The fits' own pieces of numerics, checked against independent implementations:
rsfcore.fit.lsq (bounded trust-region least squares) against scipy.optimize.least_squares,
rsfcore.fit.start's vectorised start scan against one least-squares solve per grid point,
and that importing rsfcore.fit does not import scipy.optimize (its CLI start-up cost)."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest
from scipy.optimize import least_squares as scipy_lsq

from rsfcore.fit import Law, synthetic_record
from rsfcore.fit.core import DEFAULT_BOUNDS
from rsfcore.fit.lsq import least_squares
from rsfcore.fit.start import START_EPS, StartScan, stiff_columns


def _exp_decay(x: np.ndarray, t: np.ndarray, y: np.ndarray) -> np.ndarray:
    return x[0] + x[1] * np.exp(-t / x[2]) - y


def _exp_jac(x: np.ndarray, t: np.ndarray) -> np.ndarray:
    e = np.exp(-t / x[2])
    return np.column_stack([np.ones_like(t), e, x[1] * e * t / x[2] ** 2])


@pytest.mark.parametrize(
    "ub2",
    [10.0, 1.5],  # free minimum; then the time constant's upper bound is active
)
def test_lsq_matches_scipy_on_a_bounded_exponential_fit(ub2: float) -> None:
    rng = np.random.default_rng(1)
    t = np.linspace(0.0, 10.0, 400)
    y = 0.3 + 2.0 * np.exp(-t / 2.0) + rng.normal(0.0, 0.01, t.shape)
    lb, ub = np.array([-5.0, 0.0, 0.1]), np.array([5.0, 10.0, ub2])
    x0 = np.array([0.0, 1.0, 1.0])

    def f(x: np.ndarray) -> np.ndarray:
        return _exp_decay(x, t, y)

    def j(x: np.ndarray) -> np.ndarray:
        return _exp_jac(x, t)

    ours = least_squares(f, x0, j, (lb, ub), ftol=1e-12, xtol=1e-12, gtol=1e-12)
    ref = scipy_lsq(
        f, x0, jac=j, bounds=(lb, ub), method="trf", x_scale="jac", ftol=1e-12, xtol=1e-12
    )
    assert ours.status > 0 and ref.status > 0
    # the standard errors of this fit are ~1e-3; both must find the same minimum to far
    # below them (the bound-active case: scipy stays strictly inside, by ~1e-10 relative)
    np.testing.assert_allclose(ours.x, ref.x, rtol=0, atol=1e-7)
    assert ours.cost == pytest.approx(ref.cost, rel=1e-9)
    if ub2 < 2.0:
        assert ours.x[2] == pytest.approx(ub2, abs=1e-8)


def test_lsq_stops_on_its_evaluation_budget_with_status_0() -> None:
    t = np.linspace(0.0, 10.0, 50)
    y = 1.0 + np.exp(-t / 3.0)
    res = least_squares(
        lambda x: _exp_decay(x, t, y),
        np.array([0.0, 0.1, 0.2]),
        lambda x: _exp_jac(x, t),
        (np.array([-5.0, 0.0, 0.1]), np.array([5.0, 10.0, 10.0])),
        max_nfev=3,
    )
    assert res.status == 0 and res.nfev == 3 and "maximum number" in res.message


def test_lsq_passes_exceptions_of_the_residual_through() -> None:
    class Stop(Exception):
        pass

    def f(x: np.ndarray) -> np.ndarray:
        raise Stop

    with pytest.raises(Stop):
        least_squares(f, np.zeros(2), lambda x: np.eye(2), (-np.ones(2), np.ones(2)))


def _brute_force_start(rec, eps_values, trend):  # type: ignore[no-untyped-def]
    """One numpy.linalg.lstsq per grid point (the scan as it was before vectorising)."""
    scan = StartScan(rec, DEFAULT_BOUNDS["Dc_m"], None, trend)
    best = None
    for eps in eps_values:
        for Dc in scan.Dcs:
            phi, lth, m = stiff_columns(rec, float(Dc), eps)
            cols = [np.ones(int(m.sum())), phi[m], lth[m]]
            if trend:
                cols.append(rec.load_point_m[m])
            A = np.column_stack(cols)
            coef, *_ = np.linalg.lstsq(A, rec.mu[m], rcond=None)
            r = A @ coef - rec.mu[m]
            rss = float(r @ r)
            if best is None or rss < best[0]:
                best = (rss, eps, float(Dc))
    assert best is not None
    return scan, best


@pytest.mark.parametrize("hold", [False, True])
@pytest.mark.parametrize("trend", [False, True])
def test_start_scan_picks_the_grid_point_of_per_point_solves(hold: bool, trend: bool) -> None:
    t = np.linspace(0.0, 100.0, 2000)
    if hold:
        v = np.where((t >= 20.0) & (t < 50.0), 0.0, 1e-6)
    else:
        v = np.where(t < 30.0, 1e-6, np.where(t < 60.0, 1e-5, 3e-6))
    rec = synthetic_record(
        t,
        v,
        mu0=0.6,
        a=0.01,
        b=0.015,
        Dc_m=1e-5,
        eps=0.6,
        k_per_m=2000.0,
        noise=1e-4,
        trend_per_m=20.0 if trend else 0.0,
    )
    for law in Law:
        eps_values = {Law.AGING: (1.0,), Law.SLIP: (0.0,)}.get(law, START_EPS)
        scan, (rss, eps, Dc) = _brute_force_start(rec, eps_values, trend)
        got_eps, got_Dc = scan.best(eps_values)
        assert (got_eps, got_Dc) == (eps, Dc), law
        i = int(np.flatnonzero(scan.Dcs == Dc)[0])
        # the projected RSS against lstsq's: rounding of sums over 2000 samples
        assert scan.row(eps)[i] == pytest.approx(rss, rel=1e-9)


def test_importing_the_fits_does_not_import_scipy_optimize() -> None:
    code = (
        "import sys, rsfcore.fit, rsfcore.fit.core; "
        "print(any(m == 'scipy.optimize' or m.startswith('scipy.optimize.') for m in sys.modules))"
    )
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, check=True
    ).stdout
    assert out.strip() == "False"
