"""Tests of rsfcore.diagram: grid accuracy, exact regions, boundary flags, outcomes, I/O."""

from __future__ import annotations

import csv
import json
import math
from fractions import Fraction

import numpy as np
import pytest

from rsfcore import ParameterError, Params, batch, classify
from rsfcore.critical import critical_perturbation
from rsfcore.diagram import stability_diagram

XR = np.linspace(1.0, 5.0, 100)
YE = np.linspace(0.0, 0.99, 100)


@pytest.fixture(scope="module")
def bench_grid():
    stability_diagram("kappa_ratio", XR[:3], "eps", YE[:3])  # warm-up (numba cache load)
    return stability_diagram("kappa_ratio", XR, "eps", YE)


# Speed of the benchmark grid (target 0.1 s after warm-up) is measured and printed by
# bench/bench_diagram.py together with scipy bisection; tests assert no wall-clock time.


@pytest.mark.slow
def test_grid_accuracy_against_tight_grid(bench_grid):
    """<= 1e-9 relative error on every finite point, against the same grid at rtol 1e-13."""
    tight = stability_diagram("kappa_ratio", XR, "eps", YE, rtol=1e-13)
    fin = bench_grid.kind == 1
    assert np.array_equal(fin, tight.kind == 1)
    err = np.abs(bench_grid.critical_size[fin] / tight.critical_size[fin] - 1.0)
    assert err.max() <= 1e-9
    assert np.all(err <= bench_grid.rel_accuracy[fin] + 1e-13)


def test_grid_matches_per_point_and_bisection(bench_grid):
    rng = np.random.default_rng(3)
    fin = np.argwhere(bench_grid.kind == 1)
    for i, j in fin[rng.choice(len(fin), 25, replace=False)]:
        p = Params.from_ratio(2.0, XR[i], YE[j])
        c = critical_perturbation(p)
        assert abs(bench_grid.critical_size[i, j] - c.critical_size) <= 1e-12 * c.critical_size
        d = c.critical_size
        assert classify(p, "velocity-jump", d * (1 - 1e-8)).outcome == "stable"
        assert classify(p, "velocity-jump", d * (1 + 1e-8)).outcome == "unstable"


def test_zero_and_infinite_regions_exact(bench_grid):
    # the kind follows the exact sign of 1 - x of the input doubles (issue 22; referee:
    # exact rationals of the kappa the diagram forms, kappa = r (b/a - 1))
    inf = np.zeros((len(XR), len(YE)), dtype=bool)
    for i, j in np.ndindex(inf.shape):
        kappa = float(XR[i]) * (2.0 - 1.0)
        inf[i, j] = Fraction(float(YE[j])) * Fraction(kappa) >= 1
    assert np.array_equal(bench_grid.kind == 2, inf)
    assert np.all(np.isinf(bench_grid.critical_size[inf]))
    assert np.all(np.isfinite(bench_grid.critical_size[~inf]))
    # with kappa_ratio below 1 and a moving load point: zero
    z = stability_diagram("kappa_ratio", np.linspace(0.0, 0.99, 20), "eps", YE[:20])
    assert np.all(z.kind == 0) and np.all(z.critical_size == 0.0)
    json.dumps(z.to_dict(), allow_nan=False)


def test_boundary_flags():
    xr = np.array([1.0, 25.0 / 9.0, 3.0])
    ye = np.array([0.0, 0.36, 0.5])
    d = stability_diagram("kappa_ratio", xr, "eps", ye)
    assert d.on_boundary[0].all()  # kappa = kappa_crit row
    # x = 1 up to rounding: flagged, and the kind follows the exact 1 - x (issue 22)
    omx = 1 - Fraction(0.36) * Fraction(25.0 / 9.0 * (2.0 - 1.0))
    assert d.on_boundary[1, 1] and d.kind[1, 1] == (2 if omx <= 0 else 1)
    assert not d.on_boundary[2, 0] and not d.on_boundary[1, 0]
    assert d.kind[0, 0] == 1 and "closed form" in d.methods[d.method[0, 0]]


def test_outcome_mode_against_classify():
    sizes = np.linspace(0.0, 6.0, 25)
    d = stability_diagram("kappa_ratio", np.linspace(0.8, 3.0, 12), "size", sizes, eps=0.2)
    assert d.outcome is not None and d.outcome.shape == (12, 25)
    assert np.all(d.critical_size == d.critical_size[:, :1])
    rng = np.random.default_rng(5)
    for _ in range(30):
        i, j = int(rng.integers(12)), int(rng.integers(1, 25))
        if d.outcome_uncertain[i, j]:
            continue
        p = Params.from_ratio(2.0, d.x[i], 0.2)
        assert classify(p, "velocity-jump", sizes[j]).outcome == (
            "unstable" if d.outcome[i, j] else "stable"
        )
    # a size on the critical value is flagged
    c = critical_perturbation(Params.from_ratio(2.0, 2.0, 0.25)).critical_size
    d2 = stability_diagram("kappa_ratio", [2.0, 4.0], "eps", [0.25], size=c)
    assert d2.outcome_uncertain[0, 0] and not d2.outcome_uncertain[1, 0]
    assert d2.outcome[1, 0] == 0  # x = 1 there: nothing runs away


