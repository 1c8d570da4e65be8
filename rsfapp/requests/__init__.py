"""Request models of the HTTP API (and of queued work), with units and valid ranges
stated in OpenAPI.

All quantities are dimensionless (Ciardo & Viesca scales) unless a field says
otherwise: phi = ln(V/V_*), psi = (tau - tau_*)/(a sigma), kappa = k Dc/(a sigma),
v_o = V_o/V_*, T = V_* t/Dc.  Ranges here are the first gate; rsfcore re-validates
and its ParameterError is reported the same way (422 problem+json naming the field).
"""

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
