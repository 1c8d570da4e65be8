"""The paper's figures drawn from their data (matplotlib, Agg canvas, no pyplot).

The data come from :func:`rsfapp.adapter.figures.figure_arrays` (rsfcore; every door
computes them there): a dict with the figure's ``name`` and ``quality`` and its arrays at
full resolution, drawing-only keys (``_grid``, ``_levels``, ``_shown``) included.
:func:`draw_figure` builds the matplotlib Figure; :data:`DRAWINGS` names the drawing and
the size of every figure.  Nothing here computes a number of the figure: a change of the
numbers is a change of the adapter.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
from matplotlib.figure import Figure
from matplotlib.lines import Line2D

from rsfcore import ParameterError

from ._common import new_figure

__all__ = ["DRAWINGS", "Drawing", "draw_figure"]

# colours used throughout
C_SS = "tab:blue"  # steady-state line
C_CRIT = "tab:red"  # critical trajectory
C_ACC = "tab:orange"  # acceleration line
C_U = "0.6"  # U contours
C_TRAJ = "black"  # numerical trajectories


@dataclass(frozen=True)
class Drawing:
    """How one figure is drawn from its data: the function and the size in inches."""

    draw: Callable[[dict[str, Any], Figure], None]
    size: tuple[float, float]


def draw_figure(data: Mapping[str, Any]) -> Figure:
    """The matplotlib Figure (Agg canvas) of the figure data ``data`` (the dict of
    :func:`rsfapp.adapter.figures.figure_arrays`; ``data["name"]`` chooses the drawing)."""
    name = data.get("name")
    if name not in DRAWINGS:
        raise ParameterError("name", name, "one of " + ", ".join(DRAWINGS))
    d = DRAWINGS[str(name)]
    fig = new_figure(*d.size)
    d.draw(dict(data), fig)
    return fig


def _eps_label(eps: float) -> str:
    if eps == 0.0:
        return r"$\epsilon \to 0$ (slip law)"
    if eps == 1.0:
        return r"$\epsilon = 1$ (aging law)"
    return rf"$\epsilon = {eps:g}$"


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
        ax.set_xlim(0, raw["slip_max"])
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


def _draw_stability(raw: dict[str, Any], fig: Figure) -> None:
    import matplotlib as mpl

    ax1, ax2 = fig.subplots(1, 2)
    ratio_max = raw["panel_a"]["kappa_ratio_max"]
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
        if c["eps"] > 0 and 1.0 / c["eps"] <= ratio_max:
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
    ax1.set_xlim(0.5, ratio_max)
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
        ph, ps = t["_shown"]
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
DRAWINGS: dict[str, Drawing] = {
    "velocity-step": Drawing(_draw_velocity_step, (10.0, 6.0)),
    "trajectories-kcrit": Drawing(_draw_trajectories_kcrit, (10.0, 8.0)),
    "critical-jump-kcrit": Drawing(_draw_critical_jump_kcrit, (11.0, 4.8)),
    "rate-neutral": Drawing(_draw_rate_neutral, (5.5, 4.5)),
    "stability-diagram-velocity": Drawing(_draw_stability, (11.0, 5.0)),
    "stability-diagram-load-point": Drawing(_draw_stability, (11.0, 5.0)),
    "trajectories-vo0-soft": Drawing(_draw_trajectories_vo0, (10.0, 8.0)),
    "trajectories-vo0-stiff": Drawing(_draw_trajectories_vo0, (10.0, 8.0)),
    "critical-jump-vo0": Drawing(_draw_critical_jump_vo0, (11.0, 4.8)),
    "periodic-response": Drawing(_draw_periodic, (9.0, 7.0)),
    "non-periodic-response": Drawing(_draw_non_periodic, (10.0, 9.0)),
    "continuum-modes": Drawing(_draw_modes, (11.0, 3.8)),
}