def test_other_axes_and_load_point():
    d = stability_diagram(
        "ba",
        np.linspace(1.05, 20.0, 15),
        "eps",
        np.linspace(0.0, 0.9, 10),
        kappa_ratio=2.0,
        perturbation="load-point-jump",
    )
    for i, j in ((0, 0), (7, 3), (14, 4)):
        c = critical_perturbation(Params.from_ratio(d.x[i], 2.0, d.y[j]), "load-point-jump")
        ref = math.inf if c.critical_size is None else c.critical_size
        assert d.critical_size[i, j] == pytest.approx(ref, rel=1e-12)
    d = stability_diagram("eps", [0.0, 0.5], "kappa_ratio", [0.5, 2.0], vo=0.0)
    assert d.kind[0, 0] == 1 and d.critical_size[0, 0] == pytest.approx(0.5, rel=1e-15)


def test_save_formats(tmp_path):
    d = stability_diagram("kappa_ratio", [1.0, 2.0, 6.0], "eps", [0.0, 0.25], size=2.0)
    with np.load(d.save(tmp_path / "g.npz")) as z:
        assert z["critical_size"].shape == (3, 2) and np.isinf(z["critical_size"][2, 1])
        assert np.array_equal(z["x"], d.x) and np.array_equal(z["y"], d.y) and "outcome" in z.files
        assert json.loads(str(z["meta"]))["x_name"] == "kappa_ratio"
    with open(d.save(tmp_path / "g.csv"), newline="") as fh:
        rows = list(csv.DictReader(fh))
    assert len(rows) == 6 and rows[5]["critical_size"] == "inf" and rows[0]["kind"] == "finite"
    js = json.loads((d.save(tmp_path / "g.json")).read_text())
    assert js["critical_size"][2][1] is None and js["y_name"] == "eps"
    with pytest.raises(ParameterError):
        d.save(tmp_path / "g.txt")


def test_invalid_arguments():
    with pytest.raises(ParameterError):
        stability_diagram("kappa_ratio", [1, 2], "kappa_ratio", [1, 2])
    with pytest.raises(ParameterError):
        stability_diagram("stiffness", [1, 2], "eps", [0.1])
    with pytest.raises(ParameterError):
        stability_diagram("size", [1, 2], "eps", [0.1], size=1.0)
    with pytest.raises(ParameterError):
        stability_diagram("eps", [0.1, 1.5], "ba", [2.0])
    with pytest.raises(ParameterError):
        stability_diagram("eps", [0.1], "ba", [2.0], vo=0.0, perturbation="load-point-jump")
    with pytest.raises(ParameterError):
        stability_diagram("eps", [0.1, math.nan], "ba", [2.0])


# Boundary values of each axis: b/a -> 1, kappa = 0, kappa = kappa_crit (ratio 1 and its
# neighbouring doubles), x = eps kappa/kappa_crit = 1 (ratio 4 at eps 0.25, 2 at 0.5),
# eps 0 and 1, size 0 and the smallest double.
_PIN_AXES = {
    "ba": [1.0 + 2.0**-52, 1.0000000017765576, 1.5, 2.0, 1e4],
    "kappa_ratio": [0.0, 0.5, 1.0 - 2.0**-53, 1.0, 1.0 + 2.0**-52, 2.0, 4.0, 50.0],
    "eps": [0.0, 0.25, 0.5, 0.9518881218377987, 1.0],
    "size": [0.0, 5e-324, 0.5, 1.0, 3.0, 12.6842, 1e4],
}
_PIN_FIXED = {"ba": 2.0, "kappa_ratio": 4.0, "eps": 0.25}


