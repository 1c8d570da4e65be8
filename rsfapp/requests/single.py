"""Request models of the HTTP API, with units and valid ranges stated in OpenAPI.

All quantities are dimensionless (Ciardo & Viesca scales) unless a field says
otherwise: phi = ln(V/V_*), psi = (tau - tau_*)/(a sigma), kappa = k Dc/(a sigma),
v_o = V_o/V_*, T = V_* t/Dc.  Ranges here are the first gate; rsfcore re-validates
and its ParameterError is reported the same way (422 problem+json naming the field).

SI alternative (classify, trajectory, critical): ``physical`` = {a, b, Dc_m, sigma_Pa,
k_Pa_per_m, V_star_m_s, V_load_m_s} replaces the dimensionless ba, kappa, vo (never both:
422 naming the dimensionless field given alongside); ``eps`` (the evolution law) is given
as before.  A perturbation may then be stated in SI too: ``factor`` (V_new/V_before, or
V_new/V_load for a load-point jump), ``new_slip_rate_m_s`` (velocity jump) or
``new_load_point_velocity_m_s`` (load-point jump) instead of ``size``.  All conversions are
rsfcore.units'; answers then carry an ``si`` block (times in s, slip rates in m/s, stress
in Pa).
"""

from __future__ import annotations

import math
from typing import Annotated, Any, Literal

from pydantic import (
    AliasChoices,
    ConfigDict,
    Field,
    SerializerFunctionWrapHandler,
    ValidationError,
    model_serializer,
    model_validator,
)
from pydantic_core import InitErrorDetails, PydanticCustomError

from rsfcore import limits
from rsfcore.units import SI_SIZE_FIELDS

from ._base import FL, RTOL, SIZE_TEXT, VALID_RTOL, F, Perturbation
from ._base import Model as _Model
from ._rules import Rule, not_both, null_or, nulls, stated

__all__ = [
    "AnalyticRequest",
    "BoundariesQueryRequest",
    "BoundariesRequest",
    "BoundariesSIRequest",
    "ClassifyPointsRequest",
    "ClassifyRequest",
    "CriticalRequest",
    "GridSpec",
    "PhysicalSI",
    "PhysicalScales",
    "Point",
    "SI_PERTURBATION_FIELDS",
    "StiffnessPhysical",
    "StiffnessRequest",
    "TrajectoryRequest",
    "field_error",
    "si_range_text",
]


class Point(_Model):
    """A point of the (phi, psi) plane (dimensionless)."""

    phi: float = F(
        ..., "finite real", "phi = ln(V/V_*), log slip rate (-).", name="phi", ge=-1e4, le=1e4
    )
    psi: float = F(
        ...,
        "finite real",
        "psi = (tau - tau_*)/(a sigma), stress (-).",
        name="psi",
        ge=-1e4,
        le=1e4,
    )


class _Dimless(_Model):
    ba: float = FL(limits.BA)
    kappa: float = FL(limits.KAPPA)
    eps: float = FL(limits.EPS)
    vo: float = FL(limits.VO)


def field_error(model: str, field: str, message: str, value: object) -> ValidationError:
    """A pydantic ValidationError located at ``field`` (so the 422 names that field, also
    inside a batch item), raised from a model validator."""
    return ValidationError.from_exception_data(
        model,
        [
            InitErrorDetails(
                type=PydanticCustomError("invalid_combination", message), loc=(field,), input=value
            )
        ],
    )


def _si_number(x: float) -> str:
    """A range end as the SI fields state it: powers of ten from 1e3 up as "1eN" (lab
    magnitudes), everything else as rsfcore.limits writes it."""
    if x >= 1e3 and math.isfinite(x):
        e = round(math.log10(x))
        if x == 10.0**e:
            return f"1e{e}"
    return limits.format_number(x)


def si_range_text(limit: limits.Limit) -> str:
    """The range of an SI limit as text, e.g. "(0, 1e3]" (rsfcore.limits.range_text with
    powers of ten written as such)."""
    lo = "(-inf" if limit.lo is None else ("(" if limit.lo_open else "[") + _si_number(limit.lo)
    hi = "inf)" if limit.hi is None else _si_number(limit.hi) + (")" if limit.hi_open else "]")
    return f"{lo}, {hi}"


