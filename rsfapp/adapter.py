"""The one adapter between the application (service and worker) and :mod:`rsfcore`.

Each function takes a validated request model (:mod:`rsfapp.requests`), calls rsfcore and
returns a JSON-safe dict.  rsfcore's ``ParameterError`` passes through unchanged (the API
reports it as 422 problem+json naming the field); a numerical failure (e.g.
``UndecidedError``) becomes :class:`ComputeError` (422 "could not be computed" over HTTP,
recorded per point by sweeps); a single query that runs out of the quick step budget
raises :class:`NeedsQueue`.  Nothing here does I/O or knows about HTTP.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import numpy as np
from numpy.typing import NDArray
from pydantic import BaseModel, TypeAdapter, ValidationError

from rsfcore import NUMERICS_VERSION, analytic, limits
from rsfcore import batch as _batch
from rsfcore import boundaries as _bounds
from rsfcore import critical as _critical
from rsfcore import phase as _phase
from rsfcore import protocols as _protocols
from rsfcore import stiffness as _stiff
from rsfcore import trajectory as _traj
from rsfcore.jsonsafe import jsonsafe
from rsfcore.limits import Limit
from rsfcore.params import ParameterError, Params, PhysicalParams
from rsfcore.units import (
    PhysicalInputs,
    load_point_jump_si,
    load_point_jump_size,
    velocity_jump_si,
    velocity_jump_size,
)

from .requests import (
    SI_PERTURBATION_FIELDS,
    VALID,
    AnalyticRequest,
    BoundariesRequest,
    ClassifyPointsRequest,
    ClassifyRequest,
    CriticalRequest,
    PhysicalSI,
    StiffnessRequest,
    TrajectoryRequest,
)
from .requests.fits import FIT_LAWS, FitRequest
from .requests.protocols import LoadHistoryRequest, SlideHoldSlideRequest, VelocityStepRequest

__all__ = [
    "ComputeError",
    "NeedsQueue",
    "QUICK_STEPS",
    "SAMPLING_NOTE",
    "numerics_version",
    "classify",
    "classify_points",
    "trajectory",
    "critical",
    "resolve_params",
    "resolve_size",
    "si_inputs",
    "classify_batch",
    "critical_batch",
    "item_error",
    "validate_items",
    "protocol_velocity_step",
    "protocol_slide_hold_slide",
    "protocol_load_history",
    "protocol_table",
    "PROTOCOL_COLUMNS",
    "fit",
    "fit_key_request",
    "fit_record_of",
    "fit_table",
    "FIT_COLUMNS",
    "analytic_u",
    "boundaries",
    "stiffness",
    "guard",
]


class ComputeError(RuntimeError):
    """Valid input whose computation failed numerically (message says why)."""


class NeedsQueue(ComputeError):
    """The quick in-process attempt ran out of its step budget: a long integration,
    to be computed by a worker (service.answer routes it through the queue)."""


#: Default step budget of the in-process attempt at a single query (~0.2-0.5 s of
#: integration; the setting ``RSF_QUICK_STEPS`` overrides it); a query that needs more is
#: a long integration and goes through the Celery queue.
QUICK_STEPS = 300_000


def numerics_version() -> str:
    """rsfcore.NUMERICS_VERSION (part of every cache key)."""
    return str(NUMERICS_VERSION)


def guard(fn: Callable[..., Any], *args: Any, **kwargs: Any) -> Any:
    """Call ``fn``; ParameterError passes through, other numerical failures become
    :class:`ComputeError` (:class:`NeedsQueue` when the quick step budget ran out)."""
    try:
        return fn(*args, **kwargs)
    except (ParameterError, ComputeError):
        raise
    except (ArithmeticError, ValueError, RuntimeError, FloatingPointError) as exc:
        if getattr(exc, "reason", None) == "budget" and kwargs.get("max_steps") is not None:
            raise NeedsQueue(str(exc)) from exc
        raise ComputeError(f"{type(exc).__name__}: {exc}") from exc


def _json(obj: Any) -> dict[str, Any]:
    """rsfcore.jsonsafe of a dict answer, typed as one."""
    out = jsonsafe(obj)
    assert isinstance(out, dict)
    return out


def _params(req: Any) -> Params:
    p: Params = guard(Params, ba=req.ba, kappa=req.kappa, eps=req.eps, vo=req.vo)
    return p


# --- single queries: dimensionless or SI (conversions: rsfcore.units only) ---------------
def si_inputs(req: Any) -> PhysicalInputs | None:
    """The request's ``physical`` SI set as rsfcore.units.PhysicalInputs (None without);
    its cross-field checks raise ParameterError naming ``physical.<field>``."""
    phys = getattr(req, "physical", None)
    if phys is None or not isinstance(phys, PhysicalSI):
        return None
    inputs: PhysicalInputs = guard(PhysicalInputs.from_dict, phys.model_dump(exclude_none=True))
    return inputs


def resolve_params(req: Any) -> tuple[Params, PhysicalInputs | None]:
    """(Params, PhysicalInputs or None): from ``physical`` and ``eps`` when SI, else from
    the dimensionless ba, kappa, eps, vo."""
    phys = si_inputs(req)
    if phys is None:
        return _params(req), None
    p: Params = guard(phys.to_params, req.eps)
    return p, phys


def resolve_size(req: Any, phys: PhysicalInputs | None) -> float:
    """The dimensionless perturbation size: ``size``, or the SI statement (``factor``,
    ``new_slip_rate_m_s``, ``new_load_point_velocity_m_s``) converted by rsfcore.units."""
    given = {f: getattr(req, f, None) for f in SI_PERTURBATION_FIELDS}
    given = {f: v for f, v in given.items() if v is not None}
    if not given or phys is None:
        return float(req.size)
    try:
        if req.perturbation == "velocity-jump":
            if "new_load_point_velocity_m_s" in given:
                raise ParameterError(
                    "new_load_point_velocity_m_s",
                    given["new_load_point_velocity_m_s"],
                    "not used by a velocity jump (give factor or new_slip_rate_m_s)",
                )
            return float(velocity_jump_size(phys, **given))
        if "new_slip_rate_m_s" in given:
            raise ParameterError(
                "new_slip_rate_m_s",
                given["new_slip_rate_m_s"],
                "not used by a load-point jump (give factor or new_load_point_velocity_m_s)",
            )
        return float(load_point_jump_size(phys, **given))
    except ParameterError as exc:  # name the request's field, not units' dotted one
        field = exc.field.removeprefix("perturbation.")
        raise ParameterError(field, exc.value, exc.valid) from None


def _jump_si(phys: PhysicalInputs, perturbation: str, size: float | None) -> dict[str, Any]:
    """A perturbation of dimensionless ``size`` in SI: the velocity jump (factor, new slip
    rate [m/s], shear-stress jump a sigma d [Pa] at constant state) or the load-point jump
    (new load-point velocity [m/s])."""
    if size is None or not math.isfinite(size):
        return {}
    if perturbation == "velocity-jump":
        d = guard(velocity_jump_si, phys, size).to_dict()
        d["shear_stress_jump_Pa"] = phys.shear_stress_change_Pa(size)
        d["friction_jump"] = phys.friction_change(size)
        return {"velocity_jump": d}
    return {"load_point_jump": guard(load_point_jump_si, phys, size).to_dict()}


def _scales_si(phys: PhysicalInputs) -> dict[str, Any]:
    return {
        "inputs": phys.to_dict(),
        "kappa": phys.kappa,
        "kappa_crit": phys.kappa_crit,
        "k_crit_Pa_per_m": phys.k_crit_Pa_per_m,
        "time_scale_s": phys.time_scale_s,
        "stress_scale_Pa": phys.stress_scale_Pa,
        "slip_rate_before_m_s": phys.slip_rate_before_m_s,
    }


def _outcome_si(phys: PhysicalInputs, out: dict[str, Any]) -> dict[str, Any]:
    """The ``si`` block of a classify/trajectory answer: times [s], peak slip rate [m/s],
    start shear-stress change [Pa] and friction change, the perturbation in SI."""

    def ts(T: Any) -> float | None:
        return None if T is None else phys.time_s(float(T))

    peak = out.get("peak_phi")
    start = out.get("start") or {}
    si: dict[str, Any] = {
        **_scales_si(phys),
        "blowup_time_s": ts(out.get("blowup_time")),
        "return_time_s": ts(out.get("return_time")),
        "peak_time_s": ts(out.get("peak_time")),
        "peak_slip_rate_m_s": None if peak is None else phys.slip_rate_m_s(float(peak)),
    }
    if start.get("psi") is not None:
        si["start_shear_stress_change_Pa"] = phys.shear_stress_change_Pa(float(start["psi"]))
        si["start_friction_change"] = phys.friction_change(float(start["psi"]))
        si["start_slip_rate_m_s"] = phys.slip_rate_m_s(float(start["phi"]))
    if out.get("perturbation") is not None:
        si.update(_jump_si(phys, str(out["perturbation"]), out.get("size")))
    return si


def classify(req: ClassifyRequest, max_steps: int | None = QUICK_STEPS) -> dict[str, Any]:
    """Stable/unstable outcome with certificate, peak and times (dimensionless; plus an
    ``si`` block when the request gave ``physical``).

    With the default ``max_steps`` a query needing more work raises :class:`NeedsQueue`;
    ``max_steps=None`` (the worker) uses rsfcore's full budget."""
    p, phys = resolve_params(req)
    size = resolve_size(req, phys)
    start = None if req.start is None else (req.start.phi, req.start.psi)
    kw: dict[str, Any] = {} if max_steps is None else {"max_steps": max_steps}
    if req.log_size is not None:
        kw["log_size"] = req.log_size
    res = guard(_traj.classify, p, req.perturbation, size, start=start, rtol=req.rtol, **kw)
    out = _json(res.to_dict())
    if phys is not None:
        out["si"] = jsonsafe(_outcome_si(phys, out))
    return out


