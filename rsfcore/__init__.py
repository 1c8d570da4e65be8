"""rsfcore: non-linear slip-stability analysis of a rate-and-state spring-slider.

Implements Ciardo & Viesca, "Non-linear stability analysis of slip in a single-degree-
of-freedom elastic system with frictional evolution laws spanning aging to slip".
Pure numerical core (numpy/scipy/numba); no web or I/O code.  See docs/core-api.md.
"""
from __future__ import annotations

from ._version import NUMERICS_VERSION
from .params import ParameterError, Params, PhysicalParams
from .trajectory import (
    Trajectory,
    TrajectoryResult,
    UndecidedError,
    classify,
    simulate,
    start_point,
)

__all__ = [
    "NUMERICS_VERSION",
    "ParameterError",
    "Params",
    "PhysicalParams",
    "Trajectory",
    "TrajectoryResult",
    "UndecidedError",
    "classify",
    "simulate",
    "start_point",
]
