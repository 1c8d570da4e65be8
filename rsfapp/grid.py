"""Sweep specs: validation of a :class:`~rsfapp.requests.SweepRequest` into a compact
:class:`SweepSpec`, and the lazy map from flat point indices to parameter values.

Nothing here is proportional to the number of points except what the caller asks for:
a grid is stored as its axes (``start/stop/n`` or explicit values), a chunk is a range
``[i0, i1)`` of flat indices (C order over the axes, the first axis slowest; for scattered
points the index into the arrays), and :meth:`SweepSpec.params` computes the parameter
arrays of one chunk only.

Errors are :class:`SpecError` (an ``rsfcore.ParameterError``, reported as 422
problem+json) naming the field (``axes[2].stop``, ``points.eps[17]``, ``x.values[3]`` for
the 2-D form) and its valid range; they are raised before anything is written.
"""

from __future__ import annotations

import functools
import hashlib
import math
from dataclasses import dataclass, field
from typing import Any, Literal

import numpy as np
from numpy.typing import NDArray

from rsfcore import limits, units
from rsfcore.batch import AxisTable
from rsfcore.params import ParameterError
from rsfcore.units import PhysicalInputs

from .config import Settings
from .requests import AXIS_RANGES, SweepAxis, SweepRequest
from .requests.sweeps import SI_FIXED, SI_SIZE_FIELDS

__all__ = [
    "Axis",
    "GridTables",
    "SpecError",
    "SweepSpec",
    "expand",
    "aligned_chunk",
    "cost_per_point",
    "plan_chunks",
    "si_to_size",
    "PARAM_NAMES",
    "ROWS_CACHE_BYTES",
    "SI_SIZE_FIELDS",
    "SPEC_VERSION",
]

#: Every parameter a point has (kappa is given either directly or as kappa_ratio).
PARAM_NAMES: tuple[str, ...] = ("ba", "kappa", "kappa_ratio", "eps", "vo", "size")
#: Layout version of the stored spec (part of the sweep id).
SPEC_VERSION = 2
_KAPPA_MAX = 1e6
#: Bytes of row layouts a spec keeps for its next ranges (:meth:`SweepSpec._row_params`;
#: a worker's 2^16-point parts of a grid with 10^4-point rows: 0.64 MB per fixed or
#: last-axis parameter).  Specs are cached per process (up to 65, see
#: rsfapp.store.sweeps), so this bounds their layouts to ~130 MB.
ROWS_CACHE_BYTES = 2 << 20
F64 = NDArray[np.float64]


class SpecError(ParameterError):
    """An invalid sweep spec: ``field`` names the input (e.g. ``axes[2].stop``)."""

    def __init__(self, field: str, detail: str, valid: str) -> None:
        self.field, self.value, self.valid = field, None, valid
        ValueError.__init__(self, f"{field}: {detail} (valid range: {valid})")


def _si_size_one(phys: PhysicalInputs, perturbation: str, name: str, x: float) -> float:
    """One SI size statement -> the dimensionless size (rsfcore.units.size_from_si, the
    one place of the SI size rules; ParameterError from there on an out-of-range value)."""
    return float(units.size_from_si(phys, perturbation, name, x))


def si_to_size(
    phys: PhysicalInputs, perturbation: str, name: str, values: NDArray[np.float64]
) -> F64:
    """Dimensionless perturbation sizes of SI values ``values`` of ``name`` (``factor``,
    ``new_slip_rate_m_s`` or ``new_load_point_velocity_m_s``), each distinct value
    converted once by rsfcore.units (velocity jump: d = ln(factor) = ln(V_new/V_before);
    load-point jump: dv = factor - 1 = V_new/V_load - 1), exact to a few ulp.

    Raises ParameterError (field ``perturbation.<name>``, from rsfcore.units) for a value
    out of range; empty input gives an empty array.  Cost: ~1 us per distinct value
    (measured 0.8-1.1 us; a numpy formula would take ~5 ns but would be a second copy of
    the conversions, which live in rsfcore.units)."""
    v = np.asarray(values, dtype=np.float64)
    if v.size == 0:
        return np.empty(0)
    u, inv = np.unique(v, return_inverse=True)
    out = np.array([_si_size_one(phys, perturbation, name, float(x)) for x in u])
    return np.asarray(out[inv.reshape(v.shape)], dtype=np.float64)


def _bad_mask(name: str, v: F64, perturbation: str) -> NDArray[np.bool_]:
    lo, hi, _ = AXIS_RANGES[name]
    bad = ~((v >= lo) & (v <= hi))
    if name in SI_SIZE_FIELDS:
        bad |= v <= 0.0
    if name == "ba":
        bad |= v <= 1.0
    if name == "size" and perturbation == "load-point-jump":
        bad |= v <= -1.0
    if name == "vo" and perturbation == "load-point-jump":
        bad |= v <= 0.0
    if name == "vo":
        bad |= (v > 0.0) & (v < limits.VO_MIN)  # as rsfcore.Params: times leave the doubles
    return bad


def _valid(name: str, perturbation: str) -> str:
    if name == "vo" and perturbation == "load-point-jump":
        return "(0, 1e300] (a load-point jump needs v_o > 0)"
    return AXIS_RANGES[name][2]


