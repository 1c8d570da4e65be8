"""Sweep numbers: one chunk computed by rsfcore's batch kernel, and a sweep's stored blocks
assembled into arrays, an xarray Dataset (NetCDF), CSV rows, JSON or a 2-D diagram slice.

Per point (arrays of the chunk / of the whole sweep in flat-index order):

* ``critical_size`` (float64): 0 for kind zero, inf for infinite, NaN where missing
  (not computed yet) or failed;
* ``kind`` (int8): 0 zero, 1 finite, 2 infinite, -1 missing or failed;
* ``outcome`` (int8): 0 stable, 1 unstable, -1 missing, failed or not asked (no size);
* ``rel_accuracy`` (float64): estimated relative accuracy of critical_size, NaN missing;
* ``failed`` (bool): the point could not be computed (message in the side table);
* ``method`` (int8): index into ``rsfcore.critical.METHODS``, -1 missing or failed;
* ``outcome_uncertain`` (bool): the outcome is within the accuracy of the critical size;
* ``computed`` (bool, assembled arrays only): the point's chunk is stored.

A sweep given in SI (``fixed.physical``) also carries, in NetCDF, the SI inputs and scales as
attributes (``physical_<field>``, ``time_scale_s`` = Dc/V_* [s], ``stress_scale_Pa`` =
a sigma [Pa], ``k_crit_Pa_per_m``) and the critical sizes in SI as one more variable:
``critical_slip_rate_m_s`` (velocity jump: V_before e^d_crit) or
``critical_load_point_velocity_m_s`` (load-point jump: V_load (1 + dv_crit)), converted point
by point by rsfcore.units (inf where kind is infinite or the value overflows, NaN where
missing or failed; sweeps of at most SI_VARIABLE_MAX_POINTS points, about 2 us a point,
larger ones get the formula as attribute ``si_variable_omitted``); the JSON status fields carry ``physical``.
The same SI variable is a column of the CSV (after ``critical_size``; ``inf`` where
infinite, empty where missing) and a field of each point of ``GET .../points`` and of the
JSON data (null where infinite or missing), converted by the same :func:`critical_si`, so
all formats agree bit for bit.  A sweep whose perturbation size is swept in SI (an axis
or points array ``factor``, ``new_slip_rate_m_s`` or ``new_load_point_velocity_m_s``) has
that SI value as its coordinate and also carries the dimensionless ``size`` of each value
(NetCDF variable along that axis, CSV column and point field after the swept parameters),
converted by :func:`rsfapp.grid.si_to_size`.  Sweeps give no times, so no column in s.
Dimensionless sweeps are unchanged.

Nothing here knows about HTTP; I/O is only through a :class:`~rsfapp.store.SweepStore`.
"""

from __future__ import annotations

import csv
import io
import json
import math
from collections.abc import Iterator
from typing import Any

import numpy as np
from numpy.typing import NDArray

from rsfcore import batch, units
from rsfcore.critical import KINDS, METHODS
from rsfcore.jsonsafe import finite_or_none
from rsfcore.params import ParameterError

from .grid import SpecError, SweepSpec, si_to_size
from .store.sweeps import SweepStore

__all__ = [
    "VARIABLES",
    "SI_VARIABLES",
    "SI_VARIABLE_MAX_POINTS",
    "compute_chunk",
    "critical_si",
    "si_names",
    "si_sizes",
    "assemble",
    "to_dataset",
    "netcdf_bytes",
    "csv_rows",
    "json_chunks",
    "diagram",
    "parse_slice",
]

#: Result variables of every point (NetCDF / CSV / JSON).
VARIABLES: tuple[str, ...] = (
    "critical_size",
    "kind",
    "outcome",
    "rel_accuracy",
    "failed",
    "method",
    "outcome_uncertain",
)
_OUTCOMES = ("stable", "unstable")
#: The SI variable of a sweep given in SI, per perturbation: (name, description).
SI_VARIABLES: dict[str, tuple[str, str]] = {
    "velocity-jump": (
        "critical_slip_rate_m_s",
        "critical slip rate right after the jump, V_before e^critical_size [m/s] "
        "(V_before = V_load, or V_* when V_load = 0); inf where infinite, NaN missing",
    ),
    "load-point-jump": (
        "critical_load_point_velocity_m_s",
        "critical new load-point velocity V_load (1 + critical_size) [m/s]; "
        "inf where infinite, NaN missing",
    ),
}


