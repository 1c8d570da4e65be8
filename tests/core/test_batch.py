"""rsfcore.batch.critical_points: the array form of critical_perturbation."""

from __future__ import annotations

import math

import numpy as np
import pytest

from rsfcore import batch, batchloop
from rsfcore import critical as crit
from rsfcore.diagram import stability_diagram
from rsfcore.params import ParameterError, Params
from rsfcore.trajectory import classify
from tests.e2e.test_worker_faultplugin import list_as_fallback


def _random_points(n: int, seed: int) -> tuple[np.ndarray, ...]:
    rng = np.random.default_rng(seed)
    ba = 1.0 + 10 ** rng.uniform(-1.5, 1.5, n)
    ratio = rng.uniform(0.5, 5.0, n)
    ratio[::7] = 1.0  # kappa = kappa_crit: closed forms
    eps = rng.uniform(0.0, 0.99, n)
    vo = rng.choice([0.0, 1e-3, 1.0, 7.5], n)
    return ba, ratio * (ba - 1.0), eps, vo


@pytest.mark.parametrize("pert", ["velocity-jump", "load-point-jump"])
def test_matches_critical_perturbation_point_by_point(pert: str) -> None:
    ba, kappa, eps, vo = _random_points(200, 1 if pert == "velocity-jump" else 2)
    if pert == "load-point-jump":
        vo = np.where(vo == 0.0, 2.0, vo)
    res = batch.critical_points(ba, kappa, eps, vo, perturbation=pert, rtol=1e-10)
    kinds = set()
    for i in range(ba.size):
        ref = crit.critical_perturbation(Params(ba[i], kappa[i], eps[i], vo[i]), pert, rtol=1e-10)
        kinds.add(ref.kind)
        assert crit.KINDS[res.kind[i]] == ref.kind
        assert not res.failed[i]
        if ref.kind == "finite":
            # Same compiled kernel and same fallback: equal up to rounding (1e-12 is the
            # agreement the service promises; the numbers are in fact identical).
            assert res.critical_size[i] == pytest.approx(ref.critical_size, rel=1e-12)
            assert res.rel_accuracy[i] == pytest.approx(ref.rel_accuracy, rel=1e-12)
        elif ref.kind == "zero":
            assert res.critical_size[i] == 0.0
        else:
            assert math.isinf(res.critical_size[i])
    assert kinds == {"zero", "finite", "infinite"}  # the sample covers every kind


def test_vo_independence_is_what_the_kernel_does() -> None:
    """Critical sizes do not depend on v_o > 0 (the invariance the batch relies on)."""
    p = dict(ba=3.0, kappa=5.0, eps=0.3)
    a = crit.critical_perturbation(Params(vo=1e-6, **p), rtol=1e-10).critical_size
    b = crit.critical_perturbation(Params(vo=1e6, **p), rtol=1e-10).critical_size
    assert a == b


def test_outcome_agrees_with_stability_diagram() -> None:
    kr = np.linspace(0.5, 4.0, 9)
    ep = np.linspace(0.0, 0.9, 7)
    d = stability_diagram("kappa_ratio", kr, "eps", ep, ba=2.0, vo=1.0, size=0.8)
    K, E = np.meshgrid(kr, ep, indexing="ij")
    res = batch.critical_points(2.0, (K * 1.0).ravel(), E.ravel(), 1.0, size=0.8)
    assert res.outcome is not None and d.outcome is not None
    assert np.array_equal(res.outcome, d.outcome.ravel())
    assert np.array_equal(res.outcome_uncertain, d.outcome_uncertain.ravel())
    assert np.array_equal(res.critical_size, d.critical_size.ravel())


def test_negative_size_is_classified() -> None:
    res = batch.critical_points([2.0, 2.0], [3.0, 0.5], [0.2, 0.2], 1.0, size=[-0.5, -0.5])
    for i, k in enumerate([3.0, 0.5]):
        ref = classify(Params(2.0, k, 0.2, 1.0), "velocity-jump", -0.5)
        assert res.outcome[i] == (1 if ref.outcome == "unstable" else 0)


def _flagging_kernel(monkeypatch: pytest.MonkeyPatch, eps_flagged: float) -> None:
    """The compiled loop, then every point at eps == ``eps_flagged`` listed as a
    separatrix failure (FLAG_FALLBACK), as the kernel lists them."""
    orig = batchloop.points_kernel

    def flagging(*args):
        return list_as_fallback(orig, args, orig(*args), eps_flagged)

    monkeypatch.setattr(batchloop, "points_kernel", flagging)


