"""The data behind the paper's figures (``GET /v1/figures/{name}``, ``rsf figure``,
``Client.figure_data``): the request model :class:`rsfapp.requests.figures.FigureRequest`
in, rsfcore, numbers out; no matplotlib (rsfplots draws the images from these data).
Each figure's computation imports the rsfcore modules it asks (a CLI process draws one
figure: the velocity-step curves are closed forms and load no kernel).

Each figure is computed once per (name, quality) by a ``_compute_*`` function that
returns a dict of numpy arrays and the parameters it used; keys starting with ``_`` are
what only a drawing needs (the U grids and contour levels, the part of a trajectory inside
a plotted window).

* :func:`figure_arrays`: that dict at full resolution, with ``name`` and ``quality``
  (what :func:`rsfplots.draw_figure` draws; cached, the same object for the same request);
* :func:`figure`: the answer of every door, JSON-safe: the catalogue entry (name, label,
  caption, note), the quality and the arrays without the drawing-only keys, every curve
  thinned to at most :data:`MAX_DATA_POINTS` points (first and last kept);
* :func:`figure_list`: the catalogue (``GET /v1/figures``).

Parameter values are the paper's (captions and text of Ciardo & Viesca); where the
printed caption contradicts itself the choice is stated in the figure's ``note``
(:data:`rsfapp.requests.figures.FIGURES`).  The numbers are checked against independent
values in tests/core/test_figures.py.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from functools import lru_cache
from typing import TYPE_CHECKING, Any

import numpy as np

from rsfcore import analytic as an
from rsfcore.params import Params

if TYPE_CHECKING:
    from rsfcore.trajectory import Trajectory, TrajectoryResult

from ..requests.figures import (
    FIGURE_FORMATS,
    FIGURE_QUALITIES,
    FIGURES,
    FigureRequest,
)
from ._common import guard, json_dict, numerics_version

__all__ = ["MAX_DATA_POINTS", "clip_to_window", "figure", "figure_arrays", "figure_list", "thin"]

#: Largest number of points per curve in the data of a figure's answer.
MAX_DATA_POINTS = 400

_Q = {
    "draft": {"grid": 90, "n_traj": 1500, "n_curve": 60, "n_ratio": 9, "n_slip": 200},
    "paper": {"grid": 320, "n_traj": 6000, "n_curve": 240, "n_ratio": 33, "n_slip": 600},
}


# ------------------------------------------------------------------------------ answers
def figure_arrays(req: FigureRequest) -> dict[str, Any]:
    """The full-resolution data of figure ``req.name`` at ``req.quality`` (numpy arrays,
    drawing-only keys ``_...`` included, ``name`` and ``quality`` first).  Computed once
    per process and request; do not modify the returned dict."""
    return _arrays(req.name, req.quality)


@lru_cache(maxsize=2 * len(FIGURES))
def _arrays(name: str, quality: str) -> dict[str, Any]:
    raw: dict[str, Any] = guard(_COMPUTE[name], quality)
    return {"name": name, "quality": quality, **raw}


def figure(req: FigureRequest) -> dict[str, Any]:
    """The answer: the figure's catalogue entry, its quality and the numbers it plots
    (thinned to at most :data:`MAX_DATA_POINTS` points a curve), JSON-safe."""
    info = FIGURES[req.name]
    d = _public(figure_arrays(req))
    d.pop("name")
    d.pop("quality")
    return json_dict(
        {
            "name": info.name,
            "label": info.label,
            "caption": info.caption,
            "note": info.note,
            "quality": req.quality,
            **d,
        }
    )


def figure_list() -> dict[str, Any]:
    """Every figure (name, caption '<label>: <caption>', label, note, url), the formats and
    qualities of a figure's answer and the numerics version."""
    return {
        "figures": [f.summary() for f in FIGURES.values()],
        "formats": list(FIGURE_FORMATS),
        "qualities": list(FIGURE_QUALITIES),
        "numerics_version": numerics_version(),
    }


