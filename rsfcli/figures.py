"""`rsf figure`: a figure of the paper, regenerated from rsfcore through the figure
question's request model (:class:`rsfapp.requests.figures.FigureRequest`) and adapter
(:mod:`rsfapp.adapter.figures`), drawn by rsfplots; ``--json`` prints the data (the same
JSON as ``GET /v1/figures/{name}?format=json``), ``--list`` the catalogue."""

from __future__ import annotations

import textwrap
from pathlib import Path

import typer

from rsfapp.requests.figures import FigureRequest

from .common import emit, fail, given, model_option, run

__all__ = ["app", "figure_command"]

#: `rsf figure` (mounted on `rsf` by rsfcli.main when asked for).
app = typer.Typer(rich_markup_mode=None, add_completion=False)


def _print_list() -> None:
    from rsfapp.requests.figures import FIGURES

    width = max(len(n) for n in FIGURES)
    for info in FIGURES.values():
        cap = f"{info.label}: {info.caption}"
        lines = textwrap.wrap(cap, width=100 - width - 2) or [""]
        typer.echo(f"{info.name.ljust(width)}  {lines[0]}")
        for ln in lines[1:]:
            typer.echo(" " * (width + 2) + ln)
        if info.note:
            for ln in textwrap.wrap("note: " + info.note, width=100 - width - 2):
                typer.echo(" " * (width + 2) + ln)


def figure_command(
    name: str | None, out: Path | None, list_: bool, quality: str | None, as_json: bool
) -> None:
    """List the figures (``list_``), print the data of ``name`` (``as_json``) or draw it
    to ``out`` (default NAME.png).  Exit 2 on a usage error (no or unknown name, an
    extension other than .png/.svg, an invalid quality), 1 if it could not be computed."""
    from rsfapp.requests.figures import (
        DEFAULT_FIGURE_FORMAT,
        FIGURES,
        IMAGE_FORMATS,
        FigureRequest,
    )

    if list_ and not as_json:  # the catalogue alone: no numerics imported (fast)
        _print_list()
        return
    from rsfapp.adapter import figures as adapter

    if list_:
        emit(adapter.figure_list(), True, [])
        return
    if not name:
        fail("give a figure NAME or --list (names: " + ", ".join(FIGURES) + ")")
        return
    if name not in FIGURES:
        fail(f"name: unknown figure {name!r} (valid range: one of " + ", ".join(FIGURES) + ")")
    body = given(name=name, quality=quality)
    if as_json and out is None:
        emit(run(FigureRequest, body, adapter.figure), True, [])
        return
    target = Path(out) if out is not None else Path(f"{name}.{DEFAULT_FIGURE_FORMAT}")
    if target.suffix.lower().lstrip(".") not in IMAGE_FORMATS:
        fail(f"--out must end in .png or .svg, got {str(target)!r}")
    data = run(FigureRequest, body, adapter.figure_arrays)
    from rsfplots import render_figure

    render_figure(data, target)
    if as_json:
        emit(run(FigureRequest, body, adapter.figure), True, [])
    else:
        typer.echo(f"wrote {target} ({FIGURES[name].label}; quality {data['quality']})")


@app.command("figure")
def figure(
    name: str | None = typer.Argument(None, help="Figure name (see --list)."),
    out: Path | None = typer.Option(
        None, "--out", help="Output file, .png or .svg (default NAME.png)."
    ),
    quality: str | None = model_option(FigureRequest, "quality"),
    list_: bool = typer.Option(
        False, "--list", help="List the figures with the caption each reproduces."
    ),
    as_json: bool = typer.Option(
        False,
        "--json",
        help="Print the figure's data (with --list: the catalogue) as one JSON object, "
        "as GET /v1/figures/{name}?format=json answers; with --out the image is written too.",
    ),
) -> None:
    """Regenerate a figure of the paper from rsfcore (`rsf figure --list` names them)."""
    figure_command(name, out, list_, quality, as_json)
