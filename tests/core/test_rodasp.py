"""RODASP (rsfcore.ode.rodasp, rsfcore.ode.rodasp_tableau): the coefficients, their
transformation, the compiled step, and the property it was chosen for (order kept on
stiff Prothero-Robinson problems, where RODAS4 loses it).

Every expected value here is independent of the code under test: exp(-h), the exact
solution g(x) of the Prothero-Robinson problem, or a step written out in the method's
original (untransformed) form from the printed literals.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence

import numpy as np

from rsfcore.ode import rodas4, rodas4_tableau, rodasp, rodasp_tableau

Tab = Sequence[Sequence[float]]


def _step_transformed(
    A: Tab, C: Tab, gamma: float, f: Callable[[float, float], float],
    fx: float, fy: float, x: float, y: float, h: float,
) -> tuple[float, float]:  # fmt: skip
    """One step of a RODAS-layout method in the transformed form for y' = f(x, y), as the
    pair (x, y) with x' = 1 and J = [[0, 0], [fx, fy]], written out in plain Python:
    (y_new, k_6)."""
    fac = 1.0 / (h * gamma)
    ks: list[tuple[float, float]] = []
    zx, zy = x, y
    for i in range(6):
        if i == 0:
            zx, zy = x, y
        elif i < 5:
            zx = x + sum(A[i][m] * ks[m][0] for m in range(i))
            zy = y + sum(A[i][m] * ks[m][1] for m in range(i))
        else:  # stage 6 at stage 5's argument plus k_5
            zx, zy = zx + ks[4][0], zy + ks[4][1]
        r0 = 1.0 + sum(C[i][m] / h * ks[m][0] for m in range(i))
        r1 = f(zx, zy) + sum(C[i][m] / h * ks[m][1] for m in range(i))
        k0 = r0 / fac
        ks.append((k0, (r1 + fx * k0) / (fac - fy)))
    return zy + ks[5][1], ks[5][1]


def _step_original(
    f: Callable[[float, float], float], fx: float, fy: float, x: float, y: float, h: float
) -> float:
    """One RODASP step in its original form (Hairer & Wanner II, eq. (7.4)) from the
    printed alpha_ij, beta_ij: (I - gamma h J) k_i = h f(z + sum alpha_ij k_j)
    + h J sum gamma_ij k_j, gamma_ij = beta_ij - alpha_ij; y_1 = y + sum b_j k_j with
    b_j = beta_6j, b_6 = gamma."""
    al, be, g = rodasp_tableau.ALPHA, rodasp_tableau.BETA, rodasp_tableau.GAMMA
    ks: list[tuple[float, float]] = []
    for i in range(6):
        ax = sum(al[i][j] * ks[j][0] for j in range(i))
        ay = sum(al[i][j] * ks[j][1] for j in range(i))
        gx = sum((be[i][j] - al[i][j]) * ks[j][0] for j in range(i))
        gy = sum((be[i][j] - al[i][j]) * ks[j][1] for j in range(i))
        # pair (x, y): f = (1, f), J = [[0, 0], [fx, fy]]
        r0 = h * 1.0
        r1 = h * f(x + ax, y + ay) + h * (fx * gx + fy * gy)
        k0 = r0
        k1 = (r1 + g * h * fx * k0) / (1.0 - g * h * fy)
        ks.append((k0, k1))
    b = [*be[5], g]
    return y + sum(bj * k[1] for bj, k in zip(b, ks, strict=True))


def test_transformed_coefficients_match_the_printed_method() -> None:
    """The exact-arithmetic transformation (a = alpha Gamma^-1, c = diag(1/gamma) -
    Gamma^-1) gives the same step as the printed form, to rounding (1e-14 relative: the
    two forms round differently), on a non-linear non-autonomous problem; and RODASP has
    RODAS4's layout (5 argument rows, 6 c rows, gamma 1/4)."""
    t = rodasp_tableau
    assert len(t.A) == 5 and len(t.C) == 6 and t.GAMMA == 0.25
    assert all(len(row) == i for i, row in enumerate(t.A))
    assert all(len(row) == i for i, row in enumerate(t.C))

    def f(x: float, y: float) -> float:
        return -3.0 * y * y + math.sin(2.0 * x)

    x, y, h = 0.3, 0.7, 0.05
    fx, fy = 2.0 * math.cos(2.0 * x), -6.0 * y
    y_t, _ = _step_transformed(t.A, t.C, t.GAMMA, f, fx, fy, x, y, h)
    y_o = _step_original(f, fx, fy, x, y, h)
    assert abs(y_t - y_o) <= 1e-14 * abs(y_o), (y_t, y_o)


