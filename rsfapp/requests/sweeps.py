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

Perturbation sizes in SI (with ``fixed.physical`` only, as the single queries state them):
``factor`` (V_new/V_before for a velocity jump, V_new/V_load for a load-point jump),
``new_slip_rate_m_s`` (velocity jump: the slip rate right after the jump [m/s]) or
``new_load_point_velocity_m_s`` (load-point jump: the new load-point velocity [m/s]),
fixed (``fixed.factor``, ...) or swept (an axis or points array of that name), instead
of ``size``.  Each value is converted once by rsfcore.units (d = ln(V_new/V_before),
dv = V_new/V_load - 1; :func:`rsfapp.grid.si_to_size`); the sweep's coordinates stay in
the SI values given.  At most one statement of the size; 422 naming the field when a size
is given both ways (``fixed.size``), twice in SI, in SI without ``fixed.physical``, or in
the unit of the other perturbation kind.
"""

from __future__ import annotations

from typing import Annotated, Any, Literal

from pydantic import ConfigDict, Field, SerializerFunctionWrapHandler, model_serializer

from rsfcore import limits, units

from ._base import FL, F, Perturbation
from ._base import Model as _Model
from ._rules import NULL, Rule, nulls, stated
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
    "SI_SIZE_FIELDS",
]

AxisName = Literal[
    "ba",
    "kappa",
    "kappa_ratio",
    "eps",
    "vo",
    "size",
    "factor",
    "new_slip_rate_m_s",
    "new_load_point_velocity_m_s",
]
#: The perturbation size stated in SI (alternatives to ``size``; need ``fixed.physical``),
#: fixed or swept; the names of the single queries (rsfapp.requests.single).
SI_SIZE_FIELDS: tuple[str, ...] = units.SI_SIZE_FIELDS  # the one list (rsfcore.units)
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
    "vo": (0.0, limits.VO_MAX, limits.VO_VALID_TEXT),
    "size": (
        -limits.SIZE_MAX,
        limits.SIZE_MAX,
        f"{limits.VELOCITY_JUMP_SIZE.text} "
        f"(load-point jump: (-1, {limits.format_number(limits.SIZE_MAX)}])",
    ),
    # SI sizes: the ends the values alone must satisfy (open at 0); rsfcore.units checks
    # the converted size (|d| <= 1e4; V_new/V_* <= 1e300) and names the value
    "factor": (0.0, limits.VO_MAX, "(0, 1e300] (needs fixed.physical)"),
    "new_slip_rate_m_s": (
        0.0,
        limits.VO_MAX,
        "(0, 1e300] m/s with |ln(V_new/V_before)| <= 1e4 (velocity jump; needs fixed.physical)",
    ),
    "new_load_point_velocity_m_s": (
        0.0,
        limits.VO_MAX,
        "(0, 1e300 V_star_m_s] m/s (load-point jump; needs fixed.physical)",
    ),
}
#: Largest number of explicit values of one axis.
MAX_AXIS_VALUES = 100_000
#: Largest n of one start/stop axis (the grid size limit is a setting).
MAX_AXIS_N = 1_000_000_000


def _range(name: str) -> dict[str, Any]:
    """JSON Schema of one value of parameter ``name`` (AXIS_RANGES; open at the low end
    for ba and the SI sizes).  The ends that depend on the perturbation (load-point jump:
    size > -1, vo > 0) and kappa_ratio (ba - 1) <= 1e6 are stated as text."""
    lo, hi, _ = AXIS_RANGES[name]
    low = "exclusiveMinimum" if name == "ba" or name in SI_SIZE_FIELDS else "minimum"
    return {"type": "number", low: lo, "maximum": hi}


def _axis_ranges() -> dict[str, Any]:
    return {
        "anyOf": [
            {
                "properties": {
                    "name": {"const": n},
                    "values": {"items": _range(n)},
                    "start": _range(n) | {"type": ["number", "null"]},
                    "stop": _range(n) | {"type": ["number", "null"]},
                }
            }
            for n in AXIS_RANGES
        ]
    }


class SweepAxis(_Model):
    """One sweep axis: explicit ``values`` or ``start``/``stop``/``n`` (optionally log).

    Generated values: v_k = start + (stop - start) k/(n - 1) (log: geometric), with the
    end points exact."""

    model_config = ConfigDict(
        json_schema_extra=stated(
            Rule(
                "either values, or start, stop and n (never both, never neither)",
                {
                    "anyOf": [
                        {
                            "required": ["values"],
                            "properties": {
                                "values": {"type": "array"},
                                **nulls("start", "stop", "n"),
                            },
                        },
                        {
                            "required": ["start", "stop", "n"],
                            "properties": {
                                "values": NULL,
                                "start": {"type": "number"},
                                "stop": {"type": "number"},
                                "n": {"type": "integer"},
                            },
                        },
                    ]
                },
            ),
            Rule(
                "log spacing of start/stop needs start > 0 and stop > 0",
                {
                    "anyOf": [
                        {"properties": {"log": {"const": False}}},
                        {"required": ["values"], "properties": {"values": {"type": "array"}}},
                        {
                            "properties": {
                                "start": {"exclusiveMinimum": 0},
                                "stop": {"exclusiveMinimum": 0},
                            }
                        },
                    ]
                },
            ),
            Rule(
                "values, start and stop lie in the range of the axis name ("
                + "; ".join(f"{n} {t}" for n, (_lo, _hi, t) in AXIS_RANGES.items())
                + "; with a load-point jump also size > -1 and vo > 0)",
                _axis_ranges(),
            ),
        )
    )

    name: AxisName = F(
        ...,
        "'ba', 'kappa', 'kappa_ratio', 'eps', 'vo', 'size', or with fixed.physical the SI size "
        "'factor', 'new_slip_rate_m_s' (velocity jump), 'new_load_point_velocity_m_s' "
        "(load-point jump)",
        "Swept parameter.",
        name="name",
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


def _si_size_schema(schema: dict[str, Any]) -> None:
    """The cross-field rule of the SI size fields in the JSON schema: each of ``factor``,
    ``new_slip_rate_m_s``, ``new_load_point_velocity_m_s`` is null (or absent) unless
    ``physical`` is an object, and then ``size`` is not given (null or absent) and
    neither is another SI size field.  (Rules against swept axes are checked by
    rsfapp.grid: 422 naming the field.)"""
    rules: list[dict[str, Any]] = []
    for f in SI_SIZE_FIELDS:
        others = {o: {"type": "null"} for o in SI_SIZE_FIELDS if o != f}
        rules.append(
            {
                "anyOf": [
                    {"properties": {f: {"type": "null"}}},
                    {
                        "required": ["physical"],
                        "properties": {
                            "physical": {"type": "object"},
                            "size": {"type": "null"},
                            **others,
                        },
                    },
                ]
            }
        )
    schema["allOf"] = [*schema.get("allOf", []), *rules]


class SweepFixed(_Model):
    """Values of the parameters that are not swept: dimensionless, or ba, kappa and vo
    as the SI machine ``physical`` (never both; see the module docstring), and the
    perturbation size as ``size`` or, with ``physical``, in SI."""

    model_config = ConfigDict(
        json_schema_extra=stated(
            Rule(
                "'physical' (SI) and the dimensionless ba, kappa, kappa_ratio, vo are never "
                "both given"
            ),
            Rule(
                "factor, new_slip_rate_m_s, new_load_point_velocity_m_s state the size in SI: "
                "at most one of them, only with 'physical', never with size",
            ),
            then=_si_size_schema,
        )
    )

    ba: float = FL(limits.BA)
    kappa_ratio: float | None = F(
        None,
        "null or [0, 1e6]",
        f"kappa/kappa_crit (-); default {limits.KAPPA_RATIO.default:g} "
        "(rsfcore.limits.KAPPA_RATIO, as rsfcore.diagram.stability_diagram) unless kappa is "
        "given or swept.",
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
        "both; these cannot be swept then). The sweep's data then carry SI scales "
        "and the critical sizes in SI.",
        name="fixed.physical",
    )
    factor: float | None = F(
        None,
        "null or (0, 1e300] (needs fixed.physical)",
        "SI perturbation size instead of size: V_new/V_before for a velocity jump "
        "(d = ln factor), V_new/V_load for a load-point jump (dv = factor - 1) (-).",
        name="fixed.factor",
        gt=0,
        le=limits.VO_MAX,
    )
    new_slip_rate_m_s: float | None = F(
        None,
        "null or (0, 1e300] m/s (velocity jump; needs fixed.physical)",
        "SI velocity jump instead of size: the slip rate right after the jump "
        "(d = ln(V_new/V_before)) [m/s].",
        name="fixed.new_slip_rate_m_s",
        gt=0,
        le=limits.VO_MAX,
    )
    new_load_point_velocity_m_s: float | None = F(
        None,
        "null or (0, 1e300 V_star_m_s] m/s (load-point jump; needs fixed.physical)",
        "SI load-point jump instead of size: the new load-point velocity "
        "(dv = V_new/V_load - 1) [m/s].",
        name="fixed.new_load_point_velocity_m_s",
        gt=0,
        le=limits.VO_MAX,
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


def _form(required: tuple[str, ...], types: dict[str, str]) -> dict[str, Any]:
    others = [f for f in ("axes", "points", "x", "y") if f not in required]
    return {
        "required": list(required),
        "properties": {**{f: {"type": t} for f, t in types.items()}, **nulls(*others)},
    }


class SweepRequest(_Model):
    """An N-D grid (``axes``), scattered ``points`` or the 2-D ``x``/``y`` form (exactly one
    of them), computed by the workers in chunks."""

    model_config = ConfigDict(
        json_schema_extra=stated(
            Rule(
                "exactly one form: axes, or points, or both x and y",
                {
                    "anyOf": [
                        _form(("axes",), {"axes": "array"}),
                        _form(("points",), {"points": "object"}),
                        _form(("x", "y"), {"x": "object", "y": "object"}),
                    ]
                },
            ),
            Rule("every swept parameter once: the names of x and y differ, as do those of axes"),
            Rule("the arrays of points have equal lengths"),
            Rule(
                "the values of points lie in the range of their parameter (as an axis)",
                {
                    "properties": {
                        "points": {"properties": {n: {"items": _range(n)} for n in AXIS_RANGES}}
                    }
                },
            ),
            Rule(
                "a swept parameter does not clash with fixed (e.g. kappa with kappa_ratio; "
                "with fixed.physical none of ba, kappa, kappa_ratio, vo is swept or given)"
            ),
            Rule("at most RSF_SWEEP_MAX_POINTS points (RSF_SWEEP_MAX_SCATTERED scattered)"),
        )
    )

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
    rtol: float = FL(limits.RTOL)
    chunk_points: int | None = F(
        None,
        "null or [1, 1000000]",
        "Points per chunk (default: about RSF_CHUNK_SECONDS of work).",
        name="chunk_points",
        ge=1,
        le=1_000_000,
    )
