"""What every computing `rsf` command shares: options declared from the request models,
validation and computation through :mod:`rsfapp.requests` and :mod:`rsfapp.adapter`
(the same path as HTTP), errors, and output.

Option names: an option that carries a request field is spelled exactly as the field's
JSON name (``--Dc_m``, ``--sigma_Pa``, ``--k_Pa_per_m``, ``--V_star_m_s``, ``--n_points``);
the older kebab-case spelling (``--dc-m``, ``--n-points``) is accepted too.  An option not
given is left out of the request, so its default is the request model's, the same at
every door (CLI, HTTP, Python client); the help text states it.
"""

from __future__ import annotations

import json
import math
from collections.abc import Callable
from enum import StrEnum
from typing import Any

import typer
from pydantic import BaseModel
from pydantic_core import PydanticUndefined

__all__ = [
    "JSON",
    "PerturbationKind",
    "echo_lines",
    "emit",
    "fail",
    "fmt",
    "given",
    "json_value",
    "model_default",
    "model_option",
    "run",
]

#: The ``--json`` flag of a computing command.
JSON = typer.Option(False, "--json", help="Print one JSON object.")


class PerturbationKind(StrEnum):
    """The ``--perturbation`` choices of the dimensionless commands."""

    velocity_jump = "velocity-jump"
    load_point_jump = "load-point-jump"


def fail(msg: str) -> None:
    """Exit 2 (invalid input) with ``error: msg`` on stderr."""
    typer.echo(f"error: {msg}", err=True)
    raise typer.Exit(code=2)


def fmt(x: Any) -> str:
    """A value for the text output: 6 significant digits, '-' for None."""
    return "-" if x is None else (f"{x:.6g}" if isinstance(x, float) else str(x))


def model_default(model: type[BaseModel], field: str) -> Any:
    """The default of ``model.field`` (None when the field is required or defaults to null)."""
    d = model.model_fields[field].default
    return None if d is PydanticUndefined else d


def model_option(
    model: type[BaseModel],
    field: str,
    *legacy: str,
    required: bool = False,
    help: str | None = None,  # noqa: A002 (typer's name)
) -> Any:
    """A typer option for ``model.field``: named ``--<field>`` (plus the ``legacy`` names),
    default None (= omitted: the model's default applies), help text from the field's
    description (units and valid range) plus the model's default."""
    info = model.model_fields[field]
    text = help or info.description or field
    default = model_default(model, field)
    if not required and default is not None:
        text = f"{text} Default: {default}."
    names = [f"--{field}", *(n for n in legacy if n != f"--{field}")]
    return typer.Option(... if required else None, *names, help=text)


def given(**fields: Any) -> dict[str, Any]:
    """The request body of the options given (None = not given; enums by value)."""
    out: dict[str, Any] = {}
    for k, v in fields.items():
        if v is None:
            continue
        out[k] = getattr(v, "value", v)
    return out


def json_value(field: str, text: str | None) -> Any:
    """An option that carries an object or a list of the request (``--start``,
    ``--scales``, ``--segments``), given as JSON text; None when not given.  Invalid JSON
    exits 2 naming the field; the request model then validates the value."""
    if text is None:
        return None
    try:
        return json.loads(text)
    except ValueError as exc:
        fail(f"{field}: {text!r} is not JSON ({exc}) (valid range: a JSON value, e.g. {{...}})")
    raise AssertionError("unreachable")


def run(
    model: type[BaseModel], body: dict[str, Any], fn: Callable[[Any], dict[str, Any]]
) -> dict[str, Any]:
    """Validate ``body`` as ``model`` and compute ``fn`` (an rsfapp.adapter function);
    exit 2 naming the field on invalid input, 1 on a failed computation."""
    from pydantic import ValidationError

    from rsfapp.adapter import ComputeError
    from rsfapp.requests import VALID
    from rsfcore import ParameterError

    try:
        req = model.model_validate(body)
        return fn(req)
    except ValidationError as exc:
        e = exc.errors()[0]
        loc = [p for p in e.get("loc", ()) if not isinstance(p, int)]
        field = ".".join(str(p) for p in loc) or "input"
        valid = next((VALID[str(p)] for p in reversed(loc) if str(p) in VALID), None)
        fail(f"{field}: {e.get('msg')}" + (f" (valid range: {valid})" if valid else ""))
    except ParameterError as exc:
        fail(str(exc))
    except ComputeError as exc:
        typer.echo(f"error: could not be computed: {exc}", err=True)
        raise typer.Exit(code=1) from None
    raise AssertionError("unreachable")


def emit(obj: dict[str, Any], as_json: bool, lines: list[str]) -> None:
    """One JSON object (``--json``), else the text lines."""
    if as_json:
        typer.echo(json.dumps(obj, allow_nan=False))
    else:
        typer.echo("\n".join(lines))


def _kv(d: dict[str, Any]) -> str:
    return "  ".join(f"{k} {fmt(v)}" for k, v in d.items())


def echo_lines(d: dict[str, Any]) -> list[str]:
    """The parameters an answer used, as text lines (every answer echoes them): the
    dimensionless groups (ba, kappa, eps, vo), the perturbation and its size, rtol, and
    the SI inputs when the question was asked in SI."""
    lines: list[str] = []
    si = d.get("si") or {}
    if isinstance(si, dict) and si.get("inputs"):
        lines.append(f"inputs (SI)   {_kv(si['inputs'])}")
    p = d.get("params")
    if isinstance(p, dict) and p:
        lines.append(f"params        {_kv(p)}")
    used: dict[str, Any] = {
        k: d[k]
        for k in ("perturbation", "size", "rtol")
        if k in d and d[k] is not None and not (isinstance(d[k], float) and math.isnan(d[k]))
    }
    if used:
        lines.append(f"used          {_kv(used)}")
    return lines
