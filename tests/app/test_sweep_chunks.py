"""A sweep chunk computed in parts (rsfapp.sweepdata.chunk_parts / compute_chunk /
compute_block) and its block written from the parts (rsfapp.store.sweeps.BlockWriter).

The reference is independent of the parts: one rsfcore.batch.critical_points call on the
whole chunk's parameters, and encode_block of whole arrays.  Equality is bitwise (every
stored point must be the bits rsfcore gives), so no tolerance anywhere.
"""

from __future__ import annotations

import io
import zipfile
from typing import Any

import numpy as np
import pytest
from numpy.typing import NDArray

from rsfapp import sweepdata
from rsfapp.grid import SweepSpec, expand
from rsfapp.requests import SweepRequest
from rsfapp.store.sweeps import BlockWriter, _same_bits, decode_block, encode_block
from rsfcore import batch


def spec_of(body: dict[str, Any]) -> SweepSpec:
    return expand(SweepRequest.model_validate(body), 10**8, 10**6)


#: every kind of point in one grid: kind zero (kappa_ratio < 1), the separatrix
#: (1 < kappa_ratio < 1/eps), infinite (eps kappa_ratio >= 1), kappa = kappa_crit exactly,
#: v_o = 0 (closed form L*) next to v_o > 0 (the batch splits those two)
MIXED = {
    "axes": [
        {"name": "kappa_ratio", "values": [0.5, 1.0, 1.3, 2.5, 9.0]},
        {"name": "eps", "values": [0.0, 0.2, 0.5, 0.9]},
        {"name": "vo", "values": [0.0, 1.0, 3.0]},
        {"name": "ba", "start": 1.5, "stop": 12.0, "n": 5},
    ],
}
OUTCOME = {**MIXED, "fixed": {"size": 0.7}}


def whole(spec: SweepSpec, i0: int, i1: int) -> batch.BatchResult:
    """The reference: one batch call on the chunk's parameters."""
    p = spec.params(i0, i1)
    return batch.critical_points(
        p["ba"],
        p["kappa"],
        p["eps"],
        p["vo"],
        size=p["size"],
        perturbation=spec.perturbation,
        rtol=spec.rtol,
    )


def same_bits(a: NDArray[Any], b: NDArray[Any]) -> bool:
    return a.dtype == b.dtype and a.shape == b.shape and a.tobytes() == b.tobytes()


@pytest.mark.parametrize("body", [MIXED, OUTCOME], ids=["critical", "outcome"])
@pytest.mark.parametrize("part", [1, 7, 64, 10**6])
def test_parts_give_the_bits_of_one_batch_call(monkeypatch, body, part) -> None:
    sp = spec_of(body)
    monkeypatch.setattr(sweepdata, "PART_POINTS", part)
    i0, i1 = 13, sp.n_total - 5  # parts that do not start at a row
    ref = whole(sp, i0, i1)
    arrays, errors = sweepdata.compute_chunk(sp, i0, i1)
    assert errors == ref.errors == {}
    names = {"critical_size", "rel_accuracy", "kind", "method", "failed", "on_boundary"}
    if body is OUTCOME:
        names |= {"outcome", "outcome_uncertain"}
    assert set(arrays) == names
    for name in names:
        assert same_bits(arrays[name], getattr(ref, name)), name
    # the mix is real: every kind and both v_o branches occur
    assert set(ref.kind.tolist()) == {0, 1, 2}
    # the block written from the parts holds the same bits
    data, errors = sweepdata.compute_block(sp, i0, i1)
    assert errors == {}
    got = decode_block(data)
    assert set(got) == names
    for name in names:
        assert same_bits(got[name], getattr(ref, name)), name