def test_classical_order_and_l_stability() -> None:
    """Order 4 on y' = -y (local error ratio 2^5 = 32 per halving; accept > 24), an
    embedded estimate of local order 4 (ratio 16; accept > 12), L-stability (|R(z)| <
    1e-6 at z = -1e8): a wrong digit in a coefficient breaks one of these by orders of
    magnitude."""
    t = rodasp_tableau

    def f(x: float, y: float) -> float:
        return -y

    errs, ests = [], []
    for h in (0.2, 0.1, 0.05):
        y1, k6 = _step_transformed(t.A, t.C, t.GAMMA, f, 0.0, -1.0, 0.0, 1.0, h)
        errs.append(abs(y1 - math.exp(-h)))
        ests.append(abs(k6))
    assert errs[0] / errs[1] > 24 and errs[1] / errs[2] > 24, errs
    assert ests[0] / ests[1] > 12 and ests[1] / ests[2] > 12, ests

    def stiff(x: float, y: float) -> float:
        return -1e8 * y

    y1, _ = _step_transformed(t.A, t.C, t.GAMMA, stiff, 0.0, -1e8, 0.0, 1.0, 1.0)
    assert abs(y1) < 1e-6


def _prothero_robinson_error(A: Tab, C: Tab, gamma: float, n: int) -> float:
    """Global error at x = 1 of n fixed steps on y' = lam (y - sin x) + cos x, lam = -1e6,
    y(0) = 0 (exact solution sin x)."""
    lam = -1e6

    def f(x: float, y: float) -> float:
        return lam * (y - math.sin(x)) + math.cos(x)

    x, y, h = 0.0, 0.0, 1.0 / n
    for _ in range(n):
        fx = -lam * math.cos(x) - math.sin(x)
        y, _ = _step_transformed(A, C, gamma, f, fx, lam, x, y, h)
        x += h
    return abs(y - math.sin(1.0))


def test_order_kept_on_stiff_prothero_robinson() -> None:
    """What RODASP is for: on the stiff Prothero-Robinson problem (|h lam| = 1e5 .. 4e5)
    its global error falls ~2^3 per halving of h (measured 8.1, 8.0: order 3 kept;
    accept > 6), while RODAS4's falls ~2^1 (order reduction, measured 2.3, 2.1; accept
    < 2^1.5), and at h = 1/40 RODASP is 1.4e4x more accurate (3.3e-14 against 4.6e-10;
    accept > 1e3x)."""
    p = rodasp_tableau
    r = rodas4_tableau
    e_p = [_prothero_robinson_error(p.A, p.C, p.GAMMA, n) for n in (10, 20, 40)]
    e_r = [_prothero_robinson_error(r.A, r.C, r.GAMMA, n) for n in (10, 20, 40)]
    assert e_p[0] / e_p[1] > 6 and e_p[1] / e_p[2] > 6, e_p
    assert e_r[0] / e_r[1] < 2**1.5 and e_r[1] / e_r[2] < 2**1.5, e_r
    assert e_p[2] * 1e3 < e_r[2], (e_p, e_r)


def test_compiled_scalar_step_is_the_written_out_step() -> None:
    """rsfcore.ode.rodasp.scalar_step (numba, through rodas4.step_tableau) gives the step
    written out above from the same coefficients, to 4 ulp (same operations, summed in
    another order), and the embedded estimate k_6 in the workspace (to 8 ulp of y)."""
    import numba as nb

    @nb.njit(cache=False)
    def pair_rhs(z: np.ndarray, out: np.ndarray, c: float) -> None:
        out[0] = 1.0
        out[1] = -c * z[1] * z[1] + math.sin(2.0 * z[0])

    @nb.njit(cache=False)
    def one(x: float, y: float, h: float, c: float) -> tuple[bool, float, float, float]:
        W = np.zeros((rodas4.SCALAR_WORK, 2))
        f = -c * y * y + math.sin(2.0 * x)
        ok, yn, fn = rodasp.scalar_step(
            pair_rhs, (c,), x, y, f, 2.0 * math.cos(2.0 * x), -2.0 * c * y, h, W
        )
        return ok, yn, fn, W[5, 1]

    t = rodasp_tableau
    x, y, h, c = 0.3, 0.7, 0.05, 3.0
    ok, yn, fn, k6 = one(x, y, h, c)

    def f(xx: float, yy: float) -> float:
        return -c * yy * yy + math.sin(2.0 * xx)

    y_ref, k6_ref = _step_transformed(
        t.A, t.C, t.GAMMA, f, 2.0 * math.cos(2.0 * x), -2.0 * c * y, x, y, h
    )
    assert ok
    assert abs(yn - y_ref) <= 4 * math.ulp(y_ref), (yn, y_ref)
    # k_6 is a small difference of stage sums: its rounding is relative to y, not to k_6
    assert abs(k6 - k6_ref) <= 8 * math.ulp(y_ref), (k6, k6_ref)
    assert abs(fn - f(x + h, yn)) <= 4 * math.ulp(abs(fn))


