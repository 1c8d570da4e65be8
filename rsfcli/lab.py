"""`rsf si ...`, `rsf protocol ...` and `rsf fit FILE`: the lab's units on the command line.

Every command validates its input through the same request models as the HTTP API
(:mod:`rsfapp.requests`) and computes through the same adapter (:mod:`rsfapp.adapter`),
so ``rsf si critical ... --json`` prints exactly what POST /v1/critical answers (without
``cached``/``cache_key``).  Invalid input exits with status 2 and a message naming the
field and its valid range.

SI machine options (all commands of ``si`` and ``protocol``), spelled as the JSON fields:
--a, --b, --Dc_m, --sigma_Pa, --k_Pa_per_m, --V_star_m_s, --V_load_m_s (default V_*;
``si`` only), --eps, and --f_star (``protocol``); ``si`` also --perturbation and (classify,
trajectory) the size as --size, --factor, --new_slip_rate_m_s or
--new_load_point_velocity_m_s.  The older kebab-case names (--dc-m, --sigma-pa, ...) are
accepted too.  An option not given is left out of the request: its default is the request
model's (rsfcli.common), the same as over HTTP.  They are declared once
(:func:`_machine_command` puts them first in each command's signature, in this order)
and reach the command as one :class:`Machine`.
"""

from __future__ import annotations

import csv
import inspect
import io
import json
import typing
from collections.abc import Callable
from dataclasses import dataclass, field
from enum import Enum
from pathlib import Path
from typing import Any

import typer

from rsfapp.requests import ClassifyRequest, PhysicalSI, TrajectoryRequest
from rsfapp.requests.fits import FitRequest, PosteriorOptions
from rsfapp.requests.protocols import (
    LoadHistoryRequest,
    SlideHoldSlideRequest,
    VelocityStepRequest,
)

from .common import echo_lines, emit, fail, given, json_value, model_default, model_option, run

__all__ = ["si_app", "protocol_app", "fit_app", "fit_command"]

si_app = typer.Typer(
    rich_markup_mode=None,  # help texts carry units in brackets ([m], [s]), not markup
    name="si",
    no_args_is_help=True,
    help="Queries in SI units: the "
    "machine as a, b, Dc [m], sigma [Pa], k [Pa/m], V_* and V_load [m/s]; "
    "answers also in s, m/s and Pa.",
)
protocol_app = typer.Typer(
    rich_markup_mode=None,  # help texts carry units in brackets ([m], [s]), not markup
    name="protocol",
    no_args_is_help=True,
    help="Lab protocols in SI "
    "units: velocity step, slide-hold-slide, any load history (true "
    "peaks, steady-state and peak friction changes; JSON, CSV, PNG).",
)


class Pert(str, Enum):  # noqa: UP042 (typer choices)
    velocity_jump = "velocity-jump"
    load_point_jump = "load-point-jump"


class Sampling(str, Enum):  # noqa: UP042
    tau = "tau"
    T = "T"
    seconds = "seconds"


class FitLaw(str, Enum):  # noqa: UP042
    aging = "aging"
    slip = "slip"
    nagata = "nagata"
    eps = "eps"


# Options carrying a request field are spelled exactly as the field's JSON name (the
# older kebab-case spelling is accepted too); not given = the request model's default.
A = model_option(PhysicalSI, "a", required=True)
B = model_option(PhysicalSI, "b", required=True)
DC = model_option(PhysicalSI, "Dc_m", "--dc-m", required=True)
SIGMA = model_option(PhysicalSI, "sigma_Pa", "--sigma-pa", required=True)
K = model_option(PhysicalSI, "k_Pa_per_m", "--k-pa-per-m", required=True)
VSTAR = model_option(PhysicalSI, "V_star_m_s", "--v-star-m-s", required=True)
VLOAD = model_option(PhysicalSI, "V_load_m_s", "--v-load-m-s")
EPS = model_option(ClassifyRequest, "eps")
RTOL = model_option(ClassifyRequest, "rtol")
JSON_OUT = typer.Option(False, "--json", help="Print one JSON object.")
OUT = typer.Option(
    None, "--out", help="Also write the result: .json, .csv (the samples) or .png (plot)."
)


_fail = fail
_run = run
_emit = emit