def test_a_part_that_breaks_the_batch_is_isolated_with_chunk_offsets(monkeypatch) -> None:
    sp = spec_of(
        {
            "axes": [{"name": "eps", "values": [0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7]}],
            "fixed": {"ba": 2.0, "kappa_ratio": 1.5},
        }
    )
    ref = whole(sp, 1, 7)  # the real kernel, before the patch
    orig = batch.critical_points

    def fragile(ba, kappa, eps, vo, **kw):
        if np.any(np.asarray(eps) == 0.6):
            raise ZeroDivisionError("kernel defect at eps=0.6")
        return orig(ba, kappa, eps, vo, **kw)

    def broken(*a, **kw):  # the defect breaks the fused call too: the parts take over
        raise ZeroDivisionError("kernel defect")

    monkeypatch.setattr(batch, "critical_points", fragile)
    monkeypatch.setattr(batch, "critical_grid", broken)
    monkeypatch.setattr(sweepdata, "PART_POINTS", 2)
    arrays, errors = sweepdata.compute_chunk(sp, 1, 7)  # parts [1,3) [3,5) [5,7)
    assert errors == {4: "ZeroDivisionError: kernel defect at eps=0.6"}
    assert arrays["failed"].tolist() == [False, False, False, False, True, False]
    assert np.isnan(arrays["critical_size"][4]) and arrays["kind"][4] == -1
    keep = np.arange(6) != 4
    assert same_bits(arrays["critical_size"][keep], ref.critical_size[keep])
    data, errors2 = sweepdata.compute_block(sp, 1, 7)
    assert errors2 == errors
    assert same_bits(decode_block(data)["critical_size"], arrays["critical_size"])


def entries(data: bytes) -> list[str]:
    with zipfile.ZipFile(io.BytesIO(data)) as z:
        return z.namelist()


@pytest.mark.parametrize(
    "arr",
    [
        np.zeros(10),
        np.full(12, np.nan),
        np.array([0.0] * 5 + [-0.0] * 5),  # equal values, different bits: not constant
        np.array([1.0] * 9 + [2.0]),  # the change in the last part
        np.array([3, 3, 3, 4, 3, 3, 3], np.int8),  # a change inside an early part
        np.array([True] * 17),  # 17 bytes: not whole 64-bit words
        np.array([7, 7, 7, 7, 7, 7, 7, 7, 7, 7, 7, 7, 7, 7, 7, 7], np.int16),
        np.array([b"abc"] * 9),  # 3-byte elements: no word view
        np.array([b"abc"] * 8 + [b"abd"]),
        np.array([5.0]),
        np.zeros(0),
    ],
)
@pytest.mark.parametrize("part", [1, 3, 4, 100])
def test_block_writer_writes_what_encode_block_writes(arr, part) -> None:
    arrays = {"x": arr, "y": np.arange(arr.size, dtype=np.float64)}
    w = BlockWriter()
    for a in range(0, max(arr.size, 1), part):
        w.add({k: v[a : a + part] for k, v in arrays.items()})
    data = w.finish()
    want = encode_block(arrays)
    assert entries(data) == entries(want)
    got = decode_block(data)
    for k, v in arrays.items():
        assert same_bits(got[k], v), k
    constant = arr.size > 1 and len({x.tobytes() for x in arr}) == 1
    assert (entries(data)[0] == f"x@const{arr.size}.npy") is constant


def test_block_writer_keeps_other_dimensions_as_they_are() -> None:
    a = np.arange(12.0).reshape(3, 4)
    w = BlockWriter()
    w.add({"m": a, "c": np.ones(3)})
    got = decode_block(w.finish())
    assert same_bits(got["m"], a) and same_bits(got["c"], np.ones(3))
    with pytest.raises(ValueError, match="m: only 1-D"):
        w.add({"m": a, "c": np.ones(3)})  # a second part of a 2-D array


def test_same_bits_against_an_elementwise_test() -> None:
    rng = np.random.default_rng(3)
    for dtype in (np.float64, np.float32, np.int8, np.bool_, np.int16, np.uint64):
        for n in (1, 2, 7, 8, 9, 64, 1001):
            base = np.zeros(n, dtype)
            assert _same_bits(base)
            for _ in range(3):
                b = base.copy()
                b.view(np.uint8)[rng.integers(0, b.nbytes)] = 1
                want = len({x.tobytes() for x in b}) == 1
                assert _same_bits(b) is want
                assert _same_bits(b, base[:1]) is (not b.any())