#: Meaning of each ``sampling`` value of a trajectory request (said in the answer).
SAMPLING_NOTE = {
    "tau": "evenly spaced in the integrator's bounded time tau (dense where the motion is "
    "fast); T is unevenly spaced",
    "T": "evenly spaced in T = V_* t/Dc",
    "seconds": "evenly spaced in t [s] (t = T Dc/V_*: evenly in T as well)",
}


def trajectory(req: TrajectoryRequest, max_steps: int | None = QUICK_STEPS) -> dict[str, Any]:
    """Outcome plus the trajectory downsampled to ``n_points`` (SI columns with
    ``physical`` or ``scales``), sampled as ``req.sampling`` says; ``max_steps`` as in
    :func:`classify`."""
    p, phys = resolve_params(req)
    size = resolve_size(req, phys)
    start = None if req.start is None else (req.start.phi, req.start.psi)
    physical = None
    if phys is not None:
        physical = guard(phys.to_physical_params, req.eps, req.f_star)
    elif req.scales is not None:
        s = req.scales
        physical = guard(
            PhysicalParams.from_dimensionless,
            p,
            a=s.a,
            Dc=s.Dc,
            sigma=s.sigma,
            V_star=s.V_star,
            f_star=s.f_star,
        )
    t_end = req.t_end
    if req.t_end_s is not None and phys is not None:
        t_end = phys.T_from_time(req.t_end_s)
    kw: dict[str, Any] = {} if max_steps is None else {"max_steps": max_steps}
    if req.log_size is not None:
        kw["log_size"] = req.log_size
    res = guard(
        _traj.simulate,
        p,
        req.perturbation,
        size,
        start=start,
        rtol=req.rtol,
        t_end=t_end,
        n_points=req.n_points,
        physical=physical,
        sampling="tau" if req.sampling == "tau" else "time",
        **kw,
    )
    out = _json(res.to_dict())
    out["sampling"] = {
        "kind": req.sampling,
        "n_points": req.n_points,
        "description": SAMPLING_NOTE[req.sampling],
    }
    if phys is not None:
        out["si"] = jsonsafe(_outcome_si(phys, out))
    return out


