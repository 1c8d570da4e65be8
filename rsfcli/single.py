"""`rsf classify`, `rsf trajectory`, `rsf critical`, `rsf stiffness`: the single questions
in dimensionless form (and the stiffness of a fault), asked in this process.

As every computing command (rsfcli.common): the HTTP route's request model
(:mod:`rsfapp.requests.single`) is built from the options given and answered through the
same :mod:`rsfapp.adapter` function, so ``--json`` prints the route's answer; an option
not given takes the model's default (eps = 0.25 at every door) and the text output ends
with the parameters used.
"""

from __future__ import annotations

import json
from enum import StrEnum
from pathlib import Path
from typing import Any

import typer

from rsfapp.requests import (
    ClassifyRequest,
    CriticalRequest,
    StiffnessPhysical,
    StiffnessRequest,
    TrajectoryRequest,
)

from .common import (
    JSON,
    PerturbationKind,
    echo_lines,
    emit,
    fail,
    given,
    json_value,
    model_option,
    run,
)

__all__ = ["Case", "Sampling", "app"]

#: The commands of this module (mounted on `rsf` by rsfcli.main when asked for).
app = typer.Typer(rich_markup_mode=None, add_completion=False)


class Sampling(StrEnum):
    tau = "tau"
    T = "T"
    time = "time"  # the older name of T


class Case(StrEnum):
    A = "A"
    B = "B"
    C = "C"
    D = "D"
    E = "E"


BA = model_option(ClassifyRequest, "ba")
KAPPA = model_option(ClassifyRequest, "kappa")
EPS = model_option(ClassifyRequest, "eps")
VO = model_option(ClassifyRequest, "vo")
PERT = model_option(ClassifyRequest, "perturbation")
SIZE = model_option(ClassifyRequest, "size")
LOG_SIZE = model_option(ClassifyRequest, "log_size")
RTOL = model_option(ClassifyRequest, "rtol")
START = model_option(
    ClassifyRequest,
    "start",
    help='Explicit start point as JSON, e.g. \'{"phi": 1.0, "psi": 2.0}\'; overrides '
    "perturbation and size.",
)


def _fail(exc: Exception) -> None:
    fail(str(exc))


def _emit(obj: dict[str, Any], as_json: bool, lines: list[str]) -> None:
    emit(obj, as_json, lines)


def _dimless(
    ba: float | None, kappa: float | None, eps: float | None, vo: float | None
) -> dict[str, Any]:
    return given(ba=ba, kappa=kappa, eps=eps, vo=vo)


@app.command()
def classify(
    ba: float | None = BA,
    kappa: float | None = KAPPA,
    eps: float | None = EPS,
    vo: float | None = VO,
    perturbation: PerturbationKind | None = PERT,
    size: float | None = SIZE,
    log_size: float | None = LOG_SIZE,
    rtol: float | None = RTOL,
    start: str | None = START,
    as_json: bool = JSON,
) -> None:
    """Certified outcome (stable/unstable) of one perturbation, with blow-up or return time and the true peak."""
    from rsfapp import adapter

    body = _dimless(ba, kappa, eps, vo)
    body.update(given(perturbation=perturbation, size=size, log_size=log_size, rtol=rtol))
    body.update(given(start=json_value("start", start)))
    d = run(ClassifyRequest, body, lambda r: adapter.classify(r, max_steps=None))
    _emit(
        d,
        as_json,
        [
            f"outcome       {d['outcome']}  (certificate: {d['certificate']})",
            f"blowup_time   {d['blowup_time']}",
            f"return_time   {d['return_time']}",
            f"peak_phi      {d['peak_phi']}  at T = {d['peak_time']}",
            f"rel_accuracy  {d['rel_accuracy']:.2e}   steps {d['n_steps']}",
            *_incomplete_lines(d),
            *echo_lines(d),
        ],
    )


def _incomplete_lines(d: dict[str, Any]) -> list[str]:
    """Why an answer is not complete (its ``reason``), as a text line; none when complete."""
    return [] if d.get("complete", True) else [f"incomplete    {d.get('reason') or '-'}"]


