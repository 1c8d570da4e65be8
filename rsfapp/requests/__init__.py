"""Request models of the HTTP API (and of queued work), with units and valid ranges
stated in OpenAPI.

All quantities are dimensionless (Ciardo & Viesca scales) unless a field says
otherwise: phi = ln(V/V_*), psi = (tau - tau_*)/(a sigma), kappa = k Dc/(a sigma),
v_o = V_o/V_*, T = V_* t/Dc.  Ranges here are the first gate; rsfcore re-validates
and its ParameterError is reported the same way (422 problem+json naming the field).
"""

from typing import TYPE_CHECKING

from rsfapp.lazy import lazy_getattr

if TYPE_CHECKING:  # imported on first use: a CLI command builds only its question's models
    from ._base import VALID, Perturbation
    from .single import (
        SI_PERTURBATION_FIELDS,
        AnalyticRequest,
        BoundariesQueryRequest,
        BoundariesRequest,
        BoundariesSIRequest,
        ClassifyPointsRequest,
        ClassifyRequest,
        CriticalRequest,
        GridSpec,
        PhysicalScales,
        PhysicalSI,
        Point,
        StiffnessPhysical,
        StiffnessRequest,
        TrajectoryRequest,
    )
    from .sweeps import AXIS_RANGES, AxisName, SweepAxis, SweepFixed, SweepRequest

#: Where each name lives (PEP 562: the module is imported, and its models built, on first
#: access; `rsf figure` needs neither the single nor the sweep models).
_WHERE: dict[str, str] = {
    "VALID": "_base",
    "Perturbation": "_base",
    **dict.fromkeys(
        (
            "SI_PERTURBATION_FIELDS",
            "AnalyticRequest",
            "BoundariesQueryRequest",
            "BoundariesRequest",
            "BoundariesSIRequest",
            "ClassifyPointsRequest",
            "ClassifyRequest",
            "CriticalRequest",
            "GridSpec",
            "PhysicalScales",
            "PhysicalSI",
            "Point",
            "StiffnessPhysical",
            "StiffnessRequest",
            "TrajectoryRequest",
        ),
        "single",
    ),
    **dict.fromkeys(
        ("AXIS_RANGES", "AxisName", "SweepAxis", "SweepFixed", "SweepRequest"), "sweeps"
    ),
}


_MODULES = frozenset(("single", "batch", "protocols", "fits", "sweeps", "figures"))


__getattr__ = lazy_getattr(__name__, _MODULES, _WHERE, globals())


__all__ = [
    "AXIS_RANGES",
    "AnalyticRequest",
    "AxisName",
    "BoundariesQueryRequest",
    "BoundariesRequest",
    "BoundariesSIRequest",
    "ClassifyPointsRequest",
    "ClassifyRequest",
    "CriticalRequest",
    "GridSpec",
    "Perturbation",
    "PhysicalSI",
    "PhysicalScales",
    "Point",
    "SI_PERTURBATION_FIELDS",
    "StiffnessPhysical",
    "StiffnessRequest",
    "SweepAxis",
    "SweepFixed",
    "SweepRequest",
    "TrajectoryRequest",
    "VALID",
]
