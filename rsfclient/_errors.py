"""Exceptions of rsfclient.

RsfError
 +-- ProblemError      the server answered an error (problem+json kept in ``problem``)
 +-- ConnectionFailed  no answer: connection refused (at once), a timeout, or still 503 /
 |                     429 / reset after every retry
 +-- SweepCancelled    :meth:`rsfclient.Sweep.wait` on a sweep that was cancelled
 +-- NotReady          :meth:`rsfclient.Fit.result` of a fit still queued or running
"""

from __future__ import annotations

from typing import Any

__all__ = ["ConnectionFailed", "NotReady", "ProblemError", "RsfError", "SweepCancelled"]


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
    """The API could not be reached: refused (raised at once, no retry), timed out, or
    still unavailable (503, 429, connection reset) after every retry."""


class SweepCancelled(RsfError):
    """The sweep waited for was cancelled (re-submit it to resume)."""


class NotReady(RsfError):
    """The fit (or other queued work) is still queued or running; ``state`` says which
    and ``progress`` the stage a worker is at."""

    def __init__(self, message: str, state: str, progress: str | None = None) -> None:
        super().__init__(message)
        self.state, self.progress = state, progress
