"""One source of truth for every parameter's valid range and default (rsfcore.limits):
the HTTP request models, the CLI and rsfcore itself must agree with it."""

from __future__ import annotations

import math
from typing import Any

import pytest
import typer

from rsfapp import requests
from rsfapp.requests.single import si_range_text
from rsfcli.main import app as cli
from rsfcore import Params, limits
from rsfcore.errors import ParameterError

# (request model, field, limit) for the dimensionless parameters and numerics.
HTTP_FIELDS = [
    (m, f, lim)
    for m in (requests.ClassifyRequest, requests.CriticalRequest, requests.TrajectoryRequest)
    for f, lim in (
        ("ba", limits.BA),
        ("kappa", limits.KAPPA),
        ("eps", limits.EPS),
        ("vo", limits.VO),
        ("rtol", limits.RTOL),
    )
] + [
    (requests.TrajectoryRequest, "n_points", limits.N_POINTS),
    (requests.TrajectoryRequest, "t_end", limits.T_END),
]


def _schema_bounds(prop: dict[str, Any]) -> tuple[float | None, bool, float | None, bool]:
    if "anyOf" in prop:  # Optional[...]: the numeric branch carries the bounds
        prop = next(p for p in prop["anyOf"] if p.get("type") in ("number", "integer"))
    lo = prop.get("exclusiveMinimum", prop.get("minimum"))
    hi = prop.get("exclusiveMaximum", prop.get("maximum"))
    return lo, "exclusiveMinimum" in prop, hi, "exclusiveMaximum" in prop


@pytest.mark.parametrize(
    ("model", "field", "limit"), HTTP_FIELDS, ids=[f"{m.__name__}.{f}" for m, f, _ in HTTP_FIELDS]
)
def test_http_schema_matches_limits(model: Any, field: str, limit: limits.Limit) -> None:
    prop = model.model_json_schema()["properties"][field]
    assert _schema_bounds(prop) == (limit.lo, limit.lo_open, limit.hi, limit.hi_open)
    assert model.model_fields[field].default == limit.default
    assert limit.text in prop["description"]


def _cli_params(command: str) -> dict[str, Any]:
    group: Any = typer.main.get_command(cli)  # typer's own (vendored) click Group
    cmd = group.commands[command]
    return {p.name: p for p in cmd.params if p.name}


@pytest.mark.parametrize("command", ["classify", "critical", "trajectory"])
def test_cli_defaults_and_help_match_limits(command: str) -> None:
    params = _cli_params(command)
    for name, limit in (
        ("ba", limits.BA),
        ("kappa", limits.KAPPA),
        ("eps", limits.EPS),
        ("vo", limits.VO),
        ("rtol", limits.RTOL),
    ):
        p = params[name]
        # not given = left out of the request: the request model's default applies
        # (equal to the limit's, test_http_schema_matches_limits), stated in the help
        assert p.default is None, (command, name)
        assert limit.text in (p.help or ""), (command, name)
        assert f"Default: {limit.default}." in (p.help or ""), (command, name)


@pytest.mark.parametrize(
    ("field", "limit"),
    [("ba", limits.BA), ("kappa", limits.KAPPA), ("eps", limits.EPS), ("vo", limits.VO)],
)
def test_rsfcore_accepts_exactly_the_range(field: str, limit: limits.Limit) -> None:
    """The ends behave as the range text says, and one step outside is refused naming
    the field (kappa is checked at b/a = 1e6 so that kappa = 1e6 is a valid pair)."""
    base = {"ba": 2.0, "kappa": 1.0, "eps": 0.5, "vo": 1.0}
    for end, is_open, outward in (
        (limit.lo, limit.lo_open, -math.inf),
        (limit.hi, limit.hi_open, math.inf),
    ):
        if end is None:
            continue
        vals = {**base, field: end}
        if is_open:
            with pytest.raises(ParameterError) as e:
                Params(**vals)
            assert e.value.field == field
        else:
            Params(**vals)
        outside = math.nextafter(end, outward)
        with pytest.raises(ParameterError) as e:
            Params(**{**base, field: outside})
        assert e.value.field == field and e.value.valid == limit.text