# ------------------------------------------------------------------------------ helpers
def thin(n: int, max_points: int = MAX_DATA_POINTS) -> np.ndarray:
    """Indices of at most ``max_points`` of ``n`` samples, evenly strided, first and last kept."""
    if n <= max_points:
        return np.arange(n)
    idx = np.unique(np.round(np.linspace(0, n - 1, max_points)).astype(int))
    return idx


def _samples(s: TrajectoryResult) -> Trajectory:
    """The samples of a simulation asked with n_points > 0 (never None then)."""
    assert s.trajectory is not None
    return s.trajectory


def _public(x: Any) -> Any:
    """Drop drawing-only keys ('_...') and thin every group of equal-length 1-D arrays."""
    if isinstance(x, dict):
        out = {k: _public(v) for k, v in x.items() if not str(k).startswith("_")}
        groups: dict[int, list[str]] = {}
        for k, v in out.items():
            if isinstance(v, np.ndarray) and v.ndim == 1 and v.size > MAX_DATA_POINTS:
                groups.setdefault(v.size, []).append(k)
        for n, keys in groups.items():
            idx = thin(n)
            for k in keys:
                out[k] = out[k][idx]
        return out
    if isinstance(x, (list, tuple)):
        return [_public(v) for v in x]
    return x


def clip_to_window(
    phi: np.ndarray, psi: np.ndarray, window: tuple[float, float, float, float], margin: float = 0.5
) -> tuple[np.ndarray, np.ndarray]:
    """Keep the leading part of a trajectory up to where it leaves the window (+ margin) for good.

    Runaway trajectories end at phi ~ 40+; only their part near the plotted window matters.
    """
    x0, x1, y0, y1 = window
    inside = (
        (phi >= x0 - margin) & (phi <= x1 + margin) & (psi >= y0 - margin) & (psi <= y1 + margin)
    )
    if not inside.any():
        return phi[:1], psi[:1]
    last = int(np.flatnonzero(inside)[-1])
    end = min(last + 2, phi.size)
    return phi[:end], psi[:end]


def _contours(
    phi1: np.ndarray, psi1: np.ndarray, U: np.ndarray, levels: list[float]
) -> list[dict[str, Any]]:
    """Contour lines of U (shape (n_phi, n_psi)) at the given levels, as vertex arrays."""
    import contourpy  # lazily: the `plots` extra (matplotlib's own contouring)

    z = np.ma.masked_invalid(U.T)
    gen = contourpy.contour_generator(x=phi1, y=psi1, z=z)
    out = []
    for lev in levels:
        lines = []
        for seg in gen.lines(float(lev)):
            seg = np.asarray(seg)
            if seg.shape[0] >= 2:
                lines.append({"phi": seg[:, 0].copy(), "psi": seg[:, 1].copy()})
        out.append({"level": float(lev), "lines": lines})
    return out


def _cut_closed_orbit(
    phi: np.ndarray, psi: np.ndarray, *arrays: np.ndarray
) -> tuple[np.ndarray, ...]:
    """Cut a sampled closed orbit after its first return to the start (one loop)."""
    d = np.hypot(phi - phi[0], psi - psi[0])
    far = int(np.argmax(d))
    if far == 0 or d[far] == 0.0:
        return (phi, psi, *arrays)
    after = np.arange(far, d.size)
    close = after[d[after] < 0.02 * d[far]]
    if close.size == 0:
        return (phi, psi, *arrays)
    # first local minimum of the distance in the first run of close samples
    i = int(close[0])
    while i + 1 < d.size and d[i + 1] < d[i]:
        i += 1
    end = i + 1
    return (phi[:end], psi[:end], *(a[:end] for a in arrays))