def _failed_arrays(n: int, outcome: bool) -> dict[str, NDArray[Any]]:
    out: dict[str, NDArray[Any]] = {
        "critical_size": np.full(n, math.nan),
        "rel_accuracy": np.full(n, math.nan),
        "kind": np.full(n, -1, np.int8),
        "method": np.full(n, -1, np.int8),
        "failed": np.ones(n, np.bool_),
        "on_boundary": np.zeros(n, np.bool_),
    }
    if outcome:
        out["outcome"] = np.full(n, -1, np.int8)
        out["outcome_uncertain"] = np.zeros(n, np.bool_)
    return out


def _arrays(r: batch.BatchResult) -> dict[str, NDArray[Any]]:
    arrays: dict[str, NDArray[Any]] = {
        "critical_size": r.critical_size,
        "rel_accuracy": r.rel_accuracy,
        "kind": r.kind,
        "method": r.method,
        "failed": r.failed,
        "on_boundary": r.on_boundary,
    }
    if r.outcome is not None and r.outcome_uncertain is not None:
        arrays["outcome"] = r.outcome
        arrays["outcome_uncertain"] = r.outcome_uncertain
    return arrays


def compute_chunk(
    spec: SweepSpec, i0: int, i1: int
) -> tuple[dict[str, NDArray[Any]], dict[int, str]]:
    """Results of flat indices [i0, i1): one :func:`rsfcore.batch.critical_points` call.

    Returns (arrays, errors): the per-point arrays of the module docstring (plus
    ``method``, ``on_boundary`` and, for outcomes, ``outcome_uncertain``) and
    {offset in the chunk: "Type: message"} of the failed points.

    rsfcore.batch already isolates the points whose per-point fallback fails.  Should the
    batch call itself raise (an input the spec validation let through, or a defect of the
    kernel at some point), the chunk is recomputed point by point so that only the points
    that raise are marked failed, with their messages; MemoryError propagates (the task is
    retried).
    """
    p = spec.params(i0, i1)
    n = i1 - i0
    ba, kappa, eps, vo, size = p["ba"], p["kappa"], p["eps"], p["vo"], p["size"]
    assert ba is not None and kappa is not None and eps is not None and vo is not None
    kw: dict[str, Any] = {"perturbation": spec.perturbation, "rtol": spec.rtol}
    try:
        r = batch.critical_points(ba, kappa, eps, vo, size=size, **kw)
        return _arrays(r), dict(r.errors)
    except MemoryError:
        raise
    except Exception:  # noqa: BLE001 - isolate the offending points below
        pass
    out = _failed_arrays(n, size is not None)
    errors: dict[int, str] = {}
    for k in range(n):
        sl = slice(k, k + 1)
        try:
            r = batch.critical_points(
                ba[sl], kappa[sl], eps[sl], vo[sl], size=None if size is None else size[sl], **kw
            )
        except MemoryError:
            raise
        except Exception as exc:  # noqa: BLE001 - recorded per point, the chunk goes on
            errors[k] = f"{type(exc).__name__}: {exc}"[:2000]
            continue
        for name, arr in _arrays(r).items():
            out[name][k] = arr[0]
        if r.errors:
            errors[k] = r.errors[0]
    return out, errors


def _empty(n: int) -> dict[str, NDArray[Any]]:
    return {
        "critical_size": np.full(n, math.nan),
        "kind": np.full(n, -1, np.int8),
        "outcome": np.full(n, -1, np.int8),
        "rel_accuracy": np.full(n, math.nan),
        "failed": np.zeros(n, np.bool_),
        "computed": np.zeros(n, np.bool_),
        "method": np.full(n, -1, np.int8),
        "outcome_uncertain": np.zeros(n, np.bool_),
    }


