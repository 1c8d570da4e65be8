"""RFC 9457 problem+json responses: 422 naming the field and its valid range, 404, etc.

Nothing is written to the cache or the sweep tables before validation passes, so a 422
never leaves a trace.

Infrastructure faults are never a 500 nor a hang: a database error (server down,
connection dropped, file locked or damaged) or a broker error (Redis down) is answered
503 problem+json with ``Retry-After: RSF_RETRY_AFTER_S``, a ``reason`` and a ``hint``
(how to recover).  Connections are retried for at most ``RSF_DB_RETRY_S`` first
(:mod:`rsfapp.db.engine`).
"""

from __future__ import annotations

import json
import logging
from typing import Any

from fastapi import FastAPI, Request
from fastapi.exceptions import RequestValidationError
from starlette.exceptions import HTTPException as StarletteHTTPException
from starlette.responses import Response

from rsfapp.config import get_settings
from rsfapp.db.engine import SchemaTooNew, diagnose
from rsfapp.requests import VALID
from rsfcore.params import ParameterError

__all__ = ["ProblemError", "install_handlers", "problem", "unavailable"]
log = logging.getLogger("rsf.service")
PROBLEM = "application/problem+json"


class ProblemError(Exception):
    """An error to report as problem+json.

    Args:
        status: HTTP status (4xx).
        title: short summary.
        detail: human-readable explanation.
        field: dotted name of the offending input (for 422).
        valid: valid range of that input (for 422).
    """

    def __init__(
        self,
        status: int,
        title: str,
        detail: str,
        *,
        field: str | None = None,
        valid: str | None = None,
    ) -> None:
        super().__init__(detail)
        self.status, self.title, self.detail, self.field, self.valid = (
            status,
            title,
            detail,
            field,
            valid,
        )


def problem(
    status: int,
    title: str,
    detail: str,
    errors: list[dict[str, Any]] | None = None,
    headers: dict[str, str] | None = None,
) -> Response:
    """A problem+json response."""
    body: dict[str, Any] = {
        "type": "about:blank",
        "title": title,
        "status": status,
        "detail": detail,
    }
    if errors:
        body["errors"] = errors
        body["field"] = errors[0]["field"]
        body["valid"] = errors[0].get("valid")
    return Response(
        json.dumps(body, default=str), status_code=status, media_type=PROBLEM, headers=headers
    )


def unavailable(title: str, reason: str, hint: str, retry_after_s: int | None = None) -> Response:
    """503 problem+json with ``Retry-After`` (the part named in ``title`` is down or
    busy): ``retry_after_s`` [s] if given, else RSF_RETRY_AFTER_S."""
    after = get_settings().retry_after_s if retry_after_s is None else retry_after_s
    body = {
        "type": "about:blank",
        "title": title,
        "status": 503,
        "detail": f"{reason}. {hint}.",
        "reason": reason,
        "hint": hint,
        "retry_after_s": after,
    }
    return Response(
        json.dumps(body, default=str),
        status_code=503,
        media_type=PROBLEM,
        headers={"Retry-After": str(after)},
    )


def database_problem(exc: BaseException) -> Response:
    """503 for a database exception (logged as one line, no traceback)."""
    p = diagnose(exc, get_settings().effective_cache_url)
    if p is None:
        log.error("database error", exc_info=exc)
        return unavailable(
            "Database unavailable", f"database error: {type(exc).__name__}", "retry later"
        )
    log.warning("503: %s", p.reason)
    return unavailable(
        "Database unavailable" if p.kind != "damaged" else "Database damaged", p.reason, p.hint
    )


def broker_problem(exc: BaseException) -> Response:
    """503 for a broker (Redis / filesystem queue) exception."""
    reason = (
        f"broker {get_settings().effective_broker_url.split('@')[-1]} unavailable: "
        f"{str(exc).strip() or type(exc).__name__}"
    )
    log.warning("503: %s", reason)
    return unavailable(
        "Broker unavailable",
        reason,
        "check that the broker (RSF_BROKER_URL) is running and reachable",
    )


def _field_of(loc: tuple[Any, ...]) -> str:
    parts = [p for p in loc if p not in ("body", "query", "path")]
    out = ""
    for p in parts:
        out += f"[{p}]" if isinstance(p, int) else (f".{p}" if out else str(p))
    return out or "body"


def _valid_of(loc: tuple[Any, ...]) -> str | None:
    for p in reversed(loc):
        if isinstance(p, str) and p in VALID:
            return VALID[p]
    return None


def _safe(v: Any) -> Any:
    try:
        json.dumps(v, allow_nan=False)
        return v
    except (TypeError, ValueError):
        return repr(v)


def validation_problem(exc: RequestValidationError) -> Response:
    """422 for a request that failed schema validation."""
    errors = []
    for e in exc.errors():
        loc = tuple(e.get("loc", ()))
        field = _field_of(loc)
        valid = _valid_of(loc)
        msg = str(e.get("msg", "invalid"))
        errors.append(
            {"field": field, "message": msg, "valid": valid, "input": _safe(e.get("input"))}
        )
    first = errors[0] if errors else {"field": "body", "message": "invalid", "valid": None}
    detail = f"{first['field']}: {first['message']}"
    if first.get("valid"):
        detail += f" (valid range: {first['valid']})"
    return problem(422, "Invalid input", detail, errors or [first])


def install_handlers(app: FastAPI) -> None:
    """Register the problem+json handlers on ``app``."""

    @app.exception_handler(RequestValidationError)
    async def _validation(_req: Request, exc: RequestValidationError) -> Response:
        return validation_problem(exc)

    @app.exception_handler(ProblemError)
    async def _problem(_req: Request, exc: ProblemError) -> Response:
        errs = None
        if exc.field:
            errs = [{"field": exc.field, "message": exc.detail, "valid": exc.valid}]
        return problem(exc.status, exc.title, exc.detail, errs)

    @app.exception_handler(ParameterError)
    async def _parameter(_req: Request, exc: ParameterError) -> Response:
        return problem(
            422,
            "Invalid input",
            str(exc),
            [{"field": exc.field, "message": str(exc), "valid": exc.valid}],
        )

    import sqlite3

    from kombu.exceptions import OperationalError as KombuOperationalError
    from redis.exceptions import ConnectionError as RedisConnectionError
    from redis.exceptions import TimeoutError as RedisTimeoutError
    from sqlalchemy.exc import SQLAlchemyError

    async def _db(_req: Request, exc: Exception) -> Response:
        return database_problem(exc)

    async def _broker(_req: Request, exc: Exception) -> Response:
        return broker_problem(exc)

    db_errors: tuple[type[Exception], ...] = (SQLAlchemyError, sqlite3.Error, SchemaTooNew)
    broker_errors: tuple[type[Exception], ...] = (
        KombuOperationalError,
        RedisConnectionError,
        RedisTimeoutError,
    )
    for cls in db_errors:
        app.add_exception_handler(cls, _db)
    for cls in broker_errors:
        app.add_exception_handler(cls, _broker)

    @app.exception_handler(StarletteHTTPException)
    async def _http(_req: Request, exc: StarletteHTTPException) -> Response:
        return problem(
            exc.status_code, "HTTP error", str(exc.detail), headers=getattr(exc, "headers", None)
        )
