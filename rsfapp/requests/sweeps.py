"""Request model of a sweep: an N-D grid (1 to 5 axes) or scattered points, computed by
the workers.

Three equivalent ways to give the points:

* ``axes``: a list of 1-5 axes, each ``{name, values}`` or ``{name, start, stop, n, log}``;
  the grid is their outer product, flattened in C order (the first axis varies slowest);
* ``points``: an object of equal-length arrays (``{"ba": [...], "eps": [...]}``), one
  point per index (Monte Carlo or lab-derived samples);
* ``x`` / ``y``: the original 2-D form, the same as ``axes: [x, y]``.

Parameters not swept take their ``fixed`` values.  ``kappa`` (= k Dc/(a sigma)) and
``kappa_ratio`` (= kappa/kappa_crit, kappa_crit = b/a - 1) are alternatives: give or sweep
one of them.  Per point the workers compute the critical size, or, when a ``size`` is
fixed or swept, the outcome of that perturbation.

SI: ``fixed.physical`` = {a, b, Dc_m, sigma_Pa, k_Pa_per_m, V_star_m_s, V_load_m_s} (the
names of the single queries, :class:`~rsfapp.requests.single.PhysicalSI`) describes the
machine that is not swept: it fixes ba = b/a, kappa = k Dc/(a sigma) and vo = V_load/V_*
(converted by rsfcore.units in :func:`rsfapp.grid.expand`).  Rule: with ``physical`` only
``eps`` and ``size`` may be swept, and none of fixed ``ba``, ``kappa``, ``kappa_ratio``,
``vo`` may be given (422 naming the clashing field: ``fixed.ba``, ``axes[1].name``,
``points.vo``, ...).
"""

from __future__ import annotations

from typing import Annotated, Any, Literal

from pydantic import Field, SerializerFunctionWrapHandler, model_serializer

from rsfcore import limits

from ._base import FL, RTOL, VALID_RTOL, F, Perturbation
from ._base import Model as _Model
from .single import PhysicalSI

__all__ = [
    "AXIS_RANGES",
    "AxisName",
    "MAX_AXIS_N",
    "MAX_AXIS_VALUES",
    "SweepAxis",
    "SweepFixed",
    "SweepRequest",
    "SI_FIXED",
]

AxisName = Literal["ba", "kappa", "kappa_ratio", "eps", "vo", "size"]
#: Valid range of each swept parameter (lo, hi, text); checked per value and reported as
#: e.g. ``axes[2].stop`` or ``points.eps[17]``.
AXIS_RANGES: dict[str, tuple[float, float, str]] = {
    "ba": (1.0, limits.BA_MAX, limits.BA.text),
    "kappa": (0.0, limits.KAPPA_MAX, limits.KAPPA.text),
    "kappa_ratio": (
        0.0,
        limits.KAPPA_MAX,
        f"{limits.KAPPA_RATIO.text} (and "
        f"kappa_ratio*(ba-1) <= {limits.format_number(limits.KAPPA_MAX)})",
    ),
    "eps": (0.0, 1.0, limits.EPS.text),
    "vo": (0.0, limits.VO_MAX, limits.VO.text),
    "size": (
        -limits.SIZE_MAX,
        limits.SIZE_MAX,
        f"{limits.VELOCITY_JUMP_SIZE.text} "
        f"(load-point jump: (-1, {limits.format_number(limits.SIZE_MAX)}])",
    ),
}
#: Largest number of explicit values of one axis.
MAX_AXIS_VALUES = 100_000
#: Largest n of one start/stop axis (the grid size limit is a setting).
MAX_AXIS_N = 1_000_000_000