def _csv(columns: dict[str, list[Any]]) -> str:
    keys = list(columns)
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(keys)
    for row in zip(*(columns[k] for k in keys), strict=True):
        w.writerow(["" if v is None else repr(v) if isinstance(v, float) else v for v in row])
    return buf.getvalue()


def _write(
    out: Path | None,
    result: dict[str, Any],
    table: Callable[[dict[str, Any]], dict[str, list[Any]]],
    plot: Callable[[dict[str, Any]], bytes],
) -> None:
    if out is None:
        return
    if out.suffix == ".json":
        out.write_text(json.dumps(result, allow_nan=False))
    elif out.suffix == ".csv":
        out.write_text(_csv(table(result)))
    elif out.suffix == ".png":
        out.write_bytes(plot(result))
    else:
        _fail(f"out: {str(out)!r} is invalid (valid range: a path ending in .json, .csv or .png)")


def _g(x: Any) -> str:
    return "-" if x is None else (f"{x:.6g}" if isinstance(x, float) else str(x))


SIZE = model_option(ClassifyRequest, "size")
FACTOR = model_option(ClassifyRequest, "factor")
NEWV = model_option(ClassifyRequest, "new_slip_rate_m_s", "--new-slip-rate-m-s")
NEWVLP = model_option(
    ClassifyRequest, "new_load_point_velocity_m_s", "--new-load-point-velocity-m-s"
)
PERT = model_option(ClassifyRequest, "perturbation")
FSTAR = model_option(VelocityStepRequest, "f_star", "--f-star")
NPPS = model_option(SlideHoldSlideRequest, "n_points_per_segment", "--n-points-per-segment")


@dataclass(frozen=True)
class Machine:
    """The shared options of a ``si`` / ``protocol`` command.

    Attributes:
        physical: the SI machine {a, b, Dc_m, sigma_Pa, k_Pa_per_m, V_star_m_s[,
            V_load_m_s]} (the request models' names).
        eps: evolution-law parameter (-); f_star: reference friction (protocols).
        perturbation: kind (``si``), None for protocols.
        size: the size options given ({size | factor | new_slip_rate_m_s |
            new_load_point_velocity_m_s: value}).
    """

    physical: dict[str, Any]
    eps: float | None = None
    f_star: float | None = None
    perturbation: Pert | None = None
    size: dict[str, float] = field(default_factory=dict)

    def si_body(self, rtol: float | None) -> dict[str, Any]:
        """Body of an SI query (ClassifyRequest, CriticalRequest, TrajectoryRequest): the
        options given (the others take the request model's defaults)."""
        return {
            "physical": self.physical,
            **given(eps=self.eps, rtol=rtol, perturbation=self.perturbation),
            **self.size,
        }

    def protocol_body(self, rtol: float | None) -> dict[str, Any]:
        """Common part of a protocol body (velocity step, slide-hold-slide, load history)."""
        return {"physical": self.physical, **given(eps=self.eps, f_star=self.f_star, rtol=rtol)}


_KW = inspect.Parameter.KEYWORD_ONLY
#: The size options of ``si classify`` / ``si trajectory``: (parameter, request field, option).
_SIZE_OPTIONS: tuple[tuple[str, str, Any], ...] = (
    ("size", "size", SIZE),
    ("factor", "factor", FACTOR),
    ("new_slip_rate_m_s", "new_slip_rate_m_s", NEWV),
    ("new_load_point_velocity_m_s", "new_load_point_velocity_m_s", NEWVLP),
)
#: The machine options: (parameter, request field, option, annotation).
_MACHINE_OPTIONS: tuple[tuple[str, str, Any, Any], ...] = (
    ("a", "a", A, float),
    ("b", "b", B, float),
    ("dc_m", "Dc_m", DC, float),
    ("sigma_pa", "sigma_Pa", SIGMA, float),
    ("k_pa_per_m", "k_Pa_per_m", K, float),
    ("v_star_m_s", "V_star_m_s", VSTAR, float),
)