def _si(
    limit: limits.Limit,
    description: str,
    *,
    name: str | None = None,
    valid: str | None = None,
    optional: bool = False,
) -> Any:
    """A required (or, with ``optional``, nullable) SI field whose bounds come from
    rsfcore.limits (the ``SI_*`` ranges); its range text carries the unit."""
    unit = "" if limit.unit in ("", "-") else f" {limit.unit}"
    text = valid or f"{si_range_text(limit)}{unit}"
    return FL(
        limit,
        None if optional else ...,
        description=description,
        name=name or limit.name,
        valid=f"null or {text}" if optional else text,
    )


class PhysicalSI(_Model):
    """A spring-slider in SI units (the names lab scripts rely on; rsfcore.units.PhysicalInputs).

    Cross-field rules (b > a, kappa = k Dc/(a sigma) <= 1e6, V_load/V_* <= 1e300) are
    checked by rsfcore.units and reported as 422 naming ``physical.<field>``.
    """

    a: float = _si(limits.SI_A, "Direct-effect coefficient a (-).")
    b: float = _si(limits.SI_B, "Evolution-effect coefficient b (-), b > a.", valid="(a, 1e6 a]")
    Dc_m: float = _si(limits.SI_DC_M, "Characteristic slip distance Dc [m].")
    sigma_Pa: float = _si(limits.SI_SIGMA_PA, "Effective normal stress sigma [Pa].")
    k_Pa_per_m: float = _si(
        limits.SI_K_PA_PER_M,
        "Machine (spring) stiffness k [Pa/m]; kappa = k Dc/(a sigma).",
        valid="[0, 1e6 a sigma/Dc] Pa/m",
    )
    V_star_m_s: float = _si(limits.SI_V_STAR_M_S, "Reference slip rate V_* [m/s].")
    V_load_m_s: float | None = _si(
        limits.SI_V_LOAD_M_S,
        "Load-point velocity V_o [m/s] (default V_*; 0 = stationary load point).",
        optional=True,
    )


#: The perturbation stated in SI (alternatives to ``size``; need ``physical``):
#: rsfcore.units.SI_SIZE_FIELDS, the one list.
SI_PERTURBATION_FIELDS: tuple[str, ...] = SI_SIZE_FIELDS
_DIMLESS = ("ba", "kappa", "vo")


def _check_si(m: _Model, name: str, with_size: bool) -> None:
    """``physical`` and the dimensionless ba, kappa, vo never both; SI perturbation fields
    need ``physical``, at most one of them, not with ``size`` or ``start``."""
    given = m.model_fields_set
    phys = getattr(m, "physical", None)
    if phys is not None:
        for f in _DIMLESS:
            if f in given:
                raise field_error(
                    name,
                    f,
                    f"give either 'physical' (SI) or the dimensionless "
                    f"'{f}' (with ba, kappa, vo), never both",
                    getattr(m, f),
                )
    if not with_size:
        return
    si = [f for f in SI_PERTURBATION_FIELDS if getattr(m, f, None) is not None]
    if not si:
        return
    if phys is None:
        raise field_error(
            name,
            si[0],
            f"'{si[0]}' states the perturbation in SI and needs "
            "'physical' (or give the dimensionless 'size')",
            getattr(m, si[0]),
        )
    if len(si) > 1:
        raise field_error(
            name,
            si[1],
            f"give one of {', '.join(SI_PERTURBATION_FIELDS)}, not both '{si[0]}' and '{si[1]}'",
            getattr(m, si[1]),
        )
    if "size" in given:
        raise field_error(
            name, "size", f"give either 'size' or '{si[0]}', never both", getattr(m, "size", None)
        )  # noqa: B009
    if getattr(m, "start", None) is not None:
        raise field_error(
            name,
            "start",
            f"'start' overrides the perturbation; do not give '{si[0]}' with it",
            None,
        )


