"""The paper's figures: the data of every figure (rsfapp.adapter.figures, the one adapter
of the figure question) agree with an independent value, and rsfplots draws each of them.

Figures are built at 'draft' quality (coarse grids) so that the whole file stays well
under 90 s.  "Independent" means: the printed closed forms re-implemented here, a direct
scipy integration, the vendored reference values (tests/data/reference.json), or a
property the figure must have (U constant along its trajectories, a closed orbit
returning to its start, eigenmodes vanishing at the tips).
"""

from __future__ import annotations

import json
import math
import struct
from fractions import Fraction
from pathlib import Path

import numpy as np
import pytest
from scipy.integrate import solve_ivp
from scipy.optimize import brentq
from scipy.special import lambertw

import rsfplots
from rsfapp.adapter.figures import figure, figure_arrays, figure_list
from rsfapp.requests.figures import FIGURES, FigureRequest

from .reference import reference_by_id

Q = "draft"
EXPECTED = {
    "velocity-step",
    "trajectories-kcrit",
    "critical-jump-kcrit",
    "rate-neutral",
    "stability-diagram-velocity",
    "stability-diagram-load-point",
    "trajectories-vo0-soft",
    "trajectories-vo0-stiff",
    "critical-jump-vo0",
    "periodic-response",
    "non-periodic-response",
    "continuum-modes",
}


# ----------------------------------------------------------------------------- helpers
def _reference() -> dict[str, dict]:
    return reference_by_id()


def _ref_close(got: float, case: dict, factor: float = 100.0) -> None:
    tol = max(factor * float(case["trusted_rel_tol"] or 0.0), 1e-12)
    assert got == pytest.approx(case["value"], rel=tol), case["id"]


def _a(v) -> np.ndarray:
    return np.array([np.nan if x is None else x for x in v], dtype=float)


@pytest.fixture(scope="module")
def data() -> dict[str, dict]:
    return {n: figure(FigureRequest(name=n, quality=Q)) for n in FIGURES}


def _arrays(name: str) -> dict:
    return figure_arrays(FigureRequest(name=name, quality=Q))


def _dist_to_polylines(px: np.ndarray, py: np.ndarray, lines: list[dict]) -> np.ndarray:
    """Distance of each point to the nearest segment of the polylines."""
    best = np.full(px.shape, np.inf)
    for ln in lines:
        x, y = _a(ln["phi"]), _a(ln["psi"])
        ax, ay, bx, by = x[:-1], y[:-1], x[1:], y[1:]
        dx, dy = bx - ax, by - ay
        L2 = np.maximum(dx * dx + dy * dy, 1e-300)
        t = np.clip(((px[:, None] - ax) * dx + (py[:, None] - ay) * dy) / L2, 0.0, 1.0)
        d = np.hypot(px[:, None] - (ax + t * dx), py[:, None] - (ay + t * dy)).min(axis=1)
        best = np.minimum(best, d)
    return best


# printed closed forms, re-implemented independently of rsfcore.analytic ------------------
def U_kcrit_printed(phi, psi, ba, eps, vo=1.0):
    """eq: trajectories 1 (0 < eps < 1), eq: trajectories 1-2 (eps = 1), slip limit (eps = 0)."""
    kappa = ba - 1.0
    if eps == 1.0:
        return ba * (np.exp((psi - phi) / ba) * (vo + np.exp(phi) / (ba - 1.0)) * kappa - psi)
    if eps == 0.0:  # limit eps -> 0 of eq: trajectories 1 (q = psi - phi, D = b/a)
        return np.exp(psi - phi) * (kappa * vo - np.exp(phi) * ((1.0 - ba) * phi - psi + ba))
    q = (psi - phi) * (1.0 - eps * (1.0 - 1.0 / ba))
    D = ba * (1.0 - eps) + eps
    m = ((1.0 - ba) * phi - psi) / ba
    return (
        ba
        * np.exp(q)
        * (
            kappa * vo / D
            + np.exp(phi) / eps * (np.exp(eps * m) / (eps - 1.0) + (ba - kappa * eps) / D)
        )
    )