def assemble(store: SweepStore, sweep_id: str, n_total: int) -> dict[str, NDArray[Any]]:
    """Flat arrays of every point (missing points NaN / -1, ``computed`` False)."""
    out = _empty(n_total)
    for b in store.blocks(sweep_id):
        sl = slice(b.i0, b.i1)
        for k in ("critical_size", "kind", "rel_accuracy", "failed", "method"):
            out[k][sl] = b.arrays[k]
        for k in ("outcome", "outcome_uncertain"):
            if k in b.arrays:
                out[k][sl] = b.arrays[k]
        out["computed"][sl] = True
    return out


def to_dataset(spec: SweepSpec, status: dict[str, Any], arrays: dict[str, NDArray[Any]]) -> Any:
    """An xarray Dataset: grid axes as named dimensions with coordinates (or a ``point``
    dimension with the swept parameters as variables), the result variables, the fixed
    parameters and sweep metadata as attributes."""
    import xarray as xr

    legends = {
        "kind": "-1 missing/failed, 0 zero, 1 finite, 2 infinite",
        "outcome": "-1 missing/failed/not asked, 0 stable, 1 unstable",
        "failed": "1 = could not be computed (see the status failures)",
        "critical_size": "0 for kind zero, inf for infinite, NaN where missing or "
        "failed (d for a velocity jump, dv/v_o for a load-point jump)",
        "rel_accuracy": "estimated relative accuracy of critical_size",
        "method": "-1 missing/failed, else index into: "
        + " | ".join(f"{k} {m.split(':')[0]}" for k, m in enumerate(METHODS)),
        "outcome_uncertain": "1 = |size/critical size - 1| within the accuracy (or "
        "kappa = kappa_crit up to rounding): the outcome may flip",
    }
    if spec.mode == "grid":
        dims = tuple(a.name for a in spec.axes)
        coords: dict[str, Any] = {a.name: a.all() for a in spec.axes}
        shape = spec.shape
    else:
        dims = ("point",)
        coords = {"point": np.arange(spec.n_total, dtype=np.int32)}
        shape = (spec.n_total,)
    data: dict[str, Any] = {}
    for v in VARIABLES:
        a = arrays[v]
        if a.dtype == np.bool_:
            a = a.astype(np.int8)
        data[v] = (dims, a.reshape(shape), {"description": legends[v]})
    if spec.mode == "points":
        for name, vals in spec.coords().items():
            data[name] = (("point",), vals, {"description": f"swept parameter {name}"})
    attrs: dict[str, Any] = {
        "sweep_id": status.get("id", ""),
        "status": status.get("status", ""),
        "perturbation": spec.perturbation,
        "rtol": spec.rtol,
        "output": spec.output,
        "n_total": spec.n_total,
        "n_done": int(status.get("n_done", 0)),
        "n_failed": int(status.get("n_failed", 0)),
        "numerics_version": str(status.get("numerics_version", "")),
    }
    for name, fv in spec.fixed.items():
        if fv is not None:
            attrs[f"fixed_{name}"] = float(fv)
    phys = spec.physical_inputs()
    if phys is not None:
        for name, pv in phys.to_dict().items():
            attrs[f"physical_{name}"] = float(pv)
        attrs["time_scale_s"] = phys.time_scale_s
        attrs["stress_scale_Pa"] = phys.stress_scale_Pa
        attrs["k_crit_Pa_per_m"] = phys.k_crit_Pa_per_m
        si_name, si_desc = SI_VARIABLES[spec.perturbation]
        swept_si = spec.si_size
        if swept_si is not None:  # the dimensionless size of each SI coordinate value
            sdims = (swept_si,) if spec.mode == "grid" else ("point",)
            data["size"] = (
                sdims,
                si_to_size(phys, spec.perturbation, swept_si, spec.coords()[swept_si]),
                {"description": f"dimensionless perturbation size of {swept_si} ({_SIZE_OF})"},
            )
        if spec.n_total <= SI_VARIABLE_MAX_POINTS:
            si = critical_si(phys, spec.perturbation, arrays["critical_size"])
            data[si_name] = (dims, si.reshape(shape), {"description": si_desc, "units": "m/s"})
        else:
            attrs["si_variable_omitted"] = (
                f"{si_name} is given up to {SI_VARIABLE_MAX_POINTS} points: {si_desc}"
            )
    return xr.Dataset(data, coords=coords, attrs=attrs)


