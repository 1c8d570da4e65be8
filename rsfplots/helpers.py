"""Plots of single results for the service's ``?format=png`` responses.

* :func:`plot_trajectory` -- a TrajectoryResult (or its ``to_dict()``): phase plane and phi(T).
* :func:`plot_u_field` -- a U grid (arrays, or the service's analytic-U JSON): contours of U.
* :func:`plot_diagram` -- a DiagramResult (or its ``to_dict()``): critical sizes or outcomes.

Each returns the encoded image (PNG by default, or SVG) as bytes.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np
from matplotlib.colors import ListedColormap, LogNorm

from rsfcore import ParameterError

from ._common import figure_bytes, new_figure

__all__ = ["plot_trajectory", "plot_u_field", "plot_diagram"]


def _arr(v: Any) -> np.ndarray:
    """List (None for non-finite) or array -> float array with nan."""
    if v is None:
        return np.array([], dtype=float)
    a = np.array(v, dtype=object)
    return np.array(np.where(a == None, np.nan, a), dtype=float)  # noqa: E711


def plot_trajectory(result: Any, fmt: str = "png", *, dpi: int = 100) -> bytes:
    """Phase plane (phi, psi) and phi(T) of a trajectory.

    Args:
        result: rsfcore.TrajectoryResult with a trajectory (simulate(..., n_points>0)) or its
            ``to_dict()``.
        fmt: 'png' or 'svg'.
    Raises ParameterError if the result carries no trajectory.
    """
    d = result.to_dict() if hasattr(result, "to_dict") else dict(result)
    tr = d.get("trajectory")
    if not tr:
        raise ParameterError(
            "trajectory", None, "a result with a sampled trajectory (n_points > 0 or times)"
        )
    phi, psi, T = _arr(tr["phi"]), _arr(tr["psi"]), _arr(tr["T"])
    p = d.get("params", {})
    ba = float(p.get("ba", 2.0))
    vo = float(p.get("vo", 1.0))
    fig = new_figure(9.0, 4.0)
    ax1, ax2 = fig.subplots(1, 2)
    ax1.plot(phi, psi, "k-", lw=1.2)
    ax1.plot(phi[:1], psi[:1], "go", ms=5, label="start")
    lim = np.array([np.nanmin(phi), np.nanmax(phi)]) if phi.size else np.array([-1.0, 1.0])
    span = max(1e-3, lim[1] - lim[0])
    xs = np.array([lim[0] - 0.1 * span, lim[1] + 0.1 * span])
    if vo > 0:
        ax1.plot([math.log(vo)], [(1.0 - ba) * math.log(vo)], "bx", ms=6, label="steady state")
    ax1.plot(xs, (1.0 - ba) * xs, "--", color="tab:blue", lw=0.9, label=r"$\psi = (1 - b/a)\phi$")
    ax1.set_xlabel(r"$\phi = \ln(V/V_*)$")
    ax1.set_ylabel(r"$\psi = (\tau - \tau_*)/a\sigma$")
    finite = psi[np.isfinite(psi)]
    if finite.size:
        lo, hi = np.percentile(finite, [0, 100])
        pad = 0.1 * max(1e-3, hi - lo)
        ax1.set_ylim(lo - pad, hi + pad)
    ax1.legend(fontsize=7)
    ax2.plot(T, phi, "k-", lw=1.2)
    ax2.set_xlabel(r"$T = V_* t/D_c$")
    ax2.set_ylabel(r"$\phi$")
    title = (
        f"{d.get('outcome', '')} ({d.get('certificate', '')}); b/a={ba:g}, kappa={p.get('kappa', '?'):g}, "
        f"eps={p.get('eps', '?'):g}, vo={vo:g}"
        if p
        else str(d.get("outcome", ""))
    )
    fig.suptitle(title, fontsize=9)
    return figure_bytes(fig, fmt, dpi)


def plot_u_field(
    phi: Any,
    psi: Any = None,
    U: Any = None,
    *,
    levels: Any = None,
    n_levels: int = 25,
    title: str | None = None,
    fmt: str = "png",
    dpi: int = 100,
) -> bytes:
    """Contours of a Lyapunov function U on a (phi, psi) grid.

    Args:
        phi, psi: 1-D grid axes (len n_phi, n_psi); U: (n_phi, n_psi) values (None/nan where
            undefined).  Alternatively pass the service's analytic-U JSON dict (keys phi, psi,
            U, function) as the first argument.
        levels: contour levels (default: ``n_levels`` quantile levels of U plus U = 0, drawn red).
    """
    if isinstance(phi, Mapping):
        d = phi
        phi, psi, U = d["phi"], d["psi"], d["U"]
        title = title or f"U ({d.get('function', '')})"
    x, y, z = _arr(phi), _arr(psi), np.array(_arr(np.ravel(np.array(U, dtype=object))), dtype=float)
    if x.ndim != 1 or y.ndim != 1 or z.size != x.size * y.size:
        raise ParameterError("U", "array", "shape (len(phi), len(psi)) on a grid")
    z = z.reshape(x.size, y.size)
    if x.size < 2 or y.size < 2:
        raise ParameterError("grid", f"{x.size} x {y.size}", "at least 2 x 2 points")
    zm = np.ma.masked_invalid(z.T)
    fig = new_figure(6.0, 5.0)
    ax = fig.subplots()
    if levels is None and zm.count() > 0:
        fin = zm.compressed()
        qs = np.unique(np.quantile(fin, np.linspace(0.02, 0.98, n_levels)))
        levels = qs[qs != 0.0]
    if levels is not None and len(levels):
        ax.contour(
            x, y, zm, levels=np.sort(np.asarray(levels, dtype=float)), colors="0.4", linewidths=0.7
        )
    if zm.count() > 0 and np.nanmin(z) < 0.0 < np.nanmax(z):
        ax.contour(x, y, zm, levels=[0.0], colors="tab:red", linewidths=1.5)
    ax.set_xlabel(r"$\phi$")
    ax.set_ylabel(r"$\psi$")
    ax.set_title(title or "U = const. (red: U = 0)", fontsize=10)
    return figure_bytes(fig, fmt, dpi)


_KIND_CMAP = ListedColormap(["#d62728", "#ffffff", "#1f77b4"])  # zero, finite, infinite


def plot_diagram(diagram: Any, fmt: str = "png", *, dpi: int = 100) -> bytes:
    """A stability diagram: log critical size on the grid (zero red, infinite blue), or the
    stable/unstable outcome map when the diagram was computed for a size / with a size axis.

    Args: rsfcore.diagram.DiagramResult or its ``to_dict()``.
    """
    d = diagram.to_dict() if hasattr(diagram, "to_dict") else dict(diagram)
    x, y = _arr(d["x"]), _arr(d["y"])
    cs = np.array(
        [[np.inf if v is None else float(v) for v in row] for row in d["critical_size"]],
        dtype=float,
    )
    kind = np.asarray(d["kind"], dtype=int)
    fig = new_figure(6.5, 5.0)
    ax = fig.subplots()
    xn, yn = d["x_name"], d["y_name"]
    if d.get("outcome") is not None:
        out = np.asarray(d["outcome"], dtype=float)
        m = ax.pcolormesh(
            x,
            y,
            out.T,
            cmap=ListedColormap(["#9ecae1", "#de2d26"]),
            vmin=0,
            vmax=1,
            shading="nearest",
        )
        cb = fig.colorbar(m, ax=ax, ticks=[0.25, 0.75])
        cb.ax.set_yticklabels(["stable", "unstable"])
        title = f"outcome of {d.get('perturbation', '')}"
    else:
        fin = np.where((kind == 1) & np.isfinite(cs) & (cs > 0), cs, np.nan)
        ax.pcolormesh(
            x,
            y,
            np.where(kind.T == 1, np.nan, kind.T),
            cmap=_KIND_CMAP,
            vmin=0,
            vmax=2,
            shading="nearest",
        )
        if np.any(np.isfinite(fin)):
            lo, hi = np.nanmin(fin), np.nanmax(fin)
            m = ax.pcolormesh(
                x,
                y,
                fin.T,
                norm=LogNorm(vmin=lo, vmax=max(hi, lo * 1.0001)),
                cmap="viridis",
                shading="nearest",
            )
            fig.colorbar(m, ax=ax, label="critical size")
            if x.size >= 2 and y.size >= 2:
                ax.contour(x, y, np.log(fin.T), levels=8, colors="k", linewidths=0.5)
        title = f"critical {d.get('perturbation', '')} (red: zero, blue: infinite)"
    ax.set_xlabel(xn)
    ax.set_ylabel(yn)
    fixed = ", ".join(
        f"{k}={v:g}" for k, v in (d.get("fixed") or {}).items() if isinstance(v, (int, float))
    )
    ax.set_title(title + (f"\n{fixed}" if fixed else ""), fontsize=9)
    return figure_bytes(fig, fmt, dpi)