class _SIInput(_Model):
    physical: PhysicalSI | None = F(
        None,
        "null or an object {a, b, Dc_m, sigma_Pa, k_Pa_per_m, V_star_m_s, V_load_m_s}",
        "The spring-slider in SI units, instead of ba, kappa, vo "
        "(never both). Answers then carry an 'si' block.",
        name="physical",
    )

    @model_serializer(mode="wrap")
    def _without_unused(self, handler: SerializerFunctionWrapHandler) -> dict[str, Any]:
        """With ``physical``, the dump leaves out ba, kappa, vo (unused defaults), so that
        it validates again (queued work, cache keys) and names only what was asked."""
        d: dict[str, Any] = handler(self)
        if self.physical is not None:
            for f in _DIMLESS:
                d.pop(f, None)
        return d


class _SIPerturbation(_Model):
    factor: float | None = F(
        None,
        "null or (0, 1e300]",
        "SI perturbation (needs physical), "
        "instead of size: V_new/V_before for a velocity jump, "
        "V_new/V_load for a load-point jump (-).",
        name="factor",
        gt=0,
        le=1e300,
    )
    new_slip_rate_m_s: float | None = F(
        None,
        "null or (0, 1e300] m/s",
        "SI velocity jump (needs physical): the slip rate right after the jump [m/s].",
        name="new_slip_rate_m_s",
        gt=0,
        le=1e300,
    )
    new_load_point_velocity_m_s: float | None = F(
        None,
        "null or (0, 1e300] m/s",
        "SI load-point jump (needs physical): the new load-point velocity [m/s].",
        name="new_load_point_velocity_m_s",
        gt=0,
        le=1e300,
    )


def _si_perturbation_schema(schema: dict[str, Any]) -> None:
    """The cross-field rule of the SI perturbation fields in the JSON schema: each of
    ``factor``, ``new_slip_rate_m_s``, ``new_load_point_velocity_m_s`` is null (or absent)
    unless ``physical`` is an object, and then ``size``, ``log_size`` and ``start`` are not
    given (null or absent) and neither is another SI perturbation field."""
    rules: list[dict[str, Any]] = []
    for f in SI_PERTURBATION_FIELDS:
        others = {o: {"type": "null"} for o in SI_PERTURBATION_FIELDS if o != f}
        rules.append(
            {
                "anyOf": [
                    {"properties": {f: {"type": "null"}}},
                    {
                        "required": ["physical"],
                        "not": {"required": ["size"]},
                        "properties": {
                            "physical": {"type": "object"},
                            "log_size": {"type": "null"},
                            "start": {"type": "null"},
                            **others,
                        },
                    },
                ]
            }
        )
    schema["allOf"] = [*schema.get("allOf", []), *rules]


def _size_range(lim: limits.Limit) -> dict[str, Any]:
    lo = {"exclusiveMinimum" if lim.lo_open else "minimum": lim.lo}
    hi = {"exclusiveMaximum" if lim.hi_open else "maximum": lim.hi}
    return {**lo, **hi}


def _dimless_rule(fields: tuple[str, ...]) -> Rule:
    return Rule(
        f"'physical' (SI) and the dimensionless {', '.join(fields)} are never both given",
        null_or("physical", {"properties": dict.fromkeys(fields, False)}),
    )


#: Rules of every query with a perturbation (classify, trajectory; batch items).
PERTURBATION_RULES: tuple[Rule, ...] = (
    _dimless_rule(_DIMLESS),
    Rule(
        "factor, new_slip_rate_m_s, new_load_point_velocity_m_s state the perturbation in SI: "
        "at most one of them, only with 'physical', never with size, log_size or start"
    ),
    Rule(
        "log_size is never given with size, start or an SI perturbation field",
        null_or(
            "log_size",
            {"properties": {"size": False, **nulls("start", *SI_PERTURBATION_FIELDS)}},
        ),
    ),
    Rule(
        "size lies in the range of the perturbation (unless start is given): velocity-jump "
        f"{limits.VELOCITY_JUMP_SIZE.text}; load-point-jump {limits.LOAD_POINT_JUMP_SIZE.text} "
        "with v_o (1 + dv) <= 1e300",
        {
            "anyOf": [
                {"required": ["start"], "properties": {"start": {"type": "object"}}},
                {
                    "properties": {
                        "perturbation": {"const": "velocity-jump"},
                        "size": _size_range(limits.VELOCITY_JUMP_SIZE),
                    }
                },
                {
                    "required": ["perturbation"],
                    "properties": {
                        "perturbation": {"const": "load-point-jump"},
                        "size": _size_range(limits.LOAD_POINT_JUMP_SIZE),
                    },
                },
            ]
        },
    ),
    Rule(
        "with 'physical': b > a, kappa = k_Pa_per_m Dc_m/(a sigma_Pa) <= 1e6 and "
        "V_load_m_s/V_star_m_s <= 1e300 (checked as physical.<field>)"
    ),
)