def critical(req: CriticalRequest) -> dict[str, Any]:
    """Critical perturbation size, same fields as ``rsf critical --json``; with
    ``physical`` also an ``si`` block (critical slip rate [m/s] and shear-stress jump [Pa]
    of a velocity jump, critical load-point velocity [m/s])."""
    p, phys = resolve_params(req)
    res = guard(_critical.critical_perturbation, p, req.perturbation, rtol=req.rtol)
    out = _json(res.to_dict())
    if phys is not None:
        out["si"] = jsonsafe(_critical_si(phys, out))
    return out


def _critical_si(phys: PhysicalInputs, out: dict[str, Any]) -> dict[str, Any]:
    return {
        **_scales_si(phys),
        **_jump_si(phys, str(out["perturbation"]), out.get("critical_size")),
    }


def analytic_u(req: AnalyticRequest) -> dict[str, Any]:
    """U at the given points or on the grid (closed form, vectorised)."""
    if req.points is not None:
        phi = np.array([p.phi for p in req.points])
        psi = np.array([p.psi for p in req.points])
        out: dict[str, Any] = {"phi": phi, "psi": psi}
    else:
        g = req.grid
        assert g is not None  # AnalyticRequest: exactly one of points or grid
        phi1 = np.linspace(g.phi_min, g.phi_max, g.n_phi)
        psi1 = np.linspace(g.psi_min, g.psi_max, g.n_psi)
        phi, psi = np.meshgrid(phi1, psi1, indexing="ij")
        out = {"phi": phi1, "psi": psi1, "shape": [g.n_phi, g.n_psi]}
    with np.errstate(all="ignore"):
        if req.function == "kcrit":
            u = guard(analytic.U_kcrit, phi, psi, req.ba, req.eps, req.vo)
        else:
            u = guard(analytic.U_vo0, phi, psi, req.ba, req.kappa, req.eps)
    out.update(function=req.function, U=np.asarray(u, dtype=float))
    return _json(out)


