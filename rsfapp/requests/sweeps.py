"""Request model of a sweep (a grid over parameters, computed by the workers)."""
from __future__ import annotations

from typing import Annotated, Literal

from pydantic import Field

from ._base import RTOL, VALID_RTOL, F, Perturbation
from ._base import Model as _Model

__all__ = ["AXIS_RANGES", "AxisName", "SweepAxis", "SweepFixed", "SweepRequest"]

AxisName = Literal["kappa_ratio", "eps", "ba", "size"]
#: Valid range of each sweep axis (checked per value, reported as <axis>.values[i]).
AXIS_RANGES: dict[str, tuple[float, float, str]] = {
    "kappa_ratio": (0.0, 1e6, "[0, 1e6] (and kappa_ratio*(ba-1) <= 1e6)"),
    "eps": (0.0, 1.0, "[0, 1]"),
    "ba": (1.0, 1e6, "(1, 1e6]"),
    "size": (-1e3, 1e3, "[-1e3, 1e3]"),
}


class SweepAxis(_Model):
    """One sweep axis: explicit ``values`` or ``start``/``stop``/``n`` (optionally log)."""

    name: AxisName = F(..., "'kappa_ratio', 'eps', 'ba' or 'size'", "Swept parameter.",
                       name="name")
    values: Annotated[list[float], Field(min_length=1, max_length=1000)] | None = F(
        None, "null or 1..1000 values in the axis range", "Explicit values.", name="values")
    start: float | None = F(None, "axis range (see name)", "First value.", name="start")
    stop: float | None = F(None, "axis range (see name)", "Last value.", name="stop")
    n: int | None = F(None, "[1, 1000]", "Number of values from start to stop.", name="n",
                      ge=1, le=1000)
    log: bool = F(False, "true or false", "Geometric spacing (start, stop > 0).", name="log")


class SweepFixed(_Model):
    """Values of the parameters that are not swept (dimensionless)."""

    ba: float = F(2.0, "(1, 1e6]", "b/a (-).", name="ba", gt=1.0, le=1e6)
    kappa_ratio: float = F(1.0, "[0, 1e6]", "kappa/kappa_crit (-).", name="kappa_ratio",
                           ge=0, le=1e6)
    eps: float = F(0.0, "[0, 1]", "Evolution-law parameter (-).", name="eps", ge=0, le=1)
    vo: float = F(1.0, "0 or (0, 1e300]", "v_o (-).", name="vo", ge=0, le=1e300)
    size: float | None = F(None, "null or [-1e3, 1e3]", "Perturbation size; when given "
                           "(or swept) each point gives the outcome instead of the critical "
                           "size.", name="size", ge=-1e3, le=1e3)


class SweepRequest(_Model):
    """A 2-D grid over two of {kappa_ratio, eps, ba, size}, computed by the workers."""

    x: SweepAxis
    y: SweepAxis
    fixed: SweepFixed = Field(default_factory=SweepFixed)
    perturbation: Perturbation = F("velocity-jump", "'velocity-jump' or 'load-point-jump'",
                                   "Kind of perturbation.", name="perturbation")
    rtol: float = F(1e-10, VALID_RTOL, "Relative tolerance (-).", name="rtol", **RTOL)
    chunk_points: int | None = F(None, "null or [1, 10000]", "Points per chunk (default: "
                                 "about chunk_seconds of work).", name="chunk_points",
                                 ge=1, le=10_000)