def _shared_params(*, v_load: bool, f_star: bool, perturbation: str) -> list[inspect.Parameter]:
    """The shared options, in the order the commands list them."""
    ps = [inspect.Parameter(n, _KW, default=o, annotation=t) for n, _, o, t in _MACHINE_OPTIONS]
    if v_load:
        ps.append(inspect.Parameter("v_load_m_s", _KW, default=VLOAD, annotation=float | None))
    ps.append(inspect.Parameter("eps", _KW, default=EPS, annotation=float | None))
    if f_star:
        ps.append(inspect.Parameter("f_star", _KW, default=FSTAR, annotation=float | None))
    if perturbation != "none":
        ps.append(inspect.Parameter("perturbation", _KW, default=PERT, annotation=Pert | None))
    if perturbation == "sized":
        ps += [
            inspect.Parameter(n, _KW, default=o, annotation=float | None)
            for n, _, o in _SIZE_OPTIONS
        ]
    return ps


def _machine_command(
    app: typer.Typer,
    name: str,
    *,
    v_load: bool = False,
    f_star: bool = False,
    perturbation: str = "none",
) -> Callable[[Callable[..., None]], Callable[..., None]]:
    """Register ``fn(machine: Machine, **own options)`` as command ``name`` of ``app``,
    with the shared options (machine; ``v_load``: --v-load-m-s; --eps; ``f_star``:
    --f-star; ``perturbation`` "kind": --perturbation, "sized": also the size options)
    listed first, then ``fn``'s own options."""

    def register(fn: Callable[..., None]) -> Callable[..., None]:
        shared = _shared_params(v_load=v_load, f_star=f_star, perturbation=perturbation)
        own = [p.replace(kind=_KW) for p in inspect.signature(fn).parameters.values()][
            1:
        ]  # without ``machine``
        own_hints = typing.get_type_hints(fn)

        def command(**kw: Any) -> None:
            physical = {f: kw.pop(n) for n, f, _, _ in _MACHINE_OPTIONS}
            vl = kw.pop("v_load_m_s", None)
            if vl is not None:
                physical["V_load_m_s"] = vl
            sizes = {f: kw.pop(n) for n, f, _ in _SIZE_OPTIONS if n in kw}
            machine = Machine(
                physical=physical,
                eps=kw.pop("eps"),
                f_star=kw.pop("f_star", None),
                perturbation=kw.pop("perturbation", None),
                size={f: v for f, v in sizes.items() if v is not None},
            )
            fn(machine, **kw)

        params = [*shared, *own]
        command.__signature__ = inspect.Signature(params)  # type: ignore[attr-defined]
        command.__annotations__ = {
            p.name: (own_hints[p.name] if p in own else p.annotation) for p in params
        }
        command.__name__ = fn.__name__
        command.__qualname__ = fn.__qualname__
        command.__doc__ = fn.__doc__
        app.command(name)(command)
        return fn

    return register


@_machine_command(si_app, "classify", v_load=True, perturbation="sized")
def si_classify(machine: Machine, rtol: float | None = RTOL, as_json: bool = JSON_OUT) -> None:
    """Stable or unstable, for a perturbation stated in SI; times in s, peak in m/s."""
    from rsfapp import adapter
    from rsfapp.requests import ClassifyRequest

    body = machine.si_body(rtol)
    d = _run(ClassifyRequest, body, lambda r: adapter.classify(r, max_steps=None))
    si = d["si"]
    _emit(
        d,
        as_json,
        [
            f"outcome            {d['outcome']}  (certificate: {d['certificate']})",
            f"kappa/kappa_crit   {_g(si['kappa'] / si['kappa_crit'])}",
            f"blowup_time_s      {_g(si['blowup_time_s'])}",
            f"return_time_s      {_g(si['return_time_s'])}",
            f"peak_slip_rate_m_s {_g(si['peak_slip_rate_m_s'])}  at t = {_g(si['peak_time_s'])} s",
            f"rel_accuracy       {d['rel_accuracy']:.2e}",
            *echo_lines(d),
        ],
    )


@_machine_command(si_app, "critical", v_load=True, perturbation="kind")
def si_critical(machine: Machine, rtol: float | None = RTOL, as_json: bool = JSON_OUT) -> None:
    """Critical perturbation in SI: the slip rate [m/s] (and stress jump [Pa]) of the
    critical velocity jump, or the critical load-point velocity [m/s]."""
    from rsfapp import adapter
    from rsfapp.requests import CriticalRequest

    d = _run(CriticalRequest, machine.si_body(rtol), adapter.critical)
    si = d["si"]
    jump = si.get("velocity_jump") or si.get("load_point_jump") or {}
    lines = [
        f"kind              {d['kind']}",
        f"critical_size     {_g(d['critical_size'])}",
        f"kappa/kappa_crit  {_g(si['kappa'] / si['kappa_crit'])}",
    ]
    lines += [f"{k:<17} {_g(v)}" for k, v in jump.items()]
    lines.append(f"rel_accuracy      {d['rel_accuracy']:.2e}")
    lines += echo_lines(d)
    _emit(d, as_json, lines)


