"""One source of truth for every parameter's valid range and default (rsfcore.limits):
the HTTP request models, the CLI and rsfcore itself must agree with it."""

from __future__ import annotations

import math
from typing import Any

import pytest
import typer

from rsfapp import requests
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
        assert p.default == limit.default, (command, name)
        assert limit.text in (p.help or ""), (command, name)


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