def U_vo0_printed(phi, psi, ba, kappa, eps):
    """eq: trajectories 2 (eps > 0) and its eps -> 0 limit."""
    n = ((ba - 1.0) * phi + psi) / ba
    if eps == 0.0:
        return (
            np.exp(psi * (ba - 1.0) / kappa)
            * kappa
            * ba
            * ((ba - 1.0) * n - kappa)
            / (ba - 1.0) ** 2
        )
    num = 1.0 - ba + np.exp(eps * n) * (ba - 1.0 - kappa * eps)
    return (
        np.exp(psi * (ba - kappa * eps - 1.0) / kappa)
        * kappa
        * ba
        * num
        / (eps * (ba - 1.0) * (ba - 1.0 - kappa * eps))
    )


def dcrit_kcrit_printed(ba: float, eps: float) -> float:
    """Intersection of psi = phi with eq: limiting trajectory 1 (Lambert W at eps = 0)."""
    if eps == 0.0:
        return float(1.0 + lambertw((1.0 / ba - 1.0) / math.e).real)
    kappa = ba - 1.0

    def f(phi: float) -> float:
        arg = (
            math.exp(phi + (1.0 / ba - 1.0) * eps * phi)
            * (ba - eps * (ba - 1.0))
            / ((eps - 1.0) * (math.exp(phi) * (kappa * eps - ba) - kappa * eps))
        )
        return ba / eps * math.log(arg) - phi

    return brentq(f, 1e-9, 60.0, xtol=1e-15)


def dcrit_vo0_printed(ba: float, kappa: float, eps: float) -> float:
    """eq: analytical phi crit (inf when eps kappa >= kappa_crit)."""
    x = eps * kappa / (ba - 1.0)
    if x >= 1.0:
        return math.inf
    return kappa / (ba - 1.0) if eps == 0.0 else math.log(1.0 / (1.0 - x)) / eps


# ----------------------------------------------------------------------------- rendering
def test_registry_and_list() -> None:
    assert set(FIGURES) == EXPECTED
    assert list(rsfplots.DRAWINGS) == list(FIGURES)  # a drawing for every figure
    listed = figure_list()
    assert [d["name"] for d in listed["figures"]] == list(FIGURES)
    for d in listed["figures"]:
        assert d["caption"].startswith("fig: ") and len(d["caption"]) > 40
        assert d["url"] == f"/v1/figures/{d['name']}"
    assert listed["formats"] == ["png", "svg", "json"]
    assert listed["qualities"] == ["paper", "draft"]
    # the default quality is the model's, 'paper'
    assert FigureRequest(name="rate-neutral").quality == "paper"


def _png_ok(blob: bytes) -> tuple[int, int]:
    assert blob[:8] == b"\x89PNG\r\n\x1a\n"
    assert blob[12:16] == b"IHDR"
    w, h = struct.unpack(">II", blob[16:24])
    assert w >= 300 and h >= 250
    assert len(blob) > 15_000  # a real plot, not an empty canvas
    return w, h


@pytest.mark.parametrize("name", sorted(EXPECTED))
def test_render_png(name: str, tmp_path: Path, data: dict) -> None:
    out = tmp_path / f"{name}.png"
    assert rsfplots.render_figure(_arrays(name), out) is None
    blob = out.read_bytes()
    _png_ok(blob)
    import matplotlib.image as mpimg

    img = mpimg.imread(out)
    assert img.std() > 0.05  # not blank
    json.dumps(data[name], allow_nan=False)  # JSON-safe data behind it
    assert data[name]["label"].startswith("fig: ")
    assert data[name]["name"] == name and data[name]["quality"] == Q