def unfused_block(spec: SweepSpec, i0: int, i1: int) -> tuple[bytes, dict[int, str]]:
    """The block from the parts (the unfused path of compute_block)."""
    w = BlockWriter()
    errors: dict[int, str] = {}
    for _off, arrays, errs in sweepdata.chunk_parts(spec, i0, i1):
        w.add(arrays)
        errors.update(errs)
    return w.finish(), errors


#: grids the fused path must compute as the parts do: every kind and both v_o branches
#: (MIXED), outcomes of a fixed size, sizes swept through zero and below (negative sizes
#: are classified one by one, listed by the kernel), kappa given directly, a load-point
#: jump, a size swept in SI, and cheap points decided alike (every array one value)
FUSED = {
    "critical": MIXED,
    "outcome": OUTCOME,
    "sizes": {**MIXED, "axes": [*MIXED["axes"][:2], {"name": "size", "values": [-0.4, 0.0, 0.9]}]},
    "kappa": {
        "axes": [
            {"name": "kappa", "values": [0.0, 0.5, 1.0, 4.0]},
            {"name": "eps", "start": 0.0, "stop": 0.8, "n": 6},
        ],
        "fixed": {"ba": 3.0, "vo": 1.0},
    },
    "load-point": {
        "axes": [
            {"name": "kappa_ratio", "values": [0.5, 1.0, 1.7]},
            {"name": "eps", "values": [0.1, 0.4]},
            {"name": "size", "values": [0.2, 3.0]},
        ],
        "fixed": {"ba": 2.0, "vo": 2.0},
        "perturbation": "load-point-jump",
    },
    "si-size": {
        "axes": [
            {"name": "factor", "values": [0.5, 1.5, 20.0]},
            {"name": "eps", "values": [0.1, 0.5]},
        ],
        "fixed": {
            "physical": {
                "a": 0.01,
                "b": 0.015,
                "Dc_m": 1e-5,
                "sigma_Pa": 5e7,
                "k_Pa_per_m": 2e10,
                "V_star_m_s": 1e-6,
            }
        },
    },
    "cheap": {
        "axes": [
            {"name": "kappa_ratio", "start": 0.3, "stop": 0.95, "n": 3},
            {"name": "eps", "start": 0.0, "stop": 0.6, "n": 4},
            {"name": "ba", "start": 1.2, "stop": 20.0, "n": 50},
        ],
        "fixed": {"vo": 1.0},
    },
}


