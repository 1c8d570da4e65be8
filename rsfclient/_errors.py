"""Exceptions of rsfclient.

RsfError
 +-- ProblemError      the server answered an error (problem+json kept in ``problem``)
 +-- ConnectionFailed  no answer after every retry (connection refused, timeouts, 503s)
 +-- SweepCancelled    :meth:`rsfclient.Sweep.wait` on a sweep that was cancelled
"""

from __future__ import annotations

from typing import Any

__all__ = ["ConnectionFailed", "ProblemError", "RsfError", "SweepCancelled"]


class RsfError(Exception):
    """Base class of every rsfclient error."""


class ProblemError(RsfError):
    """An error answer (4xx/5xx) of the API.

    Attributes:
        status: HTTP status code.
        problem: the problem+json body (dict; {} if the body was not JSON).
        title, detail: from the problem (detail falls back to the raw body).
        field, valid: the offending input and its valid range (422), else None.
    """

    def __init__(self, status: int, problem: dict[str, Any], text: str = "") -> None:
        self.status = status
        self.problem = problem
        self.title = str(problem.get("title", "")) or f"HTTP {status}"
        self.detail = str(problem.get("detail", "")) or text[:500]
        self.field: str | None = problem.get("field")
        self.valid: str | None = problem.get("valid")
        where = f" [{self.field}: valid {self.valid}]" if self.field else ""
        super().__init__(f"{status} {self.title}: {self.detail}{where}")


class ConnectionFailed(RsfError):
    """The API could not be reached (or stayed unavailable) after every retry."""


class SweepCancelled(RsfError):
    """The sweep waited for was cancelled (re-submit it to resume)."""
