"""Shared pieces of the request models: the field factory that states units and valid
ranges in OpenAPI, the strict base model, and the perturbation kinds."""

from __future__ import annotations

import types
import typing
from typing import Any, Literal

from pydantic import BaseModel, ConfigDict, Field, ValidationError, model_validator
from pydantic_core import InitErrorDetails, PydanticCustomError

from rsfcore import limits
from rsfcore.limits import Limit

__all__ = ["F", "FL", "Model", "Perturbation", "RTOL", "VALID", "VALID_RTOL", "bounds", "SIZE_TEXT"]

#: Human-readable valid range of every field, used in 422 problem details.
VALID: dict[str, str] = {}


def F(default: Any, valid: str, description: str, **kw: Any) -> Any:  # noqa: N802
    """A Field whose description states units and the valid range ``valid``."""
    name = kw.pop("name", None)
    if name:
        VALID[name] = valid
    return Field(
        default,
        description=f"{description} Valid range: {valid}.",
        json_schema_extra={"x-valid-range": valid},
        **kw,
    )


def _has_bool(v: Any) -> bool:
    if isinstance(v, bool):
        return True
    return isinstance(v, list) and any(isinstance(x, bool) for x in v)


def _admits_bool(annotation: Any) -> bool:
    """True when ``bool`` (or Any) is one of the types the annotation accepts."""
    if annotation is bool or annotation is Any:
        return True
    origin = typing.get_origin(annotation)
    if origin is typing.Annotated:
        return _admits_bool(typing.get_args(annotation)[0])
    if origin in (typing.Union, types.UnionType, list):
        return any(_admits_bool(a) for a in typing.get_args(annotation))
    return False


class Model(BaseModel):
    """Strict: unknown fields and NaN/inf are rejected."""

    model_config = ConfigDict(extra="forbid", allow_inf_nan=False)

    @model_validator(mode="before")
    @classmethod
    def _no_booleans_as_numbers(cls, data: Any) -> Any:
        """JSON true/false is not a number: pydantic's lax mode would read it as 1/0
        (``"vo": false`` -> v_o = 0, a different physical question), and strict mode would
        refuse the query strings of GET endpoints.  So booleans are refused here, where
        a field is numeric, naming the field."""
        if not isinstance(data, dict) or not any(map(_has_bool, data.values())):
            return data  # the common case, without walking the fields (batches of 1e5 items)
        for name, field in cls.model_fields.items():
            key = field.alias or name
            if key in data and _has_bool(data[key]) and not _admits_bool(field.annotation):
                raise ValidationError.from_exception_data(
                    cls.__name__,
                    [
                        InitErrorDetails(
                            type=PydanticCustomError(
                                "bool_not_number", "a JSON boolean is not a number"
                            ),
                            loc=(key,),
                            input=data[key],
                        )
                    ],
                )
        return data


def bounds(limit: Limit) -> dict[str, float]:
    """pydantic bounds (ge/gt/le/lt) of an rsfcore :class:`~rsfcore.limits.Limit`."""
    out: dict[str, float] = {}
    if limit.lo is not None:
        out["gt" if limit.lo_open else "ge"] = limit.lo
    if limit.hi is not None:
        out["lt" if limit.hi_open else "le"] = limit.hi
    return out


_UNSET: Any = object()


def FL(
    limit: Limit,
    default: Any = _UNSET,
    *,
    description: str | None = None,  # noqa: N802
    name: str | None = None,
    valid: str | None = None,
) -> Any:
    """A Field whose range, default and text come from ``rsfcore.limits`` (the one source
    of truth shared with rsfcore and the CLI); ``valid`` overrides the range text only
    where a field accepts more than one limit (e.g. size for both perturbations)."""
    text = valid or limit.text
    unit = "" if limit.unit in ("", "-") else f" [{limit.unit}]"
    desc = description or f"{limit.description}{unit}"
    return F(
        limit.default if default is _UNSET else default,
        text,
        desc,
        name=name or limit.name,
        **bounds(limit),
    )


Perturbation = Literal["velocity-jump", "load-point-jump"]
#: Bounds and text of every rtol field (rsfcore.limits.RTOL).
RTOL = bounds(limits.RTOL)
VALID_RTOL = limits.RTOL.text
#: Range text of a perturbation ``size`` valid for either kind (rsfcore checks the kind's own).
SIZE_TEXT = (
    f"velocity-jump: {limits.VELOCITY_JUMP_SIZE.text}; "
    f"load-point-jump: {limits.LOAD_POINT_JUMP_SIZE.text}"
)
