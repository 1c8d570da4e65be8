"""The client: single queries, sweeps and their results over HTTP (httpx)."""

from __future__ import annotations

import io
import os
import sys
import time
from collections.abc import Callable
from pathlib import Path
from types import TracebackType
from typing import Any

import httpx

from ._errors import ConnectionFailed, ProblemError, SweepCancelled

__all__ = ["Client", "Sweep"]

#: Statuses worth retrying (the service is restarting, overloaded or its database is
#: briefly unavailable: it answers 503 problem+json with Retry-After).
RETRY_STATUS = frozenset({502, 503, 504})


class Client:
    """A client of one rsf-stability API.

    Args:
        base_url: e.g. ``http://127.0.0.1:8000`` (``rsf serve``'s default).
        api_key: sent as ``Authorization: Bearer <key>`` when the server requires keys;
            default: the ``RSF_API_KEY`` environment variable (if set).
        timeout: seconds per request.
        retries: attempts after the first one for 502/503/504 answers and connection
            errors / timeouts, with exponential backoff from ``backoff`` seconds (capped
            at 10 s; a ``Retry-After`` header wins).
        transport: an httpx transport (tests: ``httpx.MockTransport``).
    """

    def __init__(
        self,
        base_url: str = "http://127.0.0.1:8000",
        *,
        api_key: str | None = None,
        timeout: float = 60.0,
        retries: int = 5,
        backoff: float = 0.5,
        transport: httpx.BaseTransport | None = None,
    ) -> None:
        if api_key is None:
            api_key = os.environ.get("RSF_API_KEY") or None
        headers = {"Authorization": f"Bearer {api_key}"} if api_key else {}
        self._http = httpx.Client(
            base_url=base_url.rstrip("/"), timeout=timeout, headers=headers, transport=transport
        )
        self.retries, self.backoff = retries, backoff

    # -- plumbing ----------------------------------------------------------------------------
    def close(self) -> None:
        """Close the connection pool."""
        self._http.close()

    def __enter__(self) -> Client:
        return self

    def __exit__(self, *exc: type[BaseException] | BaseException | TracebackType | None) -> None:
        self.close()

    def request(self, method: str, path: str, **kw: Any) -> httpx.Response:
        """One request with retries; an error answer raises :class:`ProblemError`."""
        delay = self.backoff
        last: str = ""
        for attempt in range(self.retries + 1):
            try:
                r = self._http.request(method, path, **kw)
            except httpx.TransportError as exc:
                last = f"{type(exc).__name__}: {exc}"
            else:
                if r.status_code not in RETRY_STATUS:
                    if r.status_code >= 400:
                        raise _problem(r)
                    return r
                last = f"HTTP {r.status_code}: {r.text[:200]}"
                if attempt == self.retries:
                    raise _problem(r)
                ra = r.headers.get("retry-after")
                if ra and ra.replace(".", "", 1).isdigit():
                    delay = min(float(ra), 30.0)
            if attempt < self.retries:
                time.sleep(delay)
                delay = min(delay * 2, 10.0)
        raise ConnectionFailed(
            f"{method} {path}: no answer after {self.retries + 1} attempts ({last})"
        )

    def _answer(self, path: str, body: dict[str, Any], poll: float = 0.5) -> dict[str, Any]:
        r = self.request("POST", path, json=body)
        while r.status_code == 202 and "location" in r.headers:  # long query: poll
            time.sleep(poll)
            r = self.request("GET", r.headers["location"])
        return dict(r.json())

    # -- single queries ----------------------------------------------------------------------
    def critical(
        self,
        *,
        ba: float = 2.0,
        kappa: float = 2.0,
        eps: float = 0.25,
        vo: float = 1.0,
        perturbation: str = "velocity-jump",
        rtol: float = 1e-10,
        **extra: Any,
    ) -> dict[str, Any]:
        """Critical perturbation size (POST /v1/critical): kind, critical_size,
        rel_accuracy, method, ... (dimensionless; ``extra`` passes other request fields)."""
        body = dict(ba=ba, kappa=kappa, eps=eps, vo=vo, perturbation=perturbation, rtol=rtol)
        return self._answer("/v1/critical", {**body, **extra})

    def classify(
        self,
        *,
        ba: float = 2.0,
        kappa: float = 2.0,
        eps: float = 0.25,
        vo: float = 1.0,
        size: float = 1.0,
        perturbation: str = "velocity-jump",
        rtol: float = 1e-10,
        **extra: Any,
    ) -> dict[str, Any]:
        """Certified outcome of one perturbation (POST /v1/classify); a long integration
        (202) is polled until it is done."""
        body = dict(
            ba=ba, kappa=kappa, eps=eps, vo=vo, size=size, perturbation=perturbation, rtol=rtol
        )
        return self._answer("/v1/classify", {**body, **extra})

    # -- sweeps ----------------------------------------------------------------------------
    def sweep(
        self,
        spec: dict[str, Any] | None = None,
        *,
        axes: list[dict[str, Any]] | None = None,
        points: dict[str, Any] | None = None,
        fixed: dict[str, Any] | None = None,
        perturbation: str | None = None,
        rtol: float | None = None,
        chunk_points: int | None = None,
    ) -> Sweep:
        """Submit a sweep (POST /v1/sweeps) and return its handle.

        Give a whole request body as ``spec`` or its parts: ``axes`` (1-5 grid axes, each
        ``{name, values}`` or ``{name, start, stop, n, log}``) or ``points`` (equal-length
        arrays; numpy arrays are accepted), ``fixed``, ``perturbation``, ``rtol``.
        Submitting a finished sweep returns it at once; a cancelled one is resumed.
        """
        body: dict[str, Any] = dict(spec or {})
        for k, v in (
            ("axes", axes),
            ("fixed", fixed),
            ("perturbation", perturbation),
            ("rtol", rtol),
            ("chunk_points", chunk_points),
        ):
            if v is not None:
                body[k] = v
        if points is not None:
            body["points"] = {k: [float(x) for x in v] for k, v in points.items()}
        r = self.request("POST", "/v1/sweeps", json=body)
        st = dict(r.json())
        return Sweep(self, str(st["id"]), st)

    def get_sweep(self, sweep_id: str) -> Sweep:
        """Handle of an existing sweep (its status is fetched)."""
        s = Sweep(self, sweep_id, {})
        s.status()
        return s


