"""Subsets of a sweep and reading them in bounded memory.

A :class:`Selection` picks, on every dimension of a sweep (the grid axes, or ``point`` for
scattered sweeps), a sorted set of indices, and a list of variables.  Query syntax (the
``sel``, ``isel`` and ``variables`` parameters of the data endpoints; comma-separated
items, an axis at most once):

* ``sel=<axis>:<value>``: the grid value nearest to ``value`` (the axis stays, length 1);
* ``sel=<axis>:<lo>:<hi>``: every value v with lo <= v <= hi (in either order);
* ``isel=<axis>:<i>``: index i (0-based; negative counts from the end; length 1);
* ``isel=<axis>:<start>:<stop>[:<step>]``: indices start, start+step, ... < stop
  (Python slice; start or stop may be empty);
* ``variables=critical_size,kind``: only these result variables (default: all).

Examples: ``?sel=eps:0.1:0.5&isel=vo:3``, ``?isel=point:0:1000``.  An empty selection,
an unknown axis or variable, or a malformed item is a :class:`rsfapp.grid.SpecError`
naming ``sel``, ``isel`` or ``variables`` (422 over HTTP).

:func:`slabs` cuts a selection into hyper-rectangular pieces of at most ``max_points``
points in flat-index order, and :class:`BlockReader` gathers the stored results of any
sorted set of flat indices, decoding each stored block once (the last one is kept), so a
download of any size holds one slab and one block at a time.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from typing import Any, NamedTuple

import numpy as np
from numpy.typing import NDArray

from .grid import SpecError, SweepSpec
from .store.sweeps import SweepStore

__all__ = [
    "FILL",
    "RESULT_VARIABLES",
    "SLAB_POINTS",
    "BlockReader",
    "Gathered",
    "Selection",
    "Slab",
    "parse_selection",
    "slabs",
    "thinned",
]

#: Result variables of every point, in file order; ``computed`` says the point's chunk
#: is stored.
RESULT_VARIABLES: tuple[str, ...] = (
    "critical_size",
    "kind",
    "outcome",
    "rel_accuracy",
    "failed",
    "method",
    "outcome_uncertain",
    "computed",
)
#: Value of a variable at a point not computed yet (and, for kind/outcome/method, at a
#: failed point): (dtype, fill value).
FILL: dict[str, tuple[Any, Any]] = {
    "critical_size": (np.float64, math.nan),
    "kind": (np.int8, -1),
    "outcome": (np.int8, -1),
    "rel_accuracy": (np.float64, math.nan),
    "failed": (np.int8, 0),
    "method": (np.int8, -1),
    "outcome_uncertain": (np.int8, 0),
    "computed": (np.int8, 0),
}
#: Points per slab read at once (~0.5 M: about 10 MB of result arrays).
SLAB_POINTS = 1 << 19

I64 = NDArray[np.int64]


@dataclass(frozen=True)
class Selection:
    """Sorted indices per dimension (``dims`` order) and the variables asked for."""

    dims: tuple[str, ...]
    index: tuple[I64, ...]
    variables: tuple[str, ...]
    full_shape: tuple[int, ...]

    @property
    def shape(self) -> tuple[int, ...]:
        """Shape of the selected block of the sweep."""
        return tuple(len(i) for i in self.index)

    @property
    def n(self) -> int:
        """Number of selected points."""
        return int(np.prod(self.shape, dtype=np.int64))

    @property
    def is_full(self) -> bool:
        """True when every point is selected."""
        return self.shape == self.full_shape

    def coords(self, spec: SweepSpec) -> dict[str, NDArray[Any]]:
        """Selected coordinate values per dimension (``point``: the flat indices)."""
        if spec.mode == "grid":
            return {a.name: a.at(k) for a, k in zip(spec.axes, self.index, strict=True)}
        return {"point": self.index[0]}

    def to_json(self) -> dict[str, Any]:
        """{dim: [first, last, count]} of the selection (for headers and attributes)."""
        return {
            d: [int(i[0]), int(i[-1]), len(i)] for d, i in zip(self.dims, self.index, strict=True)
        }


def _items(text: str | Sequence[str] | None) -> list[str]:
    if text is None:
        return []
    parts = [text] if isinstance(text, str) else list(text)
    return [p.strip() for t in parts for p in t.split(",") if p.strip()]


def _num(field: str, s: str) -> float:
    try:
        x = float(s)
    except ValueError:
        raise SpecError(field, f"{s!r} is not a number", "a finite number") from None
    if not math.isfinite(x):
        raise SpecError(field, f"{s!r} is not finite", "a finite number")
    return x


def _int(field: str, s: str) -> int | None:
    if s.strip() == "":
        return None
    try:
        return int(s)
    except ValueError:
        raise SpecError(field, f"{s!r} is not an integer", "an integer index") from None


def parse_selection(
    spec: SweepSpec,
    sel: str | Sequence[str] | None = None,
    isel: str | Sequence[str] | None = None,
    variables: str | Sequence[str] | None = None,
    allowed: Sequence[str] = RESULT_VARIABLES,
) -> Selection:
    """The :class:`Selection` of the query texts (module docstring); raises SpecError
    naming ``sel``, ``isel`` or ``variables``."""
    if spec.mode == "grid":
        dims = tuple(a.name for a in spec.axes)
        values = {a.name: a.all for a in spec.axes}
    else:
        dims = ("point",)
        values = {"point": lambda: np.arange(spec.n_total, dtype=np.float64)}
    shape = spec.shape
    index: dict[str, I64] = {}
    valid_dims = "one of " + ", ".join(dims)
    for field, items in (("sel", _items(sel)), ("isel", _items(isel))):
        for item in items:
            name, _, rest = item.partition(":")
            name = name.strip()
            if name not in dims or not rest:
                raise SpecError(
                    field,
                    f"{item!r} is not <dimension>:<{'value' if field == 'sel' else 'index'}...>",
                    f"comma-separated items <dimension>:... with dimension {valid_dims}",
                )
            if name in index:
                raise SpecError(field, f"dimension {name} selected twice", "each dimension once")
            n = shape[dims.index(name)]
            parts = rest.split(":")
            if field == "sel":
                vals = values[name]()
                if len(parts) == 1:
                    x = _num(field, parts[0])
                    k: I64 = np.array([int(np.argmin(np.abs(vals - x)))], dtype=np.int64)
                elif len(parts) == 2:
                    lo, hi = sorted((_num(field, parts[0]), _num(field, parts[1])))
                    k = np.flatnonzero((vals >= lo) & (vals <= hi)).astype(np.int64)
                else:
                    raise SpecError(
                        field, f"{item!r}: too many ':'", "<dim>:<v> or <dim>:<lo>:<hi>"
                    )
            else:
                if len(parts) == 1:
                    i = _int(field, parts[0])
                    if i is None or not -n <= i < n:
                        raise SpecError(
                            field, f"{item!r}: index out of range", f"an index in [-{n}, {n})"
                        )
                    k = np.array([i % n], dtype=np.int64)
                elif len(parts) <= 3:
                    a, b = _int(field, parts[0]), _int(field, parts[1])
                    step = _int(field, parts[2]) if len(parts) == 3 else None
                    if step is not None and step < 1:
                        raise SpecError(field, f"{item!r}: step {step}", "a step >= 1")
                    k = np.arange(n, dtype=np.int64)[slice(a, b, step)]
                else:
                    raise SpecError(
                        field,
                        f"{item!r}: too many ':'",
                        "<dim>:<i> or <dim>:<start>:<stop>[:<step>]",
                    )
            if k.size == 0:
                raise SpecError(field, f"{item!r} selects nothing", "a non-empty selection")
            index[name] = k
    names = _items(variables)
    for v in names:
        if v not in allowed:
            raise SpecError("variables", f"unknown variable {v!r}", "any of " + ", ".join(allowed))
    chosen = tuple(v for v in allowed if v in names) if names else tuple(allowed)
    full = tuple(
        index.get(d, np.arange(n, dtype=np.int64)) for d, n in zip(dims, shape, strict=True)
    )
    return Selection(dims, full, chosen, tuple(shape))


def thinned(
    selection: Selection, dims: Sequence[str], most: int
) -> tuple[Selection, dict[str, int]] | None:
    """Every k-th selected index of each dimension in ``dims`` that has more than
    ``most`` (k = ceil(count / most), from the first), so that each keeps at most
    ``most``; with {dim: k} of the thinned ones.  None if no dimension needs it."""
    steps = {
        d: -(-len(i) // most)
        for d, i in zip(selection.dims, selection.index, strict=True)
        if d in dims and len(i) > most
    }
    if not steps:
        return None
    index = tuple(
        i[:: steps.get(d, 1)] for d, i in zip(selection.dims, selection.index, strict=True)
    )
    return dataclasses.replace(selection, index=index), steps


class Slab(NamedTuple):
    """A hyper-rectangular piece of a selection: where it goes in the selected block
    (``out``: one slice per dimension), its shape and its flat sweep indices (sorted,
    C order of ``shape``)."""

    out: tuple[slice, ...]
    shape: tuple[int, ...]
    flat: I64


def slabs(selection: Selection, max_points: int | None = None) -> Iterator[Slab]:
    """The selection in slabs of at most ``max_points`` points (default
    :data:`SLAB_POINTS`), in flat-index order."""
    if max_points is None:
        max_points = SLAB_POINTS
    shape = selection.shape
    nd = len(shape)
    strides = [int(np.prod(selection.full_shape[k + 1 :], dtype=np.int64)) for k in range(nd)]
    tails = [int(np.prod(shape[k + 1 :], dtype=np.int64)) for k in range(nd)]
    j = next(k for k in range(nd) if tails[k] <= max_points)
    m = max(1, max_points // tails[j])
    m = -(-shape[j] // -(-shape[j] // m))  # as many pieces, of equal length: no short edge
    # flat offsets of the trailing full block (dimensions after j), C order
    trail = np.zeros(1, dtype=np.int64)
    for k in range(j + 1, nd):
        trail = (trail[:, None] + selection.index[k][None, :] * strides[k]).reshape(-1)
    for lead in np.ndindex(*shape[:j]):
        base = sum(int(selection.index[k][lead[k]]) * strides[k] for k in range(j))
        for a in range(0, shape[j], m):
            b = min(shape[j], a + m)
            col = selection.index[j][a:b] * strides[j]
            flat = (base + col[:, None] + trail[None, :]).reshape(-1)
            out = tuple(slice(i, i + 1) for i in lead) + (slice(a, b),)
            out += tuple(slice(0, shape[k]) for k in range(j + 1, nd))
            yield Slab(out, (1,) * j + (b - a,) + tuple(shape[j + 1 :]), flat)


class Gathered(NamedTuple):
    """Results at a set of flat indices: {variable: array} (fill values where not
    computed) and {position in the set: message} of failed points."""

    arrays: dict[str, NDArray[Any]]
    errors: dict[int, str]


class BlockReader:
    """Reads a sweep's stored results at any sorted flat indices, one block at a time.

    The block index (chunk number and [i0, i1) of every stored block, or of those
    overlapping ``span`` = [first, end) flat index) is read once; a
    block is decoded when first needed (only the variables asked for) and the last one
    is kept, so reading slabs in flat order decodes every block about once."""

    def __init__(
        self, store: SweepStore, sweep_id: str, span: tuple[int, int] | None = None
    ) -> None:
        self.store, self.sweep_id = store, sweep_id
        lo, hi = span if span is not None else (0, None)
        self.idx, self.i0, self.i1 = store.block_index(sweep_id, lo, hi)
        self._key: tuple[int, tuple[str, ...]] | None = None
        self._block: tuple[dict[str, NDArray[Any]], dict[int, str]] | None = None

    def _load(
        self, b: int, names: tuple[str, ...]
    ) -> tuple[dict[str, NDArray[Any]], dict[int, str]] | None:
        key = (int(self.idx[b]), names)
        if self._key != key:
            blk = self.store.read_block(self.sweep_id, int(self.idx[b]), names)
            if blk is None:  # purged meanwhile
                return None
            self._key, self._block = key, (blk.arrays, blk.errors)
        return self._block

    def gather(self, flat: I64, variables: Sequence[str], errors: bool = False) -> Gathered:
        """``variables`` (of :data:`RESULT_VARIABLES`) at the sorted flat indices
        ``flat``; with ``errors`` also the messages of failed points."""
        # filled block by block, the fill value only where no block is (no full pass)
        out = {v: np.empty(flat.size, dtype=FILL[v][0]) for v in variables}
        errs: dict[int, str] = {}
        done = 0  # out[:done] is set
        stored = tuple(v for v in variables if v != "computed")
        lo = int(np.searchsorted(self.i1, flat[0], side="right")) if flat.size else 0
        hi = int(np.searchsorted(self.i0, flat[-1], side="right")) if flat.size else 0
        for b in range(lo, hi):
            p0 = int(np.searchsorted(flat, self.i0[b], side="left"))
            p1 = int(np.searchsorted(flat, self.i1[b], side="left"))
            if p1 <= p0:
                continue
            blk = self._load(b, stored)
            if blk is None:
                break
            for v in variables:  # points between the blocks: not computed
                out[v][done:p0] = FILL[v][1]
            arrays, msgs = blk
            off = flat[p0:p1] - int(self.i0[b])
            contiguous = int(off[-1]) - int(off[0]) + 1 == off.size
            take: Any = slice(int(off[0]), int(off[-1]) + 1) if contiguous else off
            for v in stored:
                out[v][p0:p1] = arrays[v][take] if v in arrays else FILL[v][1]
            if "computed" in out:
                out["computed"][p0:p1] = 1
            done = p1
            if errors and msgs:  # few: one search each
                for o, m in msgs.items():
                    k = int(np.searchsorted(off, o))
                    if k < off.size and int(off[k]) == o:
                        errs[p0 + k] = m
        for v in variables:
            out[v][done:] = FILL[v][1]
        return Gathered(out, errs)
