"""Shared ODE machinery of rsfcore: the DOP853 tableau and its compiled building blocks.

* :mod:`rsfcore.ode.dop853_tableau`: the published Dormand-Prince 8(5,3) coefficients.
* :mod:`rsfcore.ode.rk`: stage, solution, error norm, step-size controller, starting
  step, dense output, Illinois root finder, Newton inversion of a monotone component
  (samples at given times) and stiffness indicator as numba kernels,
  used by the spring-slider engine (rsfcore.engine) and the separatrix integrator
  (rsfcore.separatrix).
* :mod:`rsfcore.ode.rodas4_tableau`: the published RODAS4 coefficients of the engine's
  Rosenbrock method for stiff phases.
"""

from __future__ import annotations

from . import dop853_tableau, rk, rodas4_tableau

__all__ = ["dop853_tableau", "rk", "rodas4_tableau"]