# (request model, field, limit) of the SI machine: PhysicalSI (the names lab scripts rely
# on) and the legacy trajectory scales; both read their ranges from rsfcore.limits.
SI_FIELDS = [
    (requests.PhysicalSI, "a", limits.SI_A),
    (requests.PhysicalSI, "b", limits.SI_B),
    (requests.PhysicalSI, "Dc_m", limits.SI_DC_M),
    (requests.PhysicalSI, "sigma_Pa", limits.SI_SIGMA_PA),
    (requests.PhysicalSI, "k_Pa_per_m", limits.SI_K_PA_PER_M),
    (requests.PhysicalSI, "V_star_m_s", limits.SI_V_STAR_M_S),
    (requests.PhysicalSI, "V_load_m_s", limits.SI_V_LOAD_M_S),
    (requests.PhysicalScales, "a", limits.SI_A),
    (requests.PhysicalScales, "Dc", limits.SI_DC_M),
    (requests.PhysicalScales, "sigma", limits.SI_SIGMA_PA),
    (requests.PhysicalScales, "V_star", limits.SI_V_STAR_M_S),
]


@pytest.mark.parametrize(
    ("model", "field", "limit"), SI_FIELDS, ids=[f"{m.__name__}.{f}" for m, f, _ in SI_FIELDS]
)
def test_si_schema_matches_limits(model: Any, field: str, limit: limits.Limit) -> None:
    """The JSON-schema bounds of every SI field are the rsfcore.limits range; its text
    (with the unit) is in the description, except b and k whose text states the rule
    relative to a (and sigma, Dc)."""
    prop = model.model_json_schema()["properties"][field]
    assert _schema_bounds(prop) == (limit.lo, limit.lo_open, limit.hi, limit.hi_open)
    if field not in ("b", "k_Pa_per_m"):
        unit = "" if limit.unit == "-" else f" {limit.unit}"
        text = si_range_text(limit)
        assert f"{text}{unit}" in prop["description"], prop["description"]
    # the model refuses one step beyond each closed end and each open end, naming the field
    base = {"a": 0.01, "b": 0.015, "Dc_m": 1e-5, "sigma_Pa": 1e7, "k_Pa_per_m": 1e9}
    base |= {"V_star_m_s": 1e-6, "Dc": 1e-5, "sigma": 1e7, "V_star": 1e-6}
    keys = set(model.model_fields)
    ok = {k: v for k, v in base.items() if k in keys}
    model.model_validate(ok)
    for end, is_open, outward in (
        (limit.lo, limit.lo_open, -math.inf),
        (limit.hi, limit.hi_open, math.inf),
    ):
        assert end is not None  # every SI range is bounded on both sides
        bad = end if is_open else math.nextafter(end, outward)
        with pytest.raises(Exception) as e:  # pydantic.ValidationError
            model.model_validate({**ok, field: bad})
        assert e.value.errors()[0]["loc"] == (field,)  # type: ignore[attr-defined]


def test_si_ranges_are_the_ones_lab_values_need() -> None:
    """Written out here (not read from rsfcore.limits): the documented SI gate."""
    assert (limits.SI_DC_M.lo, limits.SI_DC_M.hi, limits.SI_DC_M.unit) == (0.0, 1e3, "m")
    assert si_range_text(limits.SI_DC_M) == "(0, 1e3]"
    assert si_range_text(limits.SI_SIGMA_PA) == "(0, 1e12]" and limits.SI_SIGMA_PA.unit == "Pa"
    assert si_range_text(limits.SI_V_STAR_M_S) == "(0, 1e3]"
    assert si_range_text(limits.SI_V_LOAD_M_S) == "[0, 1e3]" and limits.SI_A.text == "(0, 1]"
    assert si_range_text(limits.SI_K_PA_PER_M) == "[0, 1e30]"
    assert si_range_text(limits.EPS) == "[0, 1]" and si_range_text(limits.VO) == "[0, 1e300]"


def _lab_params(group: str, command: str) -> list[Any]:
    top: Any = typer.main.get_command(cli)
    return [p for p in top.commands[group].commands[command].params if p.name]


#: The SI machine options of `rsf si` / `rsf protocol` (declared once in rsfcli.lab) and
#: the rsfcore.limits range their help states.
CLI_SI = [
    ("a", limits.SI_A),
    ("dc_m", limits.SI_DC_M),
    ("sigma_pa", limits.SI_SIGMA_PA),
    ("v_star_m_s", limits.SI_V_STAR_M_S),
    ("v_load_m_s", limits.SI_V_LOAD_M_S),
    ("eps", limits.EPS),
    ("rtol", limits.RTOL),
]
LAB_COMMANDS = [
    ("si", "classify"),
    ("si", "critical"),
    ("si", "trajectory"),
    ("protocol", "velocity-step"),
    ("protocol", "slide-hold-slide"),
    ("protocol", "load-history"),
]