def test_render_bytes_svg_and_errors() -> None:
    arrays = _arrays("continuum-modes")
    svg = rsfplots.render_figure(arrays, "svg")
    assert isinstance(svg, bytes) and b"<svg" in svg[:2000]
    png = rsfplots.render_figure(arrays, "png")
    _png_ok(png)
    # the same data draw the same bytes (PNG, and SVG with its fixed id salt)
    assert rsfplots.render_figure(arrays, "svg") == svg
    assert rsfplots.render_figure(arrays, "png") == png
    from pydantic import ValidationError

    from rsfcore import ParameterError

    with pytest.raises(ParameterError):
        rsfplots.render_figure({"name": "no-such-figure", "quality": Q}, "png")
    with pytest.raises(ParameterError):
        rsfplots.render_figure(arrays, "x.jpg")
    with pytest.raises(ValidationError) as e:
        FigureRequest(name="no-such-figure")
    assert e.value.errors()[0]["loc"] == ("name",)
    with pytest.raises(ValidationError) as e:
        FigureRequest(name="continuum-modes", quality="best")  # type: ignore[arg-type]
    assert e.value.errors()[0]["loc"] == ("quality",)


def test_cli(tmp_path: Path) -> None:
    from typer.testing import CliRunner

    from rsfcli.main import app

    cli = CliRunner()
    r = cli.invoke(app, ["figure", "--list"])
    assert r.exit_code == 0, r.output
    for name, info in FIGURES.items():
        assert name in r.output and info.label in r.output
    r = cli.invoke(app, ["figure", "--list", "--json"])
    assert r.exit_code == 0 and json.loads(r.output) == json.loads(json.dumps(figure_list()))
    target = tmp_path / "modes.svg"
    r = cli.invoke(app, ["figure", "continuum-modes", "--out", str(target), "--quality", Q])
    assert r.exit_code == 0, r.output
    assert target.read_bytes() == rsfplots.render_figure(_arrays("continuum-modes"), "svg")
    assert "quality draft" in r.output  # the text output echoes the quality used
    r = cli.invoke(app, ["figure", "continuum-modes", "--quality", Q, "--json"])
    assert r.exit_code == 0, r.output
    want = figure(FigureRequest(name="continuum-modes", quality=Q))
    assert json.loads(r.output) == json.loads(json.dumps(want))
    for argv in (
        ["figure", "nope", "--out", str(tmp_path / "x.png")],
        ["figure"],
        ["figure", "continuum-modes", "--out", str(tmp_path / "x.pdf")],
        ["figure", "continuum-modes", "--quality", "best", "--json"],
    ):
        r = cli.invoke(app, argv)
        assert r.exit_code == 2, (argv, r.output)
    assert not (tmp_path / "x.png").exists() and not (tmp_path / "x.pdf").exists()


def test_result_plots() -> None:
    from rsfcore import Params, simulate
    from rsfcore.analytic import U_kcrit
    from rsfcore.diagram import stability_diagram

    r = simulate(Params(2.0, 2.0, 0.25), "velocity-jump", 2.0, n_points=200)
    _png_ok(rsfplots.plot_trajectory(r))
    _png_ok(rsfplots.plot_trajectory(json.loads(json.dumps(r.to_dict()))))
    phi, psi = np.linspace(-3, 4, 40), np.linspace(-3, 3, 30)
    U = U_kcrit(phi[:, None], psi[None, :], 2.0, 0.25)
    _png_ok(rsfplots.plot_u_field(phi, psi, U))
    svc = {
        "phi": phi.tolist(),
        "psi": psi.tolist(),
        "U": [[None if not np.isfinite(v) else v for v in row] for row in U.tolist()],
        "function": "kcrit",
    }
    _png_ok(rsfplots.plot_u_field(svc))
    d = stability_diagram("kappa_ratio", [0.5, 1, 1.5, 2, 3], "eps", [0, 0.25, 0.5])
    _png_ok(rsfplots.plot_diagram(d))
    _png_ok(rsfplots.plot_diagram(json.loads(json.dumps(d.to_dict()))))
    d2 = stability_diagram("kappa_ratio", [1, 1.5, 2, 3], "size", [0.5, 1, 2, 4])
    _png_ok(rsfplots.plot_diagram(d2))


def test_rsfcore_does_not_import_rsfplots() -> None:
    root = Path(__file__).resolve().parents[2] / "rsfcore"
    files = list(root.rglob("*.py"))
    assert len(files) > 10  # the glob must find the package (it once looked in tests/)
    for f in files:
        assert "rsfplots" not in f.read_text(), f


