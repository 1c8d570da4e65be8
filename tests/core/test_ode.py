"""rsfcore.ode: the vendored DOP853 tableau and the shared compiled kernels.

Independent checks: SciPy's copy of the same published coefficients (the test may import
SciPy's private module; the product may not), the order conditions of the method, and
exact solutions of linear test equations.
"""

from __future__ import annotations

import ast
import math
from fractions import Fraction
from pathlib import Path

import numpy as np
import pytest
from scipy.integrate._ivp import dop853_coefficients as scipy_dop853

from rsfcore import engine
from rsfcore.ode import dop853_tableau as tab
from rsfcore.ode import rk

ROOT = Path(__file__).resolve().parents[2] / "rsfcore"


@pytest.mark.parametrize("name", ["A", "B", "C", "E3", "E5", "D"])
def test_tableau_equals_scipys_copy_bit_for_bit(name: str) -> None:
    """Both copies come from Hairer's dop853.f; typed independently, they must agree exactly
    (bit-for-bit, so that the refactoring left every number unchanged)."""
    ours = getattr(tab, name)
    theirs = getattr(scipy_dop853, name)
    assert ours.shape == theirs.shape
    assert np.array_equal(ours, theirs), np.max(np.abs(ours - theirs))
    assert (tab.N_STAGES, tab.N_STAGES_EXTENDED, tab.INTERPOLATOR_POWER) == (
        scipy_dop853.N_STAGES,
        scipy_dop853.N_STAGES_EXTENDED,
        scipy_dop853.INTERPOLATOR_POWER,
    )


def test_order_conditions() -> None:
    """Row sums equal the nodes, and the quadrature conditions sum b c^k = 1/(k+1) hold
    for k = 0..7 (order 8).  The literals carry 30 digits, so the defects are rounding of
    sums of O(10) terms of size up to 44: <= 1e-14 is a few ulp of that."""
    A, B, C = tab.A, tab.B, tab.C
    for s in range(1, tab.N_STAGES_EXTENDED):
        if s == tab.N_STAGES:
            continue  # row 12 holds the b weights, stage 13 is f(x + h, y_new) at c = 1
        assert abs(A[s, :s].sum() - C[s]) <= 1e-14, s
    for k in range(8):
        q = float(np.sum(B * C[: tab.N_STAGES] ** k))
        assert abs(q - float(Fraction(1, k + 1))) <= 1e-14, k
    # the error estimators integrate constants exactly to zero (consistent embedded pairs)
    assert abs(tab.E5.sum()) <= 1e-14 and abs(tab.E3.sum()) <= 1e-14


def _step_linear(lam: float, h: float) -> tuple[float, np.ndarray, np.ndarray]:
    """One DOP853 step of y' = lam y from y = 1 with the shared kernels; returns
    (y_new, K, F) with the dense output filled."""
    K = np.zeros((tab.N_STAGES_EXTENDED, 1))
    y = np.array([1.0])
    tmp = np.empty(1)
    K[0, 0] = lam * y[0]
    for s in range(1, tab.N_STAGES):
        rk.stage_state(K, y, h, s, tmp)
        K[s, 0] = lam * tmp[0]
    ynew = np.empty(1)
    rk.step_state(K, y, h, ynew)
    K[tab.N_STAGES, 0] = lam * ynew[0]
    for s in range(tab.N_STAGES + 1, tab.N_STAGES_EXTENDED):
        rk.stage_state(K, y, h, s, tmp)
        K[s, 0] = lam * tmp[0]
    F = np.empty((7, 1))
    rk.dense_coeffs(K, y, ynew, K[0], K[tab.N_STAGES], h, F)
    return float(ynew[0]), K, F


def test_step_is_eighth_order_and_dense_output_seventh() -> None:
    """Local error of y' = -y: h^9 scaling (ratio 2^9 = 512 per halving, we accept > 300);
    dense output at x = 0.37: h^8 local error (ratio 256, we accept > 150).  Steps from 0.8
    down to 0.2 keep the errors (5e-9 .. 3e-14) above rounding (1e-16)."""
    errs, derrs = [], []
    for h in (0.8, 0.4, 0.2):
        y1, _, F = _step_linear(-1.0, h)
        errs.append(abs(y1 - math.exp(-h)))
        out = np.empty(1)
        rk.dense_eval(F, np.array([1.0]), 0.37, out)
        derrs.append(abs(out[0] - math.exp(-0.37 * h)))
    assert errs[0] / errs[1] > 300 and errs[1] / errs[2] > 300, errs
    assert derrs[0] / derrs[1] > 150, derrs
    assert errs[2] < 1e-13 and derrs[2] < 1e-12


