"""`rsf`: command-line interface to rsfcore and the service.

Every command prints human-readable text by default and one JSON object with --json.
Invalid input exits with status 2 and a message naming the field and its valid range.
Dimensionless parameters follow the paper: --ba = b/a (> 1), --kappa = k Dc/(a sigma)
(absolute, kappa_crit = b/a - 1), --eps in [0, 1] (0 slip law, 1 aging law),
--vo = V_o/V_* (0 = stationary load point).
"""

from __future__ import annotations

import json
from enum import StrEnum
from pathlib import Path
from typing import Any

import typer

from rsfcore import limits
from rsfcore.limits import Limit

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
    time = "time"


class Case(StrEnum):
    A = "A"
    B = "B"
    C = "C"
    D = "D"
    E = "E"


def _opt(limit: Limit, flag: str, extra: str = "") -> Any:
    """A typer option whose default and help (range included) come from rsfcore.limits."""
    return typer.Option(limit.default, flag, help=f"{limit.help()}{extra}")


BA = _opt(limits.BA, "--ba")
KAPPA = _opt(limits.KAPPA, "--kappa")
EPS = _opt(limits.EPS, "--eps")
VO = _opt(limits.VO, "--vo")
PERT = typer.Option(
    PerturbationKind.velocity_jump, "--perturbation", help="Kind of perturbation from steady state."
)
SIZE = typer.Option(
    limits.VELOCITY_JUMP_SIZE.default,
    "--size",
    help="Perturbation size: velocity jump d (phi and psi jump by d), valid "
    f"range {limits.VELOCITY_JUMP_SIZE.text}; or load-point jump dv "
    f"(v_o -> v_o (1 + dv)), valid range {limits.LOAD_POINT_JUMP_SIZE.text}.",
)
RTOL = _opt(limits.RTOL, "--rtol")
JSON = typer.Option(False, "--json", help="Print one JSON object.")


def _fail(exc: Exception) -> None:
    typer.echo(f"error: {exc}", err=True)
    raise typer.Exit(code=2)


def _emit(obj: dict[str, Any], as_json: bool, lines: list[str]) -> None:
    if as_json:
        typer.echo(json.dumps(obj, allow_nan=False))
    else:
        typer.echo("\n".join(lines))


def _params(ba: float, kappa: float, eps: float, vo: float) -> Any:
    from rsfcore import Params

    return Params(ba=ba, kappa=kappa, eps=eps, vo=vo)


@app.command()
def classify(
    ba: float = BA,
    kappa: float = KAPPA,
    eps: float = EPS,
    vo: float = VO,
    perturbation: PerturbationKind = PERT,
    size: float = SIZE,
    rtol: float = RTOL,
    as_json: bool = JSON,
) -> None:
    """Certified outcome (stable/unstable) of one perturbation, with blow-up or return time and the true peak."""
    from rsfcore import ParameterError, UndecidedError
    from rsfcore import classify as _classify

    try:
        r = _classify(_params(ba, kappa, eps, vo), perturbation.value, size, rtol=rtol)
    except (ParameterError, UndecidedError) as e:
        _fail(e)
    d = r.to_dict()
    d.pop("trajectory", None)
    _emit(
        d,
        as_json,
        [
            f"outcome      {r.outcome}  (certificate: {r.certificate})",
            f"blowup_time  {r.blowup_time}",
            f"return_time  {r.return_time}",
            f"peak_phi     {r.peak_phi}  at T = {r.peak_time}",
            f"rel_accuracy {r.rel_accuracy:.2e}   steps {r.n_steps}",
        ],
    )