class ClassifyRequest(_SIPerturbation, _SIInput, _Dimless):
    """Classify one perturbation as stable or unstable (runaway); dimensionless or SI."""

    model_config = ConfigDict(
        json_schema_extra=stated(*PERTURBATION_RULES, then=_si_perturbation_schema)
    )

    perturbation: Perturbation = F(
        "velocity-jump",
        "'velocity-jump' or 'load-point-jump'",
        "Kind of perturbation from steady state.",
        name="perturbation",
    )
    size: float = F(
        limits.VELOCITY_JUMP_SIZE.default,
        SIZE_TEXT,
        "Perturbation size: jump d of (phi, psi) for velocity-jump, relative "
        "jump dv of v_o for load-point-jump (-).",
        name="size",
        ge=limits.VELOCITY_JUMP_SIZE.lo,
        le=limits.LOAD_POINT_JUMP_SIZE.hi,
    )
    log_size: float | None = F(
        None,
        "null or [-1e4, 1e6]",
        "The perturbation by its logarithm instead of size: d for a velocity jump, "
        "ln(1 + dv) for a load-point jump (-), so that a critical size beyond the double "
        "range (its log_critical_size) can be checked.",
        name="log_size",
        ge=-1e4,
        le=1e6,
    )
    start: Point | None = F(
        None,
        "null or a finite (phi, psi)",
        "Explicit start point; overrides perturbation and size.",
        name="start",
    )
    rtol: float = FL(limits.RTOL)

    @model_validator(mode="after")
    def _si_rules(self) -> ClassifyRequest:
        if self.log_size is not None:
            clash = [
                f
                for f in ("size", "start", *SI_PERTURBATION_FIELDS)
                if f in self.model_fields_set and getattr(self, f) is not None
            ]
            if clash:
                raise field_error(
                    type(self).__name__,
                    "log_size",
                    f"give either 'log_size' or '{clash[0]}', never both",
                    self.log_size,
                )
        _check_si(self, type(self).__name__, with_size=True)
        return self


class PhysicalScales(_Model):
    """Scales that turn a dimensionless solution into SI units (legacy form of the
    trajectory's SI columns: ``scales``, or ``physical`` with these keys)."""

    a: float = _si(limits.SI_A, "Direct-effect coefficient a (-).")
    Dc: float = _si(limits.SI_DC_M, "Characteristic slip distance Dc [m].", name="Dc")
    sigma: float = _si(limits.SI_SIGMA_PA, "Effective normal stress [Pa].", name="sigma")
    V_star: float = _si(limits.SI_V_STAR_M_S, "Reference slip rate V_* [m/s].", name="V_star")
    f_star: float = F(
        limits.F_STAR.default,
        "[-10, 10]",
        "Reference friction coefficient f_* (-).",
        name="f_star",
        ge=-10,
        le=10,
    )


_LEGACY_SCALES = {"Dc", "sigma", "V_star", "f_star"}


