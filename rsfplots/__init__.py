"""rsfplots: the figures of Ciardo & Viesca drawn from their data, and plots of single results.

Matplotlib with the Agg canvas only (no pyplot, no display, no web code); rsfcore does not
import this package, and this package computes nothing of a figure: the data come from
:mod:`rsfapp.adapter.figures` (the one adapter of the figure question; every door asks it).

* :func:`render_figure` draws figure data (:func:`rsfapp.adapter.figures.figure_arrays`)
  as PNG/SVG bytes or writes a .png/.svg file; :func:`draw_figure` gives the matplotlib
  Figure; ``DRAWINGS``: name -> :class:`Drawing` (function, size).
* :func:`plot_trajectory`, :func:`plot_u_field`, :func:`plot_diagram` for ``?format=png``.

The PNG resolution follows the data's quality: 'draft' 80 dpi, 'paper' 110 dpi.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any

from ._common import FORMATS, PNG_DPI, check_format, figure_bytes
from .figures import DRAWINGS, Drawing, draw_figure
from .helpers import plot_diagram, plot_trajectory, plot_u_field

__all__ = [
    "DRAWINGS",
    "Drawing",
    "FORMATS",
    "draw_figure",
    "render_figure",
    "plot_trajectory",
    "plot_u_field",
    "plot_diagram",
]


def render_figure(
    data: Mapping[str, Any], path_or_format: str | Path = "png", *, dpi: int | None = None
) -> bytes | None:
    """Draw the figure data ``data`` (``name``, ``quality`` and the arrays of
    :func:`rsfapp.adapter.figures.figure_arrays`).

    ``path_or_format``: 'png' or 'svg' -> the encoded bytes are returned; a path ending in
    .png or .svg -> the file is written (parents created) and None is returned.  ``dpi``
    defaults to the quality's (:data:`PNG_DPI`).  Raises rsfcore.ParameterError for an
    unknown figure name or format.
    """
    target: Path | None = None
    s = str(path_or_format)
    if isinstance(path_or_format, Path) or s.lower().lstrip(".") not in FORMATS:
        target = Path(path_or_format)
        fmt = check_format(target.suffix)
    else:
        fmt = check_format(s)
    fig = draw_figure(data)
    blob = figure_bytes(fig, fmt, dpi or PNG_DPI.get(str(data.get("quality")), PNG_DPI["paper"]))
    if target is None:
        return blob
    target.parent.mkdir(parents=True, exist_ok=True)
    target.write_bytes(blob)
    return None