def _grid(
    window: tuple[float, float, float, float], n: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    x0, x1, y0, y1 = window
    phi1 = np.linspace(x0, x1, n)
    psi1 = np.linspace(y0, y1, n)
    PHI, PSI = np.meshgrid(phi1, psi1, indexing="ij")
    return phi1, psi1, PHI, PSI


# ==================================================================== velocity-step
VS_EPS = (0.0, 0.2, 0.4, 0.6, 0.8, 1.0)
VS_RATIOS = tuple(10.0**k for k in (1, 2, 3, 4)) + tuple(10.0**-k for k in (1, 2, 3, 4))
VS_SLIP_MAX = 15.0


def _compute_velocity_step(quality: str) -> dict[str, Any]:
    n = _Q[quality]["n_slip"]
    s = np.concatenate([[0.0], np.geomspace(1e-4, VS_SLIP_MAX, n - 1)])
    panels = []
    for eps in VS_EPS:
        curves = [
            {"v2_over_v1": r, "slip": s, "dtau_over_bsigma": an.delta_tau(s, r, eps)}
            for r in VS_RATIOS
        ]
        panels.append({"eps": eps, "curves": curves})
    return {
        "equation": "eq: delta tau",
        "x": "slip delta/Dc since the step",
        "y": "(tau - tau_2)/(b sigma)",
        "slip_max": VS_SLIP_MAX,
        "panels": panels,
    }


# ==================================================================== kappa = kappa_crit phase planes
TK_BA = 1.25
TK_EPS = (0.0, 0.3, 0.6, 1.0)
TK_WINDOW = (-3.0, 5.0, -3.0, 2.5)


def _compute_trajectories_kcrit(quality: str) -> dict[str, Any]:
    from rsfcore.critical import critical_perturbation
    from rsfcore.trajectory import classify, simulate

    q = _Q[quality]
    ba = TK_BA
    kappa = ba - 1.0
    phi1, psi1, PHI, PSI = _grid(TK_WINDOW, q["grid"])
    panels = []
    for eps in TK_EPS:
        p = Params(ba, kappa, eps, 1.0)
        crit = critical_perturbation(p, "velocity-jump")
        dcrit = crit.critical_size
        if dcrit is not None:
            sizes = [0.3 * dcrit, 0.6 * dcrit, 0.9 * dcrit, 1.15 * dcrit]
        else:
            sizes = [0.3, 0.6, 0.9, 1.2, 1.6]
        trajs: list[dict[str, Any]] = []
        for d in sizes:
            r = classify(p, "velocity-jump", d)
            if r.outcome == "stable":
                t_end = max(10.0 * (r.return_time or 1.0), 60.0)
                s = simulate(p, "velocity-jump", d, t_end=t_end, n_points=q["n_traj"])
                tr = _samples(s)
                ph, ps, T = _cut_closed_orbit(tr.phi, tr.psi, tr.T)
            else:
                s = simulate(p, "velocity-jump", d, n_points=q["n_traj"])
                tr = _samples(s)
                ph, ps = clip_to_window(tr.phi, tr.psi, TK_WINDOW)
                T = tr.T[: ph.size]
            U0 = float(an.U_kcrit(d, d, ba, eps))
            trajs.append(
                {
                    "size": d,
                    "outcome": r.outcome,
                    "certificate": r.certificate,
                    "U": U0,
                    "T": T,
                    "phi": ph,
                    "psi": ps,
                }
            )
        with np.errstate(all="ignore"):
            U = an.U_kcrit(PHI, PSI, ba, eps)
        U = np.where(np.isfinite(U), U, np.nan)
        extra = [float(an.U_kcrit(x, x, ba, eps)) for x in np.linspace(0.15, 2.5, 9)]
        levels = sorted({t["U"] for t in trajs} | {u for u in extra if math.isfinite(u)})
        levels = [lv for lv in levels if np.nanmin(U) < lv < np.nanmax(U)]
        panel: dict[str, Any] = {
            "eps": eps,
            "kappa": kappa,
            "critical_size": dcrit,
            "critical_kind": crit.kind,
            "steady_state": {"phi": phi1[[0, -1]], "psi": (1.0 - ba) * phi1[[0, -1]]},
            "trajectories": trajs,
            "contours": _contours(phi1, psi1, U, levels),
            "_grid": (phi1, psi1, U),
            "_levels": levels,
        }
        if eps < 1.0:
            phc = np.linspace(TK_WINDOW[0], TK_WINDOW[1], 4 * q["n_curve"])
            panel["critical_trajectory"] = {
                "phi": phc,
                "psi": an.psi_crit_kcrit(phc, ba, eps),
                "U": 0.0,
            }
        panels.append(panel)
    return {"ba": ba, "kappa": kappa, "vo": 1.0, "window": TK_WINDOW, "panels": panels}


# ==================================================================== critical jump, kappa = kappa_crit
CJ_BA = 1.25
CJ_EXTRA_EPS = (0.1, 0.5, 0.99)
CJ_EXTRA_AB = (0.1, 0.5)


def _compute_critical_jump_kcrit(quality: str) -> dict[str, Any]:
    from rsfcore.critical import critical_perturbation

    n = _Q[quality]["n_curve"]
    ba = CJ_BA
    lo = np.geomspace(1e-4, 0.5, n // 2)
    hi = 1.0 - np.geomspace(0.5, 1e-4, n // 2)
    eps = np.unique(np.concatenate([[0.0], lo, hi, CJ_EXTRA_EPS]))
    d = np.array(
        [
            critical_perturbation(Params(ba, ba - 1.0, float(e)), "velocity-jump").critical_size
            for e in eps
        ],
        dtype=float,
    )
    slip_asym = an.velocity_jump_crit_slip_law(ba)
    aging_asym = np.array([an.velocity_jump_crit_aging_asymptote(ba, float(e)) for e in eps])
    ab = np.unique(np.concatenate([np.geomspace(1e-4, 0.999, n), CJ_EXTRA_AB]))
    dab = np.array(
        [
            critical_perturbation(
                Params(1.0 / a, 1.0 / a - 1.0, 0.0), "velocity-jump"
            ).critical_size
            for a in ab
        ],
        dtype=float,
    )
    return {
        "panel_a": {
            "ba": ba,
            "kappa": ba - 1.0,
            "vo": 1.0,
            "eps": eps,
            "critical_size": d,
            "slip_law_asymptote": slip_asym,
            "aging_law_asymptote": aging_asym,
        },
        "panel_b": {
            "eps": 0.0,
            "a_over_b": ab,
            "critical_size": dab,
            "small_ab_scaling": np.sqrt(2.0 * ab),
            "excluded_point": {"a_over_b": 1.0, "critical_size": 1.0},
        },
    }


# ==================================================================== rate neutral
RN_BA = 1.0 + 1e-9  # b/a = 1 exactly is outside rsfcore's range (1, 1e6]; see note


def _compute_rate_neutral(quality: str) -> dict[str, Any]:
    from rsfcore.trajectory import simulate

    p = Params(RN_BA, 1.0, 0.01, 1.0)
    s = simulate(p, "velocity-jump", 1.0, t_end=40.0, n_points=_Q[quality]["n_traj"])
    tr = _samples(s)
    return {
        "ba": RN_BA,
        "ba_paper": 1.0,
        "kappa": 1.0,
        "eps": 0.01,
        "size": 1.0,
        "outcome": s.outcome,
        "trajectory": {"T": tr.T, "phi": tr.phi, "psi": tr.psi},
    }


# ==================================================================== stability diagrams
SD_BA = 2.0
SD_EPS = (0.0, 0.05, 0.1, 0.25, 0.5, 0.75, 0.9)
SD_EPS_DRAFT = (0.0, 0.25, 0.5)
SD_RATIO_MAX = 5.0
SD_PANEL_B = {"velocity-jump": (1.0, 1.5, 2.5, 3.0), "load-point-jump": (4.0, 9.0, 12.0, 14.0)}
SD_LABELS = ("strongly subcritical", "subcritical", "near-critical", "supercritical")


def _ratios(n: int, eps: float) -> np.ndarray:
    """kappa/kappa_crit from 1 to min(5, 1/eps), clustered towards the divergence at 1/eps."""
    top = SD_RATIO_MAX if eps == 0.0 else min(SD_RATIO_MAX, 1.0 / eps)
    u = np.linspace(0.0, 1.0, n)
    x = 1.0 + (top - 1.0) * (1.0 - (1.0 - u) ** 2.5)
    if top == SD_RATIO_MAX:
        x = 1.0 + (top - 1.0) * u**1.3
    if top < SD_RATIO_MAX:  # beyond 1/eps the critical size is infinite
        x = np.concatenate([x, [SD_RATIO_MAX]])
    return np.unique(np.concatenate([x, [2.0]] if top >= 2.0 else [x]))


def _compute_stability(quality: str, perturbation: str) -> dict[str, Any]:
    from rsfcore.critical import critical_perturbation
    from rsfcore.diagram import stability_diagram
    from rsfcore.trajectory import classify, simulate

    q = _Q[quality]
    ba = SD_BA
    eps_list = SD_EPS if quality == "paper" else SD_EPS_DRAFT
    curves = []
    n_fallback = 0
    for e in eps_list:
        x = _ratios(q["n_ratio"], e)
        dg = stability_diagram("kappa_ratio", x, "eps", [e], ba=ba, perturbation=perturbation)
        n_fallback += dg.n_fallback
        curves.append(
            {
                "eps": e,
                "kappa_ratio": x,
                "critical_size": dg.critical_size[:, 0].copy(),
                "kind": dg.kind[:, 0].astype(int),
            }
        )
    # panel b
    p = Params(ba, 2.0 * (ba - 1.0), 0.25, 1.0)
    crit = critical_perturbation(p, perturbation)
    trajs: list[dict[str, Any]] = []
    for size, label in zip(SD_PANEL_B[perturbation], SD_LABELS, strict=True):
        r = classify(p, perturbation, size)
        if r.outcome == "stable":
            s = simulate(p, perturbation, size, t_end=40.0, n_points=q["n_traj"])
        else:
            s = simulate(p, perturbation, size, n_points=q["n_traj"])
        tr = _samples(s)
        vo_new = s.params.vo
        trajs.append(
            {
                "size": size,
                "label": label,
                "outcome": r.outcome,
                "T": tr.T,
                "phi": tr.phi,
                "psi": tr.psi,
                "slip": tr.slip,
                "ln_theta": tr.ln_theta,
                "new_steady_state": {"phi": math.log(vo_new), "psi": (1.0 - ba) * math.log(vo_new)},
            }
        )
    out: dict[str, Any] = {
        "perturbation": perturbation,
        "ba": ba,
        "vo": 1.0,
        "panel_a": {"curves": curves, "n_fallback": n_fallback, "kappa_ratio_max": SD_RATIO_MAX},
        "panel_b": {
            "kappa": p.kappa,
            "kappa_ratio": 2.0,
            "eps": 0.25,
            "critical_size": crit.critical_size,
            "trajectories": trajs,
        },
    }
    if perturbation == "velocity-jump":
        stable = [t for t in trajs if t["outcome"] == "stable"]
        x0 = min(-2.5, min(float(np.min(t["phi"])) for t in stable) - 0.3)
        x1 = max(4.0, 1.05 * max(float(np.max(t["phi"])) for t in stable))
        y0 = min(-2.5, min(float(np.min(t["psi"])) for t in stable) - 0.3)
        y1 = 3.5
        window = (x0, x1, y0, y1)
        phi1, psi1, PHI, PSI = _grid(window, q["grid"])
        with np.errstate(all="ignore"):
            U = an.U_kcrit(PHI, PSI, ba, 0.25)
        U = np.where(np.isfinite(U), U, np.nan)
        levels = sorted(
            {float(an.U_kcrit(d, d, ba, 0.25)) for d in (0.25, 0.5, 0.75, 1.0, 1.25)} | {0.0}
        )
        out["panel_b"]["window"] = window
        out["panel_b"]["lyapunov"] = {
            "function": "U_kcrit (eq: trajectories 1) with kappa = kappa_crit = 1",
            "contours": _contours(phi1, psi1, U, levels),
        }
        out["panel_b"]["_grid"] = (phi1, psi1, U)
        out["panel_b"]["_levels"] = levels
    else:
        stable = [t for t in trajs if t["outcome"] == "stable"]
        x0 = min(-1.0, min(float(np.min(t["phi"])) for t in stable) - 0.5)
        x1 = 1.05 * max(float(np.max(t["phi"])) for t in stable) + 0.5
        y0 = 1.05 * min(float(np.min(t["psi"])) for t in stable) - 0.5
        y1 = max(1.5, max(float(np.max(t["psi"])) for t in stable) + 0.5)
        out["panel_b"]["window"] = (x0, x1, y0, y1)
    for t in trajs:  # what the plotted window shows of each trajectory
        t["_shown"] = clip_to_window(t["phi"], t["psi"], out["panel_b"]["window"])
    return out


# ==================================================================== stationary load point phase planes
V0_BA = 2.0


def _compute_trajectories_vo0(
    quality: str, kappa: float, eps_list: tuple[float, ...], window: Any
) -> dict[str, Any]:
    from rsfcore import boundaries as bd
    from rsfcore.critical import critical_perturbation
    from rsfcore.trajectory import simulate

    q = _Q[quality]
    ba = V0_BA
    phi1, psi1, PHI, PSI = _grid(window, q["grid"])
    panels = []
    for eps in eps_list:
        p = Params(ba, kappa, eps, 0.0)
        crit = critical_perturbation(p, "velocity-jump")
        dcrit = crit.critical_size
        base = dcrit if dcrit is not None else 1.0
        fr = (0.3, 0.7, 1.3) if dcrit is not None else (0.5, 1.5, 3.0)
        sizes = [f * base for f in fr]
        trajs: list[dict[str, Any]] = []
        for d in sizes:
            # stable creep slows down for ever (phi -> -inf): run until it has left the window
            t_end = 10.0
            while True:
                s = simulate(p, "velocity-jump", d, t_end=t_end, n_points=q["n_traj"])
                tr = _samples(s)
                if s.outcome == "unstable" or tr.phi[-1] < window[0] or t_end > 1e6:
                    break
                t_end *= 10.0
            ph, ps = clip_to_window(tr.phi, tr.psi, window)
            # stable creep runs to phi -> -inf: keep it down to the window
            keep = ph >= window[0] - 0.5
            ph, ps = ph[keep], ps[keep]
            U0 = float(an.U_vo0(d, d, ba, kappa, eps))
            trajs.append(
                {
                    "size": d,
                    "outcome": s.outcome,
                    "certificate": s.certificate,
                    "U": U0,
                    "T": tr.T[: keep.size][keep],
                    "phi": ph,
                    "psi": ps,
                }
            )
        with np.errstate(all="ignore"):
            U = an.U_vo0(PHI, PSI, ba, kappa, eps)
        U = np.where(np.isfinite(U), U, np.nan)
        extra = [float(an.U_vo0(x, x, ba, kappa, eps)) for x in np.linspace(-1.5, 3.0, 10)]
        levels = sorted({t["U"] for t in trajs} | {u for u in extra if math.isfinite(u)})
        levels = [lv for lv in levels if np.nanmin(U) < lv < np.nanmax(U)]
        panel: dict[str, Any] = {
            "eps": eps,
            "critical_size": dcrit,
            "critical_kind": crit.kind,
            "x": float(eps * kappa / (ba - 1.0)),
            "steady_state": {"phi": phi1[[0, -1]], "psi": (1.0 - ba) * phi1[[0, -1]]},
            "trajectories": trajs,
            "contours": _contours(phi1, psi1, U, levels),
            "_grid": (phi1, psi1, U),
            "_levels": levels,
        }
        if dcrit is not None:
            panel["critical_trajectory"] = {
                "phi": phi1[[0, -1]],
                "psi": an.psi_crit_vo0(phi1[[0, -1]], ba, kappa, eps),
            }
        if bd.acceleration_possible(ba, kappa, eps):
            panel["acceleration_line"] = {
                "phi": phi1[[0, -1]],
                "psi": bd.acceleration_line(ba, kappa, eps, phi1[[0, -1]]),
            }
        panels.append(panel)
    return {
        "ba": ba,
        "kappa": kappa,
        "vo": 0.0,
        "eps_crit": bd.eps_crit(ba, kappa),
        "window": window,
        "panels": panels,
    }


# ==================================================================== critical jump, v_o = 0
CV_KAPPAS = (0.5, 1.0, 1.5)
CV_EXTRA_EPS = (0.3, 0.9)
CV_AB_EPS = (0.0, 0.25, 0.5, 0.75, 1.0)


def _compute_critical_jump_vo0(quality: str) -> dict[str, Any]:
    from rsfcore import boundaries as bd
    from rsfcore.critical import critical_perturbation

    n = _Q[quality]["n_curve"]
    ba = V0_BA
    eps = np.unique(
        np.concatenate(
            [np.linspace(0.0, 1.0, 2 * n + 1), CV_EXTRA_EPS, [2.0 / 3.0 - 1e-3, 2.0 / 3.0 - 1e-4]]
        )
    )
    curves_a = []
    for k in CV_KAPPAS:
        v = [
            critical_perturbation(Params(ba, k, float(e), 0.0), "velocity-jump").critical_size
            for e in eps
        ]
        curves_a.append(
            {
                "kappa": k,
                "eps": eps,
                "critical_size": np.array([np.inf if x is None else x for x in v]),
            }
        )
    ab = np.unique(np.concatenate([np.linspace(0.01, 0.99, 2 * n + 1), [0.5]]))
    curves_b = []
    for e in CV_AB_EPS:
        v = [
            critical_perturbation(Params(1.0 / a, 1.0, e, 0.0), "velocity-jump").critical_size
            for a in ab
        ]
        curves_b.append(
            {
                "eps": e,
                "a_over_b": ab,
                "critical_size": np.array([np.inf if x is None else x for x in v]),
                "ab_crit": bd.ab_crit(1.0, e),
            }
        )
    return {
        "panel_a": {
            "ba": ba,
            "vo": 0.0,
            "curves": curves_a,
            "eps_crit": {str(k): bd.eps_crit(ba, k) for k in CV_KAPPAS},
        },
        "panel_b": {"kappa": 1.0, "vo": 0.0, "curves": curves_b},
    }


# ==================================================================== appendix: periodic / non-periodic response
PR_SIZE = 1.33


def _compute_periodic(quality: str) -> dict[str, Any]:
    from rsfcore.critical import critical_perturbation
    from rsfcore.trajectory import simulate

    p = Params(2.0, 1.0, 0.25, 1.0)
    crit = critical_perturbation(p, "load-point-jump")
    n = 3 * _Q[quality]["n_traj"]
    s = simulate(p, "load-point-jump", PR_SIZE, t_end=18.0, n_points=n)
    tr = _samples(s)
    ba = p.ba
    vo_new = s.params.vo
    return {
        "ba": ba,
        "kappa": p.kappa,
        "eps": p.eps,
        "size": PR_SIZE,
        "critical_size": crit.critical_size,
        "vo_after": vo_new,
        "outcome": s.outcome,
        "U": float(an.U_kcrit(0.0, 0.0, ba, p.eps, vo_new)),
        "trajectory": {
            "T": tr.T,
            "slip": tr.slip,
            "phi": tr.phi,
            "psi": tr.psi,
            "Theta": tr.psi - tr.phi,
        },
    }


NP_SIZES = (4.0, 9.0, 12.0, 14.0)
NP_SLIP = 50.0  # about this much slip (in Dc) is shown for the stable responses


def _compute_non_periodic(quality: str) -> dict[str, Any]:
    from rsfcore.critical import critical_perturbation
    from rsfcore.trajectory import classify, simulate

    p = Params(2.0, 2.0, 0.25, 1.0)
    crit = critical_perturbation(p, "load-point-jump")
    rows: list[dict[str, Any]] = []
    for dv, label in zip(NP_SIZES, SD_LABELS, strict=True):
        r = classify(p, "load-point-jump", dv)
        if r.outcome == "stable":
            s = simulate(
                p, "load-point-jump", dv, t_end=NP_SLIP / (1.0 + dv), n_points=_Q[quality]["n_traj"]
            )
        else:
            s = simulate(p, "load-point-jump", dv, n_points=_Q[quality]["n_traj"])
        tr = _samples(s)
        vo = s.params.vo
        rows.append(
            {
                "size": dv,
                "label": label,
                "outcome": s.outcome,
                "slip": tr.slip,
                "psi": tr.psi,
                "phi": tr.phi,
                "theta": np.exp(np.clip(tr.ln_theta, -700, 700)),
                "new_steady_state": {
                    "phi": math.log(vo),
                    "psi": (1.0 - p.ba) * math.log(vo),
                    "theta": 1.0 / vo,
                },
            }
        )
    return {
        "ba": p.ba,
        "kappa": p.kappa,
        "eps": p.eps,
        "critical_size": crit.critical_size,
        "rows": rows,
    }


# ==================================================================== continuum eigenmodes
def _compute_modes(quality: str) -> dict[str, Any]:
    # imported here: rsfcore.stiffness loads scipy.integrate and scipy.special (~0.4 s of
    # CPU), which no other figure needs (bench/bench_cli.py: `rsf figure ... --out`)
    from rsfcore.stiffness import eigen_mode, eigen_stiffness

    n = 101 if quality == "draft" else 401
    cases = []
    for case, lo, kstar in (("B", -1.0, "mu'/L"), ("D", -1.0, "E'h/L^2"), ("E", 0.0, "mu/R")):
        x = np.linspace(lo, 1.0, n)
        x, delta = eigen_mode(case, 0, x=x)
        cases.append(
            {
                "case": case,
                "x": x,
                "delta": delta,
                "eigenvalue": eigen_stiffness(case, 0),
                "k_star": kstar,
            }
        )
    return {
        "cases": cases,
        "table_printed": {"B": 1.157773882, "D": math.pi**2 / 4.0, "E": 1.003059516},
    }


# ==================================================================== registry
#: name -> the function computing the figure's data at a quality.
_COMPUTE: dict[str, Callable[[str], dict[str, Any]]] = {
    "velocity-step": _compute_velocity_step,
    "trajectories-kcrit": _compute_trajectories_kcrit,
    "critical-jump-kcrit": _compute_critical_jump_kcrit,
    "rate-neutral": _compute_rate_neutral,
    "stability-diagram-velocity": lambda q: _compute_stability(q, "velocity-jump"),
    "stability-diagram-load-point": lambda q: _compute_stability(q, "load-point-jump"),
    "trajectories-vo0-soft": lambda q: _compute_trajectories_vo0(
        q, 0.5, (0.0, 0.3, 0.6, 1.0), (-3.0, 3.0, -2.5, 3.0)
    ),
    "trajectories-vo0-stiff": lambda q: _compute_trajectories_vo0(
        q, 1.5, (0.0, 0.6, 0.7, 1.0), (-4.0, 6.0, -4.0, 6.0)
    ),
    "critical-jump-vo0": _compute_critical_jump_vo0,
    "periodic-response": _compute_periodic,
    "non-periodic-response": _compute_non_periodic,
    "continuum-modes": _compute_modes,
}
assert list(_COMPUTE) == list(FIGURES), "every figure of the catalogue has its computation"
