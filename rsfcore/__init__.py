"""rsfcore: non-linear slip-stability analysis of a rate-and-state spring-slider.

Implements Ciardo & Viesca, "Non-linear stability analysis of slip in a single-degree-
of-freedom elastic system with frictional evolution laws spanning aging to slip".
Pure numerical core (numpy/scipy/numba); no web or I/O code.  The public surface below
is the one documented in docs/core-api.md; tests/core/test_public_api.py pins it.

Layout: ``params`` / ``limits`` / ``errors`` (inputs, valid ranges, exceptions),
``trajectory`` (classify, simulate), ``phase`` (classify_points), ``critical`` and
``separatrix`` (critical perturbation sizes), ``diagram``, ``boundaries``, ``analytic``,
``protocols``, ``stiffness``, ``laws``, ``engine`` with the shared ODE kernels in
``ode``, and ``_version`` (NUMERICS_VERSION).
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

from ._cache import configure as _configure_kernel_cache
from ._kernel_load import install as _install_lean_kernel_load

# before any kernel module imports numba: one per-user cache of compiled kernels, loaded
# without numba's whole compiler set-up (rsfcore/_kernel_load.py)
_configure_kernel_cache()
_install_lean_kernel_load()

from ._version import NUMERICS_VERSION  # noqa: E402

if TYPE_CHECKING:  # the names below are imported on first use (fast CLI start-up)
    from . import (
        analytic,
        boundaries,
        critical,
        diagram,
        engine,
        errors,
        laws,
        limits,
        ode,
        params,
        phase,
        protocols,
        separatrix,
        stiffness,
        trajectory,
    )
    from .analytic import U_kcrit, U_vo0
    from .boundaries import (
        ab_crit,
        acceleration_line,
        acceleration_possible,
        boundaries_summary,
        eps_crit,
        kappa_crit,
        max_unstable_kappa,
    )
    from .critical import (
        KINDS,
        PERTURBATIONS,
        CriticalResult,
        bisect_critical,
        critical_perturbation,
    )
    from .diagram import AXIS_NAMES, DiagramResult, stability_diagram
    from .engine import EngineResult
    from .errors import BudgetExceeded, IntegrationBudgetError, ParameterError, UndecidedError
    from .limits import DEFAULT_RTOL, RTOL_RANGE, Limit
    from .params import Params, PhysicalParams
    from .phase import PointsResult, classify_points
    from .protocols import (
        ProtocolResult,
        SlideHoldSlideResult,
        VelocityStepResult,
        load_history,
        slide_hold_slide,
        steady_state_friction,
        velocity_step,
    )
    from .stiffness import (
        critical_dimension,
        eigen_mode,
        eigen_stiffness,
        kappa_of_fault,
        stiffness_of_fault,
        stiffness_summary,
    )
    from .trajectory import (
        Perturbation,
        Trajectory,
        TrajectoryResult,
        classify,
        simulate,
        start_point,
    )

#: Where each public name lives (imported on first access, PEP 562), so that
#: ``from rsfcore import limits`` does not load every numba kernel module.
_WHERE: dict[str, str] = {
    "AXIS_NAMES": "diagram",
    "BudgetExceeded": "errors",
    "CriticalResult": "critical",
    "DEFAULT_RTOL": "limits",
    "DiagramResult": "diagram",
    "EngineResult": "engine",
    "IntegrationBudgetError": "errors",
    "KINDS": "critical",
    "Limit": "limits",
    "NUMERICS_VERSION": "_version",
    "PERTURBATIONS": "critical",
    "ParameterError": "errors",
    "Params": "params",
    "Perturbation": "trajectory",
    "PhysicalParams": "params",
    "PointsResult": "phase",
    "ProtocolResult": "protocols",
    "RTOL_RANGE": "limits",
    "SlideHoldSlideResult": "protocols",
    "Trajectory": "trajectory",
    "TrajectoryResult": "trajectory",
    "U_kcrit": "analytic",
    "U_vo0": "analytic",
    "UndecidedError": "errors",
    "VelocityStepResult": "protocols",
    "ab_crit": "boundaries",
    "acceleration_line": "boundaries",
    "acceleration_possible": "boundaries",
    "bisect_critical": "critical",
    "boundaries_summary": "boundaries",
    "classify": "trajectory",
    "classify_points": "phase",
    "critical_dimension": "stiffness",
    "critical_perturbation": "critical",
    "eigen_mode": "stiffness",
    "eigen_stiffness": "stiffness",
    "eps_crit": "boundaries",
    "kappa_crit": "boundaries",
    "kappa_of_fault": "stiffness",
    "load_history": "protocols",
    "max_unstable_kappa": "boundaries",
    "simulate": "trajectory",
    "slide_hold_slide": "protocols",
    "stability_diagram": "diagram",
    "start_point": "trajectory",
    "steady_state_friction": "protocols",
    "stiffness_of_fault": "stiffness",
    "stiffness_summary": "stiffness",
    "velocity_step": "protocols",
}


def __getattr__(name: str) -> Any:
    if name in _WHERE:
        value = getattr(importlib.import_module(f".{_WHERE[name]}", __name__), name)
        globals()[name] = value
        return value
    if name in __all__:  # the public names not in _WHERE are rsfcore's modules
        return importlib.import_module(f".{name}", __name__)
    raise AttributeError(f"module 'rsfcore' has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted(__all__)


__all__ = [
    # version
    "NUMERICS_VERSION",
    # errors
    "BudgetExceeded",
    "IntegrationBudgetError",
    "ParameterError",
    "UndecidedError",
    # parameters and their valid ranges
    "DEFAULT_RTOL",
    "Limit",
    "Params",
    "PhysicalParams",
    "RTOL_RANGE",
    # trajectories and classification
    "Perturbation",
    "Trajectory",
    "TrajectoryResult",
    "classify",
    "simulate",
    "start_point",
    # many start points of one parameter set
    "PointsResult",
    "classify_points",
    # critical perturbations
    "CriticalResult",
    "KINDS",
    "PERTURBATIONS",
    "bisect_critical",
    "critical_perturbation",
    # stability diagrams
    "AXIS_NAMES",
    "DiagramResult",
    "stability_diagram",
    # boundaries
    "ab_crit",
    "acceleration_line",
    "acceleration_possible",
    "boundaries_summary",
    "eps_crit",
    "kappa_crit",
    "max_unstable_kappa",
    # analytic Lyapunov functions
    "U_kcrit",
    "U_vo0",
    # lab protocols
    "ProtocolResult",
    "SlideHoldSlideResult",
    "VelocityStepResult",
    "load_history",
    "slide_hold_slide",
    "steady_state_friction",
    "velocity_step",
    # continuum stiffness
    "critical_dimension",
    "eigen_mode",
    "eigen_stiffness",
    "kappa_of_fault",
    "stiffness_of_fault",
    "stiffness_summary",
    # engine result (the kernel itself: rsfcore.engine)
    "EngineResult",
    # modules
    "analytic",
    "boundaries",
    "critical",
    "diagram",
    "engine",
    "errors",
    "laws",
    "limits",
    "ode",
    "params",
    "phase",
    "protocols",
    "separatrix",
    "stiffness",
    "trajectory",
]
