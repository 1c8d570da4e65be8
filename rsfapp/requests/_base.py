"""Shared pieces of the request models: the field factory that states units and valid
ranges in OpenAPI, the strict base model, and the perturbation kinds."""
from __future__ import annotations

from typing import Any, Literal

from pydantic import BaseModel, ConfigDict, Field

__all__ = ["F", "Model", "Perturbation", "RTOL", "VALID", "VALID_RTOL"]

#: Human-readable valid range of every field, used in 422 problem details.
VALID: dict[str, str] = {}


def F(default: Any, valid: str, description: str, **kw: Any) -> Any:  # noqa: N802
    """A Field whose description states units and the valid range ``valid``."""
    name = kw.pop("name", None)
    if name:
        VALID[name] = valid
    return Field(default, description=f"{description} Valid range: {valid}.",
                 json_schema_extra={"x-valid-range": valid}, **kw)


class Model(BaseModel):
    """Strict: unknown fields and NaN/inf are rejected."""

    model_config = ConfigDict(extra="forbid", allow_inf_nan=False)


Perturbation = Literal["velocity-jump", "load-point-jump"]
RTOL = dict(ge=1e-13, le=1e-3)
VALID_RTOL = "[1e-13, 1e-3]"


