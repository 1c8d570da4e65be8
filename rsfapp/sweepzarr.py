"""A sweep as a read-only Zarr (format 2) store: keys and their bytes, for lazy access
from xarray over HTTP (``GET /v1/sweeps/{id}/zarr/{key}``).

Layout: a group with consolidated metadata (``.zmetadata``, so opening the store is one
request), one 1-D array per dimension (the grid axes, or ``point``), one N-D array per
result variable (:data:`rsfapp.sweepselect.RESULT_VARIABLES`) and, for scattered sweeps,
the swept parameters along ``point``.  Attributes are the CF ones of the NetCDF file
(:mod:`rsfapp.sweepcf`), with ``_ARRAY_DIMENSIONS`` naming the dimensions as xarray
expects.

Chunks follow the stored blocks: when the sweep's chunk size K is m rows of the trailing
axes (K = m * n_{j+1} ... n_{N-1}, with m dividing n_j, or j = 0), the Zarr chunk is
(1, ..., 1, m, n_{j+1}, ..., n_{N-1}) and a chunk request reads exactly one block; else
the largest row-aligned shape of at most K points (a chunk then reads at most two
blocks).  A chunk is zlib-compressed C-order bytes; points not computed yet (a running
sweep) carry the array's fill value (NaN, or -1 for kind/outcome/method), so xarray shows
them as missing.
"""

from __future__ import annotations

import json
import math
import zlib
from typing import Any

import numpy as np
from numpy.typing import NDArray

from .grid import SweepSpec
from .store.sweeps import SweepStore
from .sweepselect import FILL, RESULT_VARIABLES, BlockReader, Selection

__all__ = ["ZarrSweep", "chunk_shape"]

#: Variables whose fill value marks a missing point (decoded as NaN by xarray); the 0/1
#: flags have none (0 is a value).
_MASKED = ("critical_size", "rel_accuracy", "kind", "outcome", "method")