@pytest.mark.parametrize("name", list(FUSED))
def test_fused_block_is_the_unfused_block(name) -> None:
    """The fused chunk (parameters generated in the kernel from the axes, repeated
    arrays reported by it) stores what the parts store: the same entries (an array one
    repeated value in both or in neither), every variable bit for bit (NaN and fill
    values at the same places), the same errors; for ranges that start and end inside
    a row, a single point and the whole grid."""
    sp = spec_of(FUSED[name])
    n = sp.n_total
    ranges = ((0, n), (13, n - 5), (n // 2, n // 2 + 1), (1, n // 3))
    for i0, i1 in [(a, b) for a, b in ranges if a < b]:
        fused = sweepdata.fused_block(sp, i0, i1)
        assert fused is not None
        data, errors = fused
        want, want_errors = unfused_block(sp, i0, i1)
        assert errors == want_errors
        assert entries(data) == entries(want)
        got, ref = decode_block(data), decode_block(want)
        assert set(got) == set(ref)
        for var in ref:
            assert same_bits(got[var], ref[var]), (var, i0, i1)
        assert data == want  # the same bytes, too
    if name == "cheap":
        assert all("@const" in e for e in entries(data))
    if name == "sizes":
        assert (decode_block(data)["outcome"] >= 0).all()  # negative sizes classified


def test_fused_block_failed_points_as_the_parts(monkeypatch) -> None:
    """Points whose classification raises are failed with their messages at the same
    offsets on both paths (outcome -1 there, the rest kept)."""
    import rsfcore.trajectory as traj

    orig = traj.classify

    def fragile(params, perturbation, size, **kw):
        if params.eps == 0.2:
            raise FloatingPointError(f"classify broke at eps={params.eps}")
        return orig(params, perturbation, size, **kw)

    monkeypatch.setattr(traj, "classify", fragile)
    sp = spec_of(FUSED["sizes"])
    fused = sweepdata.fused_block(sp, 3, sp.n_total - 2)
    assert fused is not None
    want, want_errors = unfused_block(sp, 3, sp.n_total - 2)
    assert fused[1] == want_errors and len(want_errors) > 0
    assert all("classify broke at eps=0.2" in m for m in want_errors.values())
    got, ref = decode_block(fused[0]), decode_block(want)
    for var in ref:
        assert same_bits(got[var], ref[var]), var
    bad = np.array(sorted(want_errors))
    assert ref["failed"][bad].all() and (ref["outcome"][bad] == -1).all()


def test_fused_block_fallback_failures_as_the_parts(monkeypatch) -> None:
    """Points the kernel hands to the bisection fallback, whose bisection raises: failed
    on both paths at the same offsets, with NaN sizes and accuracies and -1 codes (the
    fill values), every other point kept, bit for bit."""
    import rsfcore.batchloop as loop
    import rsfcore.critical as crit
    from tests.e2e.test_worker_faultplugin import list_as_fallback

    kernel = loop.points_kernel

    def flagging(*args):
        return list_as_fallback(kernel, args, kernel(*args), 0.5)

    def failing(params, *a, **kw):
        raise FloatingPointError(f"bisection broke at eps={params.eps}")

    monkeypatch.setattr(loop, "points_kernel", flagging)
    monkeypatch.setattr(crit, "bisect_critical", failing)
    for body in (MIXED, OUTCOME):
        sp = spec_of(body)
        fused = sweepdata.fused_block(sp, 7, sp.n_total - 3)
        assert fused is not None
        want, want_errors = unfused_block(sp, 7, sp.n_total - 3)
        assert fused[1] == want_errors and len(want_errors) > 0
        got, ref = decode_block(fused[0]), decode_block(want)
        for var in ref:
            assert same_bits(got[var], ref[var]), var
        bad = np.array(sorted(want_errors))
        assert (
            np.isnan(ref["critical_size"][bad]).all() and np.isnan(ref["rel_accuracy"][bad]).all()
        )
        assert (ref["kind"][bad] == -1).all() and (ref["method"][bad] == -1).all()
        assert ref["failed"].sum() == bad.size


def test_compute_block_takes_the_fused_path_for_grids(monkeypatch) -> None:
    """A grid's chunk never lays out parameters (the parts are not called); scattered
    points and a fused call that raises take the parts, with the same block."""
    sp = spec_of(MIXED)
    want = unfused_block(sp, 5, 200)

    def no_parts(*a, **kw):
        raise AssertionError("the parts were used")

    with monkeypatch.context() as m:
        m.setattr(sweepdata, "chunk_parts", no_parts)
        assert sweepdata.compute_block(sp, 5, 200) == want

    def broken(*a, **kw):
        raise ZeroDivisionError("kernel defect")

    monkeypatch.setattr(batch, "critical_grid", broken)
    assert sweepdata.fused_block(sp, 5, 200) is None
    assert sweepdata.compute_block(sp, 5, 200) == want
    pts = spec_of({"points": {"ba": [2.0, 3.0], "kappa_ratio": [0.5, 2.0], "eps": [0.1, 0.2]}})
    assert sweepdata.fused_block(pts, 0, 2) is None
