"""rsfapp.grid (specs, lazy flat-index map, chunk plan) and rsfapp.sweepdata.compute_chunk."""

from __future__ import annotations

import numpy as np
import pytest

from rsfapp.config import Settings
from rsfapp.grid import (
    _COST_S,
    MAX_CHUNK,
    Axis,
    SpecError,
    SweepSpec,
    aligned_chunk,
    cost_per_point,
    expand,
    plan_chunks,
)
from rsfapp.requests import SweepRequest
from rsfapp.sweepdata import compute_chunk
from rsfcore import ParameterError, batch, critical
from rsfcore.params import Params


def spec_of(body: dict) -> SweepSpec:
    return expand(SweepRequest.model_validate(body), 10**8, 10**6)


def test_axis_values_exact_end_points_and_spacing() -> None:
    a = Axis("eps", 7, None, 0.1, 0.7)
    v = a.all()
    assert v[0] == 0.1 and v[-1] == 0.7
    np.testing.assert_allclose(np.diff(v), 0.1, rtol=1e-14)  # linear spacing
    g = Axis("kappa_ratio", 5, None, 1.0, 16.0, log=True).all()
    np.testing.assert_allclose(g, [1, 2, 4, 8, 16], rtol=1e-15)
    assert g[-1] == 16.0
    assert Axis("ba", 1, None, 3.0, 3.0).all().tolist() == [3.0]


def test_flat_index_is_c_order_and_matches_outer_product() -> None:
    sp = spec_of(
        {
            "axes": [
                {"name": "ba", "values": [2.0, 3.0]},
                {"name": "eps", "values": [0.1, 0.2, 0.3]},
                {"name": "kappa_ratio", "start": 1.0, "stop": 2.0, "n": 2},
            ]
        }
    )
    assert sp.shape == (2, 3, 2) and sp.n_total == 12
    p = sp.params(0, 12)
    B, E, K = np.meshgrid([2.0, 3.0], [0.1, 0.2, 0.3], [1.0, 2.0], indexing="ij")
    assert p["ba"].tolist() == B.ravel().tolist() and p["eps"].tolist() == E.ravel().tolist()
    assert p["kappa"].tolist() == (K * (B - 1.0)).ravel().tolist()
    assert p["vo"].tolist() == [1.0] * 12 and p["size"] is None
    # a chunk is the same slice of the flat order
    q = sp.params(5, 9)
    assert q["eps"].tolist() == p["eps"][5:9].tolist()


def test_spec_json_round_trip_is_small() -> None:
    sp = spec_of(
        {
            "axes": [
                {"name": n, "start": 0.5, "stop": 0.9, "n": 100}
                for n in ("eps", "kappa_ratio", "vo", "size")
            ]
        }
    )
    d = sp.to_json()
    assert sp.n_total == 10**8 and len(str(d)) < 1000
    back = SweepSpec.from_json(d)
    assert (
        back.to_json() == d
        and back.params(123456, 123460)["size"].tolist()
        == sp.params(123456, 123460)["size"].tolist()
    )