def boundaries(req: BoundariesRequest) -> dict[str, Any]:
    """kappa_crit, eps_crit, (a/b)_crit, acceleration possibility and line; with
    ``physical`` (BoundariesSIRequest) b/a and kappa from the SI machine, plus an ``si``
    block (k_crit [Pa/m], kappa/kappa_crit)."""

    def soft(fn: Callable[..., Any], *a: Any) -> Any:
        try:
            return guard(fn, *a)
        except ComputeError as exc:
            return {"error": str(exc)}

    phys = si_inputs(req)
    ba, kappa = (req.ba, req.kappa) if phys is None else (phys.ba, phys.kappa)
    out: dict[str, Any] = {
        "ba": ba,
        "kappa": kappa,
        "eps": req.eps,
        "kappa_crit": guard(_bounds.kappa_crit, ba),
        "eps_crit": soft(_bounds.eps_crit, ba, kappa),
        "ab_crit": soft(_bounds.ab_crit, kappa, req.eps),
        "acceleration_possible": soft(_bounds.acceleration_possible, ba, kappa, req.eps),
        "max_unstable_kappa": soft(_bounds.max_unstable_kappa, ba, req.eps),
    }
    if phys is not None:
        out["si"] = {**_scales_si(phys), "kappa_ratio": phys.kappa / phys.kappa_crit}
    line = []
    for phi in req.phi:
        try:
            psi = guard(_bounds.acceleration_line, ba, kappa, req.eps, phi)
            line.append({"phi": phi, "psi": psi})
        except ComputeError as exc:
            line.append({"phi": phi, "psi": None, "error": str(exc)})
    out["acceleration_line"] = line
    return _json(out)


def stiffness(req: StiffnessRequest) -> dict[str, Any]:
    """Eigenvalue k/k_* and, with physical parameters, the critical dimension [m]."""
    phys = {} if req.physical is None else req.physical.model_dump()
    if phys and phys.get("h") is None:
        phys.pop("h")
    return _json(guard(_stiff.stiffness_summary, req.case, req.mode, **phys))


# Sweeps: chunks are computed by rsfapp.sweepdata.compute_chunk (rsfcore.batch).


# --- batch queries (POST /v1/classify/batch, /v1/critical/batch) -------------------------
def _loc_field(loc: tuple[Any, ...]) -> str:
    out = ""
    for part in loc:
        out += f"[{part}]" if isinstance(part, int) else (f".{part}" if out else str(part))
    return out or "item"


def item_error(
    index: int, field: str | None, message: str, valid: str | None = None
) -> dict[str, Any]:
    """The result entry of an item that could not be answered."""
    return {"index": index, "error": {"field": field, "message": message, "valid": valid}}


_ADAPTERS: dict[type, TypeAdapter[Any]] = {}


def validate_items(
    model: type[BaseModel], items: list[dict[str, Any]]
) -> tuple[list[Any], dict[int, dict[str, Any]]]:
    """Validate every item as ``model``: (validated models with None at invalid items,
    {index: error entry}).  The error names the item's first invalid field and its range
    (as the single endpoint's 422 would)."""
    ta = _ADAPTERS.get(model)
    if ta is None:
        ta = _ADAPTERS[model] = TypeAdapter(list[model])  # type: ignore[valid-type]
    try:
        return list(ta.validate_python(items)), {}
    except ValidationError as exc:
        errs: dict[int, dict[str, Any]] = {}
        for e in exc.errors():
            loc = tuple(e.get("loc", ()))
            if not loc or not isinstance(loc[0], int) or loc[0] in errs:
                continue
            valid = next(
                (VALID[p] for p in reversed(loc[1:]) if isinstance(p, str) and p in VALID), None
            )
            errs[loc[0]] = item_error(loc[0], _loc_field(loc[1:]), str(e.get("msg")), valid)
    ok = [i for i in range(len(items)) if i not in errs]
    models: list[Any] = [None] * len(items)
    for i, m in zip(ok, ta.validate_python([items[i] for i in ok]), strict=True):
        models[i] = m
    return models, errs


def _param_error(index: int, exc: ParameterError) -> dict[str, Any]:
    return item_error(index, exc.field, str(exc), exc.valid)


#: Keys of a plain dimensionless critical item (no 'physical'), with their limits.
_PLAIN_COLUMNS: dict[str, Limit] = {
    "ba": limits.BA,
    "kappa": limits.KAPPA,
    "eps": limits.EPS,
    "vo": limits.VO,
    "rtol": limits.RTOL,
}
_PLAIN_KEYS = frozenset(_PLAIN_COLUMNS) | {"perturbation"}
_NUMBER_TYPES = frozenset((float, int))


