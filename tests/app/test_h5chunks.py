"""rsfapp.h5chunks makes the bytes HDF5's own filter pipeline makes (shuffle, then
deflate level 1): every chunk written both ways is compared byte for byte with
``read_direct_chunk`` (the referee is libhdf5's filters), then read back through h5py's
decoding; edge chunks are padded with the fill value; a chunk of one repeated value is
compressed once."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest

h5py = pytest.importorskip("h5py")

from rsfapp import h5chunks  # noqa: E402


def _data(dtype: Any, shape: tuple[int, ...], seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    if np.dtype(dtype).kind == "f":
        a = rng.standard_normal(shape)
        a.reshape(-1)[::7] = np.nan
        a.reshape(-1)[::11] = np.inf
        return a.astype(dtype)
    return rng.integers(-1, 3, shape).astype(dtype)


@pytest.mark.parametrize("dtype", [np.float64, np.int8, np.int64, np.float32])
def test_chunks_equal_hdf5_filter_pipeline(tmp_path: Path, dtype: Any) -> None:
    shape, chunks = (3, 10, 7), (1, 4, 7)  # the last chunk along axis 1 is an edge (2 rows)
    fill = -1 if np.dtype(dtype).kind == "i" else np.nan
    values = _data(dtype, shape, 1)
    values[1] = values[1, 0, 0]  # a whole slab of one repeated value
    kw = dict(chunks=chunks, compression="gzip", compression_opts=h5chunks.LEVEL, shuffle=True)
    with h5py.File(tmp_path / "f.h5", "w") as f:
        ref = f.create_dataset("ref", shape, dtype, fillvalue=fill, **kw)
        ref[...] = values
        mine = f.create_dataset("mine", shape, dtype, fillvalue=fill, **kw)
        w = h5chunks.ChunkWriter(mine, fill)
        for i in range(shape[0]):
            for j0 in range(0, shape[1], chunks[1]):
                w.write((i, j0, 0), values[i : i + 1, j0 : j0 + chunks[1]])
        np.testing.assert_array_equal(mine[...], values)
        for i in range(shape[0]):
            for j0 in range(0, shape[1], chunks[1]):
                a = ref.id.read_direct_chunk((i, j0, 0))
                b = mine.id.read_direct_chunk((i, j0, 0))
                assert a[0] == b[0] == 0
                assert a[1] == b[1], (i, j0)  # edge chunks too: HDF5 pads with the fill
        # edge chunk: padded with the fill value
        raw = np.frombuffer(
            __import__("zlib").decompress(mine.id.read_direct_chunk((0, 8, 0))[1]), np.uint8
        )
        n, size = int(np.prod(chunks)), np.dtype(dtype).itemsize
        edge = raw.reshape(size, n).T.copy().view(dtype).reshape(chunks)
        np.testing.assert_array_equal(edge[:, :2], values[0:1, 8:10])
        np.testing.assert_array_equal(edge[:, 2:], np.full((1, 2, 7), fill, dtype))


def test_a_repeated_chunk_is_compressed_once(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    calls: list[int] = []
    real = h5chunks.zlib.compress
    monkeypatch.setattr(h5chunks.zlib, "compress", lambda b, lv: calls.append(1) or real(b, lv))
    with h5py.File(tmp_path / "f.h5", "w") as f:
        ds = f.create_dataset(
            "x", (6, 100), np.float64, chunks=(1, 100), compression="gzip", shuffle=True
        )
        w = h5chunks.ChunkWriter(ds, np.nan)
        for i in range(6):
            w.write((i, 0), np.zeros((1, 100)) if i < 5 else np.arange(100.0)[None])
        assert len(calls) == 2  # zeros once, the varied row once
        np.testing.assert_array_equal(ds[:5], 0.0)
        np.testing.assert_array_equal(ds[5], np.arange(100.0))


def test_shuffle_is_bytes_by_position() -> None:
    a = np.array([0x0102030405060708, 0x1112131415161718], dtype="<u8")
    assert h5chunks.shuffle(a) == bytes(
        [8, 0x18, 7, 0x17, 6, 0x16, 5, 0x15, 4, 0x14, 3, 0x13, 2, 0x12, 1, 0x11]
    )
    b = np.array([1, 2, 3], dtype=np.int8)
    assert h5chunks.shuffle(b) == b.tobytes()