class TrajectoryRequest(ClassifyRequest):
    """Integrate one trajectory and return it downsampled to ``n_points`` samples.

    ``sampling``: 'tau' (default) evenly in the integrator's bounded time (resolves slow
    creep and the fast excursion alike), 'T' evenly in T = V_* t/Dc, 'seconds' evenly in
    t [s] (needs physical; the same points as 'T', since t = T Dc/V_*).  The answer says
    which sampling it used.  With ``physical`` (SI inputs) or ``scales`` the trajectory
    has SI columns (t_s, V_m_s, tau_change_Pa, friction, theta_s, slip_m, load_point_m).
    """

    model_config = ConfigDict(
        json_schema_extra=stated(
            *PERTURBATION_RULES,
            Rule(
                "'physical' (SI inputs) and 'scales' (SI columns of a dimensionless query) "
                "are never both given",
                not_both("physical", "scales"),
            ),
            Rule(
                "sampling 'seconds' needs 'physical'",
                {
                    "anyOf": [
                        {"properties": {"sampling": {"not": {"const": "seconds"}}}},
                        {"required": ["physical"], "properties": {"physical": {"type": "object"}}},
                    ]
                },
            ),
            Rule(
                "t_end_s needs 'physical'",
                null_or(
                    "t_end_s",
                    {"required": ["physical"], "properties": {"physical": {"type": "object"}}},
                ),
            ),
            Rule("t_end and t_end_s are never both given", not_both("t_end", "t_end_s")),
            then=_si_perturbation_schema,
        )
    )

    n_points: int = FL(
        limits.N_POINTS, description="Number of output samples (spacing: see sampling)."
    )
    t_end: float | None = FL(limits.T_END, valid=f"null or {limits.T_END.text}")
    t_end_s: float | None = F(
        None,
        "null or (0, 1e30] s",
        "Stop at this time t [s] (needs physical; instead of t_end).",
        name="t_end_s",
        gt=0,
        le=1e30,
    )
    sampling: Literal["tau", "T", "seconds"] = F(
        "tau",
        "'tau', 'T' or 'seconds'",
        "Spacing of the samples: evenly in the "
        "integrator's bounded time (tau), in T, or in seconds (needs physical).",
        name="sampling",
    )
    f_star: float = F(
        limits.F_STAR.default,
        "[-10, 10]",
        "Reference friction coefficient f_* for the SI friction column (with physical) (-).",
        name="f_star",
        ge=-10,
        le=10,
    )
    scales: PhysicalScales | None = F(
        None,
        "null or an object {a, Dc, sigma, V_star, f_star}",
        "Legacy: SI columns for a dimensionless "
        "query (a 'physical' object with these keys is read "
        "as 'scales').",
        name="scales",
    )

    @model_validator(mode="before")
    @classmethod
    def _legacy_physical(cls, data: object) -> object:
        if (
            isinstance(data, dict)
            and isinstance(data.get("physical"), dict)
            and "scales" not in data
            and set(data["physical"]) & _LEGACY_SCALES
        ):
            data = dict(data)
            data["scales"] = data.pop("physical")
        return data

    @model_validator(mode="after")
    def _trajectory_rules(self) -> TrajectoryRequest:
        name = type(self).__name__
        if self.physical is not None and self.scales is not None:
            raise field_error(
                name,
                "scales",
                "give either 'physical' (SI inputs) or "
                "'scales' (SI columns of a dimensionless query), not both",
                None,
            )
        if self.physical is None:
            if self.sampling == "seconds":
                raise field_error(
                    name,
                    "sampling",
                    "'seconds' needs 'physical' (use 'T' for a dimensionless query)",
                    self.sampling,
                )
            if self.t_end_s is not None:
                raise field_error(
                    name, "t_end_s", "'t_end_s' needs 'physical' (use 't_end' in T)", self.t_end_s
                )
        if self.t_end_s is not None and self.t_end is not None:
            raise field_error(
                name, "t_end_s", "give either 't_end' or 't_end_s', never both", self.t_end_s
            )
        return self


class CriticalRequest(_SIInput, _Dimless):
    """Critical perturbation size separating stable from unstable (as `rsf critical`);
    dimensionless or SI (then also the critical slip rate / load-point velocity in m/s)."""

    model_config = ConfigDict(
        json_schema_extra=stated(_dimless_rule(_DIMLESS), PERTURBATION_RULES[-1])
    )

    perturbation: Perturbation = F(
        "velocity-jump",
        "'velocity-jump' or 'load-point-jump'",
        "Kind of perturbation from steady state.",
        name="perturbation",
    )
    rtol: float = FL(limits.RTOL)

    @model_validator(mode="after")
    def _si_rules(self) -> CriticalRequest:
        _check_si(self, type(self).__name__, with_size=False)
        return self


