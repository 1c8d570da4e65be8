"""Shared plumbing of rsfplots: Agg canvases, output formats, JSON-safe data, downsampling.

No pyplot anywhere: every figure is a :class:`matplotlib.figure.Figure` attached to an Agg
canvas, so rendering is thread-safe and never touches a display or global state.
"""

from __future__ import annotations

import io
from typing import Any

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from rsfcore import ParameterError
from rsfcore.jsonsafe import jsonsafe  # noqa: F401  (re-exported for rsfplots modules)

__all__ = [
    "FORMATS",
    "QUALITIES",
    "new_figure",
    "figure_bytes",
    "check_format",
    "check_quality",
    "jsonsafe",
    "thin",
    "clip_to_window",
]

FORMATS = ("png", "svg")
QUALITIES = ("draft", "paper")
#: largest number of points per curve in the data behind a figure
MAX_DATA_POINTS = 400

PNG_DPI = {"draft": 80, "paper": 110}


def check_quality(quality: str) -> str:
    if quality not in QUALITIES:
        raise ParameterError("quality", quality, "'draft' or 'paper'")
    return quality


def check_format(fmt: str) -> str:
    f = str(fmt).lower().lstrip(".")
    if f not in FORMATS:
        raise ParameterError("format", fmt, "'png' or 'svg' (or a path ending in .png / .svg)")
    return f


def new_figure(width: float, height: float) -> Figure:
    """A Figure of the given size in inches on its own Agg canvas (no pyplot)."""
    fig = Figure(figsize=(width, height), layout="constrained")
    FigureCanvasAgg(fig)
    return fig


def figure_bytes(fig: Figure, fmt: str = "png", dpi: int | None = None) -> bytes:
    """Encode a figure as PNG or SVG bytes."""
    fmt = check_format(fmt)
    buf = io.BytesIO()
    kw: dict[str, Any] = {"format": fmt}
    if fmt == "png":
        kw["dpi"] = dpi or PNG_DPI["paper"]
        kw["metadata"] = {"Software": "rsfplots (matplotlib Agg)"}
    else:
        kw["metadata"] = {"Date": None}  # reproducible SVG
    fig.savefig(buf, **kw)
    return buf.getvalue()


def thin(n: int, max_points: int = MAX_DATA_POINTS) -> np.ndarray:
    """Indices of at most ``max_points`` of ``n`` samples, evenly strided, first and last kept."""
    if n <= max_points:
        return np.arange(n)
    idx = np.unique(np.round(np.linspace(0, n - 1, max_points)).astype(int))
    return idx


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