@_machine_command(si_app, "trajectory", v_load=True, f_star=True, perturbation="sized")
def si_trajectory(
    machine: Machine,
    rtol: float | None = RTOL,
    n_points: int | None = model_option(TrajectoryRequest, "n_points", "--n-points"),
    sampling: Sampling | None = model_option(TrajectoryRequest, "sampling"),
    t_end_s: float | None = model_option(TrajectoryRequest, "t_end_s", "--t-end-s"),
    out: Path | None = OUT,
    as_json: bool = JSON_OUT,
) -> None:
    """A trajectory with SI columns (t_s, V_m_s, tau_change_Pa, friction, ...)."""
    from rsfapp import adapter
    from rsfapp.requests import TrajectoryRequest

    body = machine.si_body(rtol)
    body.update(given(n_points=n_points, sampling=sampling, t_end_s=t_end_s, f_star=machine.f_star))
    d = _run(TrajectoryRequest, body, lambda r: adapter.trajectory(r, max_steps=None))

    def plot(r: dict[str, Any]) -> bytes:
        from rsfplots import plot_trajectory

        return bytes(plot_trajectory(r, "png"))

    _write(out, d, lambda r: r["trajectory"], plot)
    tr = d["trajectory"]
    lines = [
        f"outcome {d['outcome']}; sampling: {d['sampling']['description']}",
        *echo_lines(d),
        "t_s V_m_s tau_change_Pa",
    ]
    lines += [
        f"{t:.10g} {_g(v)} {_g(s)}"
        for t, v, s in zip(tr["t_s"], tr["V_m_s"], tr["tau_change_Pa"], strict=True)
    ]
    _emit(d, as_json, lines)


# --------------------------------------------------------------------------- rsf protocol
def _protocol_out(d: dict[str, Any], out: Path | None, as_json: bool) -> None:
    from rsfapp import adapter

    def plot(r: dict[str, Any]) -> bytes:
        from rsfplots.lab import plot_protocol

        return plot_protocol(r, "png")

    _write(out, d, adapter.protocol_table, plot)
    fc = d.get("friction_changes", {})
    prot = d.get("protocol", d)
    lines = [f"{d['kind']}: {'UNSTABLE (runaway)' if prot.get('unstable') else 'stable'}"]
    lines += echo_lines(prot)
    lines += [f"{k:<28} {_g(v)}" for k, v in fc.items() if k != "segments"]
    for s in fc.get("segments", []):
        lines.append(
            f"segment {s['index']}: V_load {_g(s['V_load_m_s'])} m/s, df_ss "
            f"{_g(s['steady_state_delta_f'])}, peak f {_g(s['peak_friction'])} "
            f"(df_peak {_g(s['peak_delta_f'])}) at t = {_g(s['peak_time_s'])} s"
        )
    _emit(d, as_json, lines)


@_machine_command(protocol_app, "velocity-step", f_star=True)
def protocol_velocity_step(
    machine: Machine,
    v1: float = model_option(VelocityStepRequest, "V1_m_s", "--v1-m-s", required=True),
    v2: float = model_option(VelocityStepRequest, "V2_m_s", "--v2-m-s", required=True),
    slip_total_m: float | None = model_option(
        VelocityStepRequest, "slip_total_m", "--slip-total-m"
    ),
    slip_after_m: float | None = model_option(
        VelocityStepRequest, "slip_after_m", "--slip-after-m"
    ),
    n_points: int | None = model_option(VelocityStepRequest, "n_points", "--n-points"),
    rtol: float | None = RTOL,
    out: Path | None = OUT,
    as_json: bool = JSON_OUT,
) -> None:
    """Load-point velocity step V1 -> V2 from steady state: true peak, steady-state and
    peak friction changes (also in Pa), deviation from `eq: delta tau`."""
    from rsfapp import adapter
    from rsfapp.requests.protocols import VelocityStepRequest

    body = machine.protocol_body(rtol)
    body.update(
        V1_m_s=v1,
        V2_m_s=v2,
        **given(n_points=n_points, slip_total_m=slip_total_m, slip_after_m=slip_after_m),
    )
    _protocol_out(_run(VelocityStepRequest, body, adapter.protocol_velocity_step), out, as_json)