def test_failure_isolated(monkeypatch: pytest.MonkeyPatch) -> None:
    """A point whose fallback raises is recorded; the others are kept."""

    def failing(params, *a, **kw):
        raise FloatingPointError(f"boom at {params.eps}")

    _flagging_kernel(monkeypatch, 0.5)
    monkeypatch.setattr(crit, "bisect_critical", failing)
    eps = np.array([0.1, 0.5, 0.2, 0.5])
    res = batch.critical_points(2.0, 3.0, eps, 1.0)
    assert res.failed.tolist() == [False, True, False, True]
    assert set(res.errors) == {1, 3} and "boom at 0.5" in res.errors[1]
    assert np.isnan(res.critical_size[[1, 3]]).all() and (res.kind[[1, 3]] == -1).all()
    assert (res.method[[1, 3]] == -1).all() and np.isnan(res.rel_accuracy[[1, 3]]).all()
    ref = crit.critical_perturbation(Params(2.0, 3.0, 0.2, 1.0)).critical_size
    assert res.critical_size[2] == ref
    assert res.n_fallback == 2


def test_fallback_recomputes_by_bisection(monkeypatch: pytest.MonkeyPatch) -> None:
    """A listed point is recomputed by bisection and finished like the others (its
    outcome from the bisected size)."""
    _flagging_kernel(monkeypatch, 0.3)
    res = batch.critical_points(2.0, 3.0, [0.1, 0.3], 1.0, size=[0.5, 0.5], rtol=1e-8)
    bis = crit.bisect_critical(Params(2.0, 3.0, 0.3, 1.0), rtol=1e-8)
    assert res.method[1] == crit.M_BISECTION and res.n_fallback == 1
    assert res.critical_size[1] == bis.critical_size
    assert res.outcome is not None
    assert res.outcome[1] == (batch.OUTCOME_UNSTABLE if bis.critical_size < 0.5 else 0)


