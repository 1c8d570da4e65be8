"""Radau IIA of order 5 (rsfcore.ode.radau5): its coefficients against the closed forms
printed in Hairer & Wanner II, its orders on problems with known solutions (local error,
embedded estimate, collocation polynomial), its behaviour on Prothero & Robinson's stiff
problem, and the fixed-iteration replay (issue 22 item 3).

The coefficients are derived in radau5.py from the method's definition (collocation at
the Radau points); the closed forms here are the independent check (a wrong node or sign
moves an entry by O(1))."""

from __future__ import annotations

import math

import numba as nb
import numpy as np
import pytest

from rsfcore.ode import radau5

S6 = math.sqrt(6.0)


def test_tableau_matches_the_printed_closed_forms() -> None:
    """A (Hairer & Wanner II, Table IV.5.6), the eigenvalues of A^-1 (gamma = 1/u1 with
    u1 = (6 + 81^(1/3) - 9^(1/3))/30, alpha +- i beta from (12 - 81^(1/3) + 9^(1/3))/60
    and (81^(1/3) + 9^(1/3)) sqrt(3)/60 over their squared modulus: radau5.f's
    constants), and gamma e = (-(13 + 7 sqrt 6)/3, (-13 + 7 sqrt 6)/3, -1/3) (the error
    weights of eq. (8.19) times gamma).  Measured: A within 1.7e-16."""
    a = np.array(
        [
            [(88 - 7 * S6) / 360, (296 - 169 * S6) / 1800, (-2 + 3 * S6) / 225],
            [(296 + 169 * S6) / 1800, (88 + 7 * S6) / 360, (-2 - 3 * S6) / 225],
            [(16 - S6) / 36, (16 + S6) / 36, 1 / 9],
        ]
    )
    np.testing.assert_allclose(radau5.A, a, rtol=0, atol=1e-14)
    np.testing.assert_allclose(radau5.C, [(4 - S6) / 10, (4 + S6) / 10, 1.0], rtol=1e-15)
    c81, c9 = 81 ** (1 / 3), 9 ** (1 / 3)
    gamma, alpha, beta = radau5.GAMMA, radau5.ALPHA, radau5.BETA
    assert gamma == pytest.approx(30 / (6 + c81 - c9), rel=1e-14)
    al, be = (12 - c81 + c9) / 60, (c81 + c9) * math.sqrt(3) / 60
    cno = al * al + be * be
    assert alpha == pytest.approx(al / cno, rel=1e-14)
    assert beta == pytest.approx(be / cno, rel=1e-14)
    dd = np.array([-(13 + 7 * S6) / 3, (-13 + 7 * S6) / 3, -1 / 3])
    np.testing.assert_allclose(radau5.GAMMA * radau5.E, dd, rtol=1e-13)


def test_transformation_splits_a_inverse() -> None:
    """T^-1 A^-1 T = [[gamma, 0, 0], [0, alpha, -beta], [0, beta, alpha]]: the real and the
    complex system the Newton iteration solves (to rounding, 1e-13)."""
    m = radau5.TI @ np.linalg.inv(radau5.A) @ radau5.T
    want = np.array(
        [
            [radau5.GAMMA, 0.0, 0.0],
            [0.0, radau5.ALPHA, -radau5.BETA],
            [0.0, radau5.BETA, radau5.ALPHA],
        ]
    )
    np.testing.assert_allclose(m, want, rtol=0, atol=1e-13)
    np.testing.assert_allclose(radau5.TI @ radau5.T, np.eye(3), rtol=0, atol=1e-14)


@nb.njit(cache=False)
def _osc(y, out, w):
    """y0' = w y1, y1' = -w y0, y2' = y0^2 (a quadrature): y0 = cos(w t), y1 = -sin(w t)."""
    out[0] = w * y[1]
    out[1] = -w * y[0]
    out[2] = y[0] * y[0]


def _osc_exact(t: float, w: float) -> np.ndarray:
    return np.array([math.cos(w * t), -math.sin(w * t), 0.5 * t + math.sin(2 * w * t) / (4 * w)])


@nb.njit(cache=False)
def _one_step(y, h, w, n_fixed):
    n = y.shape[0]
    f = np.empty(n)
    _osc(y, f, w)
    J = np.zeros((n, 2))
    J[0, 1] = w
    J[1, 0] = -w
    J[2, 0] = 2.0 * y[0]
    sc = np.full(3, 1e-14)
    Z = np.empty((3, n))
    FZ = np.empty((3, n))
    tmp = np.empty(n)
    ftmp = np.empty(n)
    ynew = np.empty(n)
    fnew = np.empty(n)
    st, n_rhs, n_newton = radau5.step(
        _osc, (w,), y, f, h, J, sc, Z, FZ, tmp, ftmp, ynew, fnew, n_fixed
    )
    ev = np.empty(n)
    err, _ = radau5.error_norm(_osc, (w,), y, f, h, J, Z, np.ones(3), 3, False, tmp, ftmp, ev)
    F = np.empty((7, n))
    radau5.dense_coeffs(Z, F)
    return st, n_newton, ynew, Z, ev, F