# ----------------------------------------------------------------------------- data checks
def test_velocity_step(data: dict) -> None:
    d = data["velocity-step"]
    eps_seen = []
    for panel in d["panels"]:
        eps = panel["eps"]
        eps_seen.append(eps)
        for c in panel["curves"]:
            r, s, y = c["v2_over_v1"], _a(c["slip"]), _a(c["dtau_over_bsigma"])
            assert s[0] == 0.0 and y[0] == pytest.approx(
                math.log(r), rel=1e-12
            )  # starts at ln(V2/V1)
            mag = np.abs(y)
            assert np.all(np.diff(mag) <= 1e-12)  # decays monotonically
            assert mag[-1] < 0.01 * abs(math.log(r))  # to 0
            if eps == 0.0:  # slip law: ln(V2/V1) e^(-delta/Dc)
                np.testing.assert_allclose(y, math.log(r) * np.exp(-s), rtol=1e-12, atol=1e-300)
            if eps == 1.0:  # aging law: ln(1 + (V2/V1 - 1) e^(-delta/Dc))
                np.testing.assert_allclose(
                    y, np.log1p((r - 1.0) * np.exp(-s)), rtol=1e-10, atol=1e-15
                )
        assert {c["v2_over_v1"] for c in panel["curves"]} == {
            10.0**k for k in (-4, -3, -2, -1, 1, 2, 3, 4)
        }
    assert eps_seen[0] == 0.0 and eps_seen[-1] == 1.0


def _check_phase_panel(panel: dict, window, Ufun, tol_U: float = 1e-6) -> None:
    x0, x1, y0, y1 = window
    levels = [c["level"] for c in panel["contours"]]
    h = max((x1 - x0), (y1 - y0)) / 89.0  # draft grid spacing
    for t in panel["trajectories"]:
        ph, ps = _a(t["phi"]), _a(t["psi"])
        assert ph[0] == pytest.approx(t["size"]) and ps[0] == pytest.approx(
            t["size"]
        )  # 45 degree jump
        inside = (ph > x0) & (ph < x1) & (ps > y0) & (ps < y1)
        U = Ufun(ph[inside], ps[inside])
        U0 = Ufun(np.array([t["size"]]), np.array([t["size"]]))[0]
        # U (printed closed form, evaluated here) is constant along the numerical trajectory
        assert np.max(np.abs(U - U0)) <= tol_U * max(1.0, abs(U0)), (panel["eps"], t["size"])
        assert t["U"] == pytest.approx(U0, rel=1e-9, abs=1e-12)
        # ... and the trajectory lies on the plotted contour of that level
        assert t["U"] in levels
        lines = panel["contours"][levels.index(t["U"])]["lines"]
        assert lines, "no contour drawn for a trajectory's level"
        dist = _dist_to_polylines(ph[inside], ps[inside], lines)
        assert np.max(dist) < 0.6 * h, (panel["eps"], t["size"], float(np.max(dist)))


def test_trajectories_kcrit(data: dict) -> None:
    d = data["trajectories-kcrit"]
    ba = d["ba"]
    assert ba == 1.25 and d["kappa"] == 0.25
    assert [p["eps"] for p in d["panels"]] == [0.0, 0.3, 0.6, 1.0]
    for panel in d["panels"]:
        eps = panel["eps"]
        _check_phase_panel(panel, d["window"], lambda f, s, e=eps: U_kcrit_printed(f, s, ba, e))
        if eps < 1.0:
            dc = panel["critical_size"]
            assert dc == pytest.approx(dcrit_kcrit_printed(ba, eps), rel=1e-10)
            c = panel["critical_trajectory"]
            # the plotted critical trajectory passes through the critical size: psi_crit(d) = d
            assert np.interp(dc, _a(c["phi"]), _a(c["psi"])) == pytest.approx(dc, abs=2e-3)
            # and is the level U = 0 of the printed U
            assert np.nanmax(np.abs(U_kcrit_printed(_a(c["phi"]), _a(c["psi"]), ba, eps))) < 1e-9
            for t in panel["trajectories"]:
                assert t["outcome"] == ("stable" if t["size"] < dc else "unstable")
        else:
            assert panel["critical_size"] is None and panel["critical_kind"] == "infinite"
            assert all(t["outcome"] == "stable" for t in panel["trajectories"])
    ref = _reference()
    _ref_close(d["panels"][0]["critical_size"], ref["kcrit_vjump_ba1.25_eps0"])