@dataclass(frozen=True)
class Axis:
    """One grid axis: explicit ``values`` or ``n`` values from ``start`` to ``stop``.

    Generated values: v_k = start + (stop - start) k/(n - 1), or geometric with ``log``
    (v_k = start (stop/start)^(k/(n-1))); v_0 = start and v_(n-1) = stop exactly.
    """

    name: str
    n: int
    values: tuple[float, ...] | None = None
    start: float = 0.0
    stop: float = 0.0
    log: bool = False

    def at(self, k: NDArray[np.int64]) -> F64:
        """Values at integer positions ``k`` (array)."""
        if self.values is not None:
            return np.asarray(self.values, dtype=np.float64)[k]
        if self.n == 1:
            return np.full(k.shape, self.start)
        t = k / (self.n - 1.0)
        if self.log:
            a, b = math.log(self.start), math.log(self.stop)
            v = np.exp(a + (b - a) * t)
        else:
            v = self.start + (self.stop - self.start) * t
        v = np.where(k == 0, self.start, np.where(k == self.n - 1, self.stop, v))
        lo, hi = min(self.start, self.stop), max(self.start, self.stop)
        return np.clip(v, lo, hi)

    def all(self) -> F64:
        """Every value of the axis."""
        return self.at(np.arange(self.n, dtype=np.int64))

    def cached_all(self) -> F64:
        """:meth:`all`, computed once per axis and process (read-only): a chunk
        computed in parts lays out the same axis values for every part."""
        return _axis_values(self)

    def to_json(self) -> dict[str, Any]:
        """Compact JSON form (values only if explicit)."""
        if self.values is not None:
            return {"name": self.name, "n": self.n, "values": list(self.values)}
        return {
            "name": self.name,
            "n": self.n,
            "start": self.start,
            "stop": self.stop,
            "log": self.log,
        }

    @classmethod
    def from_json(cls, d: dict[str, Any]) -> Axis:
        """Inverse of :meth:`to_json`."""
        if "values" in d:
            return cls(d["name"], int(d["n"]), tuple(float(v) for v in d["values"]))
        return cls(
            d["name"], int(d["n"]), None, float(d["start"]), float(d["stop"]), bool(d["log"])
        )


@functools.lru_cache(maxsize=256)
def _axis_values(ax: Axis) -> F64:
    v = ax.all()
    v.setflags(write=False)
    return v


@dataclass(frozen=True)
class GridTables:
    """A grid sweep's parameters as rsfcore.batch.critical_grid takes them: per parameter
    a fixed value or its axis's values with the axis's stride (flat indices per step,
    C order); ``kappa`` holds kappa_ratio when ``kappa_is_ratio``; ``size`` None for
    critical sizes.  :meth:`SweepSpec.tables`."""

    ba: float | AxisTable
    kappa: float | AxisTable
    eps: float | AxisTable
    vo: float | AxisTable
    size: float | AxisTable | None
    kappa_is_ratio: bool


