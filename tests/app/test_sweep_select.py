"""rsfapp.sweepselect: selections parsed from query text, slabs that tile a selection in
flat order, and gathering stored blocks at any flat indices (checked against numpy's own
indexing of a fully assembled array, not against the code under test)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from rsfapp.db.engine import Database
from rsfapp.grid import Axis, SpecError, SweepSpec
from rsfapp.store.sweeps import SweepStore, encode_block
from rsfapp.sweepselect import BlockReader, parse_selection, slabs, thinned


def grid3() -> SweepSpec:
    return SweepSpec(
        "grid",
        [
            Axis("ba", 3, (2.0, 3.0, 4.0)),
            Axis("eps", 5, None, 0.0, 0.8),
            Axis("vo", 7, None, 0.5, 2.0),
        ],
        None,
        {"kappa_ratio": 0.5},
        "kappa_ratio",
        "velocity-jump",
        1e-10,
        "critical",
    )


def test_parse_selection_by_value_and_index() -> None:
    spec = grid3()
    s = parse_selection(spec, "eps:0.15:0.45,ba:2.9", "vo:1:6:2")
    assert s.dims == ("ba", "eps", "vo")
    assert [i.tolist() for i in s.index] == [[1], [1, 2], [1, 3, 5]]
    assert s.shape == (1, 2, 3) and s.n == 6 and not s.is_full
    assert s.variables[0] == "critical_size" and "computed" in s.variables
    s = parse_selection(spec, None, "vo:-1", "kind,critical_size")
    assert s.index[2].tolist() == [6] and s.variables == ("critical_size", "kind")
    assert parse_selection(spec).is_full


@pytest.mark.parametrize(
    ("sel", "isel", "variables", "field"),
    [
        ("nope:1", None, None, "sel"),
        ("eps:x", None, None, "sel"),
        ("eps:5:6", None, None, "sel"),  # nothing in range
        (None, "vo:7", None, "isel"),
        (None, "vo:3:3", None, "isel"),
        (None, "vo:0:5:0", None, "isel"),
        ("vo:1", "vo:1", None, "isel"),
        (None, None, "critical_size,bogus", "variables"),
        ("eps:1:2:3", None, None, "sel"),
    ],
)
def test_bad_selections_name_the_field(
    sel: str | None, isel: str | None, variables: str | None, field: str
) -> None:
    with pytest.raises(SpecError) as e:
        parse_selection(grid3(), sel, isel, variables)
    assert e.value.field == field


@pytest.mark.parametrize("max_points", [1, 2, 5, 6, 7, 20, 10**6])
def test_slabs_tile_the_selection_in_flat_order(max_points: int) -> None:
    spec = grid3()
    for sel, isel in [(None, None), ("eps:0.15:0.8", "vo:1:6:2"), (None, "ba:1,vo:3")]:
        s = parse_selection(spec, sel, isel)
        want = np.ravel_multi_index(np.meshgrid(*s.index, indexing="ij"), spec.shape).ravel()
        got = np.full(s.shape, -1)
        flat = []
        for slab in slabs(s, max_points):
            assert slab.flat.size <= max(max_points, s.shape[-1])
            got[slab.out] = slab.flat.reshape(slab.shape)
            flat.append(slab.flat)
        assert np.array_equal(np.concatenate(flat), want)
        assert np.array_equal(got.ravel(), want)


def test_gather_equals_numpy_indexing(tmp_path: Path) -> None:
    """Blocks of uneven sizes with a gap (a chunk not stored yet): gathering any sorted
    index set gives the assembled array at those indices and fill values in the gap."""
    db = Database(f"sqlite:///{tmp_path / 's.sqlite3'}")
    st = SweepStore(db)
    spec = grid3()
    n = spec.n_total
    st.create("s", spec, 10, "t")
    rng = np.random.default_rng(3)
    full = rng.random(n)
    kind = rng.integers(0, 3, n).astype(np.int8)
    edges = [(0, 10), (10, 20), (30, 40), (40, 50), (50, 60), (60, 70), (70, 80), (80, 90)]
    edges += [(90, 100), (100, n)]
    stored = np.zeros(n, bool)
    for k, (a, b) in enumerate(edges):
        arrays = {"critical_size": full[a:b], "kind": kind[a:b], "failed": np.zeros(b - a, bool)}
        errs = {1: f"E{a + 1}"} if k % 3 == 0 else {}
        st.store_block("s", a // 10 if a < 100 else 10, a, b, encode_block(arrays), errs)
        stored[a:b] = True
    r = BlockReader(st, "s")
    for flat in [
        np.arange(n),
        np.arange(15, 35),
        np.array([0, 1, 11, 25, 31, 99, 100, n - 1]),
        np.arange(0, n, 7),
    ]:
        g = r.gather(flat, ("critical_size", "kind", "computed", "outcome"), errors=True)
        ok = stored[flat]
        assert np.array_equal(g.arrays["computed"], ok.astype(np.int8))
        assert np.array_equal(g.arrays["critical_size"][ok], full[flat][ok])
        assert np.isnan(g.arrays["critical_size"][~ok]).all()
        assert np.array_equal(g.arrays["kind"], np.where(ok, kind[flat], -1))
        assert (g.arrays["outcome"] == -1).all()  # not stored in these blocks
        want_err = {
            p: f"E{int(i)}"
            for p, i in enumerate(flat)
            if any(a + 1 == i and k % 3 == 0 for k, (a, _) in enumerate(edges))
        }
        assert g.errors == want_err
    db.dispose()


def test_zarr_chunk_shape_follows_blocks() -> None:
    from rsfapp.sweepzarr import chunk_shape

    assert chunk_shape((3, 4, 6), 12) == (1, 2, 6)  # two rows: one block per chunk
    assert chunk_shape((3, 4, 6), 24) == (1, 4, 6)
    assert chunk_shape((3, 4, 6), 48) == (2, 4, 6)  # leading axis: any m
    assert chunk_shape((10, 10), 30) == (3, 10)
    assert chunk_shape((3, 4, 6), 3) == (1, 1, 3)
    assert chunk_shape((4, 10), 25) == (2, 10)  # no exact fit: rows of at most 25
    assert chunk_shape((1000,), 10**6) == (1000,)


def test_swept_values_gather_equals_at() -> None:
    """SweepSpec.swept_values gathers each short axis's values once: bit-equal to
    Axis.at at every point (linear, geometric and explicit axes, ranges of any length)."""
    spec = SweepSpec(
        "grid",
        [
            Axis("ba", 3, (2.0, 3.0, 4.0)),
            Axis("eps", 7, None, 0.013, 0.77),
            Axis("vo", 11, None, 1e-3, 17.0, True),
        ],
        None,
        {"kappa_ratio": 0.5},
        "kappa_ratio",
        "velocity-jump",
        1e-10,
        "critical",
    )
    for i0, i1 in [(0, spec.n_total), (5, 9), (100, 231), (0, 2)]:
        got = spec.swept_values(i0, i1)
        multi = np.unravel_index(np.arange(i0, i1), spec.shape)
        for ax, k in zip(spec.axes, multi, strict=True):
            assert np.array_equal(got[ax.name], ax.at(np.asarray(k, dtype=np.int64))), ax.name


def test_thinned_keeps_every_kth_index_of_long_dimensions() -> None:
    spec = SweepSpec(
        "grid",
        [Axis("eps", 10, None, 0.0, 0.9), Axis("vo", 2501, None, 0.5, 2.0)],
        None,
        {"ba": 2.0, "kappa_ratio": 0.5},
        "kappa_ratio",
        "velocity-jump",
        1e-10,
        "critical",
    )
    full = parse_selection(spec)
    t = thinned(full, ["eps", "vo"], 1000)
    assert t is not None
    sel, steps = t
    assert steps == {"vo": 3}  # ceil(2501 / 1000); eps (10) untouched
    assert sel.shape == (10, 834) and sel.index[1][-1] == 2499
    np.testing.assert_array_equal(sel.index[1], np.arange(0, 2501, 3))
    assert thinned(full, ["eps"], 1000) is None  # nothing to thin
    # a window is thinned within itself
    win = parse_selection(spec, isel="vo:100:2100")
    t2 = thinned(win, ["vo"], 1000)
    assert t2 is not None
    sel2, steps2 = t2
    assert steps2 == {"vo": 2} and sel2.index[1][0] == 100 and sel2.index[1][-1] == 2098