@_machine_command(protocol_app, "slide-hold-slide", f_star=True)
def protocol_shs(
    machine: Machine,
    v: float = model_option(SlideHoldSlideRequest, "V_m_s", "--v-m-s", required=True),
    hold_s: float = model_option(SlideHoldSlideRequest, "hold_s", "--hold-s", required=True),
    before_s: float = model_option(
        SlideHoldSlideRequest, "slide_before_s", "--slide-before-s", required=True
    ),
    after_s: float = model_option(
        SlideHoldSlideRequest, "slide_after_s", "--slide-after-s", required=True
    ),
    n_points: int | None = NPPS,
    rtol: float | None = RTOL,
    out: Path | None = OUT,
    as_json: bool = JSON_OUT,
) -> None:
    """Slide, hold, reslide: healing (true peak on reslide minus f_ss) and relaxation."""
    from rsfapp import adapter
    from rsfapp.requests.protocols import SlideHoldSlideRequest

    body = machine.protocol_body(rtol)
    body.update(
        V_m_s=v,
        hold_s=hold_s,
        **given(slide_before_s=before_s, slide_after_s=after_s, n_points_per_segment=n_points),
    )
    _protocol_out(
        _run(SlideHoldSlideRequest, body, adapter.protocol_slide_hold_slide), out, as_json
    )


@_machine_command(protocol_app, "load-history", f_star=True)
def protocol_history(
    machine: Machine,
    segments: str | None = model_option(
        LoadHistoryRequest,
        "segments",
        help='The segments as JSON, e.g. \'[{"duration_s": 10, "V_load_m_s": 1e-6}]\' '
        "(V 0 = hold); or --segment.",
    ),
    segment: list[str] | None = typer.Option(
        None, "--segment", help="DURATION_S:V_LOAD_M_S, repeated in order (V 0 = hold)."
    ),
    start_state: str | None = model_option(
        LoadHistoryRequest,
        "start_state",
        help="'steady' (the default) or an explicit state as JSON, e.g. "
        '\'{"V_m_s": 2e-6, "theta_s": 10}\'.',
    ),
    n_points: int | None = NPPS,
    rtol: float | None = RTOL,
    out: Path | None = OUT,
    as_json: bool = JSON_OUT,
) -> None:
    """Any piecewise-constant load-point history (e.g. several velocity steps)."""
    from rsfapp import adapter

    if (segments is None) == (segment is None):
        _fail("segments: give either --segments (JSON) or --segment (repeated), exactly one")
    segs: Any = [] if segments is None else json_value("segments", segments)
    for i, s in enumerate(segment or []):
        try:
            d_s, v_s = s.split(":")
            segs.append({"duration_s": float(d_s), "V_load_m_s": float(v_s)})
        except ValueError:
            _fail(
                f"segment[{i}]: {s!r} is invalid (valid range: DURATION_S:V_LOAD_M_S, e.g. 10:1e-6)"
            )
    body = machine.protocol_body(rtol)
    state: Any = start_state
    if start_state is not None and start_state.strip() != "steady":
        state = json_value("start_state", start_state)
    body.update(segments=segs, **given(n_points_per_segment=n_points, start_state=state))
    _protocol_out(_run(LoadHistoryRequest, body, adapter.protocol_load_history), out, as_json)


# --------------------------------------------------------------------------- rsf fit
def _pair(text: str, what: str, i: int) -> tuple[float, float]:
    """A window ``T_START_S:T_END_S`` or, as the JSON field, ``[T_START_S, T_END_S]``."""
    try:
        if text.lstrip().startswith("["):
            a, b = json.loads(text)
        else:
            a, b = text.split(":")
        return float(a), float(b)
    except (ValueError, TypeError):
        _fail(
            f"{what}[{i}]: {text!r} is invalid (valid range: T_START_S:T_END_S or "
            "[T_START_S, T_END_S], e.g. 30:90)"
        )
    raise AssertionError("unreachable")


