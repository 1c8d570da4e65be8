"""rsfcore: non-linear slip-stability analysis of a rate-and-state spring-slider.

Implements Ciardo & Viesca, "Non-linear stability analysis of slip in a single-degree-
of-freedom elastic system with frictional evolution laws spanning aging to slip".
Pure numerical core (numpy/scipy/numba); no web or I/O code.  See docs/core-api.md.
"""
from __future__ import annotations

#: Bumped whenever any numerical result may change; part of every cache key.
NUMERICS_VERSION = "1"

from .params import ParameterError, Params, PhysicalParams  # noqa: E402
from .trajectory import (  # noqa: E402
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