def test_critical_jump_kcrit(data: dict) -> None:
    d = data["critical-jump-kcrit"]
    a, b = d["panel_a"], d["panel_b"]
    eps, dc = _a(a["eps"]), _a(a["critical_size"])
    for e, v in zip(eps[::7], dc[::7], strict=True):
        assert v == pytest.approx(dcrit_kcrit_printed(1.25, float(e)), rel=1e-9)
    # the two asymptotes of the caption
    assert dc[0] == pytest.approx(a["slip_law_asymptote"], rel=1e-12)  # eps = 0 exactly
    assert dc[1] == pytest.approx(a["slip_law_asymptote"], rel=1e-3)  # eps = 1e-4
    near1 = eps == eps.max()
    assert 1.0 - eps.max() <= 1e-4
    assert dc[near1][0] / _a(a["aging_law_asymptote"])[near1][0] == pytest.approx(1.0, rel=0.02)
    assert np.all(np.diff(dc) > 0)  # grows with eps
    ab, db = _a(b["a_over_b"]), _a(b["critical_size"])
    np.testing.assert_allclose(db, 1.0 + lambertw((ab - 1.0) / math.e).real, rtol=1e-10)
    assert db[0] / math.sqrt(2.0 * ab[0]) == pytest.approx(1.0, rel=0.01)  # sqrt(2 a/b) scaling
    ref = _reference()
    for e, key in (
        (0.0, "kcrit_vjump_ba1.25_eps0"),
        (0.1, "kcrit_vjump_ba1.25_eps0.1"),
        (0.5, "kcrit_vjump_ba1.25_eps0.5"),
        (0.99, "kcrit_vjump_ba1.25_eps0.99"),
    ):
        _ref_close(float(dc[np.flatnonzero(eps == e)[0]]), ref[key])
    for v, key in ((0.1, "slip_kcrit_vjump_a/b=0.1"), (0.5, "slip_kcrit_vjump_a/b=0.5")):
        _ref_close(float(db[np.flatnonzero(ab == v)[0]]), ref[key])


def test_rate_neutral(data: dict) -> None:
    d = data["rate-neutral"]
    t = d["trajectory"]
    T, phi, psi = _a(t["T"]), _a(t["phi"]), _a(t["psi"])
    assert d["outcome"] == "stable" and phi[0] == 1.0 and psi[0] == 1.0
    # direct integration of eq:psi_T / eq:phi_T with b/a = 1 exactly
    ba, kappa, eps = 1.0, d["kappa"], d["eps"]

    def rhs(_t: float, y: np.ndarray) -> list[float]:
        ph, ps = y
        dps = kappa * (1.0 - math.exp(ph))
        L = ph + (ps - ph) / ba
        return [dps - ba / eps * math.expm1(-eps * L) * math.exp(ph), dps]

    sol = solve_ivp(
        rhs, (0.0, T[-1]), [1.0, 1.0], method="DOP853", rtol=1e-11, atol=1e-13, t_eval=T
    )
    np.testing.assert_allclose(phi, sol.y[0], atol=2e-6)
    np.testing.assert_allclose(psi, sol.y[1], atol=2e-6)
    assert abs(phi[-1]) < 1e-4 and abs(psi[-1]) < 1e-4  # back at steady state
    assert np.count_nonzero(np.diff(np.sign(phi)) != 0) >= 2  # spirals


def _check_diagram(d: dict, at_kcrit, ref_value: float) -> None:
    curves = d["panel_a"]["curves"]
    for c in curves:
        x, v = _a(c["kappa_ratio"]), _a(c["critical_size"])
        eps = c["eps"]
        assert x[0] == 1.0 and v[0] == pytest.approx(at_kcrit(eps), rel=1e-9)
        # infinite (null) exactly where eps kappa >= kappa_crit
        np.testing.assert_array_equal(np.isnan(v), eps * x >= 1.0)
        fin = ~np.isnan(v)
        assert np.all(np.diff(v[fin]) > 0)  # grows with the stiffness
    j = [c["eps"] for c in curves].index(0.25)
    x = _a(curves[j]["kappa_ratio"])
    got = _a(curves[j]["critical_size"])[np.flatnonzero(x == 2.0)[0]]
    assert got == pytest.approx(ref_value, rel=1e-8)
    assert d["panel_b"]["critical_size"] == pytest.approx(ref_value, rel=1e-8)


