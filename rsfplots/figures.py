"""The paper's figures that show computed results, regenerated from rsfcore.

Each figure is computed once per quality ('draft' for tests, 'paper' for the gallery and
the CLI) by a ``_compute_*`` function that returns a dict of numpy arrays (keys starting
with ``_`` are plot-only, e.g. the U grids), drawn by a ``_draw_*`` function.  The data
behind a figure is that dict without the plot-only keys, with every curve thinned to at
most 400 points and converted to JSON-safe lists (:func:`figure_data`).

Parameter values are the paper's (captions and text of Ciardo & Viesca); where the
printed caption contradicts itself the choice is stated in the spec's ``note``.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from functools import lru_cache
from typing import Any

import contourpy
import numpy as np
from matplotlib.figure import Figure
from matplotlib.lines import Line2D

from rsfcore import ParameterError, Params, classify, simulate
from rsfcore import analytic as an
from rsfcore import boundaries as bd
from rsfcore.critical import critical_perturbation
from rsfcore.diagram import stability_diagram
from rsfcore.stiffness import eigen_mode, eigen_stiffness

from ._common import MAX_DATA_POINTS, check_quality, clip_to_window, jsonsafe, new_figure, thin

__all__ = ["FigureSpec", "FIGURES", "figure_data", "build_figure"]

# colours used throughout
C_SS = "tab:blue"  # steady-state line
C_CRIT = "tab:red"  # critical trajectory
C_ACC = "tab:orange"  # acceleration line
C_U = "0.6"  # U contours
C_TRAJ = "black"  # numerical trajectories

_Q = {
    "draft": {"grid": 90, "n_traj": 1500, "n_curve": 60, "n_ratio": 9, "n_slip": 200},
    "paper": {"grid": 320, "n_traj": 6000, "n_curve": 240, "n_ratio": 33, "n_slip": 600},
}


@dataclass(frozen=True)
class FigureSpec:
    """One reproduced figure: its name, the paper label and caption it reproduces, how to build it."""

    name: str
    label: str  # the paper's \\label, e.g. 'fig: trajectories 1'
    caption: str  # one-line description of what is plotted
    compute: Callable[[str], dict[str, Any]]
    draw: Callable[[dict[str, Any], Figure], None]
    size: tuple[float, float]
    note: str = ""

    def figure(self, quality: str = "paper") -> Figure:
        """The matplotlib Figure (Agg canvas)."""
        return build_figure(self.name, quality)

    def data(self, quality: str = "paper") -> dict[str, Any]:
        """The data behind the figure, JSON-safe (see module docstring)."""
        return figure_data(self.name, quality)

    def summary(self) -> dict[str, str]:
        return {
            "name": self.name,
            "label": self.label,
            "caption": f"{self.label}: {self.caption}",
            "note": self.note,
        }


# ------------------------------------------------------------------------------ helpers
@lru_cache(maxsize=64)
def _raw(name: str, quality: str) -> dict[str, Any]:
    return FIGURES[name].compute(quality)


def _spec(name: str) -> FigureSpec:
    if name not in FIGURES:
        raise ParameterError("name", name, "one of " + ", ".join(FIGURES))
    return FIGURES[name]


def build_figure(name: str, quality: str = "paper") -> Figure:
    """Build figure ``name`` ('draft' or 'paper' quality) as a matplotlib Figure."""
    spec = _spec(name)
    quality = check_quality(quality)
    raw = _raw(name, quality)
    fig = new_figure(*spec.size)
    spec.draw(raw, fig)
    return fig


def _public(x: Any) -> Any:
    """Drop plot-only keys ('_...') and thin every group of equal-length 1-D arrays."""
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


def figure_data(name: str, quality: str = "paper") -> dict[str, Any]:
    """The arrays plotted in figure ``name`` (thinned to <= 400 points a curve), JSON-safe."""
    spec = _spec(name)
    quality = check_quality(quality)
    d = _public(_raw(name, quality))
    d = {
        "name": spec.name,
        "label": spec.label,
        "caption": spec.caption,
        "note": spec.note,
        "quality": quality,
        **d,
    }
    return jsonsafe(d)


def _contours(
    phi1: np.ndarray, psi1: np.ndarray, U: np.ndarray, levels: list[float]
) -> list[dict[str, Any]]:
    """Contour lines of U (shape (n_phi, n_psi)) at the given levels, as vertex arrays."""
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


def _eps_label(eps: float) -> str:
    if eps == 0.0:
        return r"$\epsilon \to 0$ (slip law)"
    if eps == 1.0:
        return r"$\epsilon = 1$ (aging law)"
    return rf"$\epsilon = {eps:g}$"


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
        "panels": panels,
    }


def _draw_velocity_step(raw: dict[str, Any], fig: Figure) -> None:
    axs = fig.subplots(2, 3, sharex=True, sharey=True)
    for ax, panel in zip(axs.flat, raw["panels"]):
        for c in panel["curves"]:
            r = c["v2_over_v1"]
            k = abs(round(math.log10(r)))
            up = r > 1
            shade = 0.35 + 0.15 * k
            color = (
                (0.55 * shade + 0.2, 0.0, 0.0)
                if up
                else (1.0, 0.45 + 0.1 * (4 - k), 0.45 + 0.1 * (4 - k))
            )
            ax.plot(c["slip"], c["dtau_over_bsigma"], color=color, lw=1.3)
        ax.axhline(0.0, color="0.5", lw=0.6)
        ax.set_title(_eps_label(panel["eps"]), fontsize=10)
        ax.set_xlim(0, VS_SLIP_MAX)
    for ax in axs[1]:
        ax.set_xlabel(r"$\delta/D_c$")
    for ax in axs[:, 0]:
        ax.set_ylabel(r"$\Delta\tau / b\sigma$")
    handles = [
        Line2D([], [], color=(0.75, 0, 0), label=r"$V_2/V_1 = 10^{+1..4}$"),
        Line2D([], [], color=(1.0, 0.6, 0.6), label=r"$V_2/V_1 = 10^{-1..4}$"),
    ]
    axs[0, 0].legend(handles=handles, fontsize=8, loc="upper right")
    fig.suptitle("Stress response to velocity steps, eq. (delta tau)", fontsize=11)


# ==================================================================== kappa = kappa_crit phase planes
TK_BA = 1.25
TK_EPS = (0.0, 0.3, 0.6, 1.0)
TK_WINDOW = (-3.0, 5.0, -3.0, 2.5)


def _compute_trajectories_kcrit(quality: str) -> dict[str, Any]:
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
        trajs = []
        for d in sizes:
            r = classify(p, "velocity-jump", d)
            if r.outcome == "stable":
                t_end = max(10.0 * (r.return_time or 1.0), 60.0)
                s = simulate(p, "velocity-jump", d, t_end=t_end, n_points=q["n_traj"])
                tr = s.trajectory
                ph, ps, T = _cut_closed_orbit(tr.phi, tr.psi, tr.T)
            else:
                s = simulate(p, "velocity-jump", d, n_points=q["n_traj"])
                tr = s.trajectory
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


def _draw_phase_common(ax: Any, panel: dict[str, Any], window: Any, *, ss: bool = True) -> None:
    x0, x1, y0, y1 = window
    phi1, psi1, U = panel["_grid"]
    levels = panel["_levels"]
    if levels:
        ax.contour(
            phi1,
            psi1,
            np.ma.masked_invalid(U.T),
            levels=levels,
            colors=C_U,
            linewidths=0.7,
            negative_linestyles="solid",
        )
    if ss:
        s = panel["steady_state"]
        ax.plot(s["phi"], s["psi"], "--", color=C_SS, lw=1.2)
    ax.plot([0, min(x1, y1)], [0, min(x1, y1)], ":", color="0.3", lw=0.8)
    for t in panel["trajectories"]:
        ax.plot(t["phi"], t["psi"], "-", color=C_TRAJ, lw=1.1)
        ax.plot(t["phi"][0], t["psi"][0], "o", color=C_TRAJ, ms=3)
    ax.plot(0, 0, "ko", ms=4)
    ax.set_xlim(x0, x1)
    ax.set_ylim(y0, y1)


def _draw_trajectories_kcrit(raw: dict[str, Any], fig: Figure) -> None:
    axs = fig.subplots(2, 2, sharex=True, sharey=True)
    for ax, panel in zip(axs.flat, raw["panels"]):
        _draw_phase_common(ax, panel, raw["window"])
        if "critical_trajectory" in panel:
            c = panel["critical_trajectory"]
            ax.plot(c["phi"], c["psi"], "-", color=C_CRIT, lw=1.6)
            d = panel["critical_size"]
            ax.plot(d, d, "o", mfc="white", mec=C_CRIT, ms=5)
            title = _eps_label(panel["eps"]) + rf", $\Delta\phi_{{crit}} = {d:.4g}$"
        else:
            title = _eps_label(panel["eps"]) + ", all orbits closed"
        ax.set_title(title, fontsize=9)
    for ax in axs[1]:
        ax.set_xlabel(r"$\phi = \ln(V/V_*)$")
    for ax in axs[:, 0]:
        ax.set_ylabel(r"$\psi = (\tau - \tau_*)/a\sigma$")
    fig.suptitle(
        rf"$U$ = const., $b/a = {raw['ba']:g}$, $\kappa = \kappa_{{crit}} = {raw['kappa']:g}$, $v_o = 1$",
        fontsize=11,
    )
    handles = [
        Line2D([], [], color=C_SS, ls="--", label="steady state"),
        Line2D([], [], color=C_CRIT, label="critical trajectory U = 0"),
        Line2D([], [], color=C_U, label="U = const."),
        Line2D([], [], color=C_TRAJ, label="numerical, velocity jumps"),
    ]
    axs[0, 0].legend(handles=handles, fontsize=7, loc="lower left")


# ==================================================================== critical jump, kappa = kappa_crit
CJ_BA = 1.25
CJ_EXTRA_EPS = (0.1, 0.5, 0.99)
CJ_EXTRA_AB = (0.1, 0.5)


def _compute_critical_jump_kcrit(quality: str) -> dict[str, Any]:
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


def _draw_critical_jump_kcrit(raw: dict[str, Any], fig: Figure) -> None:
    ax1, ax2 = fig.subplots(1, 2)
    a = raw["panel_a"]
    m = a["eps"] > 0
    ax1.loglog(
        a["eps"][m],
        a["critical_size"][m],
        "k-",
        lw=1.6,
        label="numerical (eq. limiting trajectory 1, psi = phi)",
    )
    ax1.axhline(
        a["slip_law_asymptote"],
        color="tab:red",
        ls="--",
        lw=1.1,
        label=r"slip-law limit $1 + W((a/b-1)/e)$",
    )
    mm = m & (a["eps"] > 0.3)
    ax1.loglog(
        a["eps"][mm],
        a["aging_law_asymptote"][mm],
        "--",
        color="tab:red",
        lw=1.1,
        label=r"aging-law limit $\ln(2 - b/a + 1/(1-\epsilon))$",
    )
    ax1.set_xlabel(r"$\epsilon$")
    ax1.set_ylabel(r"$\Delta\phi_{crit} = \ln(1 + \Delta V_{crit}/V_*)$")
    ax1.set_title(
        rf"(a) $b/a = {a['ba']:g}$, $\kappa = \kappa_{{crit}} = {a['kappa']:g}$", fontsize=10
    )
    ax1.legend(fontsize=7, loc="upper left")
    b = raw["panel_b"]
    ax2.loglog(
        b["a_over_b"],
        b["critical_size"],
        "k-",
        lw=1.6,
        label="slip law, $\\kappa = \\kappa_{crit}$",
    )
    ax2.loglog(
        b["a_over_b"],
        b["small_ab_scaling"],
        "--",
        color="tab:red",
        lw=1.1,
        label=r"$\sqrt{2\,a/b}$",
    )
    ax2.plot([1.0], [1.0], "o", mfc="white", mec="k", ms=7)
    ax2.set_xlabel(r"$a/b$")
    ax2.set_ylabel(r"$\Delta\phi_{crit}$")
    ax2.set_title("(b) slip law, vs a/b", fontsize=10)
    ax2.legend(fontsize=8, loc="upper left")


# ==================================================================== rate neutral
RN_BA = 1.0 + 1e-9  # b/a = 1 exactly is outside rsfcore's range (1, 1e6]; see note


def _compute_rate_neutral(quality: str) -> dict[str, Any]:
    p = Params(RN_BA, 1.0, 0.01, 1.0)
    s = simulate(p, "velocity-jump", 1.0, t_end=40.0, n_points=_Q[quality]["n_traj"])
    tr = s.trajectory
    return {
        "ba": RN_BA,
        "ba_paper": 1.0,
        "kappa": 1.0,
        "eps": 0.01,
        "size": 1.0,
        "outcome": s.outcome,
        "trajectory": {"T": tr.T, "phi": tr.phi, "psi": tr.psi},
    }


def _draw_rate_neutral(raw: dict[str, Any], fig: Figure) -> None:
    ax = fig.subplots()
    t = raw["trajectory"]
    ax.plot(t["phi"], t["psi"], color="0.45", lw=1.5, label="trajectory")
    x = np.array([-1.0, 1.5])
    ax.plot(x, (1.0 - raw["ba"]) * x, "--", color=C_SS, label="steady state")
    ax.plot([0, 1], [0, 1], ":", color="0.3", lw=0.8)
    ax.plot(0, 0, "ko", ms=4)
    ax.plot(1, 1, "o", color="0.45", ms=4)
    ax.set_xlabel(r"$\phi$")
    ax.set_ylabel(r"$\psi$")
    ax.set_title(
        r"rate neutral $b/a = 1$, $\kappa = 1$, $\epsilon = 0.01$, $\Delta\phi = 1$", fontsize=10
    )
    ax.legend(fontsize=8)


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
    trajs = []
    for size, label in zip(SD_PANEL_B[perturbation], SD_LABELS):
        r = classify(p, perturbation, size)
        if r.outcome == "stable":
            s = simulate(p, perturbation, size, t_end=40.0, n_points=q["n_traj"])
        else:
            s = simulate(p, perturbation, size, n_points=q["n_traj"])
        tr = s.trajectory
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
        "panel_a": {"curves": curves, "n_fallback": n_fallback},
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
    return out


def _draw_stability(raw: dict[str, Any], fig: Figure) -> None:
    import matplotlib as mpl

    ax1, ax2 = fig.subplots(1, 2)
    vel = raw["perturbation"] == "velocity-jump"
    cmap = mpl.colormaps["Blues" if vel else "Reds"]
    curves = raw["panel_a"]["curves"]
    ymin, ymax = np.inf, 0.0
    for c in curves:
        v = np.where(
            np.isfinite(c["critical_size"]) & (c["critical_size"] > 0), c["critical_size"], np.nan
        )
        if np.any(np.isfinite(v)):
            ymin = min(ymin, np.nanmin(v))
            ymax = max(ymax, np.nanmax(v))
    ymax = min(ymax, 30.0 if vel else 1e3)
    for c in curves:
        v = np.where(
            np.isfinite(c["critical_size"]) & (c["critical_size"] > 0), c["critical_size"], np.nan
        )
        col = cmap(0.95 - 0.7 * c["eps"])
        ax1.semilogy(
            c["kappa_ratio"],
            np.where(v > 3 * ymax, 3 * ymax, v),
            "-",
            color=col,
            lw=1.6,
            label=rf"$\epsilon = {c['eps']:g}$",
        )
        if c["eps"] > 0 and 1.0 / c["eps"] <= SD_RATIO_MAX:
            ax1.axvline(1.0 / c["eps"], color=col, ls=":", lw=0.8)
    ax1.axvspan(0.5, 1.0, color="0.85")
    ax1.text(
        0.75,
        math.sqrt(ymin * ymax),
        "unstable for\nany size",
        ha="center",
        va="center",
        fontsize=7,
        rotation=90,
    )
    pb = raw["panel_b"]
    if pb["critical_size"] is not None:
        ax1.plot(pb["kappa_ratio"], pb["critical_size"], "k*", ms=8)
    ax1.set_xlim(0.5, SD_RATIO_MAX)
    ax1.set_ylim(0.5 * ymin, 2.0 * ymax)
    ax1.set_xlabel(r"$\kappa/\kappa_{crit}$")
    ax1.set_ylabel(r"$\Delta\phi_{crit}$" if vel else r"$(\Delta v_o/v_o)_{crit}$")
    ax1.set_title(
        f"(a) critical {'velocity' if vel else 'load-point'} jump, b/a = {raw['ba']:g}", fontsize=10
    )
    ax1.legend(fontsize=7, loc="upper right")
    window = pb["window"]
    x0, x1, y0, y1 = window
    if vel:
        phi1, psi1, U = pb["_grid"]
        lv = pb["_levels"]
        ax2.contour(
            phi1,
            psi1,
            np.ma.masked_invalid(U.T),
            levels=[v for v in lv if v != 0.0],
            colors="tab:red",
            linestyles="dashed",
            linewidths=0.6,
        )
        ax2.contour(
            phi1,
            psi1,
            np.ma.masked_invalid(U.T),
            levels=[0.0],
            colors="tab:red",
            linestyles="dashed",
            linewidths=1.4,
        )
        ax2.plot([0, min(x1, y1)], [0, min(x1, y1)], "k--", lw=0.8)
    colors = ["tab:green", "tab:olive", "tab:orange", "tab:purple"]
    for t, col in zip(pb["trajectories"], colors):
        ph, ps = clip_to_window(t["phi"], t["psi"], window)
        ax2.plot(
            ph, ps, "-", color=col, lw=1.3, label=f"{t['label']} ({t['size']:g}): {t['outcome']}"
        )
        if not vel and t["outcome"] == "stable":
            ns = t["new_steady_state"]
            ax2.plot(ns["phi"], ns["psi"], "x", color=col, ms=6)
    xs = np.array([x0, x1])
    ax2.plot(xs, (1.0 - raw["ba"]) * xs, ":", color=C_SS, lw=1.0)
    ax2.plot(0, 0, "ko", ms=4)
    ax2.set_xlim(x0, x1)
    ax2.set_ylim(y0, y1)
    ax2.set_xlabel(r"$\phi$")
    ax2.set_ylabel(r"$\psi$")
    crit = pb["critical_size"]
    ax2.set_title(
        rf"(b) $\kappa = 2\kappa_{{crit}}$, $\epsilon = 0.25$, critical {crit:.5g}", fontsize=10
    )
    ax2.legend(fontsize=7, loc="lower left" if vel else "lower left")


# ==================================================================== stationary load point phase planes
V0_BA = 2.0


def _compute_trajectories_vo0(
    quality: str, kappa: float, eps_list: tuple[float, ...], window: Any
) -> dict[str, Any]:
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
        trajs = []
        for d in sizes:
            # stable creep slows down for ever (phi -> -inf): run until it has left the window
            t_end = 10.0
            while True:
                s = simulate(p, "velocity-jump", d, t_end=t_end, n_points=q["n_traj"])
                tr = s.trajectory
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


def _draw_trajectories_vo0(raw: dict[str, Any], fig: Figure) -> None:
    axs = fig.subplots(2, 2, sharex=True, sharey=True)
    for ax, panel in zip(axs.flat, raw["panels"]):
        _draw_phase_common(ax, panel, raw["window"])
        if "acceleration_line" in panel:
            a = panel["acceleration_line"]
            ax.plot(a["phi"], a["psi"], "--", color=C_ACC, lw=1.3)
        if "critical_trajectory" in panel:
            c = panel["critical_trajectory"]
            ax.plot(c["phi"], c["psi"], "-", color=C_CRIT, lw=1.6)
            d = panel["critical_size"]
            ax.annotate(
                "",
                xy=(d, d),
                xytext=(0, 0),
                arrowprops={"arrowstyle": "->", "color": C_CRIT, "lw": 1.5},
            )
            title = _eps_label(panel["eps"]) + rf", $\Delta\phi_{{crit}} = {d:.4g}$"
        else:
            title = _eps_label(panel["eps"]) + r", no unstable orbit ($\epsilon > \epsilon_{crit}$)"
        ax.set_title(title, fontsize=9)
    for ax in axs[1]:
        ax.set_xlabel(r"$\phi$")
    for ax in axs[:, 0]:
        ax.set_ylabel(r"$\psi$")
    kap = raw["kappa"]
    rel = "<" if kap < raw["ba"] - 1 else ">"
    fig.suptitle(
        rf"$v_o = 0$, $b/a = {raw['ba']:g}$, $\kappa = {kap:g} {rel} \kappa_{{crit}}$"
        + (rf", $\epsilon_{{crit}} = {raw['eps_crit']:.4g}$" if raw["eps_crit"] <= 1 else ""),
        fontsize=11,
    )
    handles = [
        Line2D([], [], color=C_SS, ls="--", label="steady state"),
        Line2D([], [], color=C_ACC, ls="--", label="acceleration line"),
        Line2D([], [], color=C_CRIT, label="critical trajectory U = 0"),
        Line2D([], [], color=C_U, label="U = const."),
        Line2D([], [], color=C_TRAJ, label="numerical"),
    ]
    axs[0, 0].legend(handles=handles, fontsize=7, loc="lower left")


# ==================================================================== critical jump, v_o = 0
CV_KAPPAS = (0.5, 1.0, 1.5)
CV_EXTRA_EPS = (0.3, 0.9)
CV_AB_EPS = (0.0, 0.25, 0.5, 0.75, 1.0)


def _compute_critical_jump_vo0(quality: str) -> dict[str, Any]:
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


def _draw_critical_jump_vo0(raw: dict[str, Any], fig: Figure) -> None:
    ax1, ax2 = fig.subplots(1, 2)
    a = raw["panel_a"]
    styles = {0.5: "-", 1.0: "--", 1.5: "-."}
    for c in a["curves"]:
        v = np.where(np.isfinite(c["critical_size"]), c["critical_size"], np.nan)
        rel = {0.5: "<", 1.0: "=", 1.5: ">"}[c["kappa"]]
        ax1.semilogy(
            c["eps"],
            v,
            styles[c["kappa"]],
            color="k",
            lw=1.4,
            label=rf"$\kappa = {c['kappa']:g} {rel} \kappa_{{crit}}$",
        )
    ec = a["eps_crit"]["1.5"]
    ax1.axvline(
        ec,
        color="tab:red",
        ls="--",
        lw=1.2,
        label=rf"$\epsilon_{{crit}} = {ec:.4g}$ ($\kappa = 1.5$)",
    )
    ax1.set_ylim(0.3, 30)
    ax1.set_xlabel(r"$\epsilon$")
    ax1.set_ylabel(r"$\Delta\phi_{crit}$")
    ax1.set_title(r"(a) $v_o = 0$, $b/a = 2$", fontsize=10)
    ax1.legend(fontsize=7, loc="upper left")
    b = raw["panel_b"]
    for i, c in enumerate(b["curves"]):
        col = mplcolor(i, len(b["curves"]))
        v = np.where(np.isfinite(c["critical_size"]), c["critical_size"], np.nan)
        ax2.semilogy(c["a_over_b"], v, "-", color=col, lw=1.4, label=_eps_label(c["eps"]))
        if c["ab_crit"] < 1.0:
            ax2.axvline(c["ab_crit"], color=col, ls="--", lw=0.9)
    ax2.set_xlim(0, 1)
    ax2.set_ylim(1e-2, 30)
    ax2.set_xlabel(r"$a/b$")
    ax2.set_ylabel(r"$\Delta\phi_{crit}$")
    ax2.set_title(r"(b) $v_o = 0$, $\kappa = 1$; dashed: $(a/b)_{crit}$", fontsize=10)
    ax2.legend(fontsize=7, loc="upper left")


def mplcolor(i: int, n: int) -> Any:
    import matplotlib as mpl

    return mpl.colormaps["viridis"](i / max(1, n - 1) * 0.9)


# ==================================================================== appendix: periodic / non-periodic response
PR_SIZE = 1.33


def _compute_periodic(quality: str) -> dict[str, Any]:
    p = Params(2.0, 1.0, 0.25, 1.0)
    crit = critical_perturbation(p, "load-point-jump")
    n = 3 * _Q[quality]["n_traj"]
    s = simulate(p, "load-point-jump", PR_SIZE, t_end=18.0, n_points=n)
    tr = s.trajectory
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


def _draw_periodic(raw: dict[str, Any], fig: Figure) -> None:
    axs = fig.subplots(2, 2)
    t = raw["trajectory"]
    for ax, key, lab in zip(
        axs.flat[:3],
        ("psi", "phi", "Theta"),
        (r"$\psi$", r"$\phi$", r"$\Theta = (b/a)\ln(\theta V_*/D_c)$"),
    ):
        ax.plot(t["slip"], t[key], "k-", lw=1.1)
        ax.set_xlabel(r"$\delta/D_c$")
        ax.set_ylabel(lab)
    ax = axs[1, 1]
    ax.plot(t["phi"], t["psi"], "k-", lw=1.1)
    ax.plot(t["phi"][0], t["psi"][0], "ko", ms=4)
    ax.set_xlabel(r"$\phi$")
    ax.set_ylabel(r"$\psi$")
    for a, lab in zip(axs.flat, "abcd"):
        a.set_title(f"({lab})", fontsize=9, loc="left")
    fig.suptitle(
        rf"$\kappa = \kappa_{{crit}} = 1$, $b/a = 2$, $\epsilon = 0.25$, $\Delta v_o/v_o = {raw['size']:g}$"
        rf" (critical {raw['critical_size']:.4g})",
        fontsize=10,
    )


NP_SIZES = (4.0, 9.0, 12.0, 14.0)
NP_SLIP = 50.0  # about this much slip (in Dc) is shown for the stable responses


def _compute_non_periodic(quality: str) -> dict[str, Any]:
    p = Params(2.0, 2.0, 0.25, 1.0)
    crit = critical_perturbation(p, "load-point-jump")
    rows = []
    for dv, label in zip(NP_SIZES, SD_LABELS):
        r = classify(p, "load-point-jump", dv)
        if r.outcome == "stable":
            s = simulate(
                p, "load-point-jump", dv, t_end=NP_SLIP / (1.0 + dv), n_points=_Q[quality]["n_traj"]
            )
        else:
            s = simulate(p, "load-point-jump", dv, n_points=_Q[quality]["n_traj"])
        tr = s.trajectory
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


def _draw_non_periodic(raw: dict[str, Any], fig: Figure) -> None:
    axs = fig.subplots(len(raw["rows"]), 3, sharex=True)
    colors = ["tab:green", "tab:olive", "tab:orange", "tab:purple"]
    for i, (row, col) in enumerate(zip(raw["rows"], colors)):
        for j, key in enumerate(("psi", "phi", "theta")):
            ax = axs[i, j]
            y = row[key]
            if key == "theta":
                ax.semilogy(row["slip"], y, color=col, lw=1.2)
            else:
                ax.plot(row["slip"], y, color=col, lw=1.2)
            if row["outcome"] == "stable":
                ax.axhline(row["new_steady_state"][key], color="0.5", ls=":", lw=0.8)
            if i == len(raw["rows"]) - 1:
                ax.set_xlabel(r"$\delta/D_c$")
            if i == 0:
                ax.set_title(
                    {"psi": r"$\psi$", "phi": r"$\phi$", "theta": r"$\theta V_*/D_c$"}[key],
                    fontsize=10,
                )
        axs[i, 0].set_ylabel(f"{row['size']:g}: {row['outcome']}", fontsize=8)
    fig.suptitle(
        rf"load-point jumps, $\kappa = 2\kappa_{{crit}}$, $b/a = 2$, $\epsilon = 0.25$"
        rf" (critical {raw['critical_size']:.5g})",
        fontsize=10,
    )


# ==================================================================== continuum eigenmodes
def _compute_modes(quality: str) -> dict[str, Any]:
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


def _draw_modes(raw: dict[str, Any], fig: Figure) -> None:
    axs = fig.subplots(1, 3)
    titles = {
        "B": "(B) finite interface 2L",
        "D": "(D) 2L near a free surface",
        "E": "(E) circular, radius R",
    }
    xl = {"B": "x/L", "D": "x/L", "E": "r/R"}
    for ax, c in zip(axs, raw["cases"]):
        ax.plot(c["x"], c["delta"], color="tab:red", lw=1.6)
        ax.axhline(0.0, color="0.6", lw=0.6)
        ax.set_title(titles[c["case"]], fontsize=9)
        ax.set_xlabel(xl[c["case"]])
        ax.text(
            0.5,
            0.08,
            rf"$k/k_* = {c['eigenvalue']:.10g}$" + f"\n$k_* = {c['k_star']}$",
            transform=ax.transAxes,
            ha="center",
            fontsize=8,
        )
        ax.set_ylim(-0.05, 1.1)
    axs[0].set_ylabel(r"eigenmode $\delta/\delta_{max}$")


# ==================================================================== registry
def _mk(
    name: str, label: str, caption: str, compute: Any, draw: Any, size: Any, note: str = ""
) -> FigureSpec:
    return FigureSpec(name, label, caption, compute, draw, size, note)


FIGURES: dict[str, FigureSpec] = {
    s.name: s
    for s in [
        _mk(
            "velocity-step",
            "fig: velocity stepping experiments",
            "analytic stress response (eq: delta tau) Delta tau/(b sigma) vs slip delta/Dc after velocity steps "
            "V2/V1 = 10^{+-1..4}, one panel per eps from 0 (slip law) to 1 (aging law)",
            _compute_velocity_step,
            _draw_velocity_step,
            (10.0, 6.0),
            "eps = 0, 0.2, 0.4, 0.6, 0.8, 1 (the caption does not list the panels' eps)",
        ),
        _mk(
            "trajectories-kcrit",
            "fig: trajectories 1",
            "U = const. contours in (phi, psi) for v_o = 1, b/a = 5/4, kappa = kappa_crit = 1/4, "
            "eps in {0, 0.3, 0.6, 1}; "
            "steady-state line, critical trajectory U = 0 (red), numerical trajectories from velocity jumps (black)",
            _compute_trajectories_kcrit,
            _draw_trajectories_kcrit,
            (10.0, 8.0),
        ),
        _mk(
            "critical-jump-kcrit",
            "fig: limiting perturbation 1",
            "(a) critical velocity jump dphi_crit vs eps for b/a = 5/4, kappa = kappa_crit, "
            "with the slip- and aging-law "
            "asymptotes; (b) slip law, dphi_crit vs a/b with the sqrt(2 a/b) scaling and the excluded point a/b = 1",
            _compute_critical_jump_kcrit,
            _draw_critical_jump_kcrit,
            (11.0, 4.8),
        ),
        _mk(
            "rate-neutral",
            "fig: rate neutral",
            "phase-plane trajectory for rate-neutral friction b/a = 1, kappa = 1, eps = 0.01 after a velocity jump "
            "dphi = 1: spirals back to steady state",
            _compute_rate_neutral,
            _draw_rate_neutral,
            (5.5, 4.5),
            "b/a = 1 exactly is outside rsfcore's range (1, 1e6]; computed at b/a = 1 + 1e-9 "
            "(tests compare with a direct b/a = 1 integration)",
        ),
        _mk(
            "stability-diagram-velocity",
            "fig: stability diagram2",
            "(a) critical velocity jump vs kappa/kappa_crit for several eps (b/a = 2, v_o = 1); (b) trajectories for "
            "dphi = 1, 1.5, 2.5, 3 at kappa = 2 kappa_crit, eps = 0.25 with U_kcrit level lines (red dashed)",
            lambda q: _compute_stability(q, "velocity-jump"),
            _draw_stability,
            (11.0, 5.0),
        ),
        _mk(
            "stability-diagram-load-point",
            "fig: stability diagram",
            "(a) critical load-point jump vs kappa/kappa_crit for several eps (b/a = 2); (b) trajectories for "
            "dv_o/v_o = 4, 9, 12, 14 at kappa = 2 kappa_crit, eps = 0.25",
            lambda q: _compute_stability(q, "load-point-jump"),
            _draw_stability,
            (11.0, 5.0),
            "the caption reads 12.66 off the figure; the critical jump is 12.6842",
        ),
        _mk(
            "trajectories-vo0-soft",
            "fig: trajectories 2",
            "stationary load point v_o = 0, b/a = 2, kappa = 0.5 < kappa_crit, eps in {0, 0.3, 0.6, 1}: U contours "
            "(eq: trajectories 2), critical line (red), acceleration line (orange), numerical trajectories",
            lambda q: _compute_trajectories_vo0(
                q, 0.5, (0.0, 0.3, 0.6, 1.0), (-3.0, 3.0, -2.5, 3.0)
            ),
            _draw_trajectories_vo0,
            (10.0, 8.0),
        ),
        _mk(
            "trajectories-vo0-stiff",
            "fig: trajectories 3",
            "stationary load point v_o = 0, b/a = 2, kappa = 3/2 > kappa_crit, "
            "eps in {0, 0.6, 0.7, 1}: unstable orbits "
            "vanish above eps_crit = 2/3",
            lambda q: _compute_trajectories_vo0(
                q, 1.5, (0.0, 0.6, 0.7, 1.0), (-4.0, 6.0, -4.0, 6.0)
            ),
            _draw_trajectories_vo0,
            (10.0, 8.0),
            "the caption says kappa = 2, which gives eps_crit = 1/2 and no critical line at eps = 0.6; "
            "kappa = 3/2 (the text) gives the caption's eps_crit = 2/3 and is used",
        ),
        _mk(
            "critical-jump-vo0",
            "fig: limiting perturbation 2",
            "v_o = 0: (a) dphi_crit vs eps for b/a = 2, kappa = 0.5, 1, 1.5 with eps_crit = 2/3; (b) dphi_crit vs a/b "
            "for kappa = 1 and eps in {0, 0.25, 0.5, 0.75, 1} with the (a/b)_crit asymptotes",
            _compute_critical_jump_vo0,
            _draw_critical_jump_vo0,
            (11.0, 4.8),
        ),
        _mk(
            "periodic-response",
            "fig: periodic motion",
            "kappa = kappa_crit = 1, b/a = 2, eps = 0.25, load-point jump dv_o/v_o = 1.33 (critical 4/3): psi, phi, "
            "Theta vs slip and the closed phase-plane orbit",
            _compute_periodic,
            _draw_periodic,
            (9.0, 7.0),
            "the caption's critical value 1.34 is 4/3 = 1.3333 (closed form 1/(kappa_crit (1 - eps)))",
        ),
        _mk(
            "non-periodic-response",
            "fig: non-periodic motion",
            "load-point jumps 4, 9, 12, 14 at kappa = 2 kappa_crit, b/a = 2, eps = 0.25: psi, phi, theta V*/Dc vs slip",
            _compute_non_periodic,
            _draw_non_periodic,
            (10.0, 9.0),
        ),
        _mk(
            "continuum-modes",
            "fig: continuum models",
            "smallest-eigenvalue eigenmodes (red curves of the schematic) of cases B, D and E with k/k_* "
            "(tab: table)",
            _compute_modes,
            _draw_modes,
            (11.0, 3.8),
            "the schematic itself is not computed; case B's converged eigenvalue is 1.1577738836976 "
            "(the paper prints 1.157773882)",
        ),
    ]
}