class Sweep:
    """Handle of a submitted sweep.

    Attributes:
        id: the sweep id; last: the last status seen (dict).
    """

    def __init__(self, client: Client, sweep_id: str, status: dict[str, Any]) -> None:
        self.client, self.id, self.last = client, sweep_id, status

    def __repr__(self) -> str:
        return (
            f"Sweep({self.id!r}, status={self.last.get('status')!r}, "
            f"{self.last.get('n_done')}/{self.last.get('n_total')})"
        )

    @property
    def resumed(self) -> bool:
        """The submission resumed a cancelled sweep."""
        return bool(self.last.get("resumed", False))

    def status(self) -> dict[str, Any]:
        """Current status (status, n_done, n_total, n_failed, eta_s, failures, ...)."""
        self.last = dict(self.client.request("GET", f"/v1/sweeps/{self.id}").json())
        return self.last

    def wait(
        self,
        progress: bool = False,
        poll: float = 0.5,
        timeout: float | None = None,
        on_status: Callable[[dict[str, Any]], None] | None = None,
    ) -> dict[str, Any]:
        """Poll until the sweep is done; returns the final status.

        Args:
            progress: show a progress bar on stderr (rich if installed, else a text line).
            poll: seconds between polls; timeout: give up after this many seconds
                (TimeoutError).
            on_status: called with every status seen.

        Raises :class:`SweepCancelled` if the sweep is (or gets) cancelled.
        """
        t0 = time.monotonic()
        bar = _Progress(self.id) if progress else None
        try:
            while True:
                st = self.status()
                if on_status is not None:
                    on_status(st)
                if bar is not None:
                    bar.update(st)
                if st["status"] == "done":
                    return st
                if st["status"] == "cancelled":
                    raise SweepCancelled(
                        f"sweep {self.id} was cancelled ({st['n_done']}/{st['n_total']} points)"
                    )
                if timeout is not None and time.monotonic() - t0 > timeout:
                    raise TimeoutError(f"sweep {self.id} not done after {timeout} s")
                time.sleep(poll)
        finally:
            if bar is not None:
                bar.close()

    def cancel(self) -> dict[str, Any]:
        """Cancel (DELETE); a second cancel changes nothing (``changed: false``)."""
        self.last = dict(self.client.request("DELETE", f"/v1/sweeps/{self.id}").json())
        return self.last

    def delete(self) -> None:
        """Delete the sweep and all its data (DELETE ?purge=true)."""
        self.client.request("DELETE", f"/v1/sweeps/{self.id}", params={"purge": "true"})

    def data(self, format: str = "netcdf") -> bytes:  # noqa: A002
        """The whole result (GET /data) as bytes: 'netcdf', 'csv' or 'json'."""
        return self.client.request(
            "GET", f"/v1/sweeps/{self.id}/data", params={"format": format}
        ).content

    def download(
        self,
        path: str | Path,
        format: str | None = None,  # noqa: A002
        progress: bool = False,
    ) -> Path:
        """Stream the result to ``path`` (format from the suffix: .nc, .csv, .json)."""
        p = Path(path)
        fmt = format or {".csv": "csv", ".json": "json"}.get(p.suffix.lower(), "netcdf")
        bar = _Progress(f"{self.id} -> {p.name}", unit="bytes") if progress else None
        with self.client._http.stream(
            "GET", f"/v1/sweeps/{self.id}/data", params={"format": fmt}
        ) as r:
            if r.status_code >= 400:
                r.read()
                raise _problem(r)
            total = int(r.headers.get("content-length", 0)) or None
            n = 0
            with open(p, "wb") as fh:
                for piece in r.iter_bytes():
                    fh.write(piece)
                    n += len(piece)
                    if bar is not None:
                        bar.update({"n_done": n, "n_total": total, "status": "downloading"})
        if bar is not None:
            bar.close()
        return p

    def to_xarray(self) -> Any:
        """The result as an ``xarray.Dataset`` (needs xarray; NetCDF read in memory)."""
        import xarray as xr

        return xr.open_dataset(io.BytesIO(self.data("netcdf")), engine="scipy").load()