def test_chunk_plan() -> None:
    s = Settings()
    # 10^4 separatrix points (kappa/kappa_crit fixed at its default 2 > 1, eps < 0.5):
    # 8 chunks by the minimum count, cut down to whole rows of 100: 12 rows
    assert (
        plan_chunks(
            spec_of(
                {
                    "axes": [
                        {"name": "eps", "start": 0, "stop": 0.4, "n": 100},
                        {"name": "ba", "start": 2, "stop": 3, "n": 100},
                    ]
                }
            ),
            s,
        )
        == 1200
    )
    # 10^8 points decided in closed form (kappa/kappa_crit < 1): the largest chunks
    cheap = spec_of(
        {
            "axes": [
                {"name": n, "start": 0.5, "stop": 0.9, "n": 100}
                for n in ("eps", "kappa_ratio", "vo", "size")
            ]
        }
    )
    assert plan_chunks(cheap, s) == MAX_CHUNK
    assert plan_chunks(cheap, s, 7) == 1000  # at most sweep_max_chunks chunks
    # the same grid of separatrix points: ~2 s of work a chunk (2 s / 100 us), in rows
    hard = spec_of(
        {
            "axes": [
                {"name": "eps", "start": 0.0, "stop": 0.4, "n": 100},
                {"name": "kappa_ratio", "start": 1.1, "stop": 2.0, "n": 100},
                {"name": "vo", "start": 0.5, "stop": 0.9, "n": 100},
                {"name": "size", "start": 0.5, "stop": 0.9, "n": 100},
            ]
        }
    )
    c = plan_chunks(hard, s)
    assert c == 20_000  # 2 rows of 10^4
    assert 1000 <= -(-(10**8) // c) <= s.sweep_max_chunks


def test_cost_per_point_counts_separatrix_points() -> None:
    """Half the kappa_ratio axis above 1 (and x = eps kappa/kappa_crit < 1): about half
    the points need the separatrix; the sample of 4096 points is within 4 binomial
    standard deviations (0.03) of the exact fraction 1/2."""
    sp = spec_of(
        {
            "axes": [
                {"name": "kappa_ratio", "values": [0.5, 0.9, 1.5, 1.9]},
                {"name": "eps", "start": 0.0, "stop": 0.5, "n": 300},
                {"name": "ba", "start": 2.0, "stop": 3.0, "n": 300},
            ]
        }
    )
    per = cost_per_point(sp)
    cheap, hard = _COST_S["closed_form"], _COST_S["critical"]
    frac = (per - cheap) / (hard - cheap)
    assert abs(frac - 0.5) < 0.03
    closed = spec_of({"axes": [{"name": "kappa_ratio", "start": 0.1, "stop": 0.99, "n": 50}]})
    assert cost_per_point(closed) == cheap
    infinite = spec_of(  # eps kappa >= kappa_crit everywhere: infinite, closed form
        {
            "axes": [{"name": "kappa_ratio", "start": 2.5, "stop": 4.0, "n": 50}],
            "fixed": {"eps": 0.5},
        }
    )
    assert cost_per_point(infinite) == cheap


@pytest.mark.parametrize(
    ("shape", "k", "want"),
    [
        ((100, 100, 100), 66_666, 60_000),  # 6 planes of 100 x 100 (the first axis: any m)
        ((100, 100, 10_000), 1_000_000, 1_000_000),  # one 100 x 10^4 plane
        ((7, 5, 3), 20, 15),  # 5 rows of 3 (5 divides 5)
        ((7, 5, 3), 14, 14),  # no whole rows reach 7 points: unaligned
        ((97,), 50, 50),  # 1-D: any cut is whole rows
        ((3, 1_000_003), 1000, 1000),  # a prime row length: no aligned size >= k/2
    ],
)
def test_aligned_chunk(shape: tuple[int, ...], k: int, want: int) -> None:
    got = aligned_chunk(shape, k)
    assert got == want and got <= k
    if got != k:  # whole rows: every chunk is one Zarr chunk (rsfapp.sweepzarr)
        from rsfapp.sweepzarr import chunk_shape

        assert int(np.prod(chunk_shape(shape, got))) == got


@pytest.mark.parametrize("shape", [(7, 5, 3), (100, 100, 100), (3, 1, 40), (13, 17), (1000,)])
def test_swept_values_equal_the_outer_product_at_any_range(shape: tuple[int, ...]) -> None:
    """The run-length layout of swept_values against unravel_index + Axis.at (the
    definition), bit for bit, at 200 random ranges."""
    names = ("kappa_ratio", "eps", "vo")[: len(shape)]
    sp = spec_of(
        {
            "axes": [
                {"name": nm, "start": 0.1, "stop": 0.9, "n": n, "log": nm == "vo"}
                for nm, n in zip(names, shape, strict=True)
            ]
        }
    )
    rng = np.random.default_rng(3)
    n = sp.n_total
    for _ in range(200):
        i0 = int(rng.integers(0, n))
        i1 = int(rng.integers(i0, n + 1))
        got = sp.swept_values(i0, i1)
        multi = np.unravel_index(np.arange(i0, i1), shape)
        for ax, k in zip(sp.axes, multi, strict=True):
            want = ax.at(np.asarray(k, dtype=np.int64))
            assert got[ax.name].tobytes() == want.tobytes(), (shape, i0, i1, ax.name)


@pytest.mark.parametrize(
    "body",
    [
        # kappa_ratio and eps per row, ba the row (the benchmark's layout)
        {
            "axes": [
                {"name": "kappa_ratio", "start": 0.3, "stop": 0.95, "n": 7},
                {"name": "eps", "start": 0.0, "stop": 0.6, "n": 5},
                {"name": "ba", "start": 1.2, "stop": 20.0, "n": 40},
            ],
            "fixed": {"vo": 1.0},
        },
        # ba per row, kappa_ratio the row (log), outcomes of a fixed size
        {
            "axes": [
                {"name": "ba", "start": 1.5, "stop": 9.0, "n": 6},
                {"name": "kappa_ratio", "start": 0.1, "stop": 3.0, "n": 30, "log": True},
            ],
            "fixed": {"eps": 0.2, "vo": 0.5, "size": 1.5},
        },
        # kappa (not the ratio) swept, vo the row with explicit values, a swept size
        {
            "axes": [
                {"name": "kappa", "start": 0.5, "stop": 4.0, "n": 3},
                {"name": "size", "start": -0.5, "stop": 2.0, "n": 4},
                {"name": "vo", "values": [0.0, 0.25, 1.0, 3.0, 7.5, 11.0, 20.0, 100.0]},
            ],
            "fixed": {"ba": 2.5, "eps": 0.3},
        },
        # one axis only (a single row)
        {"axes": [{"name": "eps", "start": 0.0, "stop": 1.0, "n": 50}], "fixed": {"ba": 3.0}},
    ],
)
def test_params_of_a_range_equal_point_by_point(body: dict) -> None:
    """params(i0, i1) (row-wise for ranges of two rows or more) against params_at (the
    point-by-point definition: unravel_index + Axis.at, then the same derivation), bit
    for bit, at 300 random ranges, every short one at the start and consecutive parts
    of 2.5 rows over the whole sweep as a worker takes them (an outer axis the same on
    every row of most parts: its layouts are kept and replaced when it changes)."""
    sp = spec_of(body)
    n = sp.n_total
    rng = np.random.default_rng(5)
    ranges = [(0, k) for k in range(1, min(n, 90))]
    ranges += [tuple(sorted(int(x) for x in rng.integers(0, n + 1, 2))) for _ in range(300)]
    part = max(1, 5 * sp.shape[-1] // 2)
    ranges += [(a, min(n, a + part)) for a in range(0, n, part)]
    for i0, i1 in ranges:
        got = sp.params(i0, i1)
        want = sp.params_at(np.arange(i0, i1, dtype=np.int64))
        for name, w in want.items():
            g = got[name]
            if w is None:
                assert g is None, name
                continue
            assert g is not None and g.flags.c_contiguous, name
            assert g.dtype == np.float64 and g.tobytes() == w.tobytes(), (i0, i1, name)


def test_compute_chunk_isolates_a_point_that_breaks_the_batch(monkeypatch) -> None:
    sp = spec_of(
        {
            "axes": [{"name": "eps", "values": [0.1, 0.2, 0.3, 0.4]}],
            "fixed": {"ba": 2.0, "kappa_ratio": 2.0},
        }
    )
    orig = batch.critical_points

    def fragile(ba, kappa, eps, vo, **kw):
        if np.any(np.asarray(eps) == 0.3):
            raise ZeroDivisionError("kernel defect at eps=0.3")
        return orig(ba, kappa, eps, vo, **kw)

    monkeypatch.setattr(batch, "critical_points", fragile)
    arrays, errors = compute_chunk(sp, 0, 4)
    assert arrays["failed"].tolist() == [False, False, True, False]
    assert errors == {2: "ZeroDivisionError: kernel defect at eps=0.3"}
    ref = critical.critical_perturbation(Params(2.0, 2.0, 0.4, 1.0)).critical_size
    assert arrays["critical_size"][3] == ref and np.isnan(arrays["critical_size"][2])


@pytest.mark.parametrize(
    "body",
    [
        {"x": {"name": "eps", "values": [0.1]}, "y": {"name": "ba", "values": [2.0]}},
        {"axes": [{"name": "eps", "values": [0.1]}, {"name": "ba", "values": [2.0]}]},
    ],
)
def test_xy_form_is_the_same_sweep_as_two_axes(body: dict) -> None:
    assert (
        spec_of(body).to_json()
        == spec_of(
            {"axes": [{"name": "eps", "values": [0.1]}, {"name": "ba", "values": [2.0]}]}
        ).to_json()
    )


@pytest.mark.parametrize(
    ("body", "field"),
    [
        (
            {"axes": [{"name": "ba", "start": 2, "stop": 3, "n": 3}], "fixed": {"vo": 1e-310}},
            "fixed.vo",
        ),
        ({"axes": [{"name": "vo", "values": [1e-300, 5e-324]}]}, "axes[0].values[1]"),
        ({"points": {"vo": [1.0, 1e-301]}}, "points.vo[1]"),
    ],
)
def test_vo_below_its_minimum_is_refused_as_by_params(body: dict, field: str) -> None:
    """A sweep takes v_o as a single query does (rsfcore.Params): 0 or [1e-300, 1e300].
    It accepted 0 < v_o < 1e-300, which every single query refuses."""
    with pytest.raises(ParameterError, match="vo"):
        Params(ba=2.0, kappa=0.5, eps=0.5, vo=body.get("fixed", {}).get("vo", 5e-324))
    body = {"fixed": {"ba": 2.0, "kappa": 0.5, "eps": 0.5} | body.pop("fixed", {}), **body}
    with pytest.raises(SpecError) as err:
        spec_of(body)
    assert err.value.field == field and "1e-300" in str(err.value)
    ok = {
        "fixed": {"ba": 2.0, "kappa": 0.5, "eps": 0.5},
        "axes": [{"name": "vo", "values": [0.0, 1e-300]}],
    }
    assert spec_of(ok).n_total == 2
