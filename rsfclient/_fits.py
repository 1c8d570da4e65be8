"""Fits: the handle of a submitted lab record (POST /v1/fits -> GET /v1/fits/{key}).

A fit is queued work: :meth:`rsfclient.Client.submit_fit` returns a :class:`Fit` at once;
:meth:`Fit.wait` polls until the worker is done, :meth:`Fit.result` asks once.
"""

from __future__ import annotations

import json
import os
import time
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from ._errors import NotReady
from ._http import Http
from ._results import FitResult

__all__ = ["Fit", "record_text"]


def record_text(record: Any) -> str:
    """The record as the API takes it (CSV or JSON text): text as given; a path
    (``pathlib.Path`` or ``os.PathLike``) is read; a mapping of columns (``{"t_s": [...],
    "v_lp_m_s": [...], "mu": [...]}``) becomes JSON; a pandas.DataFrame becomes CSV."""
    if isinstance(record, str):
        return record
    if isinstance(record, os.PathLike):
        return Path(record).read_text()
    if hasattr(record, "to_csv"):
        return str(record.to_csv(index=False))
    if isinstance(record, Mapping):
        return json.dumps(
            {
                k: (list(v) if isinstance(v, Sequence) and not isinstance(v, str) else v)
                for k, v in record.items()
            }
        )
    if hasattr(record, "keys"):  # e.g. a dict-like of numpy arrays
        return json.dumps({k: [float(x) for x in record[k]] for k in record})
    raise TypeError(
        "record: give CSV/JSON text, a path, a mapping of columns or a pandas.DataFrame"
    )


class Fit:
    """Handle of a submitted fit.

    Attributes:
        key: the fit's key (64 hex: the record's content hash and the options).
        state: 'queued', 'running' or 'done' as last seen; progress: the worker's stage.
    """

    def __init__(self, http: Http, key: str, answer: dict[str, Any] | None = None) -> None:
        self._http, self.key = http, key
        self._result = None if answer is None else FitResult.from_json(answer)
        self.state = "done" if self._result is not None else "queued"
        self.progress: str | None = None

    def __repr__(self) -> str:
        return f"Fit({self.key[:12]}..., state={self.state!r})"

    @property
    def path(self) -> str:
        """Where the fit lives: /v1/fits/{key}."""
        return f"/v1/fits/{self.key}"

    def poll(self) -> FitResult | None:
        """Ask once: the result when done, else None (``state``, ``progress`` updated);
        a fit that failed raises ProblemError (422)."""
        if self._result is not None:
            return self._result
        r = self._http.request("GET", self.path)
        d = r.json()
        if r.status_code == 202:
            self.state, self.progress = str(d.get("status", "queued")), d.get("progress")
            return None
        self._result, self.state = FitResult.from_json(d), "done"
        return self._result

    def result(self) -> FitResult:
        """The result if done; else :class:`NotReady` (use :meth:`wait`)."""
        res = self.poll()
        if res is None:
            raise NotReady(f"fit {self.key} is {self.state}", self.state, self.progress)
        return res

    def wait(self, timeout: float | None = None, poll: float = 0.5) -> FitResult:
        """Poll until the fit is done and return it (TimeoutError after ``timeout`` s)."""
        t0 = time.monotonic()
        while (res := self.poll()) is None:
            if timeout is not None and time.monotonic() - t0 > timeout:
                raise TimeoutError(f"fit {self.key} still {self.state} after {timeout} s")
            time.sleep(poll)
        return res

    def csv(self) -> bytes:
        """The series (t_s, v_lp_m_s, mu, model, residuals) as CSV (the fit must be done)."""
        return self._http.request("GET", self.path, params={"format": "csv"}).content

    def png(self) -> bytes:
        """Data, fit and residuals as a PNG image (the fit must be done)."""
        return self._http.request("GET", self.path, params={"format": "png"}).content