#: Largest sweep whose NetCDF gets the SI variable (about 2 us a point through
#: rsfcore.units: at most ~4 s); larger sweeps get an attribute stating the formula.
SI_VARIABLE_MAX_POINTS = 2_000_000


def critical_si(
    phys: units.PhysicalInputs, perturbation: str, critical_size: NDArray[Any]
) -> NDArray[np.float64]:
    """Critical sizes in SI, point by point through rsfcore.units (velocity_jump_si /
    load_point_jump_si, so the conversion is rsfcore's, exact to a few ulp): the new slip
    rate [m/s] of a velocity jump or the new load-point velocity [m/s] of a load-point
    jump.  inf where critical_size is +inf (kind infinite) or the SI value overflows, NaN
    where it is NaN (missing or failed).  Cost: about 2 us a finite point."""
    cs = np.asarray(critical_size, dtype=np.float64)
    out = np.full(cs.shape, math.nan)
    out[np.isposinf(cs)] = math.inf
    vel = perturbation == "velocity-jump"
    for i in np.flatnonzero(np.isfinite(cs)):
        x = float(cs[i])
        try:
            v = (
                units.velocity_jump_si(phys, x).new_slip_rate_m_s
                if vel
                else units.load_point_jump_si(phys, x).new_load_point_velocity_m_s
            )
        except ParameterError:  # |d| beyond rsfcore's range: far beyond double range
            v = math.inf if x > 0 else 0.0
        out[i] = math.inf if v is None else v
    return out


_SIZE_OF = "d = ln(V_new/V_before) or dv = V_new/V_load - 1, by rsfcore.units"


def si_names(spec: SweepSpec) -> tuple[str | None, str | None]:
    """(name of the dimensionless size column of a swept SI size, i.e. ``"size"``, or None;
    name of the SI critical-size column, or None for a dimensionless sweep)."""
    if spec.physical is None:
        return None, None
    return ("size" if spec.si_size is not None else None), SI_VARIABLES[spec.perturbation][0]


def si_sizes(spec: SweepSpec, swept: dict[str, NDArray[Any]]) -> NDArray[np.float64] | None:
    """Dimensionless sizes of the points whose swept values are ``swept`` (as
    :meth:`SweepSpec.swept_values`), for a sweep whose size is swept in SI; else None."""
    name, phys = spec.si_size, spec.physical_inputs()
    if name is None or phys is None:
        return None
    return si_to_size(phys, spec.perturbation, name, swept[name])


def netcdf_bytes(ds: Any) -> bytes:
    """The Dataset as a NetCDF file (classic 64-bit-offset format, scipy engine)."""
    return bytes(ds.to_netcdf(engine="scipy", format="NETCDF3_64BIT"))


def _method(m: int) -> str:
    return METHODS[m].split(":")[0] if m >= 0 else ""


def _fmt(v: float) -> str:
    return "" if math.isnan(v) else repr(float(v))


