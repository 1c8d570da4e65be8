"""Shared ODE machinery of rsfcore: one implementation per method (DOP853, RODAS4, RODASP,
Radau IIA).

* :mod:`rsfcore.ode.dop853_tableau`: the published Dormand-Prince 8(5,3) coefficients.
* :mod:`rsfcore.ode.rk`: stage, solution, error norm, step-size controller, starting
  step, dense output, Illinois root finder, Newton inversion of a monotone component
  (samples at given times) and stiffness indicator as numba kernels,
  used by the spring-slider engine (rsfcore.engine) and the separatrix integrator
  (rsfcore.separatrix).
* :mod:`rsfcore.ode.rodas4_tableau`: the published RODAS4 coefficients.
* :mod:`rsfcore.ode.rodas4`: the Rosenbrock method RODAS4 (step, linear solve, error norm,
  step-size controller, Hermite dense output) as numba kernels, used by the engine's stiff
  phases; its step kernel takes any tableau of RODAS's layout (``step_tableau``).
* :mod:`rsfcore.ode.rodasp_tableau`: the published RODASP coefficients (Steinebach 1995)
  and their transformed form.
* :mod:`rsfcore.ode.rodasp`: RODASP's step (RODAS4's kernel with RODASP's coefficients),
  which keeps its order on stiff problems where RODAS4 loses it; used by the separatrix
  integrator's stiff corner.
* :mod:`rsfcore.ode.radau5`: Radau IIA of order 5 (3 stages, simplified Newton in the
  real/complex split of A^-1, Hairer's embedded error estimate, the collocation
  polynomial as dense output), its coefficients derived from the method's definition;
  the engine's stiff phases (the default since NUMERICS_VERSION 9).
"""

from __future__ import annotations

from . import dop853_tableau, radau5, rk, rodas4, rodas4_tableau, rodasp, rodasp_tableau

__all__ = [
    "dop853_tableau",
    "radau5",
    "rk",
    "rodas4",
    "rodas4_tableau",
    "rodasp",
    "rodasp_tableau",
]