def _plain_critical_items(
    items: list[dict[str, Any]],
) -> tuple[NDArray[np.intp], dict[str, NDArray[Any]]]:
    """The columnar fast path of a critical batch: indices of the items that are plain
    dimensionless objects (only the keys of :data:`_PLAIN_KEYS`, JSON numbers in range,
    a known perturbation) and their columns, defaults filled in from rsfcore.limits.

    Every other item (SI, a string number, out of range, unknown key, ...) is left to the
    request model, so its answer or its error entry is exactly the single endpoint's.
    Validating 10^4 items this way takes ~5 ms instead of ~70 ms through pydantic."""
    n = len(items)
    ok = np.fromiter(
        (type(d) is dict and d.keys() <= _PLAIN_KEYS for d in items), dtype=bool, count=n
    )
    idx = np.flatnonzero(ok)
    plain = [items[i] for i in idx]
    cols: dict[str, NDArray[Any]] = {}
    good = np.ones(len(plain), dtype=bool)
    for key, lim in _PLAIN_COLUMNS.items():
        raw = [d.get(key, lim.default) for d in plain]
        typed = np.fromiter((type(v) in _NUMBER_TYPES for v in raw), dtype=bool, count=len(raw))
        try:
            vals = np.array([v if t else np.nan for v, t in zip(raw, typed, strict=True)], float)
        except OverflowError:  # an integer beyond double range: the model path says so
            vals = np.array([v if type(v) is float else np.nan for v in raw], float)
            typed &= np.fromiter((type(v) is float for v in raw), dtype=bool, count=len(raw))
        good &= typed & ~lim.bad_mask(vals)
        cols[key] = vals
    pert = np.array([_pert_index(d.get("perturbation", "velocity-jump")) for d in plain], np.intp)
    # a load-point jump needs a moving load point (v_o > 0); the model path says so
    good &= (pert >= 0) & ~((pert == 1) & (cols["vo"] == 0.0))
    cols["perturbation"] = pert
    return idx[good], {k: v[good] for k, v in cols.items()}


_PERT_INDEX = {name: i for i, name in enumerate(_critical.PERTURBATIONS)}


def _pert_index(value: object) -> int:
    """Index of a perturbation name, -1 for anything else (any JSON value, lists too)."""
    return _PERT_INDEX.get(value, -1) if isinstance(value, str) else -1


def critical_batch(items: list[dict[str, Any]]) -> dict[str, Any]:
    """Critical sizes of many items, answered item by item exactly as :func:`critical`.

    Plain dimensionless items are validated as columns (:func:`_plain_critical_items`);
    the rest through the request model.  Valid items are grouped by (perturbation, rtol)
    and each group is one call of rsfcore.batch.critical_points (the compiled loop of
    critical_perturbation, with its bisection fallback and per-point failure isolation:
    a point that fails is an error entry, the others are answered).  Returns
    {"results": [...] in item order, "n_items", "n_ok", "n_failed"}."""
    n = len(items)
    fast_idx, cols = _plain_critical_items(items)
    is_fast = np.zeros(n, dtype=bool)
    is_fast[fast_idx] = True
    rest = np.flatnonzero(~is_fast).tolist()
    results: list[dict[str, Any] | None] = [None] * n
    physs: dict[int, PhysicalInputs] = {}
    # (ba, kappa, eps, vo, perturbation index, rtol) of every valid item, in item order
    idx_l: list[int] = fast_idx.tolist()
    ba_l, ka_l = cols["ba"].tolist(), cols["kappa"].tolist()
    eps_l, vo_l = cols["eps"].tolist(), cols["vo"].tolist()
    pert_l, rtol_l = cols["perturbation"].tolist(), cols["rtol"].tolist()
    if rest:
        models, errs = validate_items(CriticalRequest, [items[i] for i in rest])
        for j, m in enumerate(models):
            i = rest[j]
            if m is None:
                e = errs[j]
                e["index"] = i
                results[i] = e
                continue
            try:
                if m.physical is None:
                    pd = {"ba": m.ba, "kappa": m.kappa, "eps": m.eps, "vo": m.vo}
                else:
                    p, ph = resolve_params(m)
                    if ph is not None:
                        physs[i] = ph
                    pd = p.as_dict()
                pert = _PERT_INDEX[m.perturbation]
                if pert == 1 and pd["vo"] == 0.0:
                    raise ParameterError(
                        "vo",
                        pd["vo"],
                        "> 0 for a load-point jump (relative jump of a moving load point)",
                    )
            except ParameterError as exc:
                results[i] = _param_error(i, exc)
                continue
            idx_l.append(i)
            ba_l.append(pd["ba"])
            ka_l.append(pd["kappa"])
            eps_l.append(pd["eps"])
            vo_l.append(pd["vo"])
            pert_l.append(pert)
            rtol_l.append(float(m.rtol))
    groups: dict[tuple[int, float], list[int]] = {}
    for j, key in enumerate(zip(pert_l, rtol_l, strict=True)):
        groups.setdefault(key, []).append(j)
    kinds, methods = _critical.KINDS, _critical.METHODS
    for (pert, rtol), js in groups.items():
        name = _critical.PERTURBATIONS[pert]
        g_ba, g_ka = [ba_l[j] for j in js], [ka_l[j] for j in js]
        g_eps, g_vo = [eps_l[j] for j in js], [vo_l[j] for j in js]
        res = _batch.critical_points(
            np.array(g_ba),
            np.array(g_ka),
            np.array(g_eps),
            np.array(g_vo),
            perturbation=name,
            rtol=rtol,
        )
        kind_l, value_l, acc_l = (
            res.kind.tolist(),
            res.critical_size.tolist(),
            res.rel_accuracy.tolist(),
        )
        meth_l, onb_l = res.method.tolist(), res.on_boundary.tolist()
        for g, j in enumerate(js):
            i = idx_l[j]
            pd = {"ba": g_ba[g], "kappa": g_ka[g], "eps": g_eps[g], "vo": g_vo[g]}
            if g in res.errors:
                results[i] = item_error(i, None, res.errors[g])
                continue
            k = kind_l[g]
            out: dict[str, Any]
            if meth_l[g] == _critical.M_BISECTION or (
                k == _critical.KIND_FINITE and not math.isfinite(value_l[g])
            ):
                # settled by bisection, or a finite size beyond double range (both rare):
                # the single path's own result, so that the method text (which may carry a
                # note) and the logarithm of a huge size are exactly the single answer's
                try:
                    r = guard(_critical.critical_perturbation, guard(Params, **pd), name, rtol=rtol)
                except (ParameterError, ComputeError) as exc:
                    results[i] = item_error(i, getattr(exc, "field", None), str(exc))
                    continue
                out = _json(r.to_dict())
            else:
                # the layout of rsfcore.critical.CriticalResult.to_dict (tested equal to the
                # single endpoint's answer item by item)
                size = (
                    None
                    if k == _critical.KIND_INFINITE
                    else (0.0 if k == _critical.KIND_ZERO else value_l[g])
                )
                met, reason = _critical.accuracy_verdict(
                    kinds[k], methods[meth_l[g]], acc_l[g], rtol
                )
                out = {
                    "kind": kinds[k],
                    "critical_size": size,
                    "log_critical_size": None
                    if size is None
                    else (size if pert == 0 else math.log1p(size)),
                    "rel_accuracy": acc_l[g],
                    "accuracy_met": met,
                    "reason": reason,
                    "method": methods[meth_l[g]],
                    "perturbation": name,
                    "params": pd,
                    "on_boundary": bool(onb_l[g]),
                }
            ph = physs.get(i)
            if ph is not None:
                out["si"] = _json(_critical_si(ph, out))
            out["index"] = i
            results[i] = out
    return _batch_summary(results)