def csv_rows(
    store: SweepStore, spec: SweepSpec, sweep_id: str, batch_rows: int = 50_000
) -> Iterator[str]:
    """CSV text in pieces: a header, then one row per point in flat-index order:
    idx, the swept parameters, kind, critical_size, outcome, rel_accuracy, method (short
    name), failed, error.  A sweep in SI also has, after critical_size, the critical size
    in SI (``critical_slip_rate_m_s`` [m/s] or ``critical_load_point_velocity_m_s``
    [m/s]: ``inf`` where infinite) and, when its size is swept in SI, the dimensionless
    ``size`` after the swept parameters.
    Missing points have empty result fields."""
    names = spec.swept
    size_col, si_col = si_names(spec)
    phys = spec.physical_inputs()
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(
        [
            "idx",
            *names,
            *([size_col] if size_col else []),
            "kind",
            "critical_size",
            *([si_col] if si_col else []),
            "outcome",
            "rel_accuracy",
            "method",
            "failed",
            "error",
        ]
    )
    yield buf.getvalue()
    blocks = store.blocks(sweep_id)
    nxt = next(blocks, None)
    i = 0
    n = spec.n_total
    while i < n:
        if nxt is not None and nxt.i0 == i:
            j, b = nxt.i1, nxt
            nxt = next(blocks, None)
        else:
            j, b = min(n, nxt.i0 if nxt is not None else n, i + batch_rows), None
        vals = spec.swept_values(i, j)
        sizes = si_sizes(spec, vals)
        si_vals = (
            critical_si(phys, spec.perturbation, b.arrays["critical_size"])
            if b is not None and phys is not None
            else None
        )
        buf = io.StringIO()
        w = csv.writer(buf, lineterminator="\n")
        for k in range(j - i):
            row: list[Any] = [i + k, *(repr(float(vals[m][k])) for m in names)]
            if sizes is not None:
                row.append(_fmt(sizes[k]))
            if b is None:
                row += [""] * (8 if si_col else 7)
            else:
                kd = int(b.arrays["kind"][k])
                oc = int(b.arrays["outcome"][k]) if "outcome" in b.arrays else -1
                row += [
                    KINDS[kd] if kd >= 0 else "",
                    _fmt(b.arrays["critical_size"][k]),
                    *([_fmt(si_vals[k])] if si_vals is not None else []),
                    _OUTCOMES[oc] if oc >= 0 else "",
                    _fmt(b.arrays["rel_accuracy"][k]),
                    _method(int(b.arrays["method"][k])),
                    int(bool(b.arrays["failed"][k])),
                    b.errors.get(k, ""),
                ]
            w.writerow(row)
        yield buf.getvalue()
        i = j


def _jlist(a: NDArray[Any], kind: str) -> str:
    if kind == "f":
        return (
            "[" + ",".join(repr(float(x)) if math.isfinite(x) else "null" for x in a.tolist()) + "]"
        )
    return json.dumps(a.astype(int).tolist())


def json_chunks(
    spec: SweepSpec,
    status: dict[str, Any],
    arrays: dict[str, NDArray[Any]],
    failures: list[tuple[int, str]],
) -> Iterator[str]:
    """JSON document in pieces: status fields, ``coords`` (axis values, or the swept
    parameters of each point), and one flat list per variable in flat-index order
    (non-finite numbers and missing points are null; ``kind`` tells infinite from
    missing), ``computed``, and ``failures`` [{idx, error}] (first 100).  A sweep in SI
    (of at most SI_VARIABLE_MAX_POINTS points) also has its SI variable in ``data``."""
    head: dict[str, Any] = {
        k: status[k]
        for k in ("id", "status", "n_total", "n_done", "n_failed", "numerics_version")
        if k in status
    }
    head.update(spec.summary())
    head["shape"] = list(spec.shape)
    head["kind_legend"] = list(KINDS)
    head["outcome_legend"] = list(_OUTCOMES)
    head["method_legend"] = list(METHODS)
    yield json.dumps(head)[:-1] + ', "coords": {'
    for n, (name, vals) in enumerate(spec.coords().items()):
        yield ("," if n else "") + json.dumps(name) + ":" + _jlist(vals, "f")
    yield '}, "data": {'
    for n, v in enumerate((*VARIABLES, "computed")):
        kind = "f" if arrays[v].dtype.kind == "f" else "i"
        yield ("," if n else "") + json.dumps(v) + ":" + _jlist(arrays[v], kind)
    phys = spec.physical_inputs()
    if phys is not None and spec.n_total <= SI_VARIABLE_MAX_POINTS:
        si = critical_si(phys, spec.perturbation, arrays["critical_size"])
        yield "," + json.dumps(SI_VARIABLES[spec.perturbation][0]) + ":" + _jlist(si, "f")
    yield '}, "failures": ' + json.dumps([{"idx": i, "error": m} for i, m in failures]) + "}"