class GridSpec(_Model):
    """A rectangular (phi, psi) grid, n_phi x n_psi points, at most 250 000 in all."""

    model_config = ConfigDict(
        json_schema_extra=stated(Rule("phi_min <= phi_max and psi_min <= psi_max"))
    )

    phi_min: float = F(-5.0, "[-1e3, 1e3]", "Smallest phi (-).", name="phi_min", ge=-1e3, le=1e3)
    phi_max: float = F(
        5.0, "[-1e3, 1e3], >= phi_min", "Largest phi (-).", name="phi_max", ge=-1e3, le=1e3
    )
    n_phi: int = F(51, "[1, 500]", "Number of phi values.", name="n_phi", ge=1, le=500)
    psi_min: float = F(-5.0, "[-1e3, 1e3]", "Smallest psi (-).", name="psi_min", ge=-1e3, le=1e3)
    psi_max: float = F(
        5.0, "[-1e3, 1e3], >= psi_min", "Largest psi (-).", name="psi_max", ge=-1e3, le=1e3
    )
    n_psi: int = F(51, "[1, 500]", "Number of psi values.", name="n_psi", ge=1, le=500)


def _one_of_points_grid(schema: dict[str, Any]) -> None:
    """Exactly one of ``points`` (a non-empty list) or ``grid`` (an object), in the schema."""
    schema["oneOf"] = [
        {"required": ["points"], "properties": {"points": {"type": "array", "minItems": 1}}},
        {"required": ["grid"], "properties": {"grid": {"type": "object"}}},
    ]
    for alt in schema.get("properties", {}).get("points", {}).get("anyOf", []):
        if alt.get("type") == "array":
            alt["minItems"] = 1


class AnalyticRequest(_Model):
    """Analytic Lyapunov function U at points or on a grid.

    ``function`` = 'kcrit': U of `eq: trajectories 1` (kappa = kappa_crit, uses vo);
    'vo0': U of `eq: trajectories 2` (stationary load point, uses kappa).
    """

    model_config = ConfigDict(
        json_schema_extra=stated(
            Rule("exactly one of points (at least one point) or grid"),
            Rule("format=png (query) needs grid"),
            then=_one_of_points_grid,
        )
    )

    function: Literal["kcrit", "vo0"] = F(
        "kcrit", "'kcrit' or 'vo0'", "Which closed form.", name="function"
    )
    ba: float = FL(limits.BA)
    eps: float = FL(limits.EPS)
    vo: float = F(
        limits.VO.default, "(0, 1e300]", "v_o (-), used by 'kcrit'.", name="vo", gt=0, le=1e300
    )
    kappa: float = FL(limits.KAPPA, description="kappa (-), used by 'vo0'.")
    points: Annotated[list[Point], Field(max_length=10_000)] | None = F(
        None, "null or 1..10000 points", "Points (phi, psi); give points or grid.", name="points"
    )
    grid: GridSpec | None = F(None, "null or a grid", "A grid; give points or grid.", name="grid")

    @model_validator(mode="after")
    def _one_of(self) -> AnalyticRequest:
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

    ba: float = FL(limits.BA)
    kappa: float = FL(limits.KAPPA)
    eps: float = FL(limits.EPS)
    phi: Annotated[list[Annotated[float, Field(ge=-1e3, le=1e3)]], Field(max_length=10_000)] = F(
        [],
        "0..10000 values in [-1e3, 1e3]",
        "phi values at which to give psi on the acceleration line (-).",
        name="phi",
    )


#: Most phi values of the query form (GET): its URL stays within what the HTTP layer
#: accepts (uvicorn/h11 refuse a request line of more than about 16 kB with 400).
MAX_QUERY_PHI = 200


class BoundariesQueryRequest(BoundariesRequest):
    """Stability boundaries as a query (GET): as the body form, at most 200 phi values."""

    phi: Annotated[
        list[Annotated[float, Field(ge=-1e3, le=1e3)]], Field(max_length=MAX_QUERY_PHI)
    ] = F(
        [],
        f"0..{MAX_QUERY_PHI} values in [-1e3, 1e3] (more with POST)",
        "phi values at which to give psi on the acceleration line (-).",
        name="phi",
    )


class BoundariesSIRequest(_SIInput, BoundariesRequest):
    """Stability boundaries (POST): dimensionless, or the machine in SI (``physical``
    instead of ba and kappa; then also k_crit [Pa/m] and kappa/kappa_crit)."""

    model_config = ConfigDict(
        json_schema_extra=stated(_dimless_rule(("ba", "kappa")), PERTURBATION_RULES[-1])
    )

    @model_validator(mode="after")
    def _si_rules(self) -> BoundariesSIRequest:
        _check_si(self, type(self).__name__, with_size=False)
        return self