@app.command()
def trajectory(
    ba: float = BA,
    kappa: float = KAPPA,
    eps: float = EPS,
    vo: float = VO,
    perturbation: PerturbationKind = PERT,
    size: float = SIZE,
    rtol: float = RTOL,
    n_points: int = typer.Option(
        limits.N_POINTS.default, "--n-points", help=limits.N_POINTS.help()
    ),
    t_end: float | None = typer.Option(
        None, "--t-end", help="Run to this dimensionless time T (default: to the decision)."
    ),
    sampling: Sampling = typer.Option(
        Sampling.tau,
        "--sampling",
        help="Samples even in the engine's hybrid time (tau) or in T (time).",
    ),
    out: Path | None = typer.Option(None, "--out", help="Also write the samples to .csv or .json."),
    as_json: bool = JSON,
) -> None:
    """A trajectory downsampled to --n-points, plus everything `classify` reports."""
    from rsfcore import ParameterError, UndecidedError, simulate

    try:
        r = simulate(
            _params(ba, kappa, eps, vo),
            perturbation.value,
            size,
            rtol=rtol,
            n_points=n_points,
            t_end=t_end,
            sampling=sampling.value,
        )
    except (ParameterError, UndecidedError) as e:
        _fail(e)
    d = r.to_dict()
    if out is not None:
        _write_table(out, d["trajectory"])
    t = r.trajectory
    assert t is not None
    lines = [
        f"outcome {r.outcome} ({r.certificate}); peak_phi {r.peak_phi} at T = {r.peak_time}",
        "T phi psi",
    ]
    lines += [f"{a:.10g} {b:.10g} {c:.10g}" for a, b, c in zip(t.T, t.phi, t.psi, strict=True)]
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
    ba: float = BA,
    kappa: float = KAPPA,
    eps: float = EPS,
    vo: float = VO,
    perturbation: PerturbationKind = PERT,
    rtol: float = RTOL,
    as_json: bool = JSON,
) -> None:
    """Critical perturbation size: kind zero / finite (with value) / infinite, method and accuracy."""
    from rsfcore import ParameterError
    from rsfcore.critical import critical_perturbation

    try:
        r = critical_perturbation(_params(ba, kappa, eps, vo), perturbation.value, rtol=rtol)
    except ParameterError as e:
        _fail(e)
    d = r.to_dict()
    _emit(
        d,
        as_json,
        [
            f"kind          {d['kind']}",
            f"critical_size {d['critical_size']}",
            f"rel_accuracy  {d['rel_accuracy']:.2e}",
            f"method        {d['method']}",
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
    ba: float = BA,
    kappa: float = KAPPA,
    eps: float = EPS,
    vo: float = VO,
    perturbation: PerturbationKind = PERT,
    size: float | None = typer.Option(
        None, "--size", help="If given, also classify this perturbation size at every point."
    ),
    rtol: float = RTOL,
    out: Path = typer.Option(
        ...,
        "--out",
        help="Output file: .npz (arrays x, y, critical_size[i, j] at x[i], y[j]; inf = infinite), .csv or .json.",
    ),
    as_json: bool = JSON,
) -> None:
    """Stability diagram on a 2-D grid of two of kappa_ratio, eps, ba, size (other parameters as in `critical`)."""
    import numpy as np

    from rsfcore import ParameterError
    from rsfcore.diagram import stability_diagram

    try:
        for label, (_, _, _, n) in (("x", x), ("y", y)):
            if not 1 <= n <= 2000:
                raise ParameterError(label, n, "N in [1, 2000]")
        if out.suffix not in (".npz", ".csv", ".json"):
            raise ParameterError("out", str(out), "a path ending in .npz, .csv or .json")
        p = _params(ba, kappa, eps, vo)
        res = stability_diagram(
            x[0],
            np.linspace(x[1], x[2], x[3]),
            y[0],
            np.linspace(y[1], y[2], y[3]),
            ba=p.ba,
            kappa_ratio=p.kappa_ratio,
            eps=p.eps,
            vo=p.vo,
            perturbation=perturbation.value,
            size=size,
            rtol=rtol,
        )
    except ParameterError as e:
        _fail(e)
    res.save(out)
    cs = np.asarray(res.critical_size)
    summary = {
        "out": str(out),
        "shape": list(cs.shape),
        "n_finite": int(np.isfinite(cs).sum() - (cs == 0).sum()),
        "n_zero": int((cs == 0).sum()),
        "n_infinite": int(np.isinf(cs).sum()),
        "n_on_boundary": int(np.asarray(res.on_boundary).sum()),
        "max_rel_accuracy": float(np.max(np.asarray(res.rel_accuracy, dtype=float), initial=0.0)),
    }
    if getattr(res, "outcome", None) is not None:
        oc = np.asarray(res.outcome)
        summary["n_unstable"] = (
            int((oc == "unstable").sum()) if oc.dtype.kind in "US" else int(oc.sum())
        )
    _emit(summary, as_json, [f"{k} {v}" for k, v in summary.items()])


@app.command()
def stiffness(
    case: Case = typer.Option(..., "--case", help="Continuum configuration of `tab: table` (A-E)."),
    mode: int = typer.Option(0, "--mode", help="Eigenmode index (0 = smallest; B, D, E only)."),
    mu: float | None = typer.Option(None, "--mu", help="Shear modulus mu [Pa] (> 0)."),
    nu: float = typer.Option(0.25, "--nu", help="Poisson's ratio, [0, 0.5)."),
    slip_mode: str = typer.Option(
        "II", "--slip-mode", help="Mode of slip: II (in-plane) or III (anti-plane)."
    ),
    sigma: float | None = typer.Option(None, "--sigma", help="Normal stress [Pa] (> 0)."),
    a: float | None = typer.Option(None, "--a", help="Direct-effect coefficient a (> 0)."),
    b: float | None = typer.Option(None, "--b", help="Evolution-effect coefficient b (> a)."),
    dc: float | None = typer.Option(
        None, "--dc", help="Characteristic slip distance Dc [m] (> 0)."
    ),
    h: float | None = typer.Option(
        None, "--h", help="Depth of the interface below the free surface [m] (cases C, D)."
    ),
    as_json: bool = JSON,
) -> None:
    """Continuum equivalent stiffness k/k_* (cases A-E) and, with physical parameters, the critical dimension."""
    from rsfcore import ParameterError
    from rsfcore.stiffness import stiffness_summary

    phys = {
        k: v
        for k, v in dict(
            mu=mu, nu=nu, mode_of_slip=slip_mode, sigma=sigma, a=a, b=b, Dc=dc, h=h
        ).items()
        if v is not None
    }
    if mu is None or sigma is None or a is None or b is None or dc is None:
        phys = {}
    try:
        d = stiffness_summary(case.value, mode=mode, **phys)
    except (ParameterError, ValueError) as e:
        _fail(e)
    _emit(d, as_json, [f"{k} {v}" for k, v in d.items()])


@app.command()
def figure(
    name: str | None = typer.Argument(None, help="Figure name (see --list)."),
    out: Path | None = typer.Option(None, "--out", help="Output file, .png or .svg."),
    list_: bool = typer.Option(
        False, "--list", help="List the figures with the caption each reproduces."
    ),
) -> None:
    """Regenerate a figure of the paper from rsfcore (`rsf figure --list` names them)."""
    from rsfplots.cli import figure_command

    code = figure_command(name, out, list_)
    if code:
        raise typer.Exit(code=code)


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
from .sweep import app as _sweep_app  # noqa: E402  (rsf sweep submit|status|download)

app.add_typer(_sweep_app, name="sweep")
from .db import app as _db_app  # noqa: E402  (rsf db upgrade|current|history|revision)

app.add_typer(_db_app, name="db")


def main() -> None:
    """Console entry point."""
    app()


if __name__ == "__main__":  # pragma: no cover
    main()