def _dense(F: np.ndarray, y0: np.ndarray, x: float) -> np.ndarray:
    from rsfcore.ode import rk

    out = np.empty(y0.shape[0])
    rk.dense_eval(F, y0, x, out)
    return out


def test_local_orders_on_a_known_solution() -> None:
    """On the harmonic oscillator with a quadrature (exact solution known), per halving of
    h: the step's local error falls 2^6 = 64x (order 5; accept > 48), the embedded
    estimate 2^4 = 16x (accept > 12), and the collocation polynomial's error at mid-step
    2^4x too (stage order 3; accept > 12).  Measured ratios 62.6-63.6, 15.8-15.9,
    16.0-16.1."""
    y0 = _osc_exact(0.0, 1.0)
    errs, ests, dens = [], [], []
    for h in (0.2, 0.1, 0.05):
        st, _, y1, Z, ev, F = _one_step(y0.copy(), h, 1.0, 0)
        assert st == 0
        errs.append(np.abs(y1 - _osc_exact(h, 1.0)).max())
        ests.append(np.abs(ev).max())
        dens.append(np.abs(_dense(F, y0, 0.5) - _osc_exact(0.5 * h, 1.0)).max())
        # the polynomial passes through the stages
        for i, ci in enumerate(radau5.C):
            np.testing.assert_allclose(_dense(F, y0, ci), y0 + Z[i], rtol=0, atol=1e-15)
    for k in range(2):
        assert errs[k] / errs[k + 1] > 48, errs
        assert ests[k] / ests[k + 1] > 12, ests
        assert dens[k] / dens[k + 1] > 12, dens


@nb.njit(cache=False)
def _pr(y, out, lam):
    """Prothero & Robinson's y' = lam (y - sin x) + cos x as the autonomous pair (x, y)."""
    out[0] = 1.0
    out[1] = lam * (y[1] - math.sin(y[0])) + math.cos(y[0])


@nb.njit(cache=False)
def _pr_run(lam, h, n_steps):
    y = np.array([0.0, 0.0])
    f = np.empty(2)
    J = np.zeros((2, 2))
    Z = np.empty((3, 2))
    FZ = np.empty((3, 2))
    tmp = np.empty(2)
    ftmp = np.empty(2)
    ynew = np.empty(2)
    fnew = np.empty(2)
    sc = np.full(2, 1e-12)
    for _ in range(n_steps):
        _pr(y, f, lam)
        J[1, 0] = -lam * math.cos(y[0]) - math.sin(y[0])
        J[1, 1] = lam
        st, _, _ = radau5.step(_pr, (lam,), y, f, h, J, sc, Z, FZ, tmp, ftmp, ynew, fnew, 0)
        if st != 0:
            return np.nan
        y[0] = ynew[0]
        y[1] = ynew[1]
    return abs(y[1] - math.sin(y[0]))


def test_prothero_robinson_error_shrinks_with_stiffness() -> None:
    """y' = lambda (y - sin x) + cos x from the smooth solution y = sin x, to x = 1 with
    h = 0.1, 0.05, 0.025: at lambda = -1e6 (h |lambda| = 2.5e4 .. 1e5) the global error
    falls 2^3 = 8x per halving (the stage order 3; accept > 6) and carries a factor
    1/|lambda| (measured 1.0e-11 / 1.0e-9 / 4.6e-8 at h = 0.1 and lambda = -1e6 / -1e4 /
    -1e2; accept < 1e-10 at -1e6): the stiff component is no obstacle, where RODAS4 drops
    to order ~1 (tests/core/test_rodasp.py).  The engine's stiff relaxations have this
    problem's shape."""
    errs = [_pr_run(-1e6, 1.0 / n, n) for n in (10, 20, 40)]
    assert all(math.isfinite(e) for e in errs), errs
    assert errs[0] < 1e-10, errs
    for k in range(2):
        assert errs[k] / errs[k + 1] > 6, errs
    soft = _pr_run(-1e2, 0.1, 10)
    assert errs[0] < 1e-2 * soft, (errs[0], soft)


def test_fixed_iterations_repeat_the_step_bit_for_bit() -> None:
    """A step taken again with the number of Newton iterations it reported gives the same
    stages, solution and dense output, bit for bit (what engine.replay_samples relies on)."""
    y0 = np.array([0.3, -0.2, 0.1])
    st, n_newton, y1, Z, _, F = _one_step(y0.copy(), 0.3, 2.0, 0)
    assert st == 0 and 2 <= n_newton <= radau5.MAX_NEWTON
    st2, n2, y1b, Zb, _, Fb = _one_step(y0.copy(), 0.3, 2.0, n_newton)
    assert st2 == 0 and n2 == n_newton
    assert np.array_equal(y1, y1b) and np.array_equal(Z, Zb) and np.array_equal(F, Fb)