def _stage_increments(
    A: Tab, C: Tab, gamma: float, f: Callable[[float, float], float],
    fx: float, fy: float, x: float, y: float, h: float,
) -> tuple[float, list[float]]:  # fmt: skip
    """The step of :func:`_step_transformed` with the y components of its six stage
    increments (the rows R[0..5] of rsfcore.ode.rodas4.step_tableau): (y_new, [k_1..k_6])."""
    fac = 1.0 / (h * gamma)
    ks: list[tuple[float, float]] = []
    zx, zy = x, y
    for i in range(6):
        if 0 < i < 5:
            zx = x + sum(A[i][m] * ks[m][0] for m in range(i))
            zy = y + sum(A[i][m] * ks[m][1] for m in range(i))
        elif i == 5:
            zx, zy = zx + ks[4][0], zy + ks[4][1]
        r0 = 1.0 + sum(C[i][m] / h * ks[m][0] for m in range(i))
        r1 = f(zx, zy) + sum(C[i][m] / h * ks[m][1] for m in range(i))
        k0 = r0 / fac
        ks.append((k0, (r1 + fx * k0) / (fac - fy)))
    return zy + ks[5][1], [k[1] for k in ks]


def _midstep(
    t: object, f: Callable[[float, float], float], fx: float, fy: float, x: float, y: float,
    h: float,
) -> float:  # fmt: skip
    """The continuous extension y0 + (y1 - y0)/2 + D2/4 + D3/8 of one step at s = 1/2
    (rsfcore.ode.rodas4's form, with the tableau's own D2, D3)."""
    y1, k = _stage_increments(t.A, t.C, t.GAMMA, f, fx, fy, x, y, h)  # type: ignore[attr-defined]
    d2 = sum(w * kk for w, kk in zip(t.D2, k, strict=False))  # type: ignore[attr-defined]
    d3 = sum(w * kk for w, kk in zip(t.D3, k, strict=False))  # type: ignore[attr-defined]
    return y + 0.5 * (y1 - y) + 0.25 * d2 + 0.125 * d3


def _order_conditions(t: object) -> list[tuple[float, ...]]:
    """(sum d, d . beta', d . alpha^2, d . (beta beta')) of D2, D3 over the original stages
    k_1..k_5, from the printed alpha_ij, beta_ij (not from the transformed a, c that the
    extension was derived through): the four order-3 conditions of a continuous
    extension (rsfcore.ode.rodasp_tableau's docstring) read (0, -1/2, -1/3, gamma - 1/6)
    for D2 and (0, 0, -1/3, -1/6) for D3."""
    al_t, be_t, g = rodasp_tableau.ALPHA, rodasp_tableau.BETA, rodasp_tableau.GAMMA
    n = 6
    al = [sum(row) for row in al_t]
    bp = [sum(row) for row in be_t]
    bbp = [sum(be_t[i][k] * bp[k] for k in range(i)) for i in range(n)]
    # Gamma (lower triangular: gamma_ij = beta_ij - alpha_ij, gamma on the diagonal)
    gam = np.zeros((n, n))
    for i in range(n):
        for j in range(i):
            gam[i, j] = be_t[i][j] - al_t[i][j]
        gam[i, i] = g
    out = []
    for dt in (t.D2, t.D3):  # type: ignore[attr-defined]
        d = np.zeros(n)
        d[:5] = dt
        do = d @ gam  # weights of the original k_j: sum_i d_i u_i, u = Gamma k
        out.append(
            (
                float(do.sum()),
                float(do @ bp),
                float(do @ np.square(al)),
                float(do @ np.array(bbp)),
            )
        )
    return out