def test_stability_diagram_velocity(data: dict) -> None:
    ref = _reference()
    d = data["stability-diagram-velocity"]
    _check_diagram(
        d,
        lambda e: dcrit_kcrit_printed(2.0, e) if e < 1 else math.inf,
        ref["vjump_ba2_r2_eps0.25"]["value"],
    )
    pb = d["panel_b"]
    assert [t["size"] for t in pb["trajectories"]] == [1.0, 1.5, 2.5, 3.0]
    for t in pb["trajectories"]:
        ph, ps = _a(t["phi"]), _a(t["psi"])
        if t["size"] < pb["critical_size"]:
            assert t["outcome"] == "stable" and abs(ph[-1]) < 1e-4 and abs(ps[-1]) < 1e-4
        else:
            assert t["outcome"] == "unstable" and ph[-1] > 30
    # the dashed level lines are U_kcrit of kappa = kappa_crit = 1: check a vertex of each
    for c in pb["lyapunov"]["contours"]:
        ln = c["lines"][0]
        u = U_kcrit_printed(_a(ln["phi"]), _a(ln["psi"]), 2.0, 0.25)
        x0, x1, y0, y1 = pb["window"]
        assert np.median(np.abs(u - c["level"])) < 0.05 * max(1.0, abs(c["level"]))


def test_stability_diagram_load_point(data: dict) -> None:
    ref = _reference()
    d = data["stability-diagram-load-point"]
    _check_diagram(d, lambda e: 1.0 / (1.0 * (1.0 - e)), ref["ljump_ba2_r2_eps0.25"]["value"])
    pb = d["panel_b"]
    assert [t["size"] for t in pb["trajectories"]] == [4.0, 9.0, 12.0, 14.0]
    assert 12.0 < pb["critical_size"] < 14.0
    for t in pb["trajectories"]:
        ph, ps = _a(t["phi"]), _a(t["psi"])
        assert ph[0] == 0.0 and ps[0] == 0.0
        if t["outcome"] == "stable":
            ell = math.log1p(t["size"])
            assert ph[-1] == pytest.approx(ell, abs=1e-4) and ps[-1] == pytest.approx(
                -ell, abs=1e-4
            )
        else:
            assert t["size"] == 14.0 and ph[-1] > 30


def _check_vo0(d: dict, ref: dict) -> None:
    ba, kappa = d["ba"], d["kappa"]
    for panel in d["panels"]:
        eps = panel["eps"]
        _check_phase_panel(
            panel, d["window"], lambda f, s, e=eps: U_vo0_printed(f, s, ba, kappa, e)
        )
        dc = dcrit_vo0_printed(ba, kappa, eps)
        if math.isfinite(dc):
            assert panel["critical_size"] == pytest.approx(dc, rel=1e-12)
            c = panel["critical_trajectory"]
            # the plotted critical line passes through (d_crit, d_crit)
            assert np.interp(dc, _a(c["phi"]), _a(c["psi"])) == pytest.approx(
                dc, rel=1e-12, abs=1e-12
            )
            for t in panel["trajectories"]:
                assert t["outcome"] == ("stable" if t["size"] < dc else "unstable")
        else:
            assert panel["critical_size"] is None and "critical_trajectory" not in panel
            assert all(t["outcome"] == "stable" for t in panel["trajectories"])
        # acceleration line (eq: acceleration line): phi increases above it, decreases below
        a = panel["acceleration_line"]
        slope = (a["psi"][1] - a["psi"][0]) / (a["phi"][1] - a["phi"][0])
        assert slope == pytest.approx(1.0 - ba)
        La = (math.log(1.0 / (1.0 - eps * kappa / ba)) / eps) if eps > 0 else kappa / ba
        for t in panel["trajectories"]:
            ph, ps = _a(t["phi"]), _a(t["psi"])
            psa = (1.0 - ba) * ph + ba * La
            assert a["psi"][0] == pytest.approx((1.0 - ba) * a["phi"][0] + ba * La, rel=1e-12)
            off = ps - psa
            dphi = np.diff(ph)
            sure = (
                (np.abs(off[:-1]) > 0.05)
                & (np.abs(off[1:]) > 0.05)
                & (np.sign(off[:-1]) == np.sign(off[1:]))
            )
            assert np.all(np.sign(dphi[sure]) == np.sign(off[:-1][sure])), (eps, t["size"])


