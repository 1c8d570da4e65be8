"""Radau IIA of order 5 (3 stages), the implicit collocation method of RADAU5, as compiled
seams for the spring-slider engine's stiff phases (rsfcore.engine, ``StiffMethod.RADAU5``).

The method (Hairer & Wanner II, Sec. IV.5 and IV.8): collocation at the Radau right
points c = ((4 - sqrt 6)/10, (4 + sqrt 6)/10, 1); the stage increments Z_i = Y_i - y0
solve

    Z_i = h sum_j a_ij f(y0 + Z_j),     a_ij = int_0^{c_i} l_j(t) dt

(l_j the Lagrange polynomials on c), and y1 = y0 + Z_3 (stiffly accurate).  Order 5,
stage order 3, L-stable; it keeps order 5 on y' = lambda (y - g(x)) + g'(x) for any
h lambda (Prothero & Robinson's problem, where RODAS4 loses order and RODASP keeps 4).

Everything is derived here from that definition (:func:`_tableau`): a_ij by exact
integration of the Lagrange polynomials, the real eigenvalue gamma and the complex pair
alpha +- i beta of A^-1 with the real basis T in which T^-1 A^-1 T = [[gamma, 0, 0],
[0, alpha, -beta], [0, beta, alpha]], and the error weights e (below);
tests/core/test_radau5.py checks them against the closed forms printed in Hairer &
Wanner II (Table IV.5.6 and eq. (8.19)) and the orders.

Kernels (a driver owns its right-hand side ``rhs(y, out, *args)``, its Jacobian J, shape
(n, 2), and its loop; as in rsfcore.ode.rodas4, f depends on y_0, y_1 alone and the other
components are quadratures):

* :func:`step`: one step.  Simplified Newton on the (y_0, y_1) stages in the transformed
  variables W = T^-1 Z, which split the 6 x 6 system into a real 2 x 2 one,
  (gamma/h - J) dW_1 = r_1, and a complex one, ((alpha + i beta)/h - J)(dW_2 + i dW_3) =
  r_2 + i r_3 (Cramer's rule on both); the quadratures' stages are Z_q = h A f_q (their
  slopes linearised to the final Newton increment).  The iteration starts from Z = 0
  (whose first residual needs no right-hand side: every stage is at y0), so a step is a
  function of (y0, h) alone and can be taken again bit for bit (rsfcore.engine
  .replay_samples).  The first increment is the linearised step; the second, the error
  of that linearisation, is accepted below NEWTON_TOL of the error weights; from the
  third on, the iteration stops when the predicted distance to the solution,
  theta/(1 - theta) |dZ| with the contraction theta = |dZ_k|/|dZ_(k-1)|, is below
  NEWTON_TOL, and fails (the driver halves the step) on divergence (theta >= 0.99), on
  a predicted non-convergence within MAX_NEWTON iterations, or on a singular matrix.
* :func:`error_norm`: the normalised local error, Hairer's filtered embedded estimate
  (Hairer & Wanner II, eq. (8.20)): err = (gamma/h - J)^-1 (f0 + (gamma/h) sum_j e_j Z_j)
  with the weights e of the embedded 3rd-order formula y0 + h (f0/gamma + sum_i b^_i
  f(Y_i)), so O(h^4) like RODAS's; with ``refine`` (after a rejection) the same once more
  with f(y0 + err) for f0, which removes the estimate's O(1) growth on stiff components.
* :func:`dense_coeffs`: the collocation polynomial of the step (degree 3 through y0 and
  the three stages) in the layout of rsfcore.ode.rk.dense_eval (coefficients 3..6 zero),
  so the engine's events and samples read it like the other methods' dense output.

Step-size control: rsfcore.ode.rodas4's controller (error exponent 1/4, matching the
estimate's order; Gustafsson's predictive correction).

Every kernel is compiled with ``inline="always"``; numba's cache does not track these
cross-module calls: after editing this file, also touch the driver (rsfcore/engine.py)
or clear NUMBA_CACHE_DIR.

References: E. Hairer, G. Wanner, Solving Ordinary Differential Equations II, 2nd ed.,
Springer 1996 (Sec. IV.5 (Radau IIA), IV.8 (implementation: transformation, simplified
Newton, error estimate)); A. Prothero, A. Robinson, Math. Comp. 28 (1974) 145-162.
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np
from numpy.typing import NDArray

__all__ = [
    "N_STAGES",
    "ORDER",
    "MAX_NEWTON",
    "NEWTON_TOL",
    "C",
    "A",
    "GAMMA",
    "ALPHA",
    "BETA",
    "T",
    "TI",
    "E",
    "step",
    "error_norm",
    "dense_coeffs",
]

#: stages per step
N_STAGES = 3
#: classical order (and order on Prothero-Robinson's problem for any h lambda)
ORDER = 5
#: most simplified Newton iterations per step
MAX_NEWTON = 7
#: the iteration stops when theta/(1 - theta) |dZ| <= NEWTON_TOL in the norm of the error
#: weights: 1 % of the local tolerance, the stages' error then a small part of the step's
NEWTON_TOL = 0.01


def _tableau() -> tuple[
    NDArray[np.float64],
    NDArray[np.float64],
    float,
    float,
    float,
    NDArray[np.float64],
    NDArray[np.float64],
    NDArray[np.float64],
]:
    """(c, A, gamma, alpha, beta, T, T^-1, e) of 3-stage Radau IIA from its definition.

    c: the zeros of d^2/dx^2 (x^3 (x - 1)^2) (Radau right points); a_ij = int_0^{c_i}
    l_j; gamma, alpha +- i beta the eigenvalues of A^-1 (beta > 0); T = [v_1, Re v_2,
    Im v_2] from their eigenvectors (A^-1 v_2 = (alpha - i beta) v_2 gives the block
    [[alpha, -beta], [beta, alpha]]); e = (b^ - b)^T A^-1 with b the last row of A and b^
    the weights of the embedded formula y0 + h (gamma0 f0 + sum_i b^_i f(Y_i)),
    gamma0 = 1/gamma, of order 3 (sum b^ c^(k-1) + gamma0 [k = 1] = 1/k, k = 1, 2, 3).
    """
    s6 = math.sqrt(6.0)
    c = np.array([(4.0 - s6) / 10.0, (4.0 + s6) / 10.0, 1.0])
    a = np.empty((3, 3))
    for j in range(3):
        # l_j as a polynomial (numpy.polynomial, increasing powers), integrated from 0
        others = [c[m] for m in range(3) if m != j]
        lj = np.polynomial.Polynomial.fromroots(others)
        lj = lj / lj(c[j])
        ij = lj.integ()
        for i in range(3):
            a[i, j] = ij(c[i]) - ij(0.0)
    ainv = np.linalg.inv(a)
    w, v = np.linalg.eig(ainv)
    k_real = int(np.argmin(np.abs(w.imag)))
    k_cplx = int(np.argmax(w.imag < 0.0))  # the eigenvalue alpha - i beta
    gamma = float(w[k_real].real)
    alpha = float(w[k_cplx].real)
    beta = float(-w[k_cplx].imag)
    v1 = v[:, k_real].real / v[0, k_real].real
    v2 = v[:, k_cplx] / v[0, k_cplx]
    t = np.column_stack([v1, v2.real, v2.imag])
    ti = np.linalg.inv(t)
    g0 = 1.0 / gamma
    vand = np.vstack([np.ones(3), c, c * c])
    bhat = np.linalg.solve(vand, np.array([1.0 - g0, 0.5, 1.0 / 3.0]))
    e = (bhat - a[2]) @ ainv
    return c, a, gamma, alpha, beta, t, ti, e


C, A, GAMMA, ALPHA, BETA, T, TI, E = _tableau()
_C1, _C2 = float(C[0]), float(C[1])
# the collocation polynomial in rsfcore.ode.rk's dense layout: q_i = (Z_i - c_i Z_3)/
# (c_i (1 - c_i)), F_2 = (q_2 - q_1)/(c_2 - c_1), F_1 = q_1 - c_1 F_2
_Q1 = 1.0 / (_C1 * (1.0 - _C1))
_Q2 = 1.0 / (_C2 * (1.0 - _C2))
_DC = 1.0 / (_C2 - _C1)


@nb.njit(cache=True, nogil=True, error_model="numpy", inline="always")
def step(rhs, args, y, f0, h, J, sc, Z, FZ, tmp, ftmp, ynew, fnew, n_fixed):
    """One Radau IIA step of signed length h from (y, f0 = f(y)) with the Jacobian J at y.

    rhs: compiled right-hand side, rhs(state, out, *args); J (n, 2): the columns
    d f/d y_0, d f/d y_1; sc (>= 2,): the error weights of y_0, y_1 (Newton's norm);
    Z (3, n): receives the stage increments; FZ (3, n), tmp, ftmp (n,): workspace; ynew,
    fnew (n,): the 5th-order solution y + Z_3 and f(ynew).  n_fixed > 0: take exactly
    that many Newton iterations, without convergence tests (the same step again, bit for
    bit, given the count it reported: rsfcore.engine.replay_samples); 0: adaptive.
    Returns (status, n_rhs, n_newton): status 0 converged, 1 Newton failed (diverged, too
    slow, or not finite: the driver shrinks the step), 2 singular matrix.
    """
    n = y.shape[0]
    gh = GAMMA / h
    ah = ALPHA / h
    bh = BETA / h
    j00 = J[0, 0]
    j01 = J[0, 1]
    j10 = J[1, 0]
    j11 = J[1, 1]
    # real system (gamma/h - J), Cramer
    r00 = gh - j00
    r11 = gh - j11
    det_r = r00 * r11 - j01 * j10
    # complex system ((alpha + i beta)/h - J)
    s = complex(ah, bh)
    c00 = s - j00
    c11 = s - j11
    det_c = c00 * c11 - j01 * j10
    if not (det_r != 0.0 and math.isfinite(det_r) and det_c != 0.0 and math.isfinite(abs(det_c))):
        return 2, 0, 0
    inv_r = 1.0 / det_r
    inv_c = 1.0 / det_c
    # W = T^-1 Z of the two Newton components, and Z itself, start at 0
    w10 = 0.0
    w11 = 0.0
    w20 = 0.0
    w21 = 0.0
    w30 = 0.0
    w31 = 0.0
    for i in range(3):
        for j in range(n):
            Z[i, j] = 0.0
    n_rhs = 0
    dyno_old = 0.0
    status = 1
    it = 0
    while it < MAX_NEWTON:
        # stage slopes
        if it == 0:
            for i in range(3):
                for j in range(n):
                    FZ[i, j] = f0[j]
        else:
            for i in range(3):
                for j in range(n):
                    tmp[j] = y[j] + Z[i, j]
                rhs(tmp, ftmp, *args)
                for j in range(n):
                    FZ[i, j] = ftmp[j]
            n_rhs += 3
        # transformed residuals G = T^-1 F - M W / h for the two Newton components
        g10 = TI[0, 0] * FZ[0, 0] + TI[0, 1] * FZ[1, 0] + TI[0, 2] * FZ[2, 0] - gh * w10
        g11 = TI[0, 0] * FZ[0, 1] + TI[0, 1] * FZ[1, 1] + TI[0, 2] * FZ[2, 1] - gh * w11
        g20 = TI[1, 0] * FZ[0, 0] + TI[1, 1] * FZ[1, 0] + TI[1, 2] * FZ[2, 0]
        g21 = TI[1, 0] * FZ[0, 1] + TI[1, 1] * FZ[1, 1] + TI[1, 2] * FZ[2, 1]
        g30 = TI[2, 0] * FZ[0, 0] + TI[2, 1] * FZ[1, 0] + TI[2, 2] * FZ[2, 0]
        g31 = TI[2, 0] * FZ[0, 1] + TI[2, 1] * FZ[1, 1] + TI[2, 2] * FZ[2, 1]
        g20 -= ah * w20 - bh * w30
        g21 -= ah * w21 - bh * w31
        g30 -= bh * w20 + ah * w30
        g31 -= bh * w21 + ah * w31
        # real solve
        d10 = (r11 * g10 + j01 * g11) * inv_r
        d11 = (r00 * g11 + j10 * g10) * inv_r
        # complex solve
        q0 = complex(g20, g30)
        q1 = complex(g21, g31)
        u0 = (c11 * q0 + j01 * q1) * inv_c
        u1 = (c00 * q1 + j10 * q0) * inv_c
        d20 = u0.real
        d30 = u0.imag
        d21 = u1.real
        d31 = u1.imag
        w10 += d10
        w11 += d11
        w20 += d20
        w21 += d21
        w30 += d30
        w31 += d31
        # back to Z; the norm of the increment dZ = T dW
        dyno = 0.0
        for i in range(3):
            dz0 = T[i, 0] * d10 + T[i, 1] * d20 + T[i, 2] * d30
            dz1 = T[i, 0] * d11 + T[i, 1] * d21 + T[i, 2] * d31
            Z[i, 0] = T[i, 0] * w10 + T[i, 1] * w20 + T[i, 2] * w30
            Z[i, 1] = T[i, 0] * w11 + T[i, 1] * w21 + T[i, 2] * w31
            dyno += (dz0 / sc[0]) ** 2 + (dz1 / sc[1]) ** 2
            # the quadratures' stage slopes, linearised to the new (y_0, y_1) stages
            for j in range(2, n):
                FZ[i, j] += J[j, 0] * dz0 + J[j, 1] * dz1
        dyno = math.sqrt(dyno / 6.0)
        if not math.isfinite(dyno):
            status = 1
            break
        it += 1
        if n_fixed > 0:
            if it >= n_fixed:
                status = 0
                break
        elif it == 1:
            # the first increment is the whole linearised step (from Z = 0): no rate yet
            if dyno <= 1e-3 * NEWTON_TOL:
                status = 0
                break
        elif it == 2:
            # the second measures the linearisation's error, not the contraction rate
            if dyno >= 0.99 * dyno_old:
                break
            if dyno <= NEWTON_TOL:
                status = 0
                break
        else:
            theta = dyno / dyno_old
            if theta >= 0.99:
                break
            faccon = theta / (1.0 - theta)
            if faccon * dyno <= NEWTON_TOL:
                status = 0
                break
            # predicted not to converge within MAX_NEWTON iterations
            if faccon * dyno * theta ** (MAX_NEWTON - it) > NEWTON_TOL:
                break
        dyno_old = max(dyno, 1e-300)
    if status != 0:
        return 1, n_rhs, it
    # the quadratures: Z_q = h A f_q(Y)
    for j in range(2, n):
        for i in range(3):
            Z[i, j] = h * (A[i, 0] * FZ[0, j] + A[i, 1] * FZ[1, j] + A[i, 2] * FZ[2, j])
    for j in range(n):
        ynew[j] = y[j] + Z[2, j]
    rhs(ynew, fnew, *args)
    return 0, n_rhs + 1, it


@nb.njit(cache=True, nogil=True, error_model="numpy", inline="always")
def error_norm(rhs, args, y, f0, h, J, Z, sc, j1, refine, tmp, ftmp, ev):
    """Normalised local error of the last :func:`step` (accept when <= 1) over components
    0 .. j1-1, and the right-hand sides it took (0, or 1 with ``refine``).

    The estimate ev = (gamma/h - J)^-1 (f0 + (gamma/h) sum_j e_j Z_j) (Hairer & Wanner II,
    eq. (8.20)); the quadratures by back substitution.  With ``refine`` (a step after a
    rejection, where the estimate of a stiff component can be O(1) too large) and err > 1,
    once more with f(y + ev) instead of f0.  sc: the error weights; ev (n,): workspace
    (receives the estimate).  Returns (err, n_rhs)."""
    n = y.shape[0]
    gh = GAMMA / h
    r00 = gh - J[0, 0]
    r11 = gh - J[1, 1]
    det_r = r00 * r11 - J[0, 1] * J[1, 0]
    inv_r = 1.0 / det_r
    for j in range(n):
        tmp[j] = f0[j] + gh * (E[0] * Z[0, j] + E[1] * Z[1, j] + E[2] * Z[2, j])
    n_rhs = 0
    for rep in range(2):
        e0 = (r11 * tmp[0] + J[0, 1] * tmp[1]) * inv_r
        e1 = (r00 * tmp[1] + J[1, 0] * tmp[0]) * inv_r
        ev[0] = e0
        ev[1] = e1
        for j in range(2, n):
            ev[j] = (tmp[j] + J[j, 0] * e0 + J[j, 1] * e1) / gh
        acc = 0.0
        for j in range(j1):
            acc += (ev[j] / sc[j]) ** 2
        err = math.sqrt(acc / j1)
        if rep == 1 or not (refine and err > 1.0):
            return err, n_rhs
        for j in range(n):
            ftmp[j] = y[j] + ev[j]
        rhs(ftmp, ev, *args)
        n_rhs += 1
        for j in range(n):
            tmp[j] = ev[j] + gh * (E[0] * Z[0, j] + E[1] * Z[1, j] + E[2] * Z[2, j])
    return math.inf, n_rhs


@nb.njit(cache=True, nogil=True, error_model="numpy", inline="always")
def dense_coeffs(Z, F):
    """The collocation polynomial of the last :func:`step` (through y0 at 0 and y0 + Z_i
    at c_i) in the layout of rsfcore.ode.rk.dense_eval: y(t0 + x h) = y0 + x (F_0 +
    (1 - x)(F_1 + x F_2)), F_3..F_6 = 0."""
    for j in range(Z.shape[1]):
        z3 = Z[2, j]
        q1 = (Z[0, j] - _C1 * z3) * _Q1
        q2 = (Z[1, j] - _C2 * z3) * _Q2
        f2 = (q2 - q1) * _DC
        F[0, j] = z3
        F[1, j] = q1 - _C1 * f2
        F[2, j] = f2
        for r in range(3, 7):
            F[r, j] = 0.0
