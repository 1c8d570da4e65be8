"""Request models of the lab protocols (rsfcore.protocols), in SI units.

The machine is the ``physical`` set of every SI query ({a, b, Dc_m, sigma_Pa, k_Pa_per_m,
V_star_m_s, V_load_m_s}; ``V_load_m_s`` is not used: the protocol sets the load-point
velocity), plus the evolution law ``eps`` (0 slip, 1 aging) and f_* for absolute
friction.  Answers carry the true per-segment peaks, steady-state and peak friction
changes, and the sampled history (JSON, CSV or PNG).
"""

from __future__ import annotations

from typing import Annotated, Literal

from pydantic import ConfigDict, Field, model_validator

from rsfcore import limits

from ._base import FL, F
from ._base import Model as _Model
from ._rules import Rule, stated
from .single import PhysicalSI, field_error

__all__ = [
    "LoadHistoryRequest",
    "ProtocolStart",
    "Segment",
    "SlideHoldSlideRequest",
    "VelocityStepRequest",
    "MAX_PROTOCOL_SAMPLES",
]

#: Largest number of output samples of one protocol answer.
MAX_PROTOCOL_SAMPLES = 200_000


#: The rules of the SI machine of every protocol (checked by rsfcore.units).
_MACHINE_RULE = Rule(
    "physical: b > a, kappa = k_Pa_per_m Dc_m/(a sigma_Pa) <= 1e6 (checked as physical.<field>)"
)


class _Machine(_Model):
    model_config = ConfigDict(json_schema_extra=stated(_MACHINE_RULE))

    physical: PhysicalSI = F(
        ...,
        "an object {a, b, Dc_m, sigma_Pa, k_Pa_per_m, V_star_m_s}",
        "The spring-slider in SI units (V_load_m_s is not used: the protocol sets the load point).",
    )
    eps: float = FL(limits.EPS)
    f_star: float = F(
        limits.F_STAR.default,
        "[-10, 10]",
        "Reference friction f_* at V_* (-).",
        name="f_star",
        ge=-10,
        le=10,
    )
    rtol: float = FL(limits.RTOL)


class VelocityStepRequest(_Machine):
    """Load-point velocity step V1 -> V2 from steady state at V1 (needs k > 0), compared
    with the infinitely stiff closed form `eq: delta tau`."""

    V1_m_s: float = F(
        ...,
        "(0, 1e3] m/s",
        "Load-point velocity before the step [m/s].",
        name="V1_m_s",
        gt=0,
        le=1e3,
    )
    V2_m_s: float = F(
        ...,
        "(0, 1e3] m/s",
        "Load-point velocity after the step [m/s].",
        name="V2_m_s",
        gt=0,
        le=1e3,
    )
    slip_total_m: float | None = F(
        None,
        "null or (0, 1e3] m",
        "Load-point displacement after the step [m] (default 10 Dc).",
        name="slip_total_m",
        gt=0,
        le=1e3,
    )
    slip_after_m: float | None = F(
        None,
        "null or [0, 1e3] m",
        "Start of the comparison window with `eq: delta tau` [m] (default 20 a sigma/k).",
        name="slip_after_m",
        ge=0,
        le=1e3,
    )
    n_points: int = F(
        400,
        "[2, 10000]",
        "Output samples, evenly spaced in time.",
        name="n_points",
        ge=2,
        le=10_000,
    )


class SlideHoldSlideRequest(_Machine):
    """Slide at V, hold (load point stopped), reslide at V: healing and relaxation."""

    V_m_s: float = F(
        ..., "(0, 1e3] m/s", "Sliding (load-point) velocity [m/s].", name="V_m_s", gt=0, le=1e3
    )
    hold_s: float = F(..., "(0, 1e12] s", "Hold time [s].", name="hold_s", gt=0, le=1e12)
    slide_before_s: float = F(
        ...,
        "(0, 1e12] s",
        "Slide before the hold [s] (from steady state).",
        name="slide_before_s",
        gt=0,
        le=1e12,
    )
    slide_after_s: float = F(
        ..., "(0, 1e12] s", "Reslide after the hold [s].", name="slide_after_s", gt=0, le=1e12
    )
    n_points_per_segment: int = F(
        200,
        "[2, 100000]",
        "Output samples per segment, evenly spaced in time.",
        name="n_points_per_segment",
        ge=2,
        le=100_000,
    )


class Segment(_Model):
    """One piece of a load history: the load point moves at V_load_m_s for duration_s."""

    duration_s: float = F(..., "(0, 1e12] s", "Duration [s].", name="duration_s", gt=0, le=1e12)
    V_load_m_s: float = F(
        ..., "[0, 1e3] m/s", "Load-point velocity [m/s] (0: hold).", name="V_load_m_s", ge=0, le=1e3
    )


class ProtocolStart(_Model):
    """An explicit start state (instead of steady state)."""

    V_m_s: float = F(..., "(0, 1e3] m/s", "Slip rate [m/s].", name="V_m_s", gt=0, le=1e3)
    theta_s: float = F(..., "(0, 1e30] s", "State theta [s].", name="theta_s", gt=0, le=1e30)


class LoadHistoryRequest(_Machine):
    """Any piecewise-constant load-point velocity history (velocity steps, holds, ...)."""

    model_config = ConfigDict(
        json_schema_extra=stated(
            _MACHINE_RULE,
            Rule(
                f"segments x n_points_per_segment <= {MAX_PROTOCOL_SAMPLES} samples in all",
            ),
        )
    )

    segments: Annotated[list[Segment], Field(min_length=1, max_length=1000)] = F(
        ...,
        "1..1000 segments",
        "The history: (duration_s, V_load_m_s) pieces in order.",
        name="segments",
    )
    n_points_per_segment: int = F(
        200,
        "[2, 100000]",
        "Output samples per segment, evenly spaced in time.",
        name="n_points_per_segment",
        ge=2,
        le=100_000,
    )
    start_state: Literal["steady"] | ProtocolStart = F(
        "steady",
        "'steady' or {V_m_s, theta_s}",
        "Start at steady state at the first "
        "segment's velocity (V_* if it is 0), or at an explicit state.",
        name="start_state",
    )

    @model_validator(mode="after")
    def _total(self) -> LoadHistoryRequest:
        n = len(self.segments) * self.n_points_per_segment
        if n > MAX_PROTOCOL_SAMPLES:
            raise field_error(
                type(self).__name__,
                "n_points_per_segment",
                f"{len(self.segments)} segments x {self.n_points_per_segment} "
                f"samples = {n} > {MAX_PROTOCOL_SAMPLES} samples in all",
                n,
            )
        return self