def test_trajectories_vo0_soft(data: dict) -> None:
    ref = _reference()
    d = data["trajectories-vo0-soft"]
    assert (
        d["kappa"] == 0.5
        and d["ba"] == 2.0
        and [p["eps"] for p in d["panels"]] == [0.0, 0.3, 0.6, 1.0]
    )
    _check_vo0(d, ref)
    _ref_close(d["panels"][0]["critical_size"], ref["vo0_vjump_ba2_k0.5_eps0"])


def test_trajectories_vo0_stiff(data: dict) -> None:
    ref = _reference()
    d = data["trajectories-vo0-stiff"]
    assert d["kappa"] == 1.5 and [p["eps"] for p in d["panels"]] == [0.0, 0.6, 0.7, 1.0]
    _ref_close(d["eps_crit"], ref["vo0_eps_crit_ba2_k1.5"])
    assert d["eps_crit"] == pytest.approx(2.0 / 3.0, rel=1e-15)  # the caption's eps_crit
    assert [p["critical_kind"] for p in d["panels"]] == ["finite", "finite", "infinite", "infinite"]
    _check_vo0(d, ref)


def test_critical_jump_vo0(data: dict) -> None:
    ref = _reference()
    d = data["critical-jump-vo0"]
    a, b = d["panel_a"], d["panel_b"]
    for c in a["curves"]:
        eps, v = _a(c["eps"]), _a(c["critical_size"])
        want = np.array([dcrit_vo0_printed(2.0, c["kappa"], float(e)) for e in eps])
        # at the double nearest eps_crit the printed formula (in doubles) says infinite, but
        # the exact 1 - x of those doubles can be positive (issue 22): then d_crit = L* =
        # -ln(1 - x)/eps, finite (referee: exact rationals)
        omx = [1 - Fraction(float(e)) * Fraction(c["kappa"]) for e in eps]  # kappa_crit = 1
        edge = ~np.isfinite(want) & np.array([o > 0 for o in omx])
        for i in np.flatnonzero(edge):
            assert v[i] == pytest.approx(-math.log(float(omx[i])) / float(eps[i]), rel=1e-14)
        np.testing.assert_array_equal(np.isnan(v), ~np.isfinite(want) & ~edge)
        np.testing.assert_allclose(v[np.isfinite(want)], want[np.isfinite(want)], rtol=1e-12)
        for e, key in (
            (0.0, "vo0_vjump_ba2_k0.5_eps0"),
            (0.3, "vo0_vjump_ba2_k1_eps0.3"),
            (0.9, "vo0_vjump_ba2_k1_eps0.9"),
        ):
            if c["kappa"] == ref[key]["inputs"]["kappa"]:
                _ref_close(float(v[np.flatnonzero(eps == e)[0]]), ref[key])
    _ref_close(a["eps_crit"]["1.5"], ref["vo0_eps_crit_ba2_k1.5"])
    for c in b["curves"]:
        ab, v = _a(c["a_over_b"]), _a(c["critical_size"])
        assert c["ab_crit"] == pytest.approx(1.0 / (c["eps"] + 1.0))
        # finite exactly below (a/b)_crit, growing towards it
        away = np.abs(ab - c["ab_crit"]) > 1e-9  # on the boundary itself rounding decides
        np.testing.assert_array_equal(np.isnan(v)[away], (ab >= c["ab_crit"])[away])
        assert np.all(np.diff(v[~np.isnan(v)]) > 0)
        want = np.array([dcrit_vo0_printed(1.0 / x, 1.0, c["eps"]) for x in ab])
        fin = np.isfinite(want) & away
        np.testing.assert_allclose(v[fin], want[fin], rtol=1e-12)
        if c["eps"] == 0.5:
            _ref_close(c["ab_crit"], ref["vo0_ab_crit_k1_eps0.5"])