def _batch_summary(results: list[dict[str, Any] | None]) -> dict[str, Any]:
    n_failed = sum(1 for r in results if r is None or "error" in r)
    return {
        "results": results,
        "n_items": len(results),
        "n_ok": len(results) - n_failed,
        "n_failed": n_failed,
    }


def classify_batch(
    items: list[dict[str, Any]], max_steps: int | None = QUICK_STEPS
) -> dict[str, Any]:
    """Outcomes of many items, each answered exactly as :func:`classify` (rsfcore has no
    vectorised classify: one compiled integration per item).  An item needing more than
    the quick step budget is reported as an error entry (ask it alone at /v1/classify,
    which queues long integrations)."""
    models, errs = validate_items(ClassifyRequest, items)
    results: list[dict[str, Any] | None] = [errs.get(i) for i in range(len(items))]
    for i, m in enumerate(models):
        if m is None:
            continue
        try:
            out = classify(m, max_steps=max_steps)
        except ParameterError as exc:
            results[i] = _param_error(i, exc)
            continue
        except NeedsQueue as exc:
            results[i] = item_error(
                i,
                None,
                f"a long integration ({exc}); send this item "
                "alone to POST /v1/classify, which queues it",
            )
            continue
        except ComputeError as exc:
            results[i] = item_error(i, None, str(exc))
            continue
        out["index"] = i
        results[i] = out
    return _batch_summary(results)


# --- lab protocols (POST /v1/protocols/*; rsfcore.protocols, SI units) -------------------
def _machine(req: Any) -> PhysicalParams:
    """The protocol's machine as rsfcore PhysicalParams (via rsfcore.units)."""
    phys = si_inputs(req)
    assert phys is not None  # ``physical`` is required by the protocol models
    machine: PhysicalParams = guard(phys.to_physical_params, req.eps, req.f_star)
    return machine