@pytest.mark.parametrize(("group", "command"), LAB_COMMANDS)
def test_cli_si_options_agree_with_limits(group: str, command: str) -> None:
    """Every SI command lists the shared machine options first, in one order, and their
    help states the rsfcore.limits ranges."""
    params = _lab_params(group, command)
    names = [p.name for p in params]
    head = ["a", "b", "dc_m", "sigma_pa", "k_pa_per_m", "v_star_m_s"]
    # f_star (the SI friction column) on the SI trajectory and the protocols only
    si_head = [
        "v_load_m_s",
        "eps",
        *(["f_star"] if command == "trajectory" else []),
        "perturbation",
    ]
    head += si_head if group == "si" else ["eps", "f_star"]
    assert names[: len(head)] == head
    by_name = {p.name: p for p in params}
    for name, limit in CLI_SI:
        if name in by_name:
            assert si_range_text(limit) in (by_name[name].help or ""), (command, name)
    assert by_name["a"].required and by_name["v_star_m_s"].required


def test_sweep_and_diagram_defaults_are_the_library_s() -> None:
    """An omitted fixed parameter of a sweep (POST /v1/sweeps, `rsf diagram`, the client,
    the dashboard's empty field) means what rsfcore.diagram.stability_diagram's omitted
    keyword means: b/a, kappa/kappa_crit, eps, v_o and rtol from rsfcore.limits (the sweep
    defaulted kappa/kappa_crit to 1, the library to 2, until 0.2)."""
    import inspect

    from rsfapp.grid import expand
    from rsfcore.diagram import stability_diagram

    lib = {
        k: p.default
        for k, p in inspect.signature(stability_diagram).parameters.items()
        if k in ("ba", "kappa_ratio", "eps", "vo", "rtol")
    }
    assert lib == {
        "ba": limits.BA.default,
        "kappa_ratio": limits.KAPPA_RATIO.default,
        "eps": limits.EPS.default,
        "vo": limits.VO.default,
        "rtol": limits.RTOL.default,
    }
    # two axes that fix nothing else: every fixed value is the model's default
    req = requests.SweepRequest.model_validate(
        {"axes": [{"name": "size", "values": [1.0]}, {"name": "eps", "values": [0.1]}]}
    )
    spec = expand(req, 10)
    assert spec.kappa_param == "kappa_ratio"
    assert {k: spec.fixed[k] for k in ("ba", "kappa_ratio", "vo")} == {
        k: lib[k] for k in ("ba", "kappa_ratio", "vo")
    }
    assert spec.rtol == lib["rtol"]
    req = requests.SweepRequest.model_validate(
        {"axes": [{"name": "size", "values": [1.0]}, {"name": "kappa_ratio", "values": [3.0]}]}
    )
    assert expand(req, 10).fixed["eps"] == lib["eps"]
    # the dashboard reads the default from the field's description (OpenAPI)
    desc = requests.SweepFixed.model_fields["kappa_ratio"].description or ""
    assert f"default {limits.format_number(lib['kappa_ratio'])} " in desc


def test_cli_fit_leaves_compare_and_burn_to_the_model(
    tmp_path: Any, monkeypatch: pytest.MonkeyPatch
) -> None:
    """`rsf fit` sends compare and posterior.burn only when given, so an omitted one is
    the request model's (compare true, burn 500: the library's sample_posterior default);
    --posterior-steps N used to burn N // 4."""
    import inspect

    from typer.testing import CliRunner

    import rsfcli.lab as lab
    from rsfapp.requests.fits import FitRequest, PosteriorOptions
    from rsfcore.fit import sample_posterior

    bodies: list[dict[str, Any]] = []

    def fake_run(model: Any, body: dict[str, Any], fn: Any) -> dict[str, Any]:
        bodies.append(body)
        raise typer.Exit(code=0)

    monkeypatch.setattr(lab, "_run", fake_run)
    rec = tmp_path / "r.csv"
    rec.write_text("t_s,v_lp_m_s,mu\n0,1e-6,0.6\n1,1e-6,0.6\n")
    r = CliRunner().invoke(cli, ["fit", str(rec), "--posterior-steps", "4000", "--json"])
    assert r.exit_code == 0, r.output
    body = bodies[-1]
    assert "compare" not in body and body["posterior"] == {"n_steps": 4000}
    req = FitRequest.model_validate(body)
    assert req.compare is True and req.posterior is not None and req.posterior.burn == 500
    assert inspect.signature(sample_posterior).parameters["burn"].default == req.posterior.burn
    assert PosteriorOptions.model_fields["burn"].default == 500
    r = CliRunner().invoke(
        cli, ["fit", str(rec), "--no-compare", "--law", "aging", "--posterior-burn", "7"]
    )
    assert r.exit_code == 0, r.output
    assert bodies[-1]["compare"] is False and bodies[-1]["posterior"] == {"burn": 7}
