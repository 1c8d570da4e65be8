"""rsfplots: the figures of Ciardo & Viesca regenerated from rsfcore, and plots of single results.

Matplotlib with the Agg canvas only (no pyplot, no display, no web code); rsfcore does not
import this package.

* ``FIGURES``: name -> :class:`FigureSpec` (paper label, one-line caption, ``figure(quality)``
  building a matplotlib Figure, ``data(quality)`` returning the plotted arrays, JSON-safe).
* :func:`render` writes a figure to .png/.svg or returns its bytes; :func:`list_figures`.
* :func:`plot_trajectory`, :func:`plot_u_field`, :func:`plot_diagram` for ``?format=png``.

Qualities: 'draft' (coarse grids, a few seconds a figure; used by the tests) and 'paper'
(the default; the gallery and ``rsf figure``).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from rsfcore import ParameterError

from ._common import FORMATS, PNG_DPI, QUALITIES, check_format, check_quality, figure_bytes
from .figures import FIGURES, FigureSpec, build_figure, figure_data
from .helpers import plot_diagram, plot_trajectory, plot_u_field

__all__ = [
    "FIGURES",
    "FigureSpec",
    "FORMATS",
    "QUALITIES",
    "render",
    "list_figures",
    "figure_data",
    "build_figure",
    "plot_trajectory",
    "plot_u_field",
    "plot_diagram",
]


def list_figures() -> list[dict[str, str]]:
    """[{name, caption}] for every figure; caption = '<paper label>: <what it shows>'."""
    return [{"name": s.name, "caption": f"{s.label}: {s.caption}"} for s in FIGURES.values()]


def render(
    name: str, path_or_format: str | Path = "png", *, quality: str = "paper", dpi: int | None = None
) -> bytes | None:
    """Render figure ``name``.

    ``path_or_format``: 'png' or 'svg' -> the encoded bytes are returned; a path ending in
    .png or .svg -> the file is written (parents created) and None is returned.
    Raises rsfcore.ParameterError for an unknown name, format or quality.
    """
    if name not in FIGURES:
        raise ParameterError("name", name, "one of " + ", ".join(FIGURES))
    quality = check_quality(quality)
    target: Path | None = None
    s = str(path_or_format)
    if isinstance(path_or_format, Path) or s.lower().lstrip(".") not in FORMATS:
        target = Path(path_or_format)
        fmt = check_format(target.suffix)
    else:
        fmt = check_format(s)
    fig = build_figure(name, quality)
    data = figure_bytes(fig, fmt, dpi or PNG_DPI[quality])
    if target is None:
        return data
    target.parent.mkdir(parents=True, exist_ok=True)
    target.write_bytes(data)
    return None


def _caption(name: str) -> str:  # pragma: no cover - convenience
    s: Any = FIGURES[name]
    return f"{s.label}: {s.caption}"