def _segment_changes(res: Any, phys: PhysicalParams) -> list[dict[str, Any]]:
    """Per segment: steady-state friction change from the previous load-point velocity
    (`eq: steady state`; None across a hold), and the peak friction change from the
    friction at the segment's start (true peak of rsfcore.protocols), also in Pa
    (tau = f sigma, `eq: MC criterion`)."""
    out: list[dict[str, Any]] = []
    t = np.asarray(res.t_s)
    f = np.asarray(res.friction)
    prev_v = None
    for s in res.segments:
        row: dict[str, Any] = {
            "index": s.index,
            "V_load_m_s": s.Vo_m_s,
            "status": s.status,
            "steady_state_delta_f": None,
            "steady_state_delta_tau_Pa": None,
            "peak_friction": s.peak_friction,
            "peak_delta_f": None,
            "peak_delta_tau_Pa": None,
            "peak_time_s": s.peak_friction_time_s,
            "peak_V_m_s": s.peak_V_m_s,
            "f_start": None,
        }
        if prev_v is not None and prev_v > 0 and s.Vo_m_s > 0:
            dss = _protocols.steady_state_friction(
                phys, s.Vo_m_s
            ) - _protocols.steady_state_friction(phys, prev_v)
            row.update(steady_state_delta_f=dss, steady_state_delta_tau_Pa=dss * phys.sigma)
        if s.status != "not_run" and t.size:
            k = int(np.searchsorted(t, s.t_start_s, side="right")) - 1
            f0 = float(f[max(k, 0)])
            row["f_start"] = f0
            if s.peak_friction is not None:
                row.update(
                    peak_delta_f=s.peak_friction - f0,
                    peak_delta_tau_Pa=(s.peak_friction - f0) * phys.sigma,
                )
        prev_v = s.Vo_m_s
        out.append(row)
    return out


def protocol_velocity_step(req: VelocityStepRequest) -> dict[str, Any]:
    """rsfcore.protocols.velocity_step, plus the lab's friction changes: steady state
    (a - b) ln(V2/V1) and peak (true peak minus f_ss(V1)), as friction and in Pa."""
    ph = _machine(req)
    res = guard(
        _protocols.velocity_step,
        ph,
        req.V1_m_s,
        req.V2_m_s,
        slip_after_m=req.slip_after_m,
        slip_total_m=req.slip_total_m,
        n_points=req.n_points,
        rtol=req.rtol,
    )
    out = _json(res.to_dict())
    f1 = _protocols.steady_state_friction(ph, req.V1_m_s)
    f2 = _protocols.steady_state_friction(ph, req.V2_m_s)
    seg = res.protocol.segments[0]
    pk = seg.peak_friction
    out["friction_changes"] = jsonsafe(
        {
            "f_ss_before": f1,
            "f_ss_after": f2,
            "steady_state_delta_f": f2 - f1,
            "steady_state_delta_tau_Pa": (f2 - f1) * ph.sigma,
            "peak_friction": pk,
            "peak_time_s": seg.peak_friction_time_s,
            "peak_delta_f": None if pk is None else pk - f1,
            "peak_delta_tau_Pa": None if pk is None else (pk - f1) * ph.sigma,
            "peak_V_m_s": seg.peak_V_m_s,
        }
    )
    out["kind"] = "velocity-step"
    return out


def protocol_slide_hold_slide(req: SlideHoldSlideRequest) -> dict[str, Any]:
    """rsfcore.protocols.slide_hold_slide: healing (peak on reslide - f_ss) and relaxation
    (f_ss - friction at the end of the hold), as friction and in Pa, plus segment peaks."""
    ph = _machine(req)
    res = guard(
        _protocols.slide_hold_slide,
        ph,
        req.V_m_s,
        req.hold_s,
        slide_before_s=req.slide_before_s,
        slide_after_s=req.slide_after_s,
        n_points_per_segment=req.n_points_per_segment,
        rtol=req.rtol,
    )
    out = _json(res.to_dict())
    heal, relax = res.healing_delta_f, res.relaxation_delta_f
    out["friction_changes"] = jsonsafe(
        {
            "healing_delta_f": heal,
            "healing_delta_tau_Pa": None if heal is None else heal * ph.sigma,
            "relaxation_delta_f": relax,
            "relaxation_delta_tau_Pa": None if relax is None else relax * ph.sigma,
            "segments": _segment_changes(res.protocol, ph),
        }
    )
    out["kind"] = "slide-hold-slide"
    return out


def protocol_load_history(req: LoadHistoryRequest) -> dict[str, Any]:
    """rsfcore.protocols.load_history for any piecewise-constant load-point history (e.g.
    several velocity steps), with per-segment steady-state and peak friction changes."""
    ph = _machine(req)
    st = req.start_state
    start: Any = "steady" if st == "steady" else (st.V_m_s, st.theta_s)
    res = guard(
        _protocols.load_history,
        ph,
        [(s.duration_s, s.V_load_m_s) for s in req.segments],
        n_points_per_segment=req.n_points_per_segment,
        rtol=req.rtol,
        start=start,
    )
    out = _json(res.to_dict())
    out["friction_changes"] = jsonsafe({"segments": _segment_changes(res, ph)})
    out["kind"] = "load-history"
    return out


#: Columns of a protocol's CSV (the sampled history), in order.
PROTOCOL_COLUMNS = (
    "t_s",
    "friction",
    "tau_change_Pa",
    "V_m_s",
    "theta_s",
    "slip_m",
    "load_point_m",
    "segment",
    "Vo_m_s",
)