def test_error_norm_and_controller() -> None:
    """The embedded estimate vanishes for a constant solution and grows like h^8 otherwise;
    the controller's factors stay in [0.2, 10] and never grow right after a rejection."""
    _, K, _ = _step_linear(0.0, 0.5)
    assert rk.error_norm(K, 0.5, np.array([1e-10]), 1) == 0.0
    _, K1, _ = _step_linear(-1.0, 0.2)
    _, K2, _ = _step_linear(-1.0, 0.1)
    e1 = rk.error_norm(K1, 0.2, np.array([1e-10]), 1)
    e2 = rk.error_norm(K2, 0.1, np.array([1e-10]), 1)
    assert 2**6 < e1 / e2 < 2**10
    assert rk.reject_factor(math.inf) == rk.MIN_FACTOR == rk.reject_factor(1e30)
    assert 0.2 <= rk.reject_factor(2.0) < 0.9
    assert rk.accept_factor(0.0, 1.0, 0.0, 1.0, False)[0] == rk.MAX_FACTOR
    assert rk.accept_factor(0.0, 1.0, 0.0, 1.0, True)[0] == 1.0
    fac, err_c = rk.accept_factor(0.5, 1.0, 0.0, 1.0, False)
    assert fac == pytest.approx(0.9 * 0.5 ** (-1 / 8)) and err_c == 0.5
    # Gustafsson: a growing error constant caps the factor below the elementary one
    fac_g, _ = rk.accept_factor(0.5, 1.0, 1.0, 0.1, False)
    assert fac_g < fac


def test_illinois_finds_a_root() -> None:
    """g(x) = cos(3x) - x on [0, 1]: root 0.3906... (checked by bisection to 1e-15)."""
    lo, hi = 0.0, 1.0
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if math.cos(3 * mid) - mid > 0 else (lo, mid)
    x0, x1, g0, g1, side = 0.0, 1.0, 1.0, math.cos(3.0) - 1.0, 0
    for _ in range(60):
        xm = rk.illinois_point(x0, x1, g0, g1)
        gm = math.cos(3 * xm) - xm
        if gm == 0.0 or x1 - x0 < 1e-15:
            break
        x0, x1, g0, g1, side = rk.illinois_update(x0, x1, g0, g1, side, xm, gm)
    assert abs(xm - lo) < 1e-14


def test_stiffness_ratio_estimates_h_lambda() -> None:
    """For y' = lam y the stage-difference estimate equals h |lam| exactly (linear RHS)."""
    lam, h = -30.0, 0.1
    K = np.zeros((tab.N_STAGES_EXTENDED, 1))
    y = np.array([1.0])
    tmp = np.empty(1)
    K[0, 0] = lam
    for s in range(1, tab.N_STAGES):
        rk.stage_state(K, y, h, s, tmp)
        K[s, 0] = lam * tmp[0]
    ynew = np.empty(1)
    rk.step_state(K, y, h, ynew)
    K[tab.N_STAGES, 0] = lam * ynew[0]
    assert rk.stiffness_ratio(K, ynew, tmp, h, 1) == pytest.approx(h * abs(lam), rel=1e-12)


def test_engine_status_and_result_types() -> None:
    assert [int(s) for s in engine.Status] == list(range(9))
    assert engine.STATUS[int(engine.Status.STEP_UNDERFLOW)] == "step_underflow"
    y0 = np.array([1.0, 0.0, 0.0])
    empty = np.empty(0)
    opts = engine.EngineOptions(
        rtol=1e-10, atol=1e-10, stop_on_return=True, phi_stop=40.0, max_steps=100_000, eq_tol=1e-6
    )
    res = engine.run(y0, 2.0, 2.0, 0.25, 1.0, opts, empty, empty, np.empty((0, 5)))
    assert isinstance(res, engine.EngineResult) and res.status is engine.Status.RETURNED
    assert res.n_steps > 0 and res.n_rhs >= 12 * res.n_steps and res.y_end.shape == (3,)
    raw = engine.integrate(
        y0, 2.0, 2.0, 0.25, 1.0, opts.typed(), empty, empty, np.empty((0, 5)), np.empty((0, 8))
    )
    same = [
        a == b or (math.isnan(a) and math.isnan(b))
        for a, b in zip(tuple(res)[2:], tuple(raw)[2:], strict=True)
    ]
    assert all(same) and int(raw[0]) == res.status


def test_no_scipy_private_import_in_rsfcore() -> None:
    """The product carries its own tableau: no module of rsfcore imports scipy.integrate._ivp."""
    for f in ROOT.rglob("*.py"):
        tree = ast.parse(f.read_text(), filename=str(f))
        for node in ast.walk(tree):
            if isinstance(node, ast.ImportFrom):
                mods = [node.module or ""]
            elif isinstance(node, ast.Import):
                mods = [a.name for a in node.names]
            else:
                continue
            for m in mods:
                assert not m.startswith("scipy.integrate._ivp"), (f, m)
