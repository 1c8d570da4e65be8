"""The HTTP connection of a client: base URL and key from the environment, retries only
where waiting helps, problem+json errors, polling of deferred answers.

Retried (every endpoint of the API is idempotent: a computation is keyed by its
parameters, a sweep or a fit by its spec, so a repeated request is the same request):

* 503 (the service is starting, or its database or broker is briefly down): after its
  ``Retry-After``, else with exponential backoff;
* 429 with ``Retry-After`` (a per-key quota): after that many seconds; a 429 without it is
  an error at once;
* a connection reset or closed by the server before it answered.

Not retried: a refused connection (nothing listens there: :class:`ConnectionFailed` at
once, naming the URL and how to start or name a service), a timeout, every other status.
"""

from __future__ import annotations

import os
import time
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any

import httpx

from ._errors import ConnectionFailed, ProblemError

__all__ = ["DEFAULT_URL", "Http", "problem_of"]

#: Base URL when neither an argument nor RSF_URL names one (`rsf serve`'s default).
DEFAULT_URL = "http://127.0.0.1:8000"
#: Longest wait honoured from a Retry-After header [s].
MAX_RETRY_AFTER_S = 60.0


def problem_of(r: httpx.Response) -> ProblemError:
    """The :class:`ProblemError` of an error answer (its problem+json, if any)."""
    try:
        body = r.json()
    except ValueError:
        body = {}
    return ProblemError(r.status_code, body if isinstance(body, dict) else {}, r.text)


def _retry_after(r: httpx.Response) -> float | None:
    ra = r.headers.get("retry-after")
    if ra is None:
        return None
    try:
        return min(max(float(ra), 0.0), MAX_RETRY_AFTER_S)
    except ValueError:
        return None


class Http:
    """One connection pool to one API.

    Args:
        base_url: e.g. ``http://127.0.0.1:8000``; default the ``RSF_URL`` environment
            variable, else :data:`DEFAULT_URL`.
        api_key: sent as ``Authorization: Bearer <key>``; default ``RSF_API_KEY`` (if set).
        timeout: seconds per request (connect, read, write).
        retries: how many times a 503, a 429 with Retry-After or a reset is retried.
        backoff: first wait of the exponential backoff [s] (doubling, at most 10 s).
        transport: an httpx transport (tests: ``httpx.MockTransport``, or an in-process app).
    """

    def __init__(
        self,
        base_url: str | None = None,
        *,
        api_key: str | None = None,
        timeout: float = 60.0,
        retries: int = 5,
        backoff: float = 0.5,
        transport: httpx.BaseTransport | None = None,
    ) -> None:
        url = base_url or os.environ.get("RSF_URL") or DEFAULT_URL
        if api_key is None:
            api_key = os.environ.get("RSF_API_KEY") or None
        headers = {"Authorization": f"Bearer {api_key}"} if api_key else {}
        self.base_url = url.rstrip("/")
        self.retries, self.backoff = retries, backoff
        self.client = httpx.Client(
            base_url=self.base_url, timeout=timeout, headers=headers, transport=transport
        )

    def close(self) -> None:
        """Close the connection pool."""
        self.client.close()

    def _refused(self, method: str, path: str, exc: Exception) -> ConnectionFailed:
        return ConnectionFailed(
            f"{method} {self.base_url}{path}: cannot connect ({exc}). Is the service running "
            "there? Start one with `rsf serve`, or name it with RSF_URL (or Client(url))."
        )

    def request(self, method: str, path: str, **kw: Any) -> httpx.Response:
        """One request; retried as the module says; an error answer raises
        :class:`ProblemError`, no answer :class:`ConnectionFailed`."""
        delay = self.backoff
        for attempt in range(self.retries + 1):
            last = attempt == self.retries
            try:
                r = self.client.request(method, path, **kw)
            except (httpx.ConnectError, httpx.UnsupportedProtocol) as exc:
                raise self._refused(method, path, exc) from None
            except httpx.TimeoutException as exc:
                raise ConnectionFailed(
                    f"{method} {self.base_url}{path}: no answer in time ({type(exc).__name__}); "
                    "give Client(timeout=...) more seconds"
                ) from None
            except (httpx.RemoteProtocolError, httpx.ReadError, httpx.WriteError) as exc:
                if last:
                    raise ConnectionFailed(
                        f"{method} {self.base_url}{path}: connection reset "
                        f"{self.retries + 1} times ({exc})"
                    ) from None
                wait = delay
            else:
                if r.status_code < 400:
                    return r
                ra = _retry_after(r)
                retryable = r.status_code == 503 or (r.status_code == 429 and ra is not None)
                if not retryable or last:
                    raise problem_of(r)
                wait = delay if ra is None else ra
            time.sleep(wait)
            delay = min(delay * 2, 10.0)
        raise AssertionError("unreachable")  # pragma: no cover

    def json(self, method: str, path: str, **kw: Any) -> dict[str, Any]:
        """The JSON object of a request's answer."""
        out = self.request(method, path, **kw).json()
        if not isinstance(out, dict):
            raise ProblemError(200, {}, f"{path}: expected a JSON object, got {type(out)}")
        return out

    def answer(self, path: str, body: dict[str, Any], poll: float = 0.5) -> dict[str, Any]:
        """POST a single query; a deferred answer (202 + Location: /v1/results/{key}) is
        polled until the result is there."""
        r = self.request("POST", path, json=body)
        while r.status_code == 202 and "location" in r.headers:
            ra = _retry_after(r)
            time.sleep(poll if ra is None else min(ra, poll * 4))
            r = self.request("GET", r.headers["location"])
        out = r.json()
        assert isinstance(out, dict)
        return out

    @contextmanager
    def stream(self, method: str, path: str, **kw: Any) -> Iterator[httpx.Response]:
        """A streamed answer (large downloads); an error answer raises ProblemError."""
        try:
            with self.client.stream(method, path, **kw) as r:
                if r.status_code >= 400:
                    r.read()
                    raise problem_of(r)
                yield r
        except (httpx.ConnectError, httpx.UnsupportedProtocol) as exc:
            raise self._refused(method, path, exc) from None