class StiffnessPhysical(_Model):
    """Physical parameters (SI) for the critical dimension of a continuum fault."""

    mu: float = F(..., "(0, 1e13] Pa", "Shear modulus [Pa].", name="mu", gt=0, le=1e13)
    nu: float = F(0.25, "[0, 0.5)", "Poisson's ratio (-).", name="nu", ge=0, lt=0.5)
    mode_of_slip: Literal["II", "III"] = F(
        "II", "'II' or 'III'", "In-plane (II) or anti-plane (III) slip.", name="mode_of_slip"
    )
    sigma_Pa: float = F(
        ...,
        "(0, 1e12] Pa",
        "Effective normal stress [Pa] (also accepted as 'sigma').",
        name="sigma_Pa",
        gt=0,
        le=1e12,
        validation_alias=AliasChoices("sigma_Pa", "sigma"),
    )
    a: float = F(..., "(0, 1]", "Direct-effect coefficient (-).", name="a", gt=0, le=1)
    b: float = F(
        ..., "(a, 1e6 a]", "Evolution-effect coefficient (-), b > a.", name="b", gt=0, le=1e6
    )
    Dc_m: float = F(
        ...,
        "(0, 1e3] m",
        "Characteristic slip distance [m] (also accepted as 'Dc').",
        name="Dc_m",
        gt=0,
        le=1e3,
        validation_alias=AliasChoices("Dc_m", "Dc"),
    )
    h: float | None = F(
        None,
        "null or (0, 1e7] m",
        "Depth of the interface [m]; required for cases C and D.",
        name="h",
        gt=0,
        le=1e7,
    )


class StiffnessRequest(_Model):
    """Eigen-stiffness of continuum case A-E and, with physical parameters, the critical
    dimension (lambda_c, L_c or R_c, in metres)."""

    model_config = ConfigDict(
        json_schema_extra=stated(
            Rule("physical.b > physical.a (velocity weakening)"),
            Rule("mode 0 only for cases A and C; physical.h is required for cases C and D"),
        )
    )

    case: Literal["A", "B", "C", "D", "E"] = F(
        "A", "'A'..'E'", "Configuration of `tab: table`.", name="case"
    )
    mode: int = F(
        0,
        "[0, 64] (0 only for A and C)",
        "Eigenmode, 0 = smallest eigenvalue.",
        name="mode",
        ge=0,
        le=64,
    )
    physical: StiffnessPhysical | None = F(
        None, "null or an object", "SI parameters.", name="physical"
    )


class ClassifyPointsRequest(_Dimless):
    """Classify many start points (phi0, psi0) for one parameter set at once: the
    separatrix is computed once and each point is placed against it (points within a
    safety margin of it are integrated); every outcome agrees with /v1/classify given the
    same start (rsfcore.phase.classify_points)."""

    model_config = ConfigDict(json_schema_extra=stated(Rule("psi has as many values as phi")))

    phi: Annotated[list[float], Field(min_length=1, max_length=100_000)] = F(
        ...,
        "1..100000 values in [-1e4, 1e4]",
        "Start phi = ln(V/V_*) of each point (-).",
        name="phi",
    )
    psi: Annotated[list[float], Field(min_length=1, max_length=100_000)] = F(
        ...,
        "1..100000 values in [-1e8, 1e8], as many as phi",
        "Start psi = (tau - tau_*)/(a sigma) of each point (-).",
        name="psi",
    )
    rtol: float = F(
        limits.RTOL.default,
        VALID_RTOL,
        "Relative tolerance of the fallback integrations (-).",
        name="rtol",
        **RTOL,
    )

    @model_validator(mode="after")
    def _same_length(self) -> ClassifyPointsRequest:
        if len(self.psi) != len(self.phi):
            raise field_error(
                type(self).__name__,
                "psi",
                f"psi has {len(self.psi)} values, phi has {len(self.phi)}: give one psi per phi",
                len(self.psi),
            )
        return self
