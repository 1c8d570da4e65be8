"""Cross-field rules of the request models, stated in their JSON schema (OpenAPI).

A rule that ties two or more fields together (checked by a model validator or by
:mod:`rsfapp.grid`) is written here once per model: as text, listed in the model schema's
``x-cross-field-rules`` and appended to its description (what generated clients, form
builders and /docs show), and, where JSON Schema can say it, as a constraint (an
``allOf`` entry), so a schema-valid request never breaks it.  Rules JSON Schema cannot
state (comparisons of two values: b > a, burn < n_steps, phi_min <= phi_max; equal
lengths of two arrays; the content of a text; a query parameter against the body) are
text only: a request that breaks one is answered 422 problem+json naming the field
(tests/e2e/schemathesis.toml accepts that 422 for exactly those operations).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, NamedTuple

__all__ = [
    "NULL",
    "Rule",
    "absent",
    "not_both",
    "nulls",
    "null_or",
    "stated",
]

#: JSON Schema of a null value.
NULL: dict[str, Any] = {"type": "null"}


class Rule(NamedTuple):
    """One cross-field rule.

    Attributes:
        text: the rule in words, naming the fields (shown in the schema).
        schema: a JSON Schema every valid request also satisfies, or None when JSON
            Schema cannot state the rule.
    """

    text: str
    schema: dict[str, Any] | None = None


def nulls(*fields: str) -> dict[str, Any]:
    """``properties`` entries: each of ``fields`` absent or null."""
    return {f: NULL for f in fields}


def absent(*fields: str) -> dict[str, Any]:
    """Schema: none of ``fields`` is given (or each is null)."""
    return {"properties": nulls(*fields)}


def null_or(field: str, then: dict[str, Any]) -> dict[str, Any]:
    """Schema: ``field`` is absent or null, or else ``then`` holds."""
    return {"anyOf": [absent(field), then]}


def not_both(a: str, b: str) -> dict[str, Any]:
    """Schema: ``a`` and ``b`` are not both given non-null."""
    return {"anyOf": [absent(a), absent(b)]}


def stated(
    *rules: Rule, then: Callable[[dict[str, Any]], None] | None = None
) -> Callable[[dict[str, Any]], None]:
    """A ``json_schema_extra`` that states ``rules`` in the model's schema (after
    ``then``, an existing ``json_schema_extra`` of the model)."""

    def apply(schema: dict[str, Any]) -> None:
        if then is not None:
            then(schema)
        constraints = [r.schema for r in rules if r.schema is not None]
        if constraints:
            schema["allOf"] = [*schema.get("allOf", []), *constraints]
        schema["x-cross-field-rules"] = [r.text for r in rules]
        lines = "\n".join(f"- {r.text}" for r in rules)
        desc = str(schema.get("description", "")).rstrip()
        schema["description"] = f"{desc}\n\nCross-field rules:\n{lines}".lstrip()

    return apply
