"""Shared plumbing of rsfplots: Agg canvases, output formats, reproducible bytes.

No pyplot anywhere: every figure is a :class:`matplotlib.figure.Figure` attached to an Agg
canvas, so rendering never touches a display; the only global state is matplotlib's
rcParams, changed for the saving of an SVG file only (fixed ids; the service renders
under one lock, :mod:`service.images`).
"""

from __future__ import annotations

import io
from typing import Any

import matplotlib as mpl
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from rsfcore import ParameterError
from rsfcore.jsonsafe import jsonsafe  # noqa: F401  (re-exported for rsfplots modules)

__all__ = [
    "FORMATS",
    "PNG_DPI",
    "new_figure",
    "figure_bytes",
    "check_format",
    "jsonsafe",
]

FORMATS = ("png", "svg")
#: PNG resolution of a paper figure by the quality of its data (dots per inch)
PNG_DPI = {"draft": 80, "paper": 110}
#: salt of the ids in an SVG file (matplotlib draws a random one per file otherwise)
SVG_HASH_SALT = "rsfplots"


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
        fig.savefig(buf, **kw)
    else:
        kw["metadata"] = {"Date": None}  # reproducible SVG: no date, fixed ids
        with mpl.rc_context({"svg.hashsalt": SVG_HASH_SALT}):
            fig.savefig(buf, **kw)
    return buf.getvalue()