def test_continuous_extension_satisfies_the_order_3_conditions() -> None:
    """RODASP's D2, D3 (derived in rodasp_tableau._dense) meet the four order-3 conditions
    of a continuous extension, evaluated here from the printed coefficients in the
    original form (residuals ~1e-15; accept 1e-12), with weights below 30 (the least-norm
    choice; the index-1 condition gave ~1e4)."""
    g = rodasp_tableau.GAMMA
    d2, d3 = _order_conditions(rodasp_tableau)
    np.testing.assert_allclose(d2, (0.0, -0.5, -1.0 / 3.0, g - 1.0 / 6.0), rtol=0, atol=1e-12)
    np.testing.assert_allclose(d3, (0.0, 0.0, -1.0 / 3.0, -1.0 / 6.0), rtol=0, atol=1e-12)
    assert max(map(abs, rodasp_tableau.D2 + rodasp_tableau.D3)) < 30.0


def test_continuous_extension_is_of_order_3() -> None:
    """The extension at mid-step against scipy's DOP853 at rtol 1e-13 on a non-linear
    non-autonomous problem: local error O(h^4), ratio -> 16 per halving (measured 9.4,
    11.2, 13.1 for RODASP, 7.5, 10.4, 12.8 for RODAS4's published extension, the same
    asymptote; accept > 11 at the last halving, where a wrong weight would leave O(h^3):
    ratio 8), and on the stiff Prothero-Robinson problem (lam = -1e6) RODASP's keeps it
    (measured 16.8, 16.4, 16.2; accept > 12) while RODAS4's falls to 2.3 (accept < 5):
    the engine's dense-output check (rodasp.error_norm) measures an O(h^4) quantity on
    stiff relaxations too."""
    from scipy.integrate import solve_ivp

    def f(x: float, y: float) -> float:
        return -3.0 * y * y + math.sin(2.0 * x)

    x, y = 0.3, 0.7
    for t in (rodasp_tableau, rodas4_tableau):
        errs = []
        for h in (0.2, 0.1, 0.05, 0.025):
            ref = solve_ivp(
                lambda s, z: [f(s, z[0])], (x, x + h / 2), [y], method="DOP853", rtol=1e-13,
                atol=1e-15,
            ).y[0, -1]  # fmt: skip
            errs.append(abs(_midstep(t, f, 2.0 * math.cos(2.0 * x), -6.0 * y, x, y, h) - ref))
        assert errs[2] / errs[3] > 11.0, (t.__name__, errs)
    lam = -1e6

    def pr(x: float, y: float) -> float:
        return lam * (y - math.sin(x)) + math.cos(x)

    x0 = 0.3
    ratios = {}
    for t in (rodasp_tableau, rodas4_tableau):
        errs = []
        for h in (0.1, 0.05, 0.025, 0.0125):
            fx = -lam * math.cos(x0) - math.sin(x0)
            ym = _midstep(t, pr, fx, lam, x0, math.sin(x0), h)
            errs.append(abs(ym - math.sin(x0 + h / 2)))
        ratios[t.__name__] = [errs[i] / errs[i + 1] for i in range(3)]
    assert min(ratios[rodasp_tableau.__name__]) > 12.0, ratios
    assert ratios[rodas4_tableau.__name__][-1] < 5.0, ratios


def test_rodas4_published_extension_is_the_same_construction() -> None:
    """The conditions of the derivation, checked on an independent published extension:
    RODAS4's d2, d3 (rodas.f) satisfy the same four order-3 conditions (through its own
    alpha, beta, recovered from its transformed a, c); residuals ~1e-15, accept 1e-12."""
    t = rodas4_tableau
    n = 6
    g = t.GAMMA
    # Gamma^-1 = diag(1/gamma) - c; alpha = a Gamma (stage 6: stage 5's argument + k_5)
    ginv = np.eye(n) / g
    for i in range(n):
        for j in range(i):
            ginv[i, j] = -t.C[i][j]
    gam = np.linalg.inv(ginv)
    a = np.zeros((n, n))
    for i in range(5):
        a[i, :i] = t.A[i]
    a[5, :4] = t.A[4]
    a[5, 4] = 1.0
    alpha = a @ gam
    beta = np.tril(alpha + gam, -1)
    al = alpha.sum(axis=1)
    bp = beta.sum(axis=1)
    bbp = beta @ bp
    for dt, want in ((t.D2, (0.0, -0.5, -1 / 3, g - 1 / 6)), (t.D3, (0.0, 0.0, -1 / 3, -1 / 6))):
        d = np.zeros(n)
        d[:5] = dt
        do = d @ gam
        got = (do.sum(), do @ bp, do @ al**2, do @ bbp)
        np.testing.assert_allclose(got, want, rtol=0, atol=1e-12)