def protocol_table(result: dict[str, Any]) -> dict[str, list[Any]]:
    """The sampled history of a protocol answer as columns (velocity steps add
    slip_since_step_m and the simulated and analytic (tau - tau_ss)/(b sigma))."""
    prot = result.get("protocol", result)
    cols = {k: prot[k] for k in PROTOCOL_COLUMNS if k in prot}
    for k in ("slip_since_step_m", "delta_tau_over_b_sigma", "analytic_over_b_sigma"):
        if k in result:
            cols[k] = result[k]
    return cols


# --- fits of lab records (POST /v1/fits, worker.tasks.fit_record; rsfcore.fit) ------------
def fit_record_of(req: FitRequest) -> Any:
    """The request's record parsed by rsfcore.fit.read_record (ParameterError naming
    ``record`` and what is wrong)."""
    from rsfcore import fit as _fit

    try:
        return guard(_fit.read_record, req.record)
    except ParameterError as exc:
        if exc.field.startswith("record"):
            raise
        raise ParameterError(f"record.{exc.field}", exc.value, exc.valid) from None


def fit_key_request(req: FitRequest) -> dict[str, Any]:
    """What identifies a fit: the record's content hash and the options (cache key)."""
    return {"record_sha256": fit_record_of(req).digest(), **req.options()}


def fit(req: FitRequest, progress: Callable[[str], None] | None = None) -> dict[str, Any]:
    """Fit the record (rsfcore.fit): the reported law's FitResult.to_dict() (params,
    stderr, residuals and series, misfit, stability answer in SI with uncertainty), plus
    ``law_comparison`` (misfit and information criteria per law) when ``compare`` and
    ``posterior`` (emcee) when asked.  ``progress`` is told each stage as it starts."""
    from rsfcore import fit as _fit

    def stage(text: str) -> None:
        if progress is not None:
            progress(text)

    stage("reading the record")
    rec = fit_record_of(req)
    opts: dict[str, Any] = {
        "stiffness": req.stiffness_per_m,
        "fit_stiffness": req.fit_stiffness,
        "nagata_c": req.nagata_c,
        "rtol": req.rtol,
        "uncertainty_samples": req.uncertainty_samples,
        "seed": req.seed,
    }
    comparison: dict[str, Any] | None = None
    if req.compare:
        stage(f"fitting {rec.n} samples with each law ({', '.join(FIT_LAWS)})")
        cmp = guard(_fit.compare_laws, rec, laws=FIT_LAWS, **opts)
        law = req.law or cmp.best or (req.law or "aging")
        res = cmp.fits[law]
        if res.ok and res.stability is None:
            stage("stability answer with uncertainty")
            guard(
                _fit.attach_stability,
                res,
                uncertainty_samples=req.uncertainty_samples,
                seed=req.seed,
            )
        comparison = {
            "best": cmp.best,
            "misfit_floor": cmp.misfit_floor,
            "scores": [s.to_dict() for s in cmp.scores],
            "params": {k: f.params for k, f in cmp.fits.items()},
            "stderr": {k: f.stderr for k, f in cmp.fits.items()},
            "status": {k: f.status.value for k, f in cmp.fits.items()},
        }
    else:
        assert req.law is not None
        stage(f"fitting {rec.n} samples ({req.law} law) and the stability answer")
        res = guard(_fit.fit_record, rec, req.law, **opts)
    out = res.to_dict(series=True)
    out["posterior"] = None
    if req.posterior is not None:
        po = req.posterior
        stage(f"posterior: {po.n_walkers} walkers x {po.n_steps} steps (emcee)")
        try:
            post = guard(
                _fit.sample_posterior,
                res,
                n_walkers=po.n_walkers,
                n_steps=po.n_steps,
                burn=po.burn,
                thin=po.thin,
                seed=req.seed,
                stability_samples=req.uncertainty_samples,
            )
            out["posterior"] = post.to_dict()
        except (ParameterError, ComputeError, ImportError) as exc:
            out["posterior"] = {"error": str(exc)}
    out["law_comparison"] = jsonsafe(comparison)
    out["options"] = req.options()
    return _json(out)


#: Columns of a fit's CSV (data, model, residuals).
FIT_COLUMNS = ("t_s", "v_lp_m_s", "mu", "model", "residuals")


def fit_table(result: dict[str, Any]) -> dict[str, list[Any]]:
    """The series of a fit answer as columns (FIT_COLUMNS)."""
    s = result.get("series") or {}
    return {k: s[k] for k in FIT_COLUMNS if k in s}


def classify_points(req: ClassifyPointsRequest) -> dict[str, Any]:
    """Outcomes of many start points for one parameter set (rsfcore.phase.classify_points:
    the separatrix once, points near it integrated); ``outcome[i]`` for (phi[i], psi[i])."""
    p = guard(Params, ba=req.ba, kappa=req.kappa, eps=req.eps, vo=req.vo)
    res = guard(_phase.classify_points, p, np.asarray(req.phi), np.asarray(req.psi), req.rtol)
    out = _json(res.to_dict())
    out["n_points"] = len(req.phi)
    return out
