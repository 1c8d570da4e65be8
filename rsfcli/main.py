"""`rsf`: command-line interface to rsfcore and the service.

Every command prints human-readable text by default and one JSON object with --json.
Invalid input exits with status 2 and a message naming the field and its valid range.
Dimensionless parameters follow the paper: --ba = b/a (> 1), --kappa = k Dc/(a sigma)
(absolute, kappa_crit = b/a - 1), --eps in [0, 1] (0 slip law, 1 aging law),
--vo = V_o/V_* (0 = stationary load point).

Every computing command builds the HTTP endpoint's request model (:mod:`rsfapp.requests`)
from the options given and answers through :mod:`rsfapp.adapter`, so ``--json`` prints the
endpoint's answer; an option not given takes the model's default (eps = 0.25 at every
door) and the text output ends with the parameters used (rsfcli.common).
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
    SweepFixed,
    SweepRequest,
    TrajectoryRequest,
)
from rsfapp.requests.figures import FigureRequest
from rsfcore.limits import Limit

from .common import echo_lines, emit, fail, given, json_value, model_option, run

app = typer.Typer(
    rich_markup_mode=None,  # help texts carry units in brackets ([m], [s]), not markup
    name="rsf",
    help="Non-linear slip-stability analysis of rate-and-state friction (spring-slider, "
    "aging-to-slip evolution laws; Ciardo & Viesca).",
    no_args_is_help=True,
    add_completion=False,
    context_settings={"help_option_names": ["-h", "--help"]},
)


class PerturbationKind(StrEnum):
    velocity_jump = "velocity-jump"
    load_point_jump = "load-point-jump"


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


def _opt(limit: Limit, flag: str, extra: str = "") -> Any:
    """A typer option whose default and help (range included) come from rsfcore.limits."""
    return typer.Option(limit.default, flag, help=f"{limit.help()}{extra}")


# The options of the single queries are the request model's fields (rsfapp.requests):
# not given = the model's default, the same as over HTTP and from the Python client.
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
JSON = typer.Option(False, "--json", help="Print one JSON object.")


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
            *echo_lines(d),
        ],
    )


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
    _emit(summary, as_json, lines)


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


@app.command()
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
    from .figures import figure_command

    figure_command(name, out, list_, quality, as_json)


INSECURE = typer.Option(
    False,
    "--insecure",
    help="Serve without API keys (RSF_AUTH=off), even on a non-loopback interface.",
)


def _insecure(insecure: bool) -> None:
    if insecure:
        import os

        os.environ["RSF_AUTH"] = "off"


@app.command()
def serve(
    host: str = typer.Option("127.0.0.1", "--host", help="Interface to bind."),
    port: int = typer.Option(8000, "--port", help="TCP port."),
    data_dir: Path = typer.Option(
        Path("rsf-data"),
        "--data-dir",
        help="Directory for the SQLite cache, sweep store and the filesystem broker.",
    ),
    insecure: bool = INSECURE,
) -> None:
    """Start the HTTP API (uvicorn) and an embedded Celery worker (filesystem broker unless RSF_BROKER_URL is set)."""
    from .serve import serve as _serve

    _insecure(insecure)

    _serve(host=host, port=port, data_dir=data_dir)


@app.command()
def api(
    host: str = typer.Option("127.0.0.1", "--host", help="Interface to bind."),
    port: int = typer.Option(8000, "--port", help="TCP port."),
    workers: int = typer.Option(
        1, "--workers", min=1, help="API processes (share only the database and broker)."
    ),
    wait_db: float = typer.Option(
        60.0, "--wait-db", min=0, help="Seconds to wait for an unreachable database at start."
    ),
    insecure: bool = INSECURE,
) -> None:
    """Start the HTTP API only (no worker); workers run with `rsf worker`, anywhere."""
    from .serve import api as _api

    _insecure(insecure)

    _api(host=host, port=port, workers=workers, wait_db_s=wait_db)


@app.command()
def worker(
    concurrency: int | None = typer.Option(
        None, "--concurrency", min=1, help="Worker processes (default: CPU count)."
    ),
    loglevel: str = typer.Option("INFO", "--loglevel", help="Celery log level."),
    wait_db: float = typer.Option(
        60.0, "--wait-db", min=0, help="Seconds to wait for an unreachable database at start."
    ),
) -> None:
    """Start a Celery worker; needs only RSF_BROKER_URL and RSF_CACHE_URL (no shared disk)."""
    from .serve import worker as _worker

    _worker(concurrency=concurrency, loglevel=loglevel, wait_db_s=wait_db)


from .keys import app as _keys_app  # noqa: E402

app.add_typer(_keys_app, name="keys")
from .lab import fit_command, protocol_app, si_app  # noqa: E402  (SI, protocols, fits)

app.add_typer(si_app, name="si")
app.add_typer(protocol_app, name="protocol")
app.command("fit")(fit_command)
from .questions import register as _register_questions  # noqa: E402  (boundaries, batches)

_register_questions(app)
from .sweep import app as _sweep_app  # noqa: E402  (rsf sweep submit|status|download)

app.add_typer(_sweep_app, name="sweep")
from .db import app as _db_app  # noqa: E402  (rsf db upgrade|current|history|revision)

app.add_typer(_db_app, name="db")


def main() -> None:
    """Console entry point."""
    app()


if __name__ == "__main__":  # pragma: no cover
    main()