def _grid_and_points(shape_values, fixed, ratio, size=None, **kw):
    """critical_grid over the C-order grid of ``shape_values`` ({name: values}) and
    critical_points on the same points laid out by numpy (meshgrid, independent of the
    kernel's walk), over ranges that start and end inside rows."""
    names = list(shape_values)
    mesh = np.meshgrid(*shape_values.values(), indexing="ij")
    flat = {n: m.ravel() for n, m in zip(names, mesh)}
    stride, strides = 1, {}
    for n in reversed(names):
        strides[n] = stride
        stride *= len(shape_values[n])
    total = stride

    def arg(name):
        if name in shape_values:
            return batch.AxisTable(np.asarray(shape_values[name], float), strides[name])
        return fixed.get(name)

    def pts(name, sl):
        return flat[name][sl] if name in flat else fixed.get(name)

    k = "kappa_ratio" if ratio else "kappa"
    for i0, i1 in ((0, total), (3, total - 2), (total // 2, total // 2 + 1)):
        sl = slice(i0, i1)
        kap = pts(k, sl)
        if ratio:
            kap = np.broadcast_to(kap, (i1 - i0,)) * (
                np.broadcast_to(pts("ba", sl), (i1 - i0,)) - 1.0
            )
        ref = batch.critical_points(
            pts("ba", sl), kap, pts("eps", sl), pts("vo", sl), size=pts("size", sl), **kw
        )
        g = batch.critical_grid(
            arg("ba"), arg(k), arg("eps"), arg("vo"), i0, i1,
            kappa_is_ratio=ratio, size=arg("size"), **kw,
        )  # fmt: skip
        got = g.to_batch()
        for f in ("kind", "critical_size", "rel_accuracy", "method", "on_boundary", "failed"):
            assert getattr(got, f).tobytes() == getattr(ref, f).tobytes(), f
        if size is not None:
            assert got.outcome.tobytes() == ref.outcome.tobytes()
            assert got.outcome_uncertain.tobytes() == ref.outcome_uncertain.tobytes()
        assert got.errors == ref.errors and got.n_fallback == ref.n_fallback
        for f, rep in g.repeated.items():  # what the kernel says of each output is true
            a = g.array(f)
            if rep is not None:
                assert rep == (a.tobytes() == np.repeat(a[:1], a.size).tobytes()), f


@pytest.mark.parametrize("pert", ["velocity-jump", "load-point-jump"])
def test_grid_gives_the_bits_of_the_points(pert: str) -> None:
    """critical_grid (parameters generated from the axes inside the compiled loop) gives
    critical_points's bits at every point: every kind, kappa = kappa_crit, v_o = 0 next
    to v_o > 0, sizes on both sides of the critical size and negative ones."""
    vo = [0.0, 1.0, 3.0] if pert == "velocity-jump" else [0.5, 3.0]
    axes = {
        "kappa_ratio": [0.5, 1.0, 1.3, 2.5, 9.0],
        "eps": [0.0, 0.2, 0.5, 0.9],
        "vo": vo,
        "ba": np.linspace(1.5, 12.0, 5),
    }
    _grid_and_points(axes, {}, True, perturbation=pert, rtol=1e-8)
    sizes = {"eps": [0.1, 0.6], "size": [-0.3, 0.0, 0.4, 2.0], "kappa_ratio": [0.5, 1.0, 1.6]}
    _grid_and_points(sizes, {"ba": 3.0, "vo": 1.0}, True, size=1, perturbation=pert, rtol=1e-8)
    direct = {"kappa": [0.0, 0.5, 2.0, 7.0], "ba": [1.5, 3.0, 9.0]}
    _grid_and_points(direct, {"eps": 0.3, "vo": 2.0}, False, perturbation=pert, rtol=1e-8)


def test_grid_failures_as_the_points(monkeypatch: pytest.MonkeyPatch) -> None:
    """Failed points (NaN sizes, -1 codes) at the same places on both paths."""

    def failing(params, *a, **kw):
        raise FloatingPointError(f"boom at {params.eps}")

    _flagging_kernel(monkeypatch, 0.5)
    monkeypatch.setattr(crit, "bisect_critical", failing)
    axes = {"eps": [0.1, 0.5, 0.2], "ba": [2.0, 4.0]}
    _grid_and_points(axes, {"kappa_ratio": 3.0, "vo": 1.0, "size": 0.5}, True, size=1)


def test_grid_repeated_outputs_are_not_laid_out() -> None:
    """Cheap points decided alike: every output one repeated value, kept as one."""
    g = batch.critical_grid(
        batch.AxisTable(np.linspace(1.2, 20.0, 1000), 1),
        batch.AxisTable(np.linspace(0.3, 0.95, 10), 1000),
        0.2,
        1.0,
        123,
        9000,
        kappa_is_ratio=True,
    )
    assert g.n == 8877 and all(g.repeated.values())
    assert all(v.size == 1 for v in g.values.values())
    assert g.values["kind"][0] == crit.KIND_ZERO and g.values["critical_size"][0] == 0.0


@pytest.mark.parametrize(
    "kw, field",
    [
        (dict(ba=batch.AxisTable(np.array([2.0, 0.5]), 1)), "ba[1]"),
        (dict(eps=batch.AxisTable(np.array([0.1, 1.5]), 3)), "eps[1]"),
        (dict(kappa=batch.AxisTable(np.array([1.0, -1.0]), 1)), "kappa_ratio[1]"),
        (dict(kappa=2e5, ba=batch.AxisTable(np.array([2.0, 7.0]), 1)), "kappa_ratio"),
        (dict(ba=batch.AxisTable(np.array([2.0]), 0)), "ba.stride"),
        (dict(i0=5, i1=4), "i1"),
    ],
)
def test_grid_bad_input_names_the_table(kw: dict, field: str) -> None:
    args = dict(ba=2.0, kappa=1.0, eps=0.1, vo=1.0, i0=0, i1=4)
    args.update(kw)
    with pytest.raises(ParameterError) as e:
        batch.critical_grid(**args, kappa_is_ratio=True)
    assert e.value.field == field


@pytest.mark.parametrize(
    "kw, field",
    [
        (dict(ba=[2.0, 0.5], kappa=1.0, eps=0.1, vo=1.0), "ba[1]"),
        (dict(ba=[2.0, 2.0], kappa=1.0, eps=[0.1, 0.2, 0.3], vo=1.0), "ba"),
        (dict(ba=[2.0, 2.0, 2.0], kappa=1.0, eps=[0.1, 0.2, 1.5], vo=1.0), "eps[2]"),
        (
            dict(ba=[2.0, 2.0], kappa=1.0, eps=0.1, vo=[1.0, 0.0], perturbation="load-point-jump"),
            "vo[1]",
        ),
        (dict(ba=[2.0, 2.0], kappa=[1.0, np.nan], eps=0.1, vo=1.0), "kappa[1]"),
    ],
)
def test_bad_input_names_element(kw: dict, field: str) -> None:
    with pytest.raises(ParameterError) as e:
        batch.critical_points(**kw)
    assert e.value.field == field


@pytest.mark.parametrize(
    "kw, limit, bad",
    [
        (dict(ba=[2.0, 1.0]), "BA", 1.0),
        (dict(kappa=[1.0, 2e6]), "KAPPA", 2e6),
        (dict(eps=[0.1, -0.5]), "EPS", -0.5),
        (dict(vo=[1.0, 2e300]), "VO", 2e300),
        (dict(size=[1.0, 1.5e4]), "VELOCITY_JUMP_SIZE", 1.5e4),
        (dict(size=[1.0, -1.0], perturbation="load-point-jump"), "LOAD_POINT_JUMP_SIZE", -1.0),
        (dict(rtol=1e-14), "RTOL", 1e-14),
    ],
)
def test_bad_input_states_the_limits_range(kw: dict, limit: str, bad: float) -> None:
    """The batch checks are the ranges of rsfcore.limits (one definition): the error names
    the element, the value given and the Limit's own range text."""
    from rsfcore import limits

    args: dict = dict(ba=2.0, kappa=1.0, eps=0.1, vo=1.0)
    args.update(kw)
    lim = limits.LIMITS[limit]
    with pytest.raises(ParameterError) as e:
        batch.critical_points(**args)
    assert e.value.field == (lim.name if limit == "RTOL" else f"{lim.name}[1]")
    assert e.value.valid == lim.text and e.value.value == bad
    # the in-range end of each limit is accepted (the ranges are not narrower than stated)
    ok = dict(args, **{k: v for k, v in kw.items() if k == "perturbation"})
    edge = lim.lo if limit in ("EPS", "RTOL") else lim.hi
    ok[lim.name] = edge
    if limit == "KAPPA":
        ok["ba"] = 1e6
    batch.critical_points(**ok)


def test_outcome_names_are_indexed_by_the_codes() -> None:
    """One definition: the diagram's legend is batchloop's, each name at its code."""
    from rsfcore import diagram

    assert diagram.OUTCOMES is batchloop.OUTCOMES
    assert batchloop.OUTCOMES[batchloop.OUTCOME_STABLE] == "stable"
    assert batchloop.OUTCOMES[batchloop.OUTCOME_UNSTABLE] == "unstable"
    assert [o.text for o in batchloop.BatchOutcome if o is not batchloop.BatchOutcome.NONE] == [
        "stable",
        "unstable",
    ]
    assert batchloop.BatchOutcome.NONE == batchloop.OUTCOME_NONE
    # the compiled loop writes the plain codes
    r = batch.critical_points([2.0, 2.0], [3.0, 3.0], [0.25, 0.25], 1.0, size=[0.5, 1e3])
    assert r.outcome is not None
    assert [batchloop.BatchOutcome(int(o)).text for o in r.outcome] == ["stable", "unstable"]


def test_deprecated_critical_batch_is_the_batch_kernel() -> None:
    """rsfcore.critical.critical_batch (deprecated) warns and gives the bits of
    critical_points (the one batch path) wherever no fallback is needed, boundaries
    x = 1 and kappa = kappa_crit (up to rounding) included."""
    ba, kap, eps = [], [], []
    for b in (1.0 + 2.0**-40, 1.5, 2.0, 1e4):
        kc = b - 1.0
        for r in (0.0, 0.5, 1.0 - 2.0**-52, 1.0, 1.0 + 2.0**-52, 2.0, 50.0):
            k = r * kc
            for e in (0.0, 0.25, 1.0) + ((kc / k, np.nextafter(kc / k, 0.0)) if k else ()):
                if 0.0 <= e <= 1.0:
                    ba.append(b), kap.append(k), eps.append(e)
    B, K, E = np.array(ba), np.array(kap), np.array(eps)
    n = B.size
    for pert, name in enumerate(crit.PERTURBATIONS):
        kind, val = np.empty(n, np.int8), np.empty(n)
        acc, meth, fl = np.empty(n), np.empty(n, np.int8), np.empty(n, np.int64)
        with pytest.warns(DeprecationWarning, match="critical_points"):
            crit.critical_batch(B, K, E, 1.0, pert, 1e-10, kind, val, acc, meth, fl)
        ok = (fl & crit.FLAG_FALLBACK) == 0
        assert ok.sum() > 0.9 * n
        r = batch.critical_points(B, K, E, 1.0, perturbation=name)
        assert np.array_equal(kind[ok], r.kind[ok])
        assert np.array_equal(meth[ok], r.method[ok])
        assert np.array_equal(acc[ok], r.rel_accuracy[ok])
        fin = ok & (kind == crit.KIND_FINITE)  # zero/infinite: the batch stores 0 / inf
        assert val[fin].tobytes() == r.critical_size[fin].tobytes()