class _Progress:
    """A progress bar over status dicts (rich if available, else a carriage-return line)."""

    def __init__(self, label: str, unit: str = "points") -> None:
        self.label, self.unit = label, unit
        self._rich: Any = None
        self._task: Any = None
        try:
            from rich.console import Console
            from rich.progress import (
                BarColumn,
                MofNCompleteColumn,
                Progress,
                TextColumn,
                TimeRemainingColumn,
            )

            self._rich = Progress(
                TextColumn("{task.description}"),
                BarColumn(),
                MofNCompleteColumn(),
                TextColumn("{task.fields[status]}"),
                TimeRemainingColumn(),
                transient=False,
                console=Console(stderr=True),
            )
            self._rich.start()
            self._task = self._rich.add_task(label, total=None, status="")
        except ImportError:
            self._rich = None

    def update(self, st: dict[str, Any]) -> None:
        done, total, status = st.get("n_done", 0), st.get("n_total"), st.get("status", "")
        if self._rich is not None:
            self._rich.update(self._task, completed=done, total=total, status=status)
        else:
            print(
                f"\r{self.label}: {done}/{total or '?'} {self.unit} {status}   ",
                end="",
                file=sys.stderr,
                flush=True,
            )

    def close(self) -> None:
        if self._rich is not None:
            self._rich.stop()
        else:
            print(file=sys.stderr)


def _problem(r: httpx.Response) -> ProblemError:
    try:
        body = r.json()
    except ValueError:
        body = {}
    return ProblemError(r.status_code, body if isinstance(body, dict) else {}, r.text)
