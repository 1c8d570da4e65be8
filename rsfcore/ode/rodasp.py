"""RODASP, the L-stable Rosenbrock method of order 4(3) that keeps its order on stiff
problems (Steinebach 1995; coefficients in rsfcore.ode.rodasp_tableau), as compiled
seams: used by the separatrix integrator (rsfcore.separatrix) in its stiff corner and by
the spring-slider engine (rsfcore.engine) in its stiff phases.

RODASP has RODAS4's layout (6 stages, gamma = 1/4, stiffly accurate, stage 6 at the
embedded solution, k_6 the error estimate), so its step is rsfcore.ode.rodas4's
:func:`~rsfcore.ode.rodas4.step_tableau` with RODASP's transformed coefficients, and the
linear solve, the error norm (without the dense-output term, which is RODAS4's) and the
step-size controller (error exponent 1/4) are RODAS4's too:

* :func:`step`: one step of length h for y' = f(y) (6 right-hand sides), arguments as
  rsfcore.ode.rodas4.step;
* :func:`error_norm`: rsfcore.ode.rodas4's error norm with RODASP's own continuous
  extension (rsfcore.ode.rodasp_tableau.D2, D3, derived there: order 3, least norm), so
  that the engine's cubic Hermite dense output is bounded as for RODAS4;
* :func:`scalar_step`: a scalar non-autonomous ODE y' = f(x, y) as the autonomous pair
  (x, y), x' = 1, on a (rsfcore.ode.rodas4.SCALAR_WORK, 2) workspace, arguments as
  rsfcore.ode.rodas4.scalar_step; its error: rsfcore.ode.rodas4.scalar_error with
  ``dense=False``.

Why a second Rosenbrock method: on y' = lambda (y - g(x)) + g'(x) with |h lambda| large
(Prothero & Robinson's problem, and the separatrix's scalar ODE where kappa is large,
d(rhs)/dy ~ -kappa e^(-phi)/|G|) RODAS4's local error falls to order ~1 in h, so each
decade of tolerance costs ~10x the steps; RODASP satisfies the extra order conditions of
that problem and keeps order ~4 (tests/core/test_rodasp.py measures both).  On the
separatrix at b/a = kappa = 1e6 to s_theta = 0 (rsfcore.separatrix, measured with the
same controller): rtol 1e-10 in 702 steps against 21,034 for RODAS4, 1e-12 in 2,383
against 209,697.  On the engine's stiff relaxations (a load-point jump at b/a = 4.9e4,
kappa = 6.1e4, eps = 1, dv = 8e45, 200 samples) RODASP with its dense check takes 2,565 /
9,646 / 18,972 steps at rtol 1e-10 / 1e-12 / 1e-13 against RODAS4's 11,287 / 37,396 /
66,654 (rsfcore.engine; with RODASP the engine hands back to DOP853 later, at h |lambda|
< 1 instead of 2).

Every kernel is compiled with ``inline="always"``; numba's cache does not track these
cross-module calls: after editing this file or rodas4.py, also touch the drivers
(rsfcore/separatrix.py, rsfcore/engine.py) or clear NUMBA_CACHE_DIR.

References: G. Steinebach, Order-reduction of ROW-methods for DAEs and method of lines
applications, Preprint 1741, TH Darmstadt, 1995; E. Hairer, G. Wanner, Solving Ordinary
Differential Equations II, 2nd ed., Springer 1996 (Sec. IV.7, VI.4); A. Prothero,
A. Robinson, Math. Comp. 28 (1974) 145-162.
"""

from __future__ import annotations

import numba as nb
import numpy as np

from . import rodas4
from . import rodasp_tableau as _rp

__all__ = ["N_STAGES", "step", "scalar_step", "error_norm"]

#: stages per step (= right-hand sides per step, f(y_new) included)
N_STAGES = rodas4.N_STAGES

# transformed a_ij (rows 0..4) and c_ij (rows 0..5), row i = stage i+1, as arrays (numba
# freezes module-level arrays as constants)
_A, _C = rodas4.tableau_arrays(_rp.A, _rp.C)
_GAMMA = _rp.GAMMA
_D2 = np.array(_rp.D2)
_D3 = np.array(_rp.D3)


@nb.njit(cache=True, nogil=True, error_model="numpy", inline="always")
def step(rhs, args, y, f0, h, J, R, tmp, ftmp, buf, ynew, fnew):
    """One RODASP step of signed length h from (y, f0 = f(y)) with the Jacobian J at y
    (arguments and result as rsfcore.ode.rodas4.step; k_6 in R[5] the error estimate)."""
    return rodas4.step_tableau(
        _A, _C, _GAMMA, rhs, args, y, f0, h, J, R, tmp, ftmp, buf, ynew, fnew
    )


@nb.njit(cache=True, nogil=True, error_model="numpy", inline="always")
def scalar_step(rhs, args, x, y, f, fx, fy, hs, W):
    """One RODASP step of signed length hs for y' = f(x, y) from (x, y) (arguments and
    result as rsfcore.ode.rodas4.scalar_step; its error: rodas4.scalar_error with
    dense=False)."""
    return rodas4.scalar_step_tableau(_A, _C, _GAMMA, rhs, args, x, y, f, fx, fy, hs, W)


@nb.njit(cache=True, nogil=True, error_model="numpy", inline="always")
def error_norm(R, f0, f1, h, sc, j0, j1, dense):
    """Normalised local error of a RODASP step: rsfcore.ode.rodas4.error_norm (k_6, and
    with ``dense`` the mid-step distance between the cubic Hermite interpolant and the
    method's own continuous extension) with RODASP's extension (rodasp_tableau.D2, D3)."""
    return rodas4.error_norm_tableau(_D2, _D3, R, f0, f1, h, sc, j0, j1, dense)
