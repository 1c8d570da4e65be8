"""`rsf diagram`: a stability diagram on a 2-D grid, the sweep request of POST /v1/sweeps
(x/y form, same defaults, :mod:`rsfapp.requests.sweeps`) computed in this process by the
sweep adapter (:mod:`rsfapp.adapter.sweeps`)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import typer

from rsfapp.requests import SweepFixed, SweepRequest

from .common import JSON, PerturbationKind, emit, fail, given, model_option, run

__all__ = ["app"]

#: The command of this module (mounted on `rsf` by rsfcli.main when asked for).
app = typer.Typer(rich_markup_mode=None, add_completion=False)


@app.command()
def diagram(
    x: tuple[str, float, float, int] = typer.Option(
        ..., "--x", help="NAME START STOP N for the first axis (NAME: kappa_ratio, eps, ba, size)."
    ),
    y: tuple[str, float, float, int] = typer.Option(
        ..., "--y", help="NAME START STOP N for the second axis."
    ),
    ba: float | None = model_option(SweepFixed, "ba"),
    kappa: float | None = model_option(SweepFixed, "kappa"),
    kappa_ratio: float | None = model_option(SweepFixed, "kappa_ratio"),
    eps: float | None = model_option(SweepFixed, "eps"),
    vo: float | None = model_option(SweepFixed, "vo"),
    perturbation: PerturbationKind | None = model_option(SweepRequest, "perturbation"),
    size: float | None = model_option(
        SweepFixed, "size", help="If given, also classify this perturbation size at every point."
    ),
    rtol: float | None = model_option(SweepRequest, "rtol"),
    out: Path = typer.Option(
        ...,
        "--out",
        help="Output file: .npz (arrays x, y, critical_size[i, j] at x[i], y[j]; inf = infinite), .csv or .json.",
    ),
    as_json: bool = JSON,
) -> None:
    """Stability diagram on a 2-D grid of two of kappa_ratio, eps, ba, size: the sweep
    request of POST /v1/sweeps (x/y form, same defaults), computed in this process."""
    from rsfapp.adapter import sweeps

    if out.suffix not in (".npz", ".csv", ".json"):
        fail(f"out={str(out)!r} is invalid: valid range is a path ending in .npz, .csv or .json")
    body: dict[str, Any] = {
        "x": {"name": x[0], "start": x[1], "stop": x[2], "n": x[3]},
        "y": {"name": y[0], "start": y[1], "stop": y[2], "n": y[3]},
        "fixed": given(ba=ba, kappa=kappa, kappa_ratio=kappa_ratio, eps=eps, vo=vo, size=size),
        **given(perturbation=perturbation, rtol=rtol),
    }
    req_echo: dict[str, Any] = {}

    def compute(req: SweepRequest) -> dict[str, Any]:
        res = sweeps.diagram(req)
        res.save(out)
        req_echo.update(req.model_dump(exclude_none=True, exclude={"chunk_points"}))
        return sweeps.diagram_summary(res)

    summary = {"out": str(out), **run(SweepRequest, body, compute), "request": req_echo}
    lines = [f"{k} {v}" for k, v in summary.items() if k != "request"]
    fixed = req_echo.get("fixed", {})
    lines.append("fixed         " + "  ".join(f"{k} {v}" for k, v in fixed.items()))
    lines.append(
        f"used          perturbation {req_echo.get('perturbation')}  rtol {req_echo.get('rtol')}"
    )
    emit(summary, as_json, lines)