@app.command()
def trajectory(
    ba: float | None = BA,
    kappa: float | None = KAPPA,
    eps: float | None = EPS,
    vo: float | None = VO,
    perturbation: PerturbationKind | None = PERT,
    size: float | None = SIZE,
    log_size: float | None = LOG_SIZE,
    rtol: float | None = RTOL,
    n_points: int | None = model_option(TrajectoryRequest, "n_points", "--n-points"),
    t_end: float | None = model_option(
        TrajectoryRequest,
        "t_end",
        "--t-end",
        help="Run to this dimensionless time T (default: to the decision).",
    ),
    sampling: Sampling | None = model_option(
        TrajectoryRequest,
        "sampling",
        help="Samples even in the engine's hybrid time (tau) or in T ('time' is T too). "
        "Default: tau.",
    ),
    start: str | None = START,
    scales: str | None = model_option(
        TrajectoryRequest,
        "scales",
        help="SI columns of a dimensionless query, as JSON: "
        '\'{"a": .., "Dc": .., "sigma": .., "V_star": .., "f_star": ..}\'.',
    ),
    out: Path | None = typer.Option(None, "--out", help="Also write the samples to .csv or .json."),
    as_json: bool = JSON,
) -> None:
    """A trajectory downsampled to --n_points, plus everything `classify` reports."""
    from rsfapp import adapter

    if out is not None and out.suffix not in (".csv", ".json"):
        _fail(
            ValueError(
                f"out={str(out)!r} is invalid: valid range is a path ending in .csv or .json"
            )
        )
    body = _dimless(ba, kappa, eps, vo)
    body.update(
        given(
            perturbation=perturbation,
            size=size,
            log_size=log_size,
            rtol=rtol,
            n_points=n_points,
            t_end=t_end,
            sampling=None if sampling is None else ("T" if sampling.value == "time" else sampling),
            start=json_value("start", start),
            scales=json_value("scales", scales),
        )
    )
    d = run(TrajectoryRequest, body, lambda r: adapter.trajectory(r, max_steps=None))
    tr = d["trajectory"]
    if out is not None:
        _write_table(out, tr)
    lines = [
        f"outcome {d['outcome']} ({d['certificate']}); peak_phi {d['peak_phi']} at T = "
        f"{d['peak_time']}",
        *_incomplete_lines(d),
        *echo_lines(d),
        f"sampling      {d['sampling']['kind']}: {d['sampling']['description']}",
        "T phi psi",
    ]
    lines += [
        f"{a:.10g} {b:.10g} {c:.10g}" for a, b, c in zip(tr["T"], tr["phi"], tr["psi"], strict=True)
    ]
    _emit(d, as_json, lines)


def _write_table(path: Path, columns: dict[str, list[float]]) -> None:
    if path.suffix == ".json":
        path.write_text(json.dumps(columns, allow_nan=False))
    elif path.suffix == ".csv":
        keys = list(columns)
        rows = zip(*(columns[k] for k in keys), strict=True)
        path.write_text(
            ",".join(keys) + "\n" + "\n".join(",".join(repr(v) for v in row) for row in rows) + "\n"
        )
    else:
        _fail(
            ValueError(
                f"out={str(path)!r} is invalid: valid range is a path ending in .csv or .json"
            )
        )


@app.command()
def critical(
    ba: float | None = BA,
    kappa: float | None = KAPPA,
    eps: float | None = EPS,
    vo: float | None = VO,
    perturbation: PerturbationKind | None = PERT,
    rtol: float | None = RTOL,
    as_json: bool = JSON,
) -> None:
    """Critical perturbation size: kind zero / finite (with value) / infinite, method and accuracy."""
    from rsfapp import adapter

    body = _dimless(ba, kappa, eps, vo)
    body.update(given(perturbation=perturbation, rtol=rtol))
    d = run(CriticalRequest, body, adapter.critical)
    _emit(
        d,
        as_json,
        [
            f"kind          {d['kind']}",
            f"critical_size {d['critical_size']}",
            f"log_critical_size {d['log_critical_size']}",
            f"rel_accuracy  {d['rel_accuracy']:.2e}",
            f"method        {d['method']}",
            *echo_lines(d),
        ],
    )


@app.command()
def stiffness(
    case: Case = typer.Option(..., "--case", help="Continuum configuration of `tab: table` (A-E)."),
    mode: int | None = model_option(StiffnessRequest, "mode"),
    mu: float | None = model_option(StiffnessPhysical, "mu"),
    nu: float | None = model_option(StiffnessPhysical, "nu"),
    slip_mode: str | None = model_option(StiffnessPhysical, "mode_of_slip", "--slip-mode"),
    sigma: float | None = model_option(StiffnessPhysical, "sigma_Pa", "--sigma"),
    a: float | None = model_option(StiffnessPhysical, "a"),
    b: float | None = model_option(StiffnessPhysical, "b"),
    dc: float | None = model_option(StiffnessPhysical, "Dc_m", "--dc"),
    h: float | None = model_option(StiffnessPhysical, "h"),
    as_json: bool = JSON,
) -> None:
    """Continuum equivalent stiffness k/k_* (cases A-E) and, with physical parameters
    (--mu, --sigma_Pa, --a, --b, --Dc_m), the critical dimension."""
    from rsfapp import adapter

    body: dict[str, Any] = {"case": case.value, **given(mode=mode)}
    if None not in (mu, sigma, a, b, dc):
        body["physical"] = given(
            mu=mu, nu=nu, mode_of_slip=slip_mode, sigma_Pa=sigma, a=a, b=b, Dc_m=dc, h=h
        )
    d = run(StiffnessRequest, body, adapter.stiffness)
    _emit(d, as_json, [f"{k} {v}" for k, v in d.items()])