@pytest.mark.parametrize(
    "x_name, y_name, size",
    [
        ("kappa_ratio", "eps", None),
        ("eps", "ba", 1.0),
        ("ba", "kappa_ratio", 0.0),
        ("kappa_ratio", "size", None),
        ("size", "eps", None),
    ],
)
@pytest.mark.parametrize(
    "pert, vo", [("velocity-jump", 0.0), ("velocity-jump", 1.0), ("load-point-jump", 1e-3)]
)
def test_diagram_is_the_batch_point_by_point(
    x_name: str, y_name: str, size: float | None, pert: str, vo: float
) -> None:
    """Every output of the diagram is, bit for bit, what rsfcore.batch.critical_points
    gives at the same points laid out independently (numpy meshgrid, kappa = ratio (b/a -
    1) formed by numpy): the diagram has no finishing rule of its own (zero/infinite
    values, boundary flag, outcome: rsfcore.batchloop.finish_point), also where a size
    axis reuses one critical size for every size, and on the boundaries."""
    xv, yv = np.array(_PIN_AXES[x_name]), np.array(_PIN_AXES[y_name])
    if "ba" in (x_name, y_name) and "kappa_ratio" in (x_name, y_name):
        xv = xv[xv <= 1e3] if x_name == "ba" else xv  # kappa <= 1e6
        yv = yv[yv <= 1e3] if y_name == "ba" else yv
    d = stability_diagram(x_name, xv, y_name, yv, perturbation=pert, vo=vo, size=size, **_PIN_FIXED)
    X, Y = np.meshgrid(xv, yv, indexing="ij")
    at = {k: np.full(X.shape, v) for k, v in _PIN_FIXED.items()}
    at[x_name], at[y_name] = X, Y
    ba = at["ba"].ravel()
    sz = at["size"].ravel() if "size" in at else (None if size is None else np.full(ba.size, size))
    ref = batch.critical_points(
        ba,
        at["kappa_ratio"].ravel() * (ba - 1.0),
        at["eps"].ravel(),
        vo,
        perturbation=pert,
        size=sz,
    )
    assert not ref.failed.any()
    shape = X.shape
    for name in ("kind", "critical_size", "rel_accuracy", "method", "on_boundary"):
        got, want = getattr(d, name), getattr(ref, name).reshape(shape)
        assert got.dtype == want.dtype and np.array_equal(got, want, equal_nan=True), name
    assert np.array_equal(np.signbit(d.critical_size), np.signbit(ref.critical_size.reshape(shape)))
    if sz is None:
        assert d.outcome is None and d.outcome_uncertain is None
    else:
        assert d.outcome is not None and ref.outcome is not None
        assert np.array_equal(d.outcome, ref.outcome.reshape(shape))
        assert np.array_equal(d.outcome_uncertain, ref.outcome_uncertain.reshape(shape))
    # the grid spans what it is meant to: every kind, and boundary points
    # (zero needs kappa < kappa_crit with v_o > 0: a kappa_ratio axis)
    zero = vo > 0.0 and "kappa_ratio" in (x_name, y_name)
    assert set(np.unique(d.kind).tolist()) >= ({0, 1, 2} if zero else {1, 2})
    assert d.on_boundary.any()


def test_fallback_runs_once_per_parameter_point_and_a_failure_raises(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """Points the kernel lists for bisection (forced here at eps = 0.3) are bisected once
    per parameter point whatever the number of sizes on a size axis, and finished like
    the others; a bisection that raises reaches the caller with its own exception."""
    from rsfcore import batchloop
    from rsfcore import critical as crit
    from rsfcore import diagram as dg
    from tests.e2e.test_worker_faultplugin import list_as_fallback

    orig = batchloop.points_kernel
    monkeypatch.setattr(
        batchloop, "points_kernel", lambda *a: list_as_fallback(orig, a, orig(*a), 0.3)
    )
    real = crit.bisect_critical
    calls: list[Params] = []

    def counting(p: Params, *a: object, **kw: object) -> object:
        calls.append(p)
        return real(p, *a, **kw)  # type: ignore[arg-type]

    monkeypatch.setattr(crit, "bisect_critical", counting)
    sizes = [0.0, 1.0, 5.0, 50.0]
    d = stability_diagram("size", sizes, "eps", [0.1, 0.3], kappa_ratio=3.0, rtol=1e-8)
    assert len(calls) == 1 and d.n_fallback == 1
    bis = real(Params(2.0, 3.0, 0.3, 1.0), rtol=1e-8)
    assert bis.critical_size is not None and 1.0 < bis.critical_size < 50.0
    assert (d.critical_size[:, 1] == bis.critical_size).all()
    assert (d.method[:, 1] == crit.M_BISECTION).all() and (d.kind[:, 1] == 1).all()
    assert d.outcome is not None
    assert d.outcome[:, 1].tolist() == [int(s > bis.critical_size) for s in sizes]

    def failing(p: Params, *a: object, **kw: object) -> object:
        raise FloatingPointError(f"boom at {p.eps}")

    monkeypatch.setattr(crit, "bisect_critical", failing)
    monkeypatch.setattr(dg, "bisect_critical", failing)
    with pytest.raises(FloatingPointError, match="boom at 0.3"):
        stability_diagram("kappa_ratio", [2.0, 3.0], "eps", [0.1, 0.3], rtol=1e-8)