def parse_slice(spec: SweepSpec, text: str | None) -> dict[str, int]:
    """``slice`` query text ("ba:2.0,vo:1") -> {axis name: index of the nearest value};
    the remaining axes must be exactly two.  Raises SpecError naming ``slice``."""
    if spec.mode != "grid":
        raise SpecError("slice", "a diagram needs a grid sweep", "a grid (axes) sweep")
    fixed: dict[str, int] = {}
    names = [a.name for a in spec.axes]
    for part in filter(None, (text or "").split(",")):
        name, sep, val = part.partition(":")
        name = name.strip()
        if not sep or name not in names:
            raise SpecError(
                "slice",
                f"{part!r} is not <axis>:<value>",
                "comma-separated <axis>:<value> with axes " + ", ".join(names),
            )
        try:
            x = float(val)
        except ValueError:
            raise SpecError("slice", f"{val!r} is not a number", "a number") from None
        ax = spec.axes[names.index(name)]
        fixed[name] = int(np.argmin(np.abs(ax.all() - x)))
    # an axis of length 1 needs no slice value
    for a in spec.axes:
        if a.n == 1 and a.name not in fixed and len(spec.axes) - len(fixed) > 2:
            fixed[a.name] = 0
    if len(spec.axes) - len(fixed) != 2:
        raise SpecError(
            "slice",
            f"{len(spec.axes) - len(fixed)} axes left free",
            "values for all but two axes, e.g. slice=" + ",".join(f"{n}:<value>" for n in names[2:])
            if len(names) > 2
            else "a 2-D grid",
        )
    return fixed


def diagram(
    spec: SweepSpec,
    status: dict[str, Any],
    arrays: dict[str, NDArray[Any]],
    fixed_idx: dict[str, int],
) -> dict[str, Any]:
    """A 2-D slice as a stability diagram, laid out like
    ``rsfcore.diagram.DiagramResult.to_dict()``: critical_size[i][j] at (x[i], y[j]) (null
    where infinite or missing), kind codes 0 zero / 1 finite / 2 infinite, outcome codes 0
    stable / 1 unstable (null where missing) for outcome sweeps, present[i][j] (computed
    without error), plus status, n_done, n_total, n_failed and ``slice`` (the values of the
    other axes)."""
    free = [a for a in spec.axes if a.name not in fixed_idx]
    sel = tuple(fixed_idx.get(a.name, slice(None)) for a in spec.axes)

    def sl(v: str) -> NDArray[Any]:
        return np.asarray(arrays[v].reshape(spec.shape)[sel])

    cs, kind, oc = sl("critical_size"), sl("kind"), sl("outcome")
    ok = sl("computed") & ~sl("failed")
    outcome_mode = spec.output == "outcome"
    present = ok & (oc >= 0) if outcome_mode else ok
    csl = [[finite_or_none(v) for v in row] for row in cs.tolist()]
    kl = np.where(kind >= 0, kind, 1).astype(int).tolist()
    ol = [[(float(v) if v >= 0 else None) for v in row] for row in oc.tolist()]
    sl_vals = {
        a.name: float(a.at(np.array([fixed_idx[a.name]]))[0])
        for a in spec.axes
        if a.name in fixed_idx
    }
    fixed = {k: v for k, v in spec.fixed.items() if v is not None}
    fixed.update(sl_vals)
    return {
        "x_name": free[0].name,
        "x": free[0].all().tolist(),
        "y_name": free[1].name,
        "y": free[1].all().tolist(),
        "critical_size": csl,
        "kind": kl,
        "kind_legend": list(KINDS),
        "outcome": ol if outcome_mode else None,
        "outcome_legend": list(_OUTCOMES),
        "present": present.tolist(),
        "perturbation": spec.perturbation,
        "rtol": spec.rtol,
        "fixed": fixed,
        "slice": sl_vals,
        "id": status["id"],
        "status": status["status"],
        "n_done": status["n_done"],
        "n_total": status["n_total"],
        "n_failed": status["n_failed"],
        "numerics_version": status.get("numerics_version"),
    }
