"""Request models of the HTTP API, with units and valid ranges stated in OpenAPI.

All quantities are dimensionless (Ciardo & Viesca scales) unless a field says
otherwise: phi = ln(V/V_*), psi = (tau - tau_*)/(a sigma), kappa = k Dc/(a sigma),
v_o = V_o/V_*, T = V_* t/Dc.  Ranges here are the first gate; rsfcore re-validates
and its ParameterError is reported the same way (422 problem+json naming the field).
"""
from __future__ import annotations

from typing import Annotated, Literal

from pydantic import Field, model_validator

from ._base import RTOL, VALID_RTOL, F, Perturbation
from ._base import Model as _Model

__all__ = [
    "AnalyticRequest", "BoundariesRequest", "ClassifyRequest", "CriticalRequest",
    "GridSpec", "PhysicalScales", "Point", "StiffnessPhysical", "StiffnessRequest",
    "TrajectoryRequest",
]


class Point(_Model):
    """A point of the (phi, psi) plane (dimensionless)."""

    phi: float = F(..., "finite real", "phi = ln(V/V_*), log slip rate (-).", name="phi",
                   ge=-1e4, le=1e4)
    psi: float = F(..., "finite real", "psi = (tau - tau_*)/(a sigma), stress (-).", name="psi",
                   ge=-1e4, le=1e4)


class _Dimless(_Model):
    ba: float = F(2.0, "(1, 1e6]", "b/a, rate-weakening ratio (-).", name="ba", gt=1.0, le=1e6)
    kappa: float = F(1.0, "[0, 1e6]", "kappa = k Dc/(a sigma), dimensionless stiffness (-); "
                     "the linear critical value is b/a - 1.", name="kappa", ge=0.0, le=1e6)
    eps: float = F(0.0, "[0, 1]", "Evolution-law parameter: 0 = slip law, 1 = aging law (-).",
                   name="eps", ge=0.0, le=1.0)
    vo: float = F(1.0, "0 or (0, 1e300]", "v_o = V_o/V_*, load-point velocity (-).", name="vo",
                  ge=0.0, le=1e300)


class ClassifyRequest(_Dimless):
    """Classify one perturbation as stable or unstable (runaway)."""

    perturbation: Perturbation = F("velocity-jump", "'velocity-jump' or 'load-point-jump'",
                                   "Kind of perturbation from steady state.", name="perturbation")
    size: float = F(1.0, "[-1e3, 1e3] (load-point-jump: > -1)",
                    "Perturbation size: jump d of (phi, psi) for velocity-jump, relative "
                    "jump dv of v_o for load-point-jump (-).", name="size", ge=-1e3, le=1e3)
    start: Point | None = F(None, "null or a finite (phi, psi)",
                            "Explicit start point; overrides perturbation and size.", name="start")
    rtol: float = F(1e-10, VALID_RTOL, "Relative tolerance of the integrator (-).",
                    name="rtol", **RTOL)


class PhysicalScales(_Model):
    """Scales that turn the dimensionless solution into SI units."""

    a: float = F(..., "(0, 1]", "Direct-effect coefficient a (-).", name="a", gt=0, le=1)
    Dc: float = F(..., "(0, 1e3] m", "Characteristic slip distance Dc [m].", name="Dc",
                  gt=0, le=1e3)
    sigma: float = F(..., "(0, 1e12] Pa", "Effective normal stress [Pa].", name="sigma",
                     gt=0, le=1e12)
    V_star: float = F(..., "(0, 1e3] m/s", "Reference slip rate V_* [m/s].", name="V_star",
                      gt=0, le=1e3)
    f_star: float = F(0.6, "[-10, 10]", "Reference friction coefficient f_* (-).",
                      name="f_star", ge=-10, le=10)


class TrajectoryRequest(ClassifyRequest):
    """Integrate one trajectory and return it downsampled to ``n_points`` samples."""

    n_points: int = F(200, "[2, 10000]", "Number of output samples (equally spaced in the "
                      "integrator's bounded time).", name="n_points", ge=2, le=10_000)
    t_end: float | None = F(None, "null or (0, 1e12]", "Stop at this dimensionless time "
                            "T = V_* t/Dc (default: at the certificate).", name="t_end",
                            gt=0, le=1e12)
    physical: PhysicalScales | None = F(None, "null or an object", "Adds SI columns.",
                                        name="physical")


class CriticalRequest(_Dimless):
    """Critical perturbation size separating stable from unstable (as `rsf critical`)."""

    perturbation: Perturbation = F("velocity-jump", "'velocity-jump' or 'load-point-jump'",
                                   "Kind of perturbation from steady state.", name="perturbation")
    rtol: float = F(1e-10, VALID_RTOL, "Relative tolerance of the integrator (-).",
                    name="rtol", **RTOL)