def test_periodic_response(data: dict) -> None:
    ref = _reference()
    d = data["periodic-response"]
    _ref_close(d["critical_size"], ref["kcrit_ljump_ba2_eps0.25"])
    assert d["size"] < d["critical_size"] and d["outcome"] == "stable" and d["U"] < 0
    t = d["trajectory"]
    T, phi, psi, Th = _a(t["T"]), _a(t["phi"]), _a(t["psi"]), _a(t["Theta"])
    np.testing.assert_allclose(Th, psi - phi, atol=1e-12)
    assert phi[0] == 0.0 and psi[0] == 0.0
    # U of the new load-point velocity is conserved (closed orbit)
    U = U_kcrit_printed(phi, psi, 2.0, 0.25, d["vo_after"])
    assert np.max(np.abs(U - d["U"])) < 1e-6 * abs(d["U"])
    # periodic: phi crosses 0 upwards once a period, each time back at the start psi = 0
    i = np.flatnonzero((phi[:-1] < 0) & (phi[1:] >= 0))
    assert i.size >= 2
    w = -phi[i] / (phi[i + 1] - phi[i])
    Tc = T[i] + w * (T[i + 1] - T[i])
    psic = psi[i] + w * (psi[i + 1] - psi[i])
    np.testing.assert_allclose(psic, 0.0, atol=0.03)
    per = np.diff(np.r_[0.0, Tc])
    np.testing.assert_allclose(per, per.mean(), rtol=0.01)


def test_non_periodic_response(data: dict) -> None:
    ref = _reference()
    d = data["non-periodic-response"]
    _ref_close(d["critical_size"], ref["ljump_ba2_r2_eps0.25"])
    assert [r["size"] for r in d["rows"]] == [4.0, 9.0, 12.0, 14.0]
    for r in d["rows"]:
        phi, psi, th = _a(r["phi"]), _a(r["psi"]), _a(r["theta"])
        if r["size"] < d["critical_size"]:
            ell = math.log1p(r["size"])  # new steady state at v_o (1 + dv)
            assert r["outcome"] == "stable"
            assert phi[-1] == pytest.approx(ell, abs=1e-4) and psi[-1] == pytest.approx(
                -ell, abs=1e-4
            )
            assert th[-1] == pytest.approx(1.0 / (1.0 + r["size"]), rel=1e-4)
        else:
            assert r["outcome"] == "unstable" and phi[-1] > 30 and psi[-1] < psi[0]


def test_continuum_modes(data: dict) -> None:
    ref = _reference()
    d = data["continuum-modes"]
    cases = {c["case"]: c for c in d["cases"]}
    for name in ("B", "D", "E"):
        y = _a(cases[name]["delta"])
        assert np.max(y) == pytest.approx(1.0, abs=1e-3)
        assert abs(y[-1]) < 1e-8  # vanishes at the tip x = 1 (rim r = R for E)
        if name != "E":
            assert abs(y[0]) < 1e-8  # and at x = -1
            np.testing.assert_allclose(y, y[::-1], atol=1e-8)  # symmetric lowest mode
    np.testing.assert_allclose(
        _a(cases["D"]["delta"]), np.cos(math.pi * _a(cases["D"]["x"]) / 2.0), atol=1e-12
    )
    assert cases["D"]["eigenvalue"] == pytest.approx(math.pi**2 / 4.0, rel=1e-15)
    _ref_close(cases["B"]["eigenvalue"], ref["eig_interval_B"])
    _ref_close(cases["E"]["eigenvalue"], ref["eig_disk_E"])
    # the table's printed digits: E agrees to all 10 printed, B only to 9 (not converged)
    assert cases["E"]["eigenvalue"] == pytest.approx(1.003059516, abs=1e-9)
    assert cases["B"]["eigenvalue"] == pytest.approx(1.157773882, abs=2e-9)
