"""Sweep numbers: one chunk computed by rsfcore's batch kernel, and a sweep's stored blocks
(or a subset of them, :mod:`rsfapp.sweepselect`) written as NetCDF-4, CSV rows, JSON or a
2-D diagram slice, slab by slab in bounded memory.

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

import contextlib
import csv
import io
import json
import math
import os
from collections.abc import Callable, Iterator
from typing import Any

import numpy as np
from numpy.typing import NDArray

from rsfcore import batch, units
from rsfcore.critical import KINDS, METHODS
from rsfcore.jsonsafe import finite_or_none
from rsfcore.params import ParameterError

from .grid import SpecError, SweepSpec, si_to_size
from .numtext import float_texts, int_texts, json_floats, json_ints
from .store.sweeps import BlockWriter, SweepStore
from .sweepselect import (
    FILL,
    RESULT_VARIABLES,
    BlockReader,
    Gathered,
    Selection,
    Slab,
    slabs,
)

__all__ = [
    "VARIABLES",
    "SI_VARIABLES",
    "SI_VARIABLE_MAX_POINTS",
    "PART_POINTS",
    "STORED",
    "chunk_parts",
    "compute_block",
    "fused_block",
    "compute_chunk",
    "critical_si",
    "si_names",
    "si_sizes",
    "netcdf_variables",
    "write_netcdf",
    "file_pieces",
    "csv_rows",
    "CSV_SLAB_ROWS",
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


#: The arrays of a stored block, in the order the block holds them (``outcome`` and
#: ``outcome_uncertain`` only when the sweep has a size).
STORED: tuple[str, ...] = (
    "critical_size",
    "rel_accuracy",
    "kind",
    "method",
    "failed",
    "on_boundary",
    "outcome",
    "outcome_uncertain",
)


def _arrays(r: batch.BatchResult) -> dict[str, NDArray[Any]]:
    arrays: dict[str, NDArray[Any]] = {name: getattr(r, name) for name in STORED[:6]}
    if r.outcome is not None and r.outcome_uncertain is not None:
        arrays["outcome"] = r.outcome
        arrays["outcome_uncertain"] = r.outcome_uncertain
    return arrays


#: Points per call of the batch kernel within a chunk (2^16).  A chunk of cheap points
#: (10^6, decided in closed form at ~40 ns a point) computed in one call streams its
#: parameters and the kernel's temporaries (~150 bytes a point) through main memory;
#: in parts of 2^16 points they stay in a core's L2 cache (measured on the 2-core
#: Xeon, 4 MiB L2, one 10^6-point chunk: parameters + kernel 40 ms in parts of 2^15-2^17
#: points against 6-11 + 45-52 ms in one call; 4096-point parts: 73 ms, Python's
#: per-call cost).  Each point's result does not depend on the other points of the call
#: (:func:`rsfcore.batch.critical_points` computes every point on its own), so the parts
#: give the same bits as one call (tests/app/test_sweep_chunks.py).
PART_POINTS = 1 << 16


def chunk_parts(
    spec: SweepSpec, i0: int, i1: int
) -> Iterator[tuple[int, dict[str, NDArray[Any]], dict[int, str]]]:
    """Results of flat indices [i0, i1) in parts of at most :data:`PART_POINTS` points,
    in index order: (offset of the part in the chunk, its arrays, {offset in the chunk:
    "Type: message"} of its failed points).  Each part is one
    :func:`rsfcore.batch.critical_points` call on parameters generated just before it.

    rsfcore.batch already isolates the points whose per-point fallback fails.  Should the
    batch call itself raise (an input the spec validation let through, or a defect of the
    kernel at some point), that part is recomputed point by point so that only the points
    that raise are marked failed, with their messages; MemoryError propagates (the task is
    retried)."""
    for a in range(i0, i1, PART_POINTS):
        arrays, errs = _compute_part(spec, a, min(i1, a + PART_POINTS))
        yield a - i0, arrays, {a - i0 + k: msg for k, msg in errs.items()}


def compute_chunk(
    spec: SweepSpec, i0: int, i1: int
) -> tuple[dict[str, NDArray[Any]], dict[int, str]]:
    """Results of flat indices [i0, i1) (:func:`chunk_parts` assembled).

    Returns (arrays, errors): the per-point arrays of the module docstring (plus
    ``method``, ``on_boundary`` and, for outcomes, ``outcome_uncertain``) and
    {offset in the chunk: "Type: message"} of the failed points.
    """
    n = i1 - i0
    if n <= PART_POINTS:
        return _compute_part(spec, i0, i1)
    out: dict[str, NDArray[Any]] = {}
    errors: dict[int, str] = {}
    for off, arrays, errs in chunk_parts(spec, i0, i1):
        if not out:
            out = {name: np.empty(n, arr.dtype) for name, arr in arrays.items()}
        for name, arr in arrays.items():
            out[name][off : off + arr.size] = arr
        errors.update(errs)
    return out, errors


def compute_block(spec: SweepSpec, i0: int, i1: int) -> tuple[bytes, dict[int, str]]:
    """Flat indices [i0, i1) computed and encoded as the block the store keeps
    (:func:`rsfapp.store.sweeps.encode_block` of :func:`compute_chunk`'s arrays, the same
    bytes); returns (block, errors).

    A grid's chunk is computed fused (:func:`fused_block`: one compiled call that
    generates the parameters from the axes and reports the arrays that are one repeated
    value).  Scattered points, and a chunk the fused call refuses or breaks on, go the
    unfused way: in parts (:func:`chunk_parts`), the block written from the parts
    (:class:`rsfapp.store.sweeps.BlockWriter`) without assembling them, a part that
    breaks the batch call recomputed point by point."""
    fused = fused_block(spec, i0, i1)
    if fused is not None:
        return fused
    w = BlockWriter()
    errors: dict[int, str] = {}
    for _off, arrays, errs in chunk_parts(spec, i0, i1):
        w.add(arrays)
        errors.update(errs)
    return w.finish(), errors


def fused_block(spec: SweepSpec, i0: int, i1: int) -> tuple[bytes, dict[int, str]] | None:
    """:func:`compute_block` of a grid's range in one :func:`rsfcore.batch.critical_grid`
    call on the spec's axis tables (:meth:`SweepSpec.tables`): no parameter array, and
    an array that is one repeated value over the range is neither laid out nor tested
    (the kernel says so).  The same bits and block bytes as the parts
    (tests/app/test_sweep_chunks.py).  None for scattered points, or when the call
    raises (a value the spec's validation let through, or a defect of the kernel: the
    unfused path then isolates the points that raise); MemoryError propagates."""
    t = spec.tables()
    if t is None:
        return None
    try:
        r = batch.critical_grid(
            t.ba,
            t.kappa,
            t.eps,
            t.vo,
            i0,
            i1,
            kappa_is_ratio=t.kappa_is_ratio,
            perturbation=spec.perturbation,
            rtol=spec.rtol,
            size=t.size,
        )
    except MemoryError:
        raise
    except Exception:  # noqa: BLE001 - the unfused path isolates the offending points
        return None
    w = BlockWriter()
    for name in STORED:
        if name in r.values:
            w.add_whole(name, r.values[name], r.n, r.repeated[name])
    return w.finish(), dict(r.errors)


def _compute_part(
    spec: SweepSpec, i0: int, i1: int
) -> tuple[dict[str, NDArray[Any]], dict[int, str]]:
    """:func:`compute_chunk` of [i0, i1) in one batch call (point by point if it raises)."""
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


def netcdf_variables(spec: SweepSpec) -> tuple[str, ...]:
    """Variables a ``variables=`` list may name: the results, ``computed`` and, for a
    sweep in SI, its SI critical size."""
    _, si_col = si_names(spec)
    return (*RESULT_VARIABLES, *([si_col] if si_col else []))


def _slab_values(
    reader: BlockReader, spec: SweepSpec, slab: Slab, names: tuple[str, ...], errors: bool = False
) -> Gathered:
    """The result variables ``names`` at a slab (the SI variable converted here)."""
    _, si_col = si_names(spec)
    stored = tuple(v for v in names if v != si_col)
    need = (
        stored if si_col not in names or "critical_size" in stored else (*stored, "critical_size")
    )
    g = reader.gather(slab.flat, need, errors)
    phys = spec.physical_inputs()
    if si_col and si_col in names and phys is not None:
        g.arrays[si_col] = critical_si(phys, spec.perturbation, g.arrays["critical_size"])
    return g


def write_netcdf(
    store: SweepStore,
    spec: SweepSpec,
    status: dict[str, Any],
    selection: Selection,
    path: str,
    how: str = "",
    progress: Callable[[int, int], None] | None = None,
) -> None:
    """Write the selected part of a sweep to ``path`` as NetCDF-4 (HDF5, written by
    h5netcdf) slab by slab, in bounded memory (one slab of
    :data:`~rsfapp.sweepselect.SLAB_POINTS` points and one stored block at a time).
    ``progress(done, total)`` is called after each slab (points written, selected) and
    once more when the file is closed.

    CF-1.10 metadata (:mod:`rsfapp.sweepcf`); variables zlib-compressed (level 1, with
    byte shuffle) in chunks of one slab, each compressed and written whole by
    :mod:`rsfapp.h5chunks` (a chunk of one repeated value compressed once); missing
    points are ``_FillValue`` (NaN for the floats, -1 for kind/outcome/method).  Grid
    axes are dimensions with coordinate variables; scattered sweeps have a ``point``
    dimension (the flat indices) with the swept parameters as variables.  A sweep in SI
    also gets its SI critical size (a selection of at most :data:`SI_VARIABLE_MAX_POINTS` points; else the formula as
    attribute ``si_variable_omitted``) and, when its size is swept in SI, ``size``."""
    import h5netcdf

    from . import h5chunks
    from .sweepcf import coordinate_attrs, global_attrs, variable_attrs

    dims = selection.dims
    shape = selection.shape
    coords = selection.coords(spec)
    vattrs = variable_attrs(spec)
    size_col, si_col = si_names(spec)
    names = tuple(v for v in selection.variables if v != si_col)
    phys = spec.physical_inputs()
    with_si = si_col is not None and si_col in selection.variables
    if with_si and selection.n > SI_VARIABLE_MAX_POINTS:
        with_si = False
    first = next(slabs(selection))
    chunks = first.shape
    attrs = global_attrs(
        spec, status, None if selection.is_full else selection.to_json(), how or "rsf sweep data"
    )
    if si_col and si_col in selection.variables and not with_si:
        attrs["si_variable_omitted"] = (
            f"{si_col} is given up to {SI_VARIABLE_MAX_POINTS} points: "
            + SI_VARIABLES[spec.perturbation][1]
        )
    with h5netcdf.File(path, "w") as f:
        f.dimensions = dict(zip(dims, shape, strict=True))
        for d in dims:
            v = f.create_variable(d, (d,), np.float64 if d != "point" else np.int64, data=coords[d])
            v.attrs.update(coordinate_attrs(d))
        if spec.mode == "points":
            for name, vals in spec.coords().items():
                v = f.create_variable(
                    name, ("point",), np.float64, data=np.asarray(vals)[selection.index[0]]
                )
                v.attrs.update(coordinate_attrs(name))
        if phys is not None and size_col is not None and spec.si_size is not None:
            sdim = spec.si_size if spec.mode == "grid" else "point"
            sv = si_to_size(phys, spec.perturbation, spec.si_size, spec.coords()[spec.si_size])
            if spec.mode == "points":
                sv = sv[selection.index[0]]
            else:
                sv = sv[selection.index[dims.index(sdim)]]
            v = f.create_variable("size", (sdim,), np.float64, data=sv)
            v.attrs.update(coordinate_attrs("size"))
            v.attrs["comment"] = f"dimensionless size of {spec.si_size} ({_SIZE_OF})"
        out: dict[str, Any] = {}
        for name in (*names, *([si_col] if with_si and si_col else [])):
            dtype, fill = FILL.get(name, (np.float64, math.nan))
            kw: dict[str, Any] = {}
            if (
                name in ("kind", "outcome", "method", "critical_size", "rel_accuracy")
                or name == si_col
            ):
                kw["fillvalue"] = dtype(fill)
            out[name] = f.create_variable(
                name,
                dims,
                dtype,
                chunks=chunks,
                compression="gzip",
                compression_opts=h5chunks.LEVEL,
                shuffle=True,
                **kw,
            )
            if name == si_col:
                out[name].attrs.update(
                    {"long_name": SI_VARIABLES[spec.perturbation][1], "units": "m/s"}
                )
            else:
                out[name].attrs.update(vattrs[name])
        f.attrs.update(attrs)
    # the values: one slab = one chunk of every variable, compressed here and written
    # whole (rsfapp.h5chunks: a chunk of one repeated value is compressed once)
    import h5py

    reader = BlockReader(store, status.get("id", "") or "")
    want = tuple(out)
    done = 0
    with h5py.File(path, "r+") as h5:
        writers = {
            name: h5chunks.ChunkWriter(h5[name], FILL.get(name, (None, math.nan))[1])
            for name in want
        }
        for slab in slabs(selection):
            g = _slab_values(reader, spec, slab, want)
            offset = tuple(int(s.start) for s in slab.out)
            for name, w in writers.items():
                w.write(offset, g.arrays[name].reshape(slab.shape))
            del g
            done += slab.flat.size
            if progress is not None and done < selection.n:
                progress(done, selection.n)
    if progress is not None:
        progress(selection.n, selection.n)


def file_pieces(path: str, piece: int = 1 << 20) -> Iterator[bytes]:
    """The file in pieces of ``piece`` bytes, deleted when done (or abandoned)."""
    try:
        with open(path, "rb") as fh:
            while data := fh.read(piece):
                yield data
    finally:
        with contextlib.suppress(OSError):
            os.unlink(path)


def _method(m: int) -> str:
    return METHODS[m].split(":")[0] if m >= 0 else ""


def _fmt(v: float) -> str:
    return "" if math.isnan(v) else repr(float(v))


#: Rows of CSV text made at once: a slab of text is ~25 Python objects a row (fields, row,
#: piece), so 2^14 rows hold ~25 MB at most (50,000 rows: +64 MB over idle in process,
#: 2^14: +27 MB, at the same rows per CPU second).
CSV_SLAB_ROWS = 1 << 14


def csv_rows(
    store: SweepStore,
    spec: SweepSpec,
    sweep_id: str,
    selection: Selection,
    rows: int = CSV_SLAB_ROWS,
) -> Iterator[str]:
    """CSV text in pieces (``rows`` rows at a time): a header, then one row per selected point
    in flat-index order: idx, the swept parameters, kind, critical_size, outcome,
    rel_accuracy, method (short name), failed, error.  A sweep in SI also has, after
    critical_size, the critical size in SI (``critical_slip_rate_m_s`` [m/s] or
    ``critical_load_point_velocity_m_s`` [m/s]: ``inf`` where infinite) and, when its
    size is swept in SI, the dimensionless ``size`` after the swept parameters.  Missing
    points have empty result fields.  ``variables`` keeps only those result columns
    (``error`` goes with ``failed``)."""
    names = spec.swept
    size_col, si_col = si_names(spec)
    chosen = selection.variables
    cols = [
        c
        for c in ("kind", "critical_size", si_col, "outcome", "rel_accuracy", "method", "failed")
        if c and c in chosen
    ]
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(
        [
            "idx",
            *names,
            *([size_col] if size_col else []),
            *cols,
            *(["error"] if "failed" in cols else []),
        ]
    )
    yield buf.getvalue()
    reader = BlockReader(store, sweep_id)
    need = tuple(dict.fromkeys((*(c for c in cols if c != si_col), "computed")))
    if si_col in cols:
        need = (*need, si_col)
    for slab in slabs(selection, rows):
        flat = slab.flat
        i, j = int(flat[0]), int(flat[-1]) + 1
        vals = spec.swept_values(i, j) if j - i == flat.size else spec.swept_at(flat)
        sizes = si_sizes(spec, vals)
        g = _slab_values(reader, spec, slab, need, errors="failed" in cols)
        a = g.arrays
        done = a["computed"].astype(bool)
        columns: list[list[str]] = [int_texts(flat)]
        columns += [float_texts(vals[m]) for m in names]
        if sizes is not None:
            columns.append(float_texts(sizes, nan=""))
        for c in cols:
            x = a[c]
            if c in _CODE_TEXT:  # codes -> labels (object arrays: tolist only increfs)
                col = _CODE_TEXT[c][np.maximum(x.astype(np.int64) + 1, 0)].tolist()
            elif c == "failed":
                col = int_texts(x)
            else:
                col = float_texts(x, nan="")
            columns.append(_blank(col, done))
            if c == "failed":
                errs = [""] * flat.size
                for k, msg in g.errors.items():
                    errs[k] = _quote(msg)
                columns.append(errs)
        yield "\n".join(map(",".join, zip(*columns, strict=True))) + "\n"


#: CSV text of the codes of ``kind``, ``outcome`` and ``method`` at code + 1 ("" at -1).
_CODE_TEXT: dict[str, NDArray[np.object_]] = {
    "kind": np.array(["", *KINDS], dtype=object),
    "outcome": np.array(["", *_OUTCOMES], dtype=object),
    "method": np.array(["", *(m.split(":")[0] for m in METHODS)], dtype=object),
}


def _blank(col: list[str], done: NDArray[np.bool_]) -> list[str]:
    """Empty where the point is not computed."""
    if done.all():
        return col
    return [v if d else "" for v, d in zip(col, done.tolist(), strict=True)]


def _quote(text: str) -> str:
    """A CSV field (RFC 4180 quoting when needed)."""
    if any(ch in text for ch in ',"\n\r'):
        return '"' + text.replace('"', '""') + '"'
    return text


def _jlist(a: NDArray[Any], kind: str) -> str:
    return json_floats(a) if kind == "f" else json_ints(a)


def json_chunks(
    store: SweepStore,
    spec: SweepSpec,
    status: dict[str, Any],
    selection: Selection,
    failures: list[tuple[int, str]],
) -> Iterator[str]:
    """JSON document in pieces, one slab of one variable at a time (bounded memory):
    status fields, ``shape`` (of the selection) and ``selection`` ({dim: [first index,
    last index, count]}), ``coords`` (selected axis values, or the swept parameters of
    each selected point), and ``data``: one flat list per variable in flat-index order
    of the selection (non-finite numbers and missing points are null; ``kind`` tells
    infinite from missing), ``computed``, and ``failures`` [{idx, error}] (the first 100
    of the sweep).  A sweep in SI (a selection of at most SI_VARIABLE_MAX_POINTS
    points) also has its SI variable in ``data``."""
    head: dict[str, Any] = {
        k: status[k]
        for k in ("id", "status", "n_total", "n_done", "n_failed", "numerics_version")
        if k in status
    }
    head.update(spec.summary())
    head["shape"] = list(selection.shape)
    head["selection"] = selection.to_json()
    head["kind_legend"] = list(KINDS)
    head["outcome_legend"] = list(_OUTCOMES)
    head["method_legend"] = list(METHODS)
    yield json.dumps(head)[:-1] + ', "coords": {'
    if spec.mode == "grid":
        coords = selection.coords(spec)
    else:
        assert spec.points is not None
        coords = {n: np.asarray(v)[selection.index[0]] for n, v in spec.points.items()}
    for n, (name, vals) in enumerate(coords.items()):
        yield ("," if n else "") + json.dumps(name) + ":" + _jlist(vals, "f")
    yield '}, "data": {'
    _, si_col = si_names(spec)
    names = [v for v in selection.variables if v != si_col]
    if si_col and si_col in selection.variables and selection.n <= SI_VARIABLE_MAX_POINTS:
        names.append(si_col)
    reader = BlockReader(store, str(status.get("id", "")))
    for n, v in enumerate(names):
        kind = "i" if v in FILL and FILL[v][0] is not np.float64 else "f"
        yield ("," if n else "") + json.dumps(v) + ":["
        for m, slab in enumerate(slabs(selection)):
            body = _jlist(_slab_values(reader, spec, slab, (v,)).arrays[v], kind)[1:-1]
            yield ("," if m else "") + body
        yield "]"
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
    store: SweepStore,
    spec: SweepSpec,
    status: dict[str, Any],
    fixed_idx: dict[str, int],
    selection: Selection | None = None,
) -> dict[str, Any]:
    """A 2-D slice as a stability diagram, laid out like
    ``rsfcore.diagram.DiagramResult.to_dict()``: critical_size[i][j] at (x[i], y[j]) (null
    where infinite or missing), kind codes 0 zero / 1 finite / 2 infinite, outcome codes 0
    stable / 1 unstable (null where missing) for outcome sweeps, present[i][j] (computed
    without error), plus status, n_done, n_total, n_failed and ``slice`` (the values of the
    other axes).  ``selection`` (``sel``/``isel``) narrows the two free axes to a window.
    Only the slice is read (memory and time scale with the slice, not the sweep)."""
    index = list(selection.index if selection is not None else (np.arange(a.n) for a in spec.axes))
    for k, a in enumerate(spec.axes):
        if a.name in fixed_idx:
            index[k] = np.array([fixed_idx[a.name]], dtype=np.int64)
    sel = Selection(
        tuple(a.name for a in spec.axes),
        tuple(np.asarray(i, dtype=np.int64) for i in index),
        ("critical_size", "kind", "outcome", "failed", "computed"),
        spec.shape,
    )
    free = [(a, index[k]) for k, a in enumerate(spec.axes) if a.name not in fixed_idx]
    shape2 = (len(free[0][1]), len(free[1][1]))
    arrays = {v: np.empty(sel.n, dtype=FILL[v][0]) for v in sel.variables}
    reader = BlockReader(store, str(status["id"]))
    pos = 0
    for slab in slabs(sel):
        g = reader.gather(slab.flat, sel.variables)
        for v in sel.variables:
            arrays[v][pos : pos + slab.flat.size] = g.arrays[v]
        pos += slab.flat.size

    def sl(v: str) -> NDArray[Any]:
        return arrays[v].reshape(shape2)

    cs, kind, oc = sl("critical_size"), sl("kind"), sl("outcome")
    ok = (sl("computed") > 0) & (sl("failed") == 0)
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
        "x_name": free[0][0].name,
        "x": free[0][0].at(free[0][1]).tolist(),
        "y_name": free[1][0].name,
        "y": free[1][0].at(free[1][1]).tolist(),
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