class GridSpec(_Model):
    """A rectangular (phi, psi) grid, n_phi x n_psi points, at most 250 000 in all."""

    phi_min: float = F(-5.0, "[-1e3, 1e3]", "Smallest phi (-).", name="phi_min", ge=-1e3, le=1e3)
    phi_max: float = F(5.0, "[-1e3, 1e3], >= phi_min", "Largest phi (-).", name="phi_max",
                       ge=-1e3, le=1e3)
    n_phi: int = F(51, "[1, 500]", "Number of phi values.", name="n_phi", ge=1, le=500)
    psi_min: float = F(-5.0, "[-1e3, 1e3]", "Smallest psi (-).", name="psi_min", ge=-1e3, le=1e3)
    psi_max: float = F(5.0, "[-1e3, 1e3], >= psi_min", "Largest psi (-).", name="psi_max",
                       ge=-1e3, le=1e3)
    n_psi: int = F(51, "[1, 500]", "Number of psi values.", name="n_psi", ge=1, le=500)


class AnalyticRequest(_Model):
    """Analytic Lyapunov function U at points or on a grid.

    ``function`` = 'kcrit': U of `eq: trajectories 1` (kappa = kappa_crit, uses vo);
    'vo0': U of `eq: trajectories 2` (stationary load point, uses kappa).
    """

    function: Literal["kcrit", "vo0"] = F("kcrit", "'kcrit' or 'vo0'", "Which closed form.",
                                          name="function")
    ba: float = F(2.0, "(1, 1e6]", "b/a (-).", name="ba", gt=1.0, le=1e6)
    eps: float = F(0.0, "[0, 1]", "Evolution-law parameter (-).", name="eps", ge=0, le=1)
    vo: float = F(1.0, "(0, 1e300]", "v_o (-), used by 'kcrit'.", name="vo", gt=0, le=1e300)
    kappa: float = F(1.0, "[0, 1e6]", "kappa (-), used by 'vo0'.", name="kappa", ge=0, le=1e6)
    points: Annotated[list[Point], Field(max_length=10_000)] | None = F(
        None, "null or 1..10000 points", "Points (phi, psi); give points or grid.", name="points")
    grid: GridSpec | None = F(None, "null or a grid", "A grid; give points or grid.",
                              name="grid")

    @model_validator(mode="after")
    def _one_of(self) -> "AnalyticRequest":
        if (self.points is None) == (self.grid is None):
            raise ValueError("give exactly one of 'points' or 'grid'")
        if self.points is not None and not self.points:
            raise ValueError("'points' must hold at least one point")
        if self.grid is not None:
            g = self.grid
            if g.phi_max < g.phi_min or g.psi_max < g.psi_min:
                raise ValueError("grid needs phi_min <= phi_max and psi_min <= psi_max")
        return self


class BoundariesRequest(_Model):
    """Stability boundaries at (ba, kappa, eps) and optionally the acceleration line."""

    ba: float = F(2.0, "(1, 1e6]", "b/a (-).", name="ba", gt=1.0, le=1e6)
    kappa: float = F(1.0, "[0, 1e6]", "kappa (-).", name="kappa", ge=0, le=1e6)
    eps: float = F(0.0, "[0, 1]", "Evolution-law parameter (-).", name="eps", ge=0, le=1)
    phi: Annotated[list[Annotated[float, Field(ge=-1e3, le=1e3)]], Field(max_length=10_000)] = F(
        [], "0..10000 values in [-1e3, 1e3]", "phi values at which to give psi on the "
        "acceleration line (-).", name="phi")


class StiffnessPhysical(_Model):
    """Physical parameters (SI) for the critical dimension of a continuum fault."""

    mu: float = F(..., "(0, 1e13] Pa", "Shear modulus [Pa].", name="mu", gt=0, le=1e13)
    nu: float = F(0.25, "[0, 0.5)", "Poisson's ratio (-).", name="nu", ge=0, lt=0.5)
    mode_of_slip: Literal["II", "III"] = F("II", "'II' or 'III'", "In-plane (II) or "
                                           "anti-plane (III) slip.", name="mode_of_slip")
    sigma: float = F(..., "(0, 1e12] Pa", "Effective normal stress [Pa].", name="sigma",
                     gt=0, le=1e12)
    a: float = F(..., "(0, 1]", "Direct-effect coefficient (-).", name="a", gt=0, le=1)
    b: float = F(..., "(a, 1e6 a]", "Evolution-effect coefficient (-), b > a.", name="b",
                 gt=0, le=1e6)
    Dc: float = F(..., "(0, 1e3] m", "Characteristic slip distance [m].", name="Dc",
                  gt=0, le=1e3)
    h: float | None = F(None, "null or (0, 1e7] m", "Depth of the interface [m]; required "
                        "for cases C and D.", name="h", gt=0, le=1e7)


class StiffnessRequest(_Model):
    """Eigen-stiffness of continuum case A-E and, with physical parameters, the critical
    dimension (lambda_c, L_c or R_c, in metres)."""

    case: Literal["A", "B", "C", "D", "E"] = F("A", "'A'..'E'", "Configuration of `tab: "
                                               "table`.", name="case")
    mode: int = F(0, "[0, 64] (0 only for A and C)", "Eigenmode, 0 = smallest eigenvalue.",
                  name="mode", ge=0, le=64)
    physical: StiffnessPhysical | None = F(None, "null or an object", "SI parameters.",
                                           name="physical")
