"""The OpenAPI document made exact: what the service really answers, so that other lab
tools can generate clients from it.

FastAPI's generated schema is post-processed once (:func:`install` replaces
``app.openapi``):

* every 4xx/5xx answer is ``application/problem+json`` with the :data:`PROBLEM_SCHEMA`
  (RFC 9457 plus ``field``, ``valid`` and ``errors``), as :mod:`service.errors` sends it;
* operations with a body document 400 (unparsable body) and 413 (body too large); every
  operation documents 431 (headers too large), 401/403 (API key, scope), and the
  computing ones 429 (quota, with ``Retry-After``);
* the single-query endpoints document their 202 + ``Location: /v1/results/{key}``
  answer (a computation still running after the inline budget, or a long integration
  sent to the queue);
* every operation states the API-key scope it needs (``x-required-scope``).
"""

from __future__ import annotations

from typing import Any

from fastapi import FastAPI
from fastapi.openapi.utils import get_openapi

from .admission import is_computing
from .auth import scope_for

__all__ = ["PROBLEM_SCHEMA", "install", "refine"]

PROBLEM_MEDIA = "application/problem+json"
#: JSON schema of every error answer.
PROBLEM_SCHEMA: dict[str, Any] = {
    "title": "Problem",
    "type": "object",
    "description": "RFC 9457 problem details.  For 422: `field` names the offending "
    "input, `valid` states its valid range, `errors` lists every error.",
    "required": ["type", "title", "status", "detail"],
    "properties": {
        "type": {"type": "string"},
        "title": {"type": "string"},
        "status": {"type": "integer"},
        "detail": {"type": "string"},
        "field": {"type": ["string", "null"]},
        "valid": {"type": ["string", "null"]},
        "errors": {"type": "array", "items": {"type": "object"}},
    },
    "additionalProperties": True,
}
_DEFERRED_SCHEMA: dict[str, Any] = {
    "title": "Deferred",
    "type": "object",
    "required": ["status", "cache_key"],
    "properties": {
        "status": {"type": "string", "enum": ["running", "queued"]},
        "cache_key": {"type": "string", "pattern": "^[0-9a-f]{64}$"},
        "location": {"type": "string"},
    },
}
_REF_PROBLEM = {"$ref": "#/components/schemas/Problem"}
_HDR = {"schema": {"type": "string"}}
_STANDARD: dict[str, str] = {
    "400": "Unparsable body (not JSON, or not UTF-8) (problem+json), or a request the HTTP "
    "layer cannot parse at all, e.g. a URL too long (text/plain).",
    "401": "No API key, or an unknown, malformed or revoked one (problem+json; header "
    "`WWW-Authenticate: Bearer`).",
    "403": "The key's scope does not allow this request, or the sweep belongs to another "
    "key (problem+json).",
    "413": "Request body larger than the limit of this endpoint (problem+json), refused "
    "before it is read.",
    "429": "Quota of this key exceeded (problem+json); retry after `Retry-After` seconds.",
    "431": "Request headers too large (problem+json).",
}
#: Single-query endpoints answered 202 + Location when their computation is deferred.
_DEFERRABLE = {
    "/v1/classify",
    "/v1/classify/points",
    "/v1/trajectory",
    "/v1/critical",
    "/v1/analytic/u",
    "/v1/boundaries",
    "/v1/stiffness",
}


def _problem_content() -> dict[str, Any]:
    return {PROBLEM_MEDIA: {"schema": _REF_PROBLEM}}


def refine(schema: dict[str, Any]) -> dict[str, Any]:
    """Post-process a FastAPI OpenAPI document in place (see module docstring)."""
    comps = schema.setdefault("components", {})
    schemas = comps.setdefault("schemas", {})
    schemas["Problem"] = PROBLEM_SCHEMA
    schemas["Deferred"] = _DEFERRED_SCHEMA
    for path, ops in schema.get("paths", {}).items():
        for method, op in ops.items():
            if not isinstance(op, dict) or "responses" not in op:
                continue
            resp: dict[str, Any] = op["responses"]
            codes = ["400", "401", "403", "431"]
            if "requestBody" in op:
                codes += ["413"]
            if is_computing(path) or (path == "/v1/sweeps" and method == "post"):
                codes.append("429")
            for c in codes:
                resp.setdefault(c, {"description": _STANDARD[c]})
            if "429" in resp:
                resp["429"].setdefault("headers", {})["Retry-After"] = {
                    "description": "Seconds to wait.",
                    "schema": {"type": "integer"},
                }
            if "401" in resp:
                resp["401"].setdefault("headers", {})["WWW-Authenticate"] = _HDR
            if path in _DEFERRABLE:
                r202 = resp.setdefault("202", {"description": ""})
                r202["description"] = (
                    "Still computing (a long integration goes through the queue): poll "
                    "`Location: /v1/results/{key}`, then repeat the request."
                )
            if "202" in resp and not resp["202"].get("content"):
                resp["202"]["content"] = {
                    "application/json": {"schema": {"$ref": "#/components/schemas/Deferred"}}
                }
                resp["202"]["headers"] = {"Location": _HDR, "Retry-After": _HDR}
            for code, r in resp.items():
                if str(code)[0] in "45":
                    r["content"] = _problem_content()
                    if str(code) == "400":
                        r["content"]["text/plain"] = {"schema": {"type": "string"}}
                elif str(code).startswith("2") and not r.get("content"):
                    r["content"] = {"application/json": {"schema": {"type": "object"}}}
            extra = op.get("x-required-scope")
            op["x-required-scope"] = extra or scope_for(path, method).value
    used = repr(schema.get("paths", {}))
    for name in ("HTTPValidationError", "ValidationError"):
        if (
            name in schemas
            and f"#/components/schemas/{name}" not in used
            and f"#/components/schemas/{name}"
            not in repr({k: v for k, v in schemas.items() if k != name})
        ):
            del schemas[name]
    return schema


def install(app: FastAPI) -> None:
    """Make ``app.openapi()`` return the refined document (built once)."""

    def openapi() -> dict[str, Any]:
        if app.openapi_schema is None:
            app.openapi_schema = refine(
                get_openapi(
                    title=app.title,
                    version=app.version,
                    openapi_version=app.openapi_version,
                    summary=app.summary,
                    description=app.description,
                    routes=app.routes,
                    servers=app.servers,
                    tags=app.openapi_tags,
                )
            )
        return app.openapi_schema

    app.openapi = openapi  # type: ignore[method-assign]