class SweepAxis(_Model):
    """One sweep axis: explicit ``values`` or ``start``/``stop``/``n`` (optionally log).

    Generated values: v_k = start + (stop - start) k/(n - 1) (log: geometric), with the
    end points exact."""

    name: AxisName = F(
        ..., "'ba', 'kappa', 'kappa_ratio', 'eps', 'vo' or 'size'", "Swept parameter.", name="name"
    )
    values: Annotated[list[float], Field(min_length=1, max_length=MAX_AXIS_VALUES)] | None = F(
        None,
        f"null or 1..{MAX_AXIS_VALUES} values in the axis range",
        "Explicit values.",
        name="values",
    )
    start: float | None = F(None, "axis range (see name)", "First value.", name="start")
    stop: float | None = F(None, "axis range (see name)", "Last value.", name="stop")
    n: int | None = F(
        None,
        f"[1, {MAX_AXIS_N}]",
        "Number of values from start to stop.",
        name="n",
        ge=1,
        le=MAX_AXIS_N,
    )
    log: bool = F(False, "true or false", "Geometric spacing (start, stop > 0).", name="log")


#: The dimensionless parameters that ``fixed.physical`` determines (never given or swept
#: together with it).
SI_FIXED: tuple[str, ...] = ("ba", "kappa", "kappa_ratio", "vo")


class SweepFixed(_Model):
    """Values of the parameters that are not swept: dimensionless, or ba, kappa and vo
    as the SI machine ``physical`` (never both; see the module docstring)."""

    ba: float = FL(limits.BA)
    kappa_ratio: float | None = F(
        None,
        "null or [0, 1e6]",
        "kappa/kappa_crit (-); default 1 unless kappa is given or swept.",
        name="kappa_ratio",
        ge=0,
        le=1e6,
    )
    kappa: float | None = F(
        None,
        "null or [0, 1e6]",
        "kappa = k Dc/(a sigma) (-), instead of kappa_ratio.",
        name="kappa",
        ge=0,
        le=1e6,
    )
    eps: float = FL(limits.EPS)
    vo: float = FL(limits.VO)
    size: float | None = F(
        None,
        f"null or {AXIS_RANGES['size'][2]}",
        "Perturbation size; when given "
        "(or swept) each point gives the outcome instead of the critical "
        "size.",
        name="size",
        ge=-limits.SIZE_MAX,
        le=limits.SIZE_MAX,
    )
    physical: PhysicalSI | None = F(
        None,
        "null or an object {a, b, Dc_m, sigma_Pa, k_Pa_per_m, V_star_m_s, V_load_m_s}",
        "The machine in SI units instead of ba, kappa/kappa_ratio and vo (never "
        "both; these cannot be swept then). The sweep's data then carry SI scales.",
        name="fixed.physical",
    )

    @model_serializer(mode="wrap")
    def _without_unused(self, handler: SerializerFunctionWrapHandler) -> dict[str, Any]:
        """With ``physical``, the dump leaves out the dimensionless defaults it replaces,
        so that it validates again and names only what was asked."""
        d: dict[str, Any] = handler(self)
        if self.physical is not None:
            for f in SI_FIXED:
                if f not in self.model_fields_set:
                    d.pop(f, None)
        return d


class SweepRequest(_Model):
    """An N-D grid (``axes``), scattered ``points`` or the 2-D ``x``/``y`` form (exactly one
    of them), computed by the workers in chunks."""

    axes: Annotated[list[SweepAxis], Field(min_length=1, max_length=5)] | None = F(
        None,
        "null or 1..5 axes with different names",
        "Grid axes (outer product, first axis slowest).",
        name="axes",
    )
    points: dict[AxisName, list[float]] | None = F(
        None,
        "null or equal-length arrays (at most RSF_SWEEP_MAX_SCATTERED)",
        "Scattered points: one array per swept parameter.",
        name="points",
    )
    x: SweepAxis | None = None
    y: SweepAxis | None = None
    fixed: SweepFixed = Field(default_factory=SweepFixed)
    perturbation: Perturbation = F(
        "velocity-jump",
        "'velocity-jump' or 'load-point-jump'",
        "Kind of perturbation.",
        name="perturbation",
    )
    rtol: float = F(1e-10, VALID_RTOL, "Relative tolerance (-).", name="rtol", **RTOL)
    chunk_points: int | None = F(
        None,
        "null or [1, 1000000]",
        "Points per chunk (default: about RSF_CHUNK_SECONDS of work).",
        name="chunk_points",
        ge=1,
        le=1_000_000,
    )