def chunk_shape(shape: tuple[int, ...], k: int) -> tuple[int, ...]:
    """Zarr chunk shape of a grid of ``shape`` whose blocks hold ``k`` consecutive flat
    points (module docstring): one block per chunk where possible."""
    nd = len(shape)
    for j in range(nd):
        tail = int(np.prod(shape[j + 1 :], dtype=np.int64))
        if k % tail == 0:
            m = k // tail
            if 1 <= m <= shape[j] and (j == 0 or shape[j] % m == 0):
                return (1,) * j + (m,) + tuple(shape[j + 1 :])
    for j in range(nd):  # fallback: rows of the trailing axes, at most k points
        tail = int(np.prod(shape[j + 1 :], dtype=np.int64))
        if tail <= k:
            return (1,) * j + (max(1, min(shape[j], k // tail)),) + tuple(shape[j + 1 :])
    return (1,) * (nd - 1) + (max(1, min(shape[-1], k)),)


def _dtype_str(dt: Any) -> str:
    return str(np.dtype(dt).str)


def _jsonable(attrs: dict[str, Any]) -> dict[str, Any]:
    out: dict[str, Any] = {}
    for k, v in attrs.items():
        if isinstance(v, np.ndarray):
            v = v.tolist()
        elif isinstance(v, np.generic):
            v = v.item()
        if isinstance(v, float) and not math.isfinite(v):
            v = str(v)
        out[k] = v
    return out


class ZarrSweep:
    """The Zarr keys of one sweep (metadata built once; chunks read on request)."""

    def __init__(
        self, store: SweepStore, spec: SweepSpec, status: dict[str, Any], block_points: int
    ) -> None:
        from .sweepcf import coordinate_attrs, global_attrs, variable_attrs

        self.store, self.spec, self.status = store, spec, status
        self.sweep_id = str(status["id"])
        self.shape = spec.shape
        self.dims = tuple(a.name for a in spec.axes) if spec.mode == "grid" else ("point",)
        self.chunks = chunk_shape(self.shape, max(1, block_points))
        meta: dict[str, Any] = {".zgroup": {"zarr_format": 2}}
        meta[".zattrs"] = _jsonable(
            global_attrs(
                spec,
                status,
                None,
                f"served as Zarr by GET /v1/sweeps/{self.sweep_id}/zarr",
                when=str(status.get("created_at") or ""),  # stable across requests
            )
        )
        self.coords: dict[str, NDArray[Any]] = {}
        if spec.mode == "grid":
            for a in spec.axes:
                self.coords[a.name] = a.all()
        else:
            self.coords["point"] = np.arange(spec.n_total, dtype=np.int64)
            assert spec.points is not None
            for name, vals in spec.points.items():
                self.coords[name] = np.asarray(vals, dtype=np.float64)
        for name, vals in self.coords.items():
            dim = name if spec.mode == "grid" or name == "point" else "point"
            meta[f"{name}/.zarray"] = self._zarray(vals.shape, vals.shape, vals.dtype, None)
            meta[f"{name}/.zattrs"] = {"_ARRAY_DIMENSIONS": [dim], **coordinate_attrs(name)}
        vattrs = variable_attrs(spec)
        for v in RESULT_VARIABLES:
            dt, fill = FILL[v]
            meta[f"{v}/.zarray"] = self._zarray(
                self.shape, self.chunks, dt, fill if v in _MASKED else None, compress=True
            )
            meta[f"{v}/.zattrs"] = {"_ARRAY_DIMENSIONS": list(self.dims), **_jsonable(vattrs[v])}
        self.meta = meta

    @staticmethod
    def _zarray(
        shape: tuple[int, ...],
        chunks: tuple[int, ...],
        dtype: Any,
        fill: Any,
        compress: bool = False,
    ) -> dict[str, Any]:
        if isinstance(fill, float) and math.isnan(fill):
            fill = "NaN"
        return {
            "zarr_format": 2,
            "shape": list(shape),
            "chunks": list(chunks),
            "dtype": _dtype_str(dtype),
            "compressor": {"id": "zlib", "level": 1} if compress else None,
            "fill_value": fill,
            "order": "C",
            "filters": None,
            "dimension_separator": ".",
        }

    def consolidated(self) -> bytes:
        """``.zmetadata``: every metadata key in one document."""
        return json.dumps({"zarr_consolidated_format": 1, "metadata": self.meta}).encode()

    def get(self, key: str) -> bytes | None:
        """The bytes of ``key``, or None if the store has no such key."""
        if key == ".zmetadata":
            return self.consolidated()
        if key in self.meta:
            return json.dumps(self.meta[key]).encode()
        name, _, ck = key.rpartition("/")
        if name in self.coords:
            if ck != "0":
                return None
            return np.ascontiguousarray(self.coords[name]).tobytes()
        if name in RESULT_VARIABLES:
            return self._chunk(name, ck)
        return None

    def _chunk(self, name: str, ck: str) -> bytes | None:
        try:
            pos = tuple(int(p) for p in ck.split("."))
        except ValueError:
            return None
        if len(pos) != len(self.shape):
            return None
        index = []
        for p, c, n in zip(pos, self.chunks, self.shape, strict=True):
            if p < 0 or p * c >= n:
                return None
            index.append(np.arange(p * c, min(n, (p + 1) * c), dtype=np.int64))
        sel = Selection(self.dims, tuple(index), (name,), self.shape)
        strides = [
            int(np.prod(self.shape[k + 1 :], dtype=np.int64)) for k in range(len(self.shape))
        ]
        flat = np.zeros(1, dtype=np.int64)
        for k, idx in enumerate(sel.index):
            flat = (flat[:, None] + idx[None, :] * strides[k]).reshape(-1)
        span = (int(flat[0]), int(flat[-1]) + 1)
        g = BlockReader(self.store, self.sweep_id, span).gather(flat, (name,))
        dt, fill = FILL[name]
        out = np.full(self.chunks, fill, dtype=dt)  # edge chunks are padded
        out[tuple(slice(0, len(i)) for i in sel.index)] = g.arrays[name].reshape(sel.shape)
        return zlib.compress(np.ascontiguousarray(out).tobytes(), 1)
