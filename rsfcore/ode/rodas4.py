"""RODAS4, the L-stable Rosenbrock method of order 4(3), as compiled seams used by the
spring-slider engine (rsfcore.engine, stiff phases) and the separatrix phase portraits
(rsfcore.phase); its step kernel also runs RODASP (rsfcore.ode.rodasp, the separatrix
integrator's stiff corner).

The method is written once here; a driver owns its right-hand side, its Jacobian, its
loop and its events, and calls

* :func:`step`: one step of length h for y' = f(y) (6 right-hand sides), the driver's
  right-hand side passed in as a compiled function ``rhs(y, out, *args)``;
* :func:`step_tableau`, :func:`scalar_step_tableau`: the same step for any 6-stage
  stiffly accurate method of RODAS's layout given its transformed coefficients (RODASP,
  rsfcore.ode.rodasp, shares the code this way);
* :func:`error_norm`: the step's normalised local error (the embedded estimate k_6,
  optionally with the gap between the cubic Hermite dense output and RODAS4's own
  continuous extension);
* :func:`reject_factor`, :func:`accept_factor`: the step-size controller of rodas.f
  (safety 0.9, factor in [0.2, 6], Gustafsson's predictive correction when the previous
  accepted step is given; Hairer & Wanner II, Sec. IV.8 and VI.4);
* :func:`hermite_coeffs`: the cubic Hermite dense output of a step, in the layout of
  rsfcore.ode.rk.dense_eval;
* :func:`spectral_radius`: the largest |eigenvalue| of the stiff 2 x 2 block;
* :func:`scalar_step`, :func:`scalar_error`: a scalar non-autonomous ODE y' = f(x, y) as
  the autonomous pair (x, y), x' = 1, on a (SCALAR_WORK, 2) workspace (the separatrix's
  drivers: rsfcore.separatrix, rsfcore.phase).

Structure of the systems (both users): the Jacobian is non-zero in its first two columns
only, i.e. y = (y_0, y_1, q_2, ..., q_{n-1}) where f depends on (y_0, y_1) alone and the
q_i are quadratures.  J is passed as its two columns, shape (n, 2); the linear systems
(I/(h gamma) - J) k = r are solved by Cramer's rule on the 2 x 2 block and back
substitution for the quadratures (:func:`solve`).  The engine: (phi, L, c T[, s, s_o]);
the separatrix: the non-autonomous scalar ODE y' = f(x, y) as the autonomous pair (x, y)
with x' = 1 (J = [[0, 0], [df/dx, df/dy]]).

One step (autonomous form, Hairer & Wanner II, eq. (7.4'); coefficients in
rsfcore.ode.rodas4_tableau):

    (I/(h gamma) - J) k_i = f(y + sum_{j<i} a_ij k_j) + sum_{j<i} (c_ij/h) k_j,  i = 1..6

stage 6 at the embedded 3rd-order solution y + a_51 k_1 + ... + a_54 k_4 + k_5, the new
solution that plus k_6, so k_6 is the error estimate.

Arithmetic is in the order of the engine's former copy (sums left to right, c_ij/h formed
once per stage), so the engine's results are bit-identical to it (tests/core).

Every kernel is compiled with ``inline="always"`` (as rsfcore.ode.rk).  Numba's cache does
not track these cross-module calls: after editing this file, also touch the drivers
(rsfcore/engine.py, rsfcore/separatrix.py) or clear NUMBA_CACHE_DIR.

References: E. Hairer, G. Wanner, Solving Ordinary Differential Equations II, 2nd ed.,
Springer 1996 (Sec. IV.7 (7.4'), IV.8, VI.4; rodas.f).
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np
from numpy.typing import NDArray

from . import rodas4_tableau as _ro

__all__ = [
    "N_STAGES",
    "MIN_FACTOR",
    "MAX_FACTOR",
    "step",
    "step_tableau",
    "solve",
    "error_norm",
    "error_norm_tableau",
    "reject_factor",
    "accept_factor",
    "hermite_coeffs",
    "spectral_radius",
    "SCALAR_WORK",
    "tableau_arrays",
    "scalar_step",
    "scalar_step_tableau",
    "scalar_error",
]

#: stages per step (= right-hand sides per step, f(y_new) included with the first one given)
N_STAGES = 6
#: smallest / largest step-size ratio per step (rodas.f: FAC1 = 5, FAC2 = 1/6; the
#: kernels write them as the literals 1/6 and 5 of rodas.f)
MIN_FACTOR = 0.2
MAX_FACTOR = 6.0


def tableau_arrays(
    a: tuple[tuple[float, ...], ...], c: tuple[tuple[float, ...], ...]
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """The lower-triangular a_ij (stage arguments, 5 x 5) and c_ij (6 x 5) of a
    transformed 6-stage Rosenbrock tableau as arrays, row i = stage i+1, zeros above
    (numba freezes module-level arrays as constants)."""
    a_arr = np.zeros((5, 5))
    for i, row in enumerate(a):
        a_arr[i, : len(row)] = row
    c_arr = np.zeros((6, 5))
    for i, row in enumerate(c):
        c_arr[i, : len(row)] = row
    return a_arr, c_arr


_A, _C = tableau_arrays(_ro.A, _ro.C)
_D2 = np.array(_ro.D2)
_D3 = np.array(_ro.D3)
_GAMMA = _ro.GAMMA


@nb.njit(cache=True, nogil=True, error_model="numpy", inline="always")
def solve(r, out, m00, m01, m10, m11, inv_det, J, fac):
    """out = (fac I - J)^-1 r for J with its first two columns only (n, 2).

    (m00, m01; m10, m11) = fac I - J[:2, :2] and inv_det = 1/its determinant (Cramer's
    rule); the quadratures i >= 2 by back substitution, out_i = (r_i + J_i0 out_0 +
    J_i1 out_1)/fac."""
    k0 = (m11 * r[0] - m01 * r[1]) * inv_det
    k1 = (m00 * r[1] - m10 * r[0]) * inv_det
    out[0] = k0
    out[1] = k1
    for i in range(2, r.shape[0]):
        out[i] = (r[i] + J[i, 0] * k0 + J[i, 1] * k1) / fac


@nb.njit(cache=True, nogil=True, error_model="numpy", inline="always")
def step_tableau(A, C, gamma, rhs, args, y, f0, h, J, R, tmp, ftmp, buf, ynew, fnew):
    """One step of a 6-stage stiffly accurate Rosenbrock method of RODAS's layout, given
    its transformed coefficients A (5, 5) (rows = stages 1..5; stage 6 is stage 5's
    argument plus k_5), C (6, 5) and gamma: RODAS4 (:func:`step`) and RODASP
    (rsfcore.ode.rodasp.step) share this code.  Arguments and result as :func:`step`."""
    n = y.shape[0]
    fac = 1.0 / (h * gamma)
    m00 = fac - J[0, 0]
    m01 = -J[0, 1]
    m10 = -J[1, 0]
    m11 = fac - J[1, 1]
    det = m00 * m11 - m01 * m10
    if not (det != 0.0 and math.isfinite(det)):
        return False
    inv_det = 1.0 / det
    solve(f0, R[0], m00, m01, m10, m11, inv_det, J, fac)
    for s in range(1, N_STAGES):
        # the argument of stage s+1 (stage 6: that of stage 5 plus k_5)
        if s < N_STAGES - 1:
            for j in range(n):
                acc = y[j]
                for m in range(s):
                    acc += A[s, m] * R[m, j]
                tmp[j] = acc
        else:
            for j in range(n):
                tmp[j] += R[s - 1, j]
        rhs(tmp, ftmp, *args)
        for j in range(n):
            acc = ftmp[j]
            for m in range(s):
                acc += (C[s, m] / h) * R[m, j]
            buf[j] = acc
        solve(buf, R[s], m00, m01, m10, m11, inv_det, J, fac)
    for j in range(n):
        ynew[j] = tmp[j] + R[N_STAGES - 1, j]
    rhs(ynew, fnew, *args)
    return True


@nb.njit(cache=True, nogil=True, error_model="numpy", inline="always")
def step(rhs, args, y, f0, h, J, R, tmp, ftmp, buf, ynew, fnew):
    """One RODAS4 step of signed length h from (y, f0 = f(y)) with the Jacobian J at y.

    rhs: compiled right-hand side, called as rhs(state, out, *args); J (n, 2): the
    columns d f/d y_0, d f/d y_1 (all other columns zero); R (6, n): filled with the stage
    increments k_1..k_6 (k_6 the embedded error estimate); tmp, ftmp, buf (n,): workspace;
    ynew, fnew (n,): the 4th-order solution and f(ynew).  Six right-hand sides.  Returns
    False (and fills nothing) when I/(h gamma) - J is singular or its determinant is not
    finite (the driver then shrinks the step); non-finite stages show as a non-finite
    ynew or fnew, which the driver checks.
    """
    return step_tableau(_A, _C, _GAMMA, rhs, args, y, f0, h, J, R, tmp, ftmp, buf, ynew, fnew)


@nb.njit(cache=True, nogil=True, error_model="numpy", inline="always")
def error_norm_tableau(D2, D3, R, f0, f1, h, sc, j0, j1, dense):
    """:func:`error_norm` for a method of RODAS's layout whose continuous extension has
    the weights D2, D3 (5,) over the stage increments k_1..k_5 (RODASP:
    rsfcore.ode.rodasp.error_norm)."""
    e_step = 0.0
    e_dense = 0.0
    for j in range(j0, j1):
        e_step += (R[5, j] / sc[j]) ** 2
        if dense:
            d2 = 0.0
            d3 = 0.0
            for m in range(5):
                d2 += D2[m] * R[m, j]
                d3 += D3[m] * R[m, j]
            dd = 0.125 * h * (f0[j] - f1[j]) - 0.25 * d2 - 0.125 * d3
            e_dense += (dd / sc[j]) ** 2
    return math.sqrt(max(e_step, e_dense) / (j1 - j0))


@nb.njit(cache=True, nogil=True, error_model="numpy", inline="always")
def error_norm(R, f0, f1, h, sc, j0, j1, dense):
    """Normalised local error of a step (accept when <= 1), over components j0 .. j1-1.

    The weighted RMS norm sqrt(sum_j (e_j/sc_j)^2 / (j1 - j0)) of the embedded estimate
    e = k_6; with ``dense`` the larger of that and the same norm of the mid-step distance
    between the cubic Hermite interpolant of (y0, f0), (y1, f1) (:func:`hermite_coeffs`,
    the dense output the engine locates events on) and RODAS4's own continuous extension,
    h (f0 - f1)/8 - D2/4 - D3/8, both O(h^4): bounding it keeps located events and samples
    as accurate as the steps.  sc: the weights (atol + rtol |y|, rsfcore.ode.rk.error_scale).
    """
    return error_norm_tableau(_D2, _D3, R, f0, f1, h, sc, j0, j1, dense)


@nb.njit(cache=True, nogil=True, error_model="numpy", inline="always")
def reject_factor(err):
    """Step-size factor after a rejected step (err > 1, or not finite: MIN_FACTOR)."""
    if not math.isfinite(err):
        return MIN_FACTOR
    return 1.0 / max(1.0 / 6.0, min(5.0, err**0.25 / 0.9))


@nb.njit(cache=True, nogil=True, error_model="numpy", inline="always")
def accept_factor(err, h, h_prev, err_prev, rejected_last):
    """Step-size factor after an accepted step, and the floored error to remember.

    err <= 1 the step's error; h the step just taken; h_prev, err_prev the previous
    accepted step and its remembered error (h_prev <= 0: none).  The elementary factor
    1/max(1/6, min(5, err^(1/4)/0.9)) (rodas.f), capped by Gustafsson's predictive
    correction (h_prev/h) (err^2/err_prev)^(1/4)/0.9 when a previous step is given; no
    growth after a rejection.  Returns (factor in [0.2, 6], max(err, 1e-2)).
    """
    fac = 1.0 / max(1.0 / 6.0, min(5.0, err**0.25 / 0.9))
    if h_prev > 0.0:
        gus = (h_prev / h) * (max(err, 1e-12) ** 2 / err_prev) ** 0.25 / 0.9
        fac = min(fac, 1.0 / max(1.0 / 6.0, min(5.0, gus)))
    if rejected_last:
        fac = min(1.0, fac)
    return fac, max(1e-2, err)


@nb.njit(cache=True, nogil=True, error_model="numpy", inline="always")
def hermite_coeffs(y0, y1, f0, f1, h, F):
    """Dense output of a Rosenbrock step in the layout of rsfcore.ode.rk.dense_eval: the
    cubic Hermite interpolant of (y0, f0) and (y1, f1) (coefficients 3..6 zero)."""
    for j in range(y0.shape[0]):
        dy = y1[j] - y0[j]
        F[0, j] = dy
        F[1, j] = h * f0[j] - dy
        F[2, j] = 2.0 * dy - h * (f1[j] + f0[j])
        for r in range(3, 7):
            F[r, j] = 0.0


@nb.njit(cache=True, nogil=True, error_model="numpy", inline="always")
def spectral_radius(J):
    """Largest |eigenvalue| of the 2 x 2 block J[:2, :2] (the stiff part of the system)."""
    tr = J[0, 0] + J[1, 1]
    det = J[0, 0] * J[1, 1] - J[0, 1] * J[1, 0]
    disc = 0.25 * tr * tr - det
    if disc >= 0.0:
        s = math.sqrt(disc)
        return max(abs(0.5 * tr + s), abs(0.5 * tr - s))
    return math.sqrt(abs(det))


#: rows of the workspace of :func:`scalar_step` (shape (SCALAR_WORK, 2), zeros initially):
#: 0-5 the stages, 6 the pair state, 7 its slope, 8-10 scratch, 11 the new state, 12 its
#: slope, 13 the error weights, 14-15 the Jacobian columns (row 14 = d x'/d(x, y) stays 0)
SCALAR_WORK = 16


@nb.njit(cache=True, nogil=True, error_model="numpy", inline="always")
def scalar_step_tableau(A, C, gamma, rhs, args, x, y, f, fx, fy, hs, W):
    """:func:`scalar_step` for any tableau of RODAS's layout (:func:`step_tableau`)."""
    W[6, 0] = x
    W[6, 1] = y
    W[7, 0] = 1.0
    W[7, 1] = f
    W[15, 0] = fx
    W[15, 1] = fy
    ok = step_tableau(
        A, C, gamma, rhs, args, W[6], W[7], hs, W[14:16], W[0:6], W[8], W[9], W[10], W[11],
        W[12],
    )  # fmt: skip
    return ok, W[11, 1], W[12, 1]


@nb.njit(cache=True, nogil=True, error_model="numpy", inline="always")
def scalar_step(rhs, args, x, y, f, fx, fy, hs, W):
    """One RODAS4 step of signed length hs for y' = f(x, y) from (x, y), as the pair
    z = (x, y) with z' = (1, f): rhs(z, out, *args) is the pair's right-hand side, f, fx,
    fy = f and its partials d f/dx, d f/dy at (x, y) (J = [[0, 0], [fx, fy]]); W the
    (SCALAR_WORK, 2) workspace.  Returns (ok, y_new, f(x + hs, y_new)); ok False when the
    linear system is singular (non-finite stages show as a non-finite y_new or slope)."""
    return scalar_step_tableau(_A, _C, _GAMMA, rhs, args, x, y, f, fx, fy, hs, W)


@nb.njit(cache=True, nogil=True, error_model="numpy", inline="always")
def scalar_error(W, hs, sc, dense):
    """:func:`error_norm` of the last :func:`scalar_step` over y alone, weight sc."""
    W[13, 1] = sc
    return error_norm(W[0:6], W[7], W[12], hs, W[13], 1, 2, dense)