def fit_command(
    file: Path = typer.Argument(
        ...,
        help="Lab record: CSV with header t_s (or x_lp_m), v_lp_m_s, mu, any other headers "
        "with --column, a units row, or the protocol output as written; or JSON columns.",
    ),
    law: FitLaw | None = typer.Option(
        None,
        "--law",
        help="Evolution law of the reported fit (default: the best of the comparison).",
    ),
    k_pa_per_m: float | None = model_option(FitRequest, "k_Pa_per_m", "--k-pa-per-m"),
    sigma_pa: float | None = model_option(FitRequest, "sigma_Pa", "--sigma-pa"),
    k_friction_per_m: float | None = model_option(
        FitRequest, "k_friction_per_m", "--k-friction-per-m", "--stiffness"
    ),
    fit_stiffness: bool | None = typer.Option(
        None,
        "--fit_stiffness/--no-fit_stiffness",
        "--fit-stiffness/--fixed-stiffness",
        help="Fit the stiffness (a given one is the start) or keep it fixed.  Default: "
        "fitted unless a stiffness is given.",
    ),
    rigid: bool = typer.Option(
        False,
        "--rigid_machine",
        "--rigid",
        help="Assume an infinitely stiff machine (V follows the load point).",
    ),
    trend: bool = typer.Option(
        False,
        "--trend/--no-trend",
        help="Fit a linear friction trend in load-point displacement [1/m].",
    ),
    window: list[str] | None = typer.Option(
        None,
        "--windows",
        "--window",
        help="T_START_S:T_END_S (or [T_START_S, T_END_S]), repeated: only these times enter "
        "the misfit.",
    ),
    step: list[int] | None = typer.Option(
        None,
        "--steps",
        "--step",
        help="Segment index, repeated (0 = before the first step): only these enter the misfit.",
    ),
    column: list[str] | None = typer.Option(
        None,
        "--column",
        help="QUANTITY=HEADER[:UNIT], repeated (t, x_lp, v_lp, mu, tau, sigma_n), e.g. "
        "'v_lp=LP Velocity:um/s'.",
    ),
    columns: str | None = model_option(
        FitRequest,
        "columns",
        help='The column map as JSON, e.g. \'{"t": "t_s", "mu": "mu"}\' (or --column).',
    ),
    nagata_c: float | None = model_option(FitRequest, "nagata_c"),
    rtol: float | None = model_option(FitRequest, "rtol"),
    seed: int | None = model_option(FitRequest, "seed"),
    decimal: str | None = model_option(FitRequest, "decimal"),
    smooth: int | None = model_option(FitRequest, "smooth"),
    time_budget_s: float | None = model_option(FitRequest, "time_budget_s", "--time-budget-s"),
    compare: bool | None = typer.Option(
        None,
        "--compare/--no-compare",
        help="Fit every law and compare them (AIC/BIC). Default: "
        f"{model_default(FitRequest, 'compare')}.",
    ),
    samples: int | None = model_option(FitRequest, "uncertainty_samples", "--uncertainty-samples"),
    series: bool = typer.Option(
        False, "--series", help="Include the data/model/residual series in --json output."
    ),
    posterior_steps: int | None = typer.Option(
        None,
        "--posterior-steps",
        help="Also sample the posterior with emcee: posterior.n_steps, steps per walker "
        f"[10, 100000] (posterior.n_walkers {model_default(PosteriorOptions, 'n_walkers')} "
        f"walkers, thin {model_default(PosteriorOptions, 'thin')}).",
    ),
    posterior_burn: int | None = typer.Option(
        None,
        "--posterior-burn",
        help="posterior.burn: steps discarded, < --posterior-steps. Default: "
        f"{model_default(PosteriorOptions, 'burn')}.",
    ),
    out: Path | None = typer.Option(
        None,
        "--out",
        help="Also write .json (all), .csv (series) or .png (data, fit, per-step residuals).",
    ),
    as_json: bool = JSON_OUT,
) -> None:
    """Fit mu0, a, b, Dc (and eps, machine stiffness, trend) to a lab record; compare the
    laws; say how close sample and machine are to instability (SI, with uncertainty).
    With no stiffness given it is fitted (docs/fitting.md); a status other than 'ok'
    (suspect, rejected, ill_conditioned, ...) says why in the message."""
    from rsfapp import adapter
    from rsfapp.requests.fits import FitRequest

    if not file.is_file():
        _fail(f"file: {str(file)!r} is not a readable file")
    body: dict[str, Any] = {"record": file.read_text(encoding="utf-8-sig")}
    opt: dict[str, Any] = {
        "uncertainty_samples": samples,
        "time_budget_s": time_budget_s,
        "decimal": decimal,
        "law": None if law is None else law.value,
        "k_Pa_per_m": k_pa_per_m,
        "sigma_Pa": sigma_pa,
        "k_friction_per_m": k_friction_per_m,
        "fit_stiffness": fit_stiffness,
        "smooth": smooth,
        "nagata_c": nagata_c,
        "rtol": rtol,
        "seed": seed,
        "compare": compare,
        "columns": json_value("columns", columns),
        "steps": step or None,
        "windows": [_pair(w, "window", i) for i, w in enumerate(window or [])] or None,
    }
    body.update({k: v for k, v in opt.items() if v is not None})
    if rigid:
        body["rigid_machine"] = True
    if trend:
        body["trend"] = True
    if column and columns is not None:
        _fail("columns: give either --columns (JSON) or --column (repeated), not both")
    if column:
        try:
            from rsfcore.fit import parse_column_map

            body["columns"] = parse_column_map(column)
        except ValueError as exc:
            _fail(str(exc))
    if posterior_steps is not None or posterior_burn is not None:
        body["posterior"] = given(n_steps=posterior_steps, burn=posterior_burn)
    d = _run(FitRequest, body, adapter.fit)

    def plot(r: dict[str, Any]) -> bytes:
        from rsfplots.lab import plot_fit

        return plot_fit(r, "png")

    _write(out, d, adapter.fit_table, plot)
    shown = d if series else {k: v for k, v in d.items() if k != "series"}
    p, se = d["params"], d["stderr"]
    lines = [f"law {d['law']}: {d['status']} - {d['message']}"]
    for w in d.get("warnings") or []:
        if w not in d["message"]:
            lines.append(f"  note: {w}")
    for k in ("mu0", "a", "b", "Dc_m", "eps", "k_per_m", "k_Pa_per_m", "trend_per_m"):
        if k in p and not (k == "trend_per_m" and k not in d["fitted"]):
            err = se.get(k)
            lines.append(
                f"  {k:<11} {_g(p[k])}"
                + (
                    f" +- {_g(err)}"
                    if err is not None
                    else " (fixed)"
                    if k not in d["fitted"] and k != "k_Pa_per_m"
                    else ""
                )
            )
    lines.append(
        f"  stiffness {d.get('stiffness_mode')}; rms misfit {_g(d['misfit']['rms'])} over "
        f"{d['misfit']['n']} samples, AIC {_g(d['misfit']['aic'])}"
    )
    steps = d.get("steps") or []
    if len(steps) > 1:
        lines.append("  per step: " + ", ".join(f"#{s['index']} rms {_g(s['rms'])}" for s in steps))
    comp = d.get("law_comparison")
    if comp:
        lines.append(f"law comparison (best: {comp['best']}):")
        lines += [
            f"  {s['law']:<7} rms {_g(s['rms'])}  dAIC {_g(s['delta_aic'])}  weight "
            f"{_g(s['akaike_weight'])}  ({s['status']})"
            for s in comp["scores"]
        ]
    st = d.get("stability")
    if st:
        kc_pa = st.get("critical_stiffness_Pa_per_m")
        lines.append(
            f"stability: {st.get('regime')}; kappa/kappa_crit {_g(st.get('kappa_ratio'))}"
            f"; critical stiffness {_g(st.get('critical_stiffness_per_m'))} 1/m"
            + (f" = {_g(kc_pa)} Pa/m" if kc_pa is not None else "")
        )
        if st.get("message"):
            lines.append(f"  {st['message']}")
    _emit(shown, as_json, lines)


#: `rsf fit` on its own (mounted on `rsf` by rsfcli.main when asked for).
fit_app = typer.Typer(rich_markup_mode=None, add_completion=False)
fit_app.command("fit")(fit_command)