@dataclass
class SweepSpec:
    """A validated sweep.

    Attributes:
        mode: "grid" (outer product of ``axes``) or "points" (scattered ``points``).
        axes: the grid axes (empty for scattered points).
        points: {name: float64 array} of the scattered points (None for a grid).
        fixed: values of the parameters that are not swept (ba, eps, vo, size and one of
            kappa / kappa_ratio; size None when neither fixed nor swept).
        kappa_param: "kappa" or "kappa_ratio": how kappa is given.
        perturbation: "velocity-jump" or "load-point-jump"; rtol: requested accuracy.
        output: "critical" (critical sizes) or "outcome" (a size is fixed or swept).
        physical: the SI machine of ``fixed.physical`` (rsfcore.units.PhysicalInputs'
            seven fields, V_load_m_s with its default applied), None for a dimensionless
            sweep; ``fixed`` then holds its conversion (ba, kappa, vo).  A fixed SI size
            is in ``fixed`` under its own name (``factor``, ...) next to its conversion
            ``size``; a swept one is an axis (or points array) of that name, converted to
            sizes per chunk by :func:`si_to_size` (:attr:`si_size`).
    """

    mode: Literal["grid", "points"]
    axes: list[Axis]
    points: dict[str, F64] | None
    fixed: dict[str, float | None]
    kappa_param: str
    perturbation: str
    rtol: float
    output: str
    points_sha256: str = ""
    _n: int = field(default=0, repr=False)
    _names: tuple[str, ...] = field(default=(), repr=False)
    physical: dict[str, float] | None = None
    #: per parameter that is the same on every row: its read-only layout over the most
    #: rows a range has needed (:meth:`_row_params`), kept for the spec's next ranges
    _rows_cache: dict[str, F64] = field(default_factory=dict, repr=False, compare=False)
    #: :meth:`tables`, built once
    _tables: list[GridTables] = field(default_factory=list, repr=False, compare=False)

    def __post_init__(self) -> None:
        if self.mode == "grid":
            self._n = int(np.prod([a.n for a in self.axes], dtype=np.int64))
        elif self.points is not None:
            self._n = int(next(iter(self.points.values())).size)
            self._names = tuple(self.points)

    @property
    def n_total(self) -> int:
        """Number of points."""
        return self._n

    @property
    def shape(self) -> tuple[int, ...]:
        """Grid shape (axis lengths), or (n,) for scattered points."""
        if self.mode == "grid":
            return tuple(a.n for a in self.axes)
        return (self._n,)

    def physical_inputs(self) -> PhysicalInputs | None:
        """The SI machine (rsfcore.units.PhysicalInputs), or None for a dimensionless sweep."""
        return None if self.physical is None else PhysicalInputs(**self.physical)

    @property
    def si_size(self) -> str | None:
        """Name of the SI size statement (``factor``, ``new_slip_rate_m_s``,
        ``new_load_point_velocity_m_s``) that is swept, else None."""
        return next((n for n in self.swept if n in SI_SIZE_FIELDS), None)

    @property
    def swept(self) -> list[str]:
        """Names of the swept parameters, in axis (or points) order."""
        if self.mode == "grid":
            return [a.name for a in self.axes]
        return list(self._names)

    def params(self, i0: int, i1: int) -> dict[str, F64 | None]:
        """Parameter arrays of flat indices [i0, i1): ba, kappa (not the ratio), eps, vo
        and size (None when the sweep computes critical sizes): contiguous arrays, not to
        be written to (some are read-only views of a layout kept for the next ranges).

        A grid range spanning at least two rows of its last axis is computed row-wise
        (:meth:`_row_params`: the other axes' values once per row, broadcast), the same
        numbers as point by point."""
        rows = self._row_params(i0, i1)
        if rows is not None:
            return rows
        return self._derive(self.swept_values(i0, i1), (i1 - i0,))

    def params_at(self, flat: NDArray[np.int64]) -> dict[str, F64 | None]:
        """As :meth:`params`, at the flat indices ``flat`` (any order)."""
        return self._derive(self.swept_at(flat), (int(flat.size),))

    def _row_params(self, i0: int, i1: int) -> dict[str, F64 | None] | None:
        """:meth:`params` of [i0, i1) for a grid whose last axis ("a row", L values) is
        at most half the range long; else None.

        The rows the range touches are laid out as a (rows, L) block: the last axis's
        values as one row (1, L), each other axis's value once per row (rows, 1), fixed
        values as (1, 1); the derived kappa (kappa_ratio (ba - 1)) is one broadcast
        operation.  A parameter that varies within a row only (the last axis, a fixed
        value) is the same for every range of as many rows: laid out once per spec and
        returned as a read-only view (rsfcore's batch call takes read-only arrays); one
        that varies per row is written once.  The range is a contiguous view of the
        block (at most two partial rows computed and not used).  Every element is the
        same IEEE operation on the same values as :meth:`_derive` point by point, so the
        same bits (tests/app/test_sweep_spec.py).  Sweeps with an SI size take the
        point-by-point path."""
        n = i1 - i0
        if self.mode != "grid" or self.si_size is not None or n <= 0:
            return None
        last = self.axes[-1]
        width = last.n
        if 2 * width > n:
            return None
        r0, r1 = i0 // width, (i1 - 1) // width + 1
        vals: dict[str, F64] = {last.name: last.cached_all()[None, :]}
        stride = 1  # in rows
        for ax in reversed(self.axes[:-1]):
            k = (np.arange(r0, r1, dtype=np.int64) // stride) % ax.n
            vals[ax.name] = ax.cached_all()[k][:, None]
            stride *= ax.n
        shape = (r1 - r0, width)
        off = i0 - r0 * width
        out: dict[str, F64 | None] = {}
        for name, v in self._derive(vals, (1, 1)).items():
            if v is None:
                out[name] = None
                continue
            if v.shape[0] == 1:  # the same on every row
                t = self._rows_cache.get(name)
                if t is None or t.shape[0] < shape[0] or t.shape[1] != width:
                    t = np.broadcast_to(v, shape).copy()
                    t.flags.writeable = False
                    kept = sum(a.nbytes for k, a in self._rows_cache.items() if k != name)
                    if kept + t.nbytes > ROWS_CACHE_BYTES:  # specs are kept per process
                        self._rows_cache.clear()
                    if t.nbytes <= ROWS_CACHE_BYTES:
                        self._rows_cache[name] = t
                v = t[: shape[0]]
            elif v.shape != shape:  # one value per row
                v = np.repeat(v.reshape(-1), width).reshape(shape)
            out[name] = v.reshape(-1)[off : off + n]
        return out

    def _derive(self, vals: dict[str, F64], shape: tuple[int, ...]) -> dict[str, F64 | None]:
        """ba, kappa, eps, vo and size from the swept values ``vals`` (arrays that
        broadcast to ``shape``): fixed values filled in, kappa from kappa_ratio, an SI
        size converted."""
        for name, v in self.fixed.items():
            if name not in vals and v is not None:
                vals[name] = np.full(shape, float(v))
        if self.kappa_param == "kappa_ratio":
            vals["kappa"] = vals["kappa_ratio"] * (vals["ba"] - 1.0)
        si = self.si_size
        if si is not None:  # the swept SI size, converted by rsfcore.units
            phys = self.physical_inputs()
            assert phys is not None
            vals["size"] = si_to_size(phys, self.perturbation, si, vals[si])
        return {
            "ba": vals["ba"],
            "kappa": vals["kappa"],
            "eps": vals["eps"],
            "vo": vals["vo"],
            "size": vals.get("size") if self.output == "outcome" else None,
        }

    def tables(self) -> GridTables | None:
        """The grid's parameters as axis tables (:class:`GridTables`), None for
        scattered points.  The values are those :meth:`params` gives at every point:
        each axis's :meth:`Axis.cached_all`, fixed values as given, a swept SI size
        converted value by value (:func:`si_to_size` is elementwise), and kappa from
        kappa_ratio by the same operation, done by the kernel per point."""
        if self.mode != "grid":
            return None
        if self._tables:
            return self._tables[0]
        stride = 1
        table: dict[str, float | AxisTable] = {}
        for ax in reversed(self.axes):
            table[ax.name] = AxisTable(ax.cached_all(), stride)
            stride *= ax.n
        for name, v in self.fixed.items():
            if name not in table and v is not None:
                table[name] = float(v)
        si = self.si_size
        if si is not None:
            phys = self.physical_inputs()
            assert phys is not None
            t = table[si]
            assert isinstance(t, AxisTable)
            table["size"] = AxisTable(si_to_size(phys, self.perturbation, si, t.values), t.stride)
        ratio = self.kappa_param == "kappa_ratio"
        self._tables.append(
            GridTables(
                table["ba"],
                table["kappa_ratio" if ratio else "kappa"],
                table["eps"],
                table["vo"],
                table.get("size") if self.output == "outcome" else None,
                ratio,
            )
        )
        return self._tables[0]

    def swept_values(self, i0: int, i1: int) -> dict[str, F64]:
        """Values of the swept parameters at flat indices [i0, i1).

        A grid axis shorter than the range has its values computed once and laid out by
        copying (repeat each value over its run of ``stride`` flat indices, or tile the
        axis for the last one): no index arithmetic per point, the same numbers as
        :meth:`Axis.at` elementwise (a chunk of 10^6 points: ~10 ms instead of ~70 ms)."""
        vals: dict[str, F64] = {}
        if self.mode != "grid":
            assert self.points is not None
            for name, arr in self.points.items():
                vals[name] = np.asarray(arr[i0:i1], dtype=np.float64)
            return vals
        size = i1 - i0
        stride = 1
        strides: list[int] = []
        for ax in reversed(self.axes):
            strides.append(stride)
            stride *= ax.n
        for ax, st in zip(self.axes, reversed(strides), strict=True):
            if size == 0:
                vals[ax.name] = np.empty(0)
            elif ax.n >= size:  # a long axis: its values at the indices of the range
                k = (np.arange(i0, i1, dtype=np.int64) // st) % ax.n
                vals[ax.name] = ax.at(k)
            elif st == 1:
                off = i0 % ax.n
                reps = -(-(off + size) // ax.n)
                vals[ax.name] = np.tile(ax.cached_all(), reps)[off : off + size]
            else:
                runs = np.arange(i0 // st, (i1 - 1) // st + 1, dtype=np.int64)
                counts = np.minimum(i1, (runs + 1) * st) - np.maximum(i0, runs * st)
                vals[ax.name] = np.repeat(ax.cached_all()[runs % ax.n], counts)
        return vals

    def swept_at(self, flat: NDArray[np.int64]) -> dict[str, F64]:
        """Values of the swept parameters at the flat indices ``flat`` (any order)."""
        if self.mode == "grid":
            multi = np.unravel_index(flat, self.shape)
            return {
                ax.name: ax.at(np.asarray(k, dtype=np.int64))
                for ax, k in zip(self.axes, multi, strict=True)
            }
        assert self.points is not None
        return {n: np.asarray(v, dtype=np.float64)[flat] for n, v in self.points.items()}

    def coords(self) -> dict[str, F64]:
        """Axis values (grid) or the swept point arrays (scattered)."""
        if self.mode == "grid":
            return {a.name: a.all() for a in self.axes}
        assert self.points is not None
        return dict(self.points)

    def to_json(self) -> dict[str, Any]:
        """Canonical JSON (small: no point arrays; scattered points by their digest)."""
        d: dict[str, Any] = {
            "v": SPEC_VERSION,
            "mode": self.mode,
            "fixed": self.fixed,
            "kappa_param": self.kappa_param,
            "perturbation": self.perturbation,
            "rtol": self.rtol,
            "output": self.output,
            "n_total": self.n_total,
        }
        if self.mode == "grid":
            d["axes"] = [a.to_json() for a in self.axes]
        else:
            d["points"] = {"names": self.swept, "n": self.n_total, "sha256": self.points_sha256}
        if self.physical is not None:  # only then: dimensionless sweeps keep their ids
            d["physical"] = dict(self.physical)
        return d

    def summary(self) -> dict[str, Any]:
        """What a status poll shows: dims (names and lengths), fixed values, mode."""
        if self.mode == "grid":
            dims = [{"name": a.name, "n": a.n} for a in self.axes]
        else:
            dims = [{"name": "point", "n": self.n_total, "parameters": self.swept}]
        out: dict[str, Any] = {
            "mode": self.mode,
            "dims": dims,
            "output": self.output,
            "fixed": {k: v for k, v in self.fixed.items() if v is not None},
            "perturbation": self.perturbation,
            "rtol": self.rtol,
        }
        if self.physical is not None:
            out["physical"] = dict(self.physical)
        return out

    @classmethod
    def from_json(cls, d: dict[str, Any], points: dict[str, F64] | None = None) -> SweepSpec:
        """Inverse of :meth:`to_json` (``points``: the stored scattered arrays)."""
        axes = [Axis.from_json(a) for a in d.get("axes", [])]
        sha = d["points"]["sha256"] if d["mode"] == "points" else ""
        names = tuple(d["points"]["names"]) if d["mode"] == "points" else ()
        return cls(
            d["mode"],
            axes,
            points,
            dict(d["fixed"]),
            d["kappa_param"],
            d["perturbation"],
            float(d["rtol"]),
            d["output"],
            sha,
            int(d.get("n_total", 0)),
            names,
            None if d.get("physical") is None else dict(d["physical"]),
        )


def _axis(ax: SweepAxis, where: str, pert: str) -> Axis:
    valid = _valid(ax.name, pert)
    if ax.values is not None:
        if any(v is not None for v in (ax.start, ax.stop, ax.n)):
            raise SpecError(f"{where}.values", "give either values or start/stop/n", valid)
        v = np.asarray(ax.values, dtype=np.float64)
        bad = _bad_mask(ax.name, v, pert)
        if bad.any():
            k = int(np.argmax(bad))
            raise SpecError(f"{where}.values[{k}]", f"{v[k]!r} out of range for {ax.name}", valid)
        return Axis(ax.name, int(v.size), tuple(float(x) for x in v))
    for f in ("start", "stop", "n"):
        if getattr(ax, f) is None:
            raise SpecError(
                f"{where}.{f}",
                "required when values is not given",
                "an integer >= 1" if f == "n" else valid,
            )
    for f in ("start", "stop"):
        x = float(getattr(ax, f))
        if _bad_mask(ax.name, np.array([x]), pert)[0]:
            raise SpecError(f"{where}.{f}", f"{x!r} out of range for {ax.name}", valid)
    assert ax.start is not None and ax.stop is not None and ax.n is not None
    if ax.log and (ax.start <= 0 or ax.stop <= 0):
        raise SpecError(
            f"{where}.start" if ax.start <= 0 else f"{where}.stop",
            "log spacing needs start, stop > 0",
            "> 0",
        )
    return Axis(ax.name, int(ax.n), None, float(ax.start), float(ax.stop), bool(ax.log))


def _digest(points: dict[str, F64]) -> str:
    h = hashlib.sha256()
    for name in sorted(points):
        h.update(name.encode())
        h.update(np.ascontiguousarray(points[name], dtype="<f8").tobytes())
    return h.hexdigest()


def expand(req: SweepRequest, max_points: int, max_scattered: int | None = None) -> SweepSpec:
    """Validate ``req`` into a :class:`SweepSpec` (raises :class:`SpecError`).

    Args:
        req: the request (exactly one of ``axes``, ``points``, ``x``/``y``).
        max_points: largest number of points (RSF_SWEEP_MAX_POINTS).
        max_scattered: largest number of scattered points (RSF_SWEEP_MAX_SCATTERED).
    """
    pert = req.perturbation
    forms = [
        f
        for f, given in (
            ("axes", req.axes is not None),
            ("points", req.points is not None),
            ("x", req.x is not None or req.y is not None),
        )
        if given
    ]
    if len(forms) != 1:
        raise SpecError(
            forms[1] if len(forms) > 1 else "axes",
            "give exactly one of axes, points or x/y",
            "one of: axes (1-5 grid axes), points (scattered), x and y (2-D)",
        )
    form = forms[0]
    axes: list[Axis] = []
    points: dict[str, F64] | None = None
    where: dict[str, str] = {}  # parameter -> field prefix of its source
    if form == "x":
        if req.x is None or req.y is None:
            raise SpecError(
                "y" if req.x is not None else "x", "the 2-D form needs x and y", "an axis object"
            )
        srcs: list[tuple[SweepAxis, str]] = [(req.x, "x"), (req.y, "y")]
    elif form == "axes":
        assert req.axes is not None
        srcs = [(a, f"axes[{k}]") for k, a in enumerate(req.axes)]
    else:
        srcs = []
    for ax, w in srcs:
        if ax.name in where:
            raise SpecError(
                f"{w}.name",
                f"{ax.name} is already swept",
                "a parameter not already swept (ba, kappa, kappa_ratio, eps, vo, size)",
            )
        axes.append(_axis(ax, w, pert))
        where[ax.name] = w
    if form == "points":
        assert req.points is not None
        if not req.points:
            raise SpecError("points", "no parameter given", "1 to 6 equal-length arrays")
        points = {}
        n0: int | None = None
        first = ""
        for pname, vals in req.points.items():
            name = str(pname)
            v = np.asarray(vals, dtype=np.float64)
            if n0 is None:
                n0, first = int(v.size), name
                if n0 == 0:
                    raise SpecError(f"points.{name}", "empty", "at least one point")
                if max_scattered is not None and n0 > max_scattered:
                    raise SpecError(
                        f"points.{name}",
                        f"{n0} points exceed the limit",
                        f"<= {max_scattered} points (RSF_SWEEP_MAX_SCATTERED)",
                    )
            elif v.size != n0:
                raise SpecError(
                    f"points.{name}", f"length {v.size}", f"length {n0}, as points.{first}"
                )
            bad = _bad_mask(name, v, pert)
            if bad.any():
                k = int(np.argmax(bad))
                raise SpecError(
                    f"points.{name}[{k}]", f"{v[k]!r} out of range for {name}", _valid(name, pert)
                )
            points[name] = v
            where[name] = f"points.{name}"

    fx = req.fixed
    phys = _physical(req, where, form)
    si_fixed = _si_size(req, where, form, phys, axes, points)

    # kappa and kappa_ratio: one of them
    uses_kappa = "kappa" in where or (fx.kappa is not None and "kappa_ratio" not in where)
    if "kappa" in where and "kappa_ratio" in where:
        raise SpecError(
            f"{where['kappa_ratio']}" + (".name" if form != "points" else ""),
            "kappa and kappa_ratio cannot both be swept",
            "one of kappa or kappa_ratio",
        )
    if uses_kappa and fx.kappa_ratio is not None and "kappa_ratio" not in where:
        raise SpecError(
            "fixed.kappa_ratio",
            "give kappa or kappa_ratio, not both",
            "null when kappa is given or swept",
        )
    kappa_param = "kappa" if uses_kappa or phys is not None else "kappa_ratio"
    fixed: dict[str, float | None] = {
        "ba": fx.ba,
        "eps": fx.eps,
        "vo": fx.vo,
        "size": fx.size,
        kappa_param: (
            fx.kappa
            if uses_kappa
            else (limits.KAPPA_RATIO.default if fx.kappa_ratio is None else fx.kappa_ratio)
        ),
    }
    if phys is not None:  # the one conversion SI -> dimensionless (rsfcore.units)
        fixed.update(ba=phys.ba, kappa=phys.kappa, vo=phys.vo)
    fixed.update(si_fixed)  # a fixed SI size and its conversion
    vo_fixed = fixed.get("vo")
    if "vo" not in where and vo_fixed is not None and 0.0 < vo_fixed < limits.VO_MIN:
        raise SpecError(
            "fixed.physical" if phys is not None else "fixed.vo",
            f"{vo_fixed!r} out of range for vo",
            limits.VO_VALID_TEXT,
        )
    for name in where:
        fixed.pop(name, None)
    sized = "size" in where or any(f in where for f in SI_SIZE_FIELDS)
    output = "outcome" if (sized or fixed.get("size") is not None) else "critical"
    if output == "critical":
        fixed.pop("size", None)

    spec = SweepSpec(
        "grid" if points is None else "points",
        axes,
        points,
        fixed,
        kappa_param,
        pert,
        float(req.rtol),
        output,
        _digest(points) if points is not None else "",
        physical=None if phys is None else phys.to_dict(),
    )
    if spec.n_total > max_points:
        fld = "y.values" if form == "x" else ("axes" if form == "axes" else "points")
        raise SpecError(
            fld,
            f"{spec.n_total} points exceed the limit",
            f"<= {max_points} points (RSF_SWEEP_MAX_POINTS)",
        )
    _check_combinations(spec, where)
    return spec


def _physical(req: SweepRequest, where: dict[str, str], form: str) -> PhysicalInputs | None:
    """``fixed.physical`` converted by rsfcore.units (ParameterError naming
    ``fixed.physical.<field>``), after the rule: with it, none of ba, kappa,
    kappa_ratio, vo is fixed or swept (SpecError naming the clashing field)."""
    fx = req.fixed
    if fx.physical is None:
        return None
    valid = (
        "with fixed.physical, only eps and size may be swept or fixed "
        "(physical sets ba, kappa and vo)"
    )
    for name in SI_FIXED:
        if name in fx.model_fields_set and getattr(fx, name) is not None:
            raise SpecError(
                f"fixed.{name}", f"give either fixed.physical (SI) or fixed.{name}", valid
            )
    for name in SI_FIXED:
        if name in where:
            fld = where[name] + ("" if form == "points" else ".name")
            raise SpecError(fld, f"{name} cannot be swept with fixed.physical", valid)
    phys = PhysicalInputs.from_dict(
        fx.physical.model_dump(exclude_none=True), prefix="fixed.physical"
    )
    if req.perturbation == "load-point-jump" and not phys.vo > 0.0:
        raise SpecError(
            "fixed.physical.V_load_m_s",
            "a load-point jump needs a moving load point",
            "(0, 1e300 V_star_m_s] m/s",
        )
    return phys


_SI_ONE = (
    "one statement of the perturbation size: size, or with fixed.physical one of factor, "
    "new_slip_rate_m_s (velocity jump), new_load_point_velocity_m_s (load-point jump); "
    "fixed or swept"
)


def _convert_checked(
    phys: PhysicalInputs, pert: str, name: str, values: F64, fields: list[str]
) -> F64:
    """:func:`si_to_size` of ``values`` whose field names are ``fields`` (same length):
    SpecError naming the first value that rsfcore.units refuses or whose size is out of
    the perturbation's range."""
    try:
        sizes = si_to_size(phys, pert, name, values)
    except ParameterError as exc:
        bad = [k for k, x in enumerate(values.tolist()) if not _si_ok(phys, pert, name, x)]
        k = bad[0] if bad else 0
        unit = " m/s" if name.endswith("_m_s") else ""
        raise SpecError(
            fields[k],
            f"{float(values[k])!r} out of range for {name}",
            f"{exc.valid}{unit} (rsfcore.units)",
        ) from None
    bad_size = _bad_mask("size", sizes, pert)
    if bad_size.any():
        k = int(np.argmax(bad_size))
        formula = "d = ln(V_new/V_before)" if pert == "velocity-jump" else "dv = V_new/V_load - 1"
        raise SpecError(
            fields[k],
            f"{float(values[k])!r} converts to size {float(sizes[k])!r}, out of range",
            f"a value whose size ({formula}) is in {_valid('size', pert)}",
        )
    return sizes


def _si_ok(phys: PhysicalInputs, pert: str, name: str, x: float) -> bool:
    try:
        _si_size_one(phys, pert, name, x)
    except ParameterError:
        return False
    return True


def _si_size(
    req: SweepRequest,
    where: dict[str, str],
    form: str,
    phys: PhysicalInputs | None,
    axes: list[Axis],
    points: dict[str, F64] | None,
) -> dict[str, float]:
    """The perturbation size stated in SI (fixed or swept), after the rules of the module
    docstring of rsfapp.requests.sweeps (SpecError naming the field).  Returns the fixed
    statement and its conversion ``{name: value, "size": size}`` (empty when the size is
    not fixed in SI); a swept statement is only checked here (every explicit value, the
    ends of a start/stop axis: the conversions are monotonic) and converted per chunk."""
    fx = req.fixed
    pert = req.perturbation
    stmts: list[tuple[str, str, bool]] = [
        (f, where[f] + ("" if form == "points" else ".name"), True)
        for f in SI_SIZE_FIELDS
        if f in where
    ]
    stmts += [(f, f"fixed.{f}", False) for f in SI_SIZE_FIELDS if getattr(fx, f) is not None]
    if not stmts:
        return {}
    name, fld, swept = stmts[0]
    if phys is None:
        raise SpecError(
            fld,
            f"{name} states the perturbation size in SI and needs fixed.physical",
            "with fixed.physical (the SI machine); without it give the dimensionless size",
        )
    if len(stmts) > 1:
        raise SpecError(stmts[1][1], f"the size is already given as {fld}", _SI_ONE)
    if fx.size is not None:
        raise SpecError("fixed.size", f"give either fixed.size or {fld}, never both", _SI_ONE)
    if "size" in where:
        raise SpecError(fld, f"the size is already swept ({where['size']})", _SI_ONE)
    if name not in units.SI_SIZE_FOR_KIND[pert]:
        kinds = " or ".join(units.SI_SIZE_FOR_KIND[pert])
        raise SpecError(fld, f"{name} is not used by a {pert}", f"{kinds} for a {pert}")
    if not swept:
        x = float(getattr(fx, name))
        size = _convert_checked(phys, pert, name, np.array([x]), [fld])
        return {name: x, "size": float(size[0])}
    if points is not None:
        v = points[name]
        _convert_checked(phys, pert, name, v, [f"points.{name}[{k}]" for k in range(v.size)])
        return {}
    w = where[name]
    ax = next(a for a in axes if a.name == name)
    if ax.values is not None:
        v = np.asarray(ax.values, dtype=np.float64)
        _convert_checked(phys, pert, name, v, [f"{w}.values[{k}]" for k in range(v.size)])
    else:
        ends = np.array([ax.start, ax.stop])
        _convert_checked(phys, pert, name, ends, [f"{w}.start", f"{w}.stop"])
    return {}


def _extremes(spec: SweepSpec, name: str) -> F64:
    if spec.mode == "grid":
        for a in spec.axes:
            if a.name == name:
                vals = np.asarray(a.values) if a.values is not None else np.array([a.start, a.stop])
                return np.array([vals.min(), vals.max()])
    v = spec.fixed.get(name)
    return np.array([0.0 if v is None else float(v)])


def _check_combinations(spec: SweepSpec, where: dict[str, str]) -> None:
    """Constraints between parameters: kappa_ratio (b/a - 1) <= 1e6 and, for a load-point
    jump, v_o > 0 (fixed) and size > -1 (fixed)."""
    if spec.perturbation == "load-point-jump":
        if "vo" not in where and not (spec.fixed["vo"] or 0.0) > 0.0:
            raise SpecError("fixed.vo", "load-point-jump needs vo > 0", "(0, 1e300]")
        s = spec.fixed.get("size")
        if "size" not in where and s is not None and s <= -1.0:
            raise SpecError("fixed.size", "load-point-jump needs size > -1", "(-1, 1e3]")
    if spec.kappa_param != "kappa_ratio":
        return
    valid = "kappa_ratio*(ba-1) <= 1e6"
    if spec.mode == "points" and ("kappa_ratio" in where or "ba" in where):
        kappa = spec.params(0, spec.n_total)["kappa"]
        assert kappa is not None
        bad = np.asarray(kappa > _KAPPA_MAX)
        if bad.any():
            k = int(np.argmax(bad))
            name = "kappa_ratio" if "kappa_ratio" in where else "ba"
            raise SpecError(f"points.{name}[{k}]", "kappa = kappa_ratio*(ba-1) exceeds 1e6", valid)
        return
    kr = _extremes(spec, "kappa_ratio").max()
    ba = _extremes(spec, "ba").max()
    if kr * (ba - 1.0) > _KAPPA_MAX:
        if "kappa_ratio" in where:
            w = where["kappa_ratio"]
            ax = next(a for a in spec.axes if a.name == "kappa_ratio")
            fld = (
                f"{w}.values"
                if ax.values is not None
                else (f"{w}.stop" if ax.stop >= ax.start else f"{w}.start")
            )
        elif "ba" in where:
            fld = "fixed.kappa_ratio"
        else:
            fld = "fixed.kappa_ratio"
        raise SpecError(fld, f"kappa = {kr:g}*({ba:g}-1) exceeds 1e6", valid)


#: Expected seconds of work per point, for the default chunk size, measured on the
#: compiled batch kernel on one core of the development machine: a finite critical size
#: by the separatrix method 60-130 us on average (3000 random points over
#: kappa/kappa_crit 1.01-5, eps 0-0.6, b/a 1.2-20: 126 us at load 8; up to ~400 us next
#: to kappa_crit); negative sizes are classified one by one, ~100 us; a point decided in
#: closed form ~0.2 us of kernel plus ~0.1 us of parameters, encoding and storage.
_COST_S = {"critical": 1e-4, "classify": 1e-4, "closed_form": 3e-7}
#: Points of the spec whose kind :func:`cost_per_point` looks at (seeded, spread over
#: the whole sweep): the estimated fraction of separatrix points is within ~1.5 % (one
#: standard deviation of a binomial fraction at this size).
_COST_SAMPLE = 4096
#: Default chunking splits a sweep into at least this many chunks (parallel workers) ...
_MIN_CHUNKS = 8
#: ... and large sweeps into at least 64 chunks, so that chunks of unequal cost (parts of
#: a grid where the separatrix is slow) balance over the workers, unless a chunk would
#: then hold less than this much work [s]: below it the fixed cost of a chunk (two
#: transactions, a broker message, ~10-30 ms) would no longer be small against its work.
_MIN_CHUNK_S = 0.5
#: Largest chunk (points): bounds a chunk's memory (~60 bytes a point while it is
#: computed) and lost work.
MAX_CHUNK = 1_000_000


def cost_per_point(spec: SweepSpec) -> float:
    """Estimated seconds of work per point of ``spec`` [s], from the kinds of a sample of
    its points: a point with kappa_crit < kappa < kappa_crit/eps and v_o > 0 needs the
    separatrix (``_COST_S["critical"]``), the others are decided in closed form
    (kappa < kappa_crit: zero; eps kappa >= kappa_crit: infinite; v_o = 0: L*).  An
    outcome sweep with negative sizes costs ``_COST_S["classify"]`` a point.  An
    estimate for sizing chunks, not a promise (the separatrix cost varies 50x)."""
    if spec.output == "outcome" and _negative_sizes(spec):
        return _COST_S["classify"]
    n = spec.n_total
    if n <= _COST_SAMPLE:
        flat = np.arange(n, dtype=np.int64)
    else:
        flat = np.sort(np.random.default_rng(0).integers(0, n, _COST_SAMPLE, dtype=np.int64))
    p = spec.params_at(flat)
    ba, kappa, eps, vo = p["ba"], p["kappa"], p["eps"], p["vo"]
    assert ba is not None and kappa is not None and eps is not None and vo is not None
    kc = ba - 1.0  # kappa_crit
    hard = float(np.mean((vo > 0) & (kappa >= kc) & (eps * kappa < kc)))
    return hard * _COST_S["critical"] + (1.0 - hard) * _COST_S["closed_form"]


def _largest_divisor(n: int, most: int) -> int:
    """The largest divisor of ``n`` that is at most ``most`` (0 if none)."""
    best = 0
    for d in range(1, math.isqrt(n) + 1):
        if n % d == 0:
            for c in (d, n // d):
                if c <= most:
                    best = max(best, c)
    return best


def aligned_chunk(shape: tuple[int, ...], k: int) -> int:
    """The largest chunk size of at most ``k`` points that is whole rows of the trailing
    axes of a grid of ``shape`` (m * n_{j+1} ... n_{N-1} points, with m dividing n_j, or
    any m for the first axis), so that each stored block is one Zarr chunk
    (:func:`rsfapp.sweepzarr.chunk_shape`) and a chunk request reads one block; ``k``
    itself if no such size reaches k/2."""
    best = 0
    for j, nj in enumerate(shape):
        tail = int(np.prod(shape[j + 1 :], dtype=np.int64))
        if tail > k:
            continue
        m_max = min(nj, k // tail)
        if j == 0:
            m = m_max
        else:
            m = _largest_divisor(nj, m_max)
        best = max(best, m * tail)
    return best if 2 * best >= k else k


def _negative_sizes(spec: SweepSpec) -> bool:
    """True when some point has a negative size (classified one by one: slower)."""
    if (spec.fixed.get("size") or 0.0) < 0:
        return True
    for name in ("size", *SI_SIZE_FIELDS):
        if spec.mode == "grid":
            ax = next((a for a in spec.axes if a.name == name), None)
            if ax is None:
                continue
            lo = min(ax.values) if ax.values is not None else min(ax.start, ax.stop)
        elif spec.points is not None and name in spec.points:
            lo = float(spec.points[name].min())
        else:
            continue
        if name != "size":  # the SI statement's smallest value, converted
            phys = spec.physical_inputs()
            assert phys is not None
            lo = float(si_to_size(phys, spec.perturbation, name, np.array([lo]))[0])
        return lo < 0
    return False


def plan_chunks(spec: SweepSpec, settings: Settings, requested: int | None = None) -> int:
    """Points per chunk: ``requested``, else about ``settings.chunk_seconds`` of work at
    the estimated cost per point (:func:`cost_per_point`: a sweep of points decided in
    closed form gets chunks of up to MAX_CHUNK points, one of separatrix points ~2 x 10^4),
    with at least _MIN_CHUNKS chunks, at least 64 chunks unless that leaves less than
    _MIN_CHUNK_S of work in one, whole rows of the grid's trailing axes
    (:func:`aligned_chunk`), and at most ``settings.sweep_max_chunks`` chunks."""
    n = spec.n_total
    max_chunks = getattr(settings, "sweep_max_chunks", 100_000)
    least = max(-(-n // max_chunks), 1)
    if requested:
        return max(min(requested, MAX_CHUNK), least)
    per = cost_per_point(spec)
    chunk = max(
        1,
        min(
            int(settings.chunk_seconds / per),
            -(-n // _MIN_CHUNKS),
            max(-(-n // 64), int(_MIN_CHUNK_S / per)),
        ),
    )
    chunk = min(chunk, MAX_CHUNK)
    if spec.mode == "grid":
        chunk = aligned_chunk(spec.shape, chunk)
    return max(chunk, least)
