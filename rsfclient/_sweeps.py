"""Sweeps: the handle of a submitted sweep (status, wait with progress, points, data,
cancel) and its typed status and pages of points.

A sweep is submitted by :meth:`rsfclient.Client.sweep` (the body of ``POST /v1/sweeps``);
everything after that is here, on ``/v1/sweeps/{id}/...``.
"""

from __future__ import annotations

import io
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from ._errors import SweepCancelled
from ._http import Http
from ._progress import Progress
from ._results import Answer
from ._tables import need

__all__ = ["DATA_FORMATS", "Sweep", "SweepPoints", "SweepStatus"]

#: Formats of GET /v1/sweeps/{id}/data, and the file suffix of each.
DATA_FORMATS = {"netcdf": ".nc", "csv": ".csv", "json": ".json"}


@dataclass(frozen=True, kw_only=True)
class SweepStatus(Answer):
    """Status of a sweep (GET /v1/sweeps/{id}): status 'queued' | 'running' | 'done' |
    'cancelled', progress n_done/n_total (n_failed of them failed), eta_s [s], ISO 8601
    timestamps, dims (name and length of each axis), the fixed values, perturbation,
    rtol and output; on submission ``created`` / ``resumed``, on cancel ``changed``;
    ``failures``: the first failed points."""

    id: str
    status: str
    n_done: int
    n_total: int
    n_failed: int = 0
    n_chunks: int | None = None
    eta_s: float | None = None
    created_at: str | None = None
    started_at: str | None = None
    finished_at: str | None = None
    mode: str | None = None
    dims: list[dict[str, Any]] = field(default_factory=list)
    output: str | None = None
    fixed: dict[str, Any] | None = None
    perturbation: str | None = None
    rtol: float | None = None
    created: bool | None = None
    resumed: bool | None = None
    changed: bool | None = None
    failures: list[dict[str, Any]] = field(default_factory=list)

    @property
    def finished(self) -> bool:
        """Done or cancelled (nothing more will be computed unless re-submitted)."""
        return self.status in ("done", "cancelled")


@dataclass(frozen=True, kw_only=True)
class SweepPoints(Answer):
    """One page of points (GET /v1/sweeps/{id}/points): ``points`` from ``offset``, each
    with idx, the swept values, computed, kind, critical_size, outcome, rel_accuracy,
    method, failed, error; ``next_offset`` (None on the last page)."""

    id: str
    status: str
    offset: int
    limit: int
    next_offset: int | None = None
    points: list[dict[str, Any]] = field(default_factory=list)

    def to_pandas(self) -> Any:
        """The page as a pandas.DataFrame (one row per point)."""
        return need("pandas").DataFrame(self.points)


def _subset(
    fmt: str, sel: str | None, isel: str | None, variables: str | list[str] | None
) -> dict[str, str]:
    params = {"format": fmt}
    if sel:
        params["sel"] = sel
    if isel:
        params["isel"] = isel
    if variables:
        params["variables"] = variables if isinstance(variables, str) else ",".join(variables)
    return params


class Sweep:
    """Handle of a submitted sweep.

    Attributes:
        id: the sweep id (32 hex); last: the last :class:`SweepStatus` seen.
    """

    def __init__(self, http: Http, sweep_id: str, status: SweepStatus | None = None) -> None:
        self._http, self.id = http, sweep_id
        self.last = status if status is not None else self.status()

    def __repr__(self) -> str:
        st = self.last
        return f"Sweep({self.id!r}, status={st.status!r}, {st.n_done}/{st.n_total})"

    @property
    def resumed(self) -> bool:
        """The submission resumed a cancelled sweep."""
        return bool(self.last.resumed)

    def _path(self, tail: str = "") -> str:
        return f"/v1/sweeps/{self.id}{tail}"

    def status(self) -> SweepStatus:
        """The current status (also kept as :attr:`last`)."""
        self.last = SweepStatus.from_json(self._http.json("GET", self._path()))
        return self.last

    def wait(
        self,
        progress: bool = False,
        poll: float = 0.5,
        timeout: float | None = None,
        on_status: Callable[[SweepStatus], None] | None = None,
    ) -> SweepStatus:
        """Poll until the sweep is done; returns the final status.

        Args:
            progress: show a progress bar on stderr (rich if installed, else a text line).
            poll: seconds between polls; timeout: give up after this many seconds
                (TimeoutError).
            on_status: called with every status seen.

        Raises :class:`SweepCancelled` if the sweep is (or gets) cancelled.
        """
        t0 = time.monotonic()
        bar = Progress(self.id) if progress else None
        try:
            while True:
                st = self.status()
                if on_status is not None:
                    on_status(st)
                if bar is not None:
                    bar.update(st)
                if st.status == "done":
                    return st
                if st.status == "cancelled":
                    raise SweepCancelled(
                        f"sweep {self.id} was cancelled ({st.n_done}/{st.n_total} points)"
                    )
                if timeout is not None and time.monotonic() - t0 > timeout:
                    raise TimeoutError(f"sweep {self.id} not done after {timeout} s")
                time.sleep(poll)
        finally:
            if bar is not None:
                bar.close()

    def spec(self) -> dict[str, Any]:
        """The stored spec (GET .../spec): axes, fixed values, perturbation, rtol, output."""
        return self._http.json("GET", self._path("/spec"))

    def points(self, offset: int = 0, limit: int = 1000) -> SweepPoints:
        """One page of points in flat-index order (C order over the axes); also while
        the sweep runs (points not computed yet have ``computed: false``)."""
        d = self._http.json("GET", self._path("/points"), params={"offset": offset, "limit": limit})
        return SweepPoints.from_json(d)

    def iter_points(self, limit: int = 1000) -> Iterator[dict[str, Any]]:
        """Every point, page by page."""
        offset: int | None = 0
        while offset is not None:
            page = self.points(offset, limit)
            yield from page.points
            offset = page.next_offset

    def data(
        self,
        format: str = "netcdf",  # noqa: A002
        sel: str | None = None,
        isel: str | None = None,
        variables: str | list[str] | None = None,
    ) -> bytes:
        """The result (GET .../data) as bytes: 'netcdf', 'csv' or 'json'; a subset cut on
        the server with ``sel`` (by value: 'eps:0.1:0.5,ba:2'), ``isel`` (by index:
        'vo:3', 'point:0:1000') and ``variables`` ('critical_size,kind' or a list)."""
        return self._http.request(
            "GET", self._path("/data"), params=_subset(format, sel, isel, variables)
        ).content

    def download(
        self,
        path: str | Path,
        format: str | None = None,  # noqa: A002
        progress: bool = False,
        sel: str | None = None,
        isel: str | None = None,
        variables: str | list[str] | None = None,
    ) -> Path:
        """Stream the result (or the subset ``sel``/``isel``/``variables``, as
        :meth:`data`) to ``path`` (format from the suffix: .nc, .csv, .json)."""
        p = Path(path)
        suffixes = {v: k for k, v in DATA_FORMATS.items()}
        fmt = format or suffixes.get(p.suffix.lower(), "netcdf")
        bar = Progress(f"{self.id} -> {p.name}", unit="bytes") if progress else None
        try:
            with (
                self._http.stream(
                    "GET", self._path("/data"), params=_subset(fmt, sel, isel, variables)
                ) as r,
                open(p, "wb") as fh,
            ):
                total = int(r.headers.get("content-length", 0)) or None
                n = 0
                for piece in r.iter_bytes():
                    fh.write(piece)
                    n += len(piece)
                    if bar is not None:
                        bar.update({"n_done": n, "n_total": total, "status": "downloading"})
        finally:
            if bar is not None:
                bar.close()
        return p

    def to_xarray(
        self,
        lazy: bool = False,
        sel: str | None = None,
        isel: str | None = None,
        variables: str | list[str] | None = None,
    ) -> Any:
        """The result as an ``xarray.Dataset``: grid axes as named coordinates, or a
        ``point`` dimension for scattered sweeps; variables critical_size, kind, outcome,
        rel_accuracy, failed, method, outcome_uncertain, computed (and the SI critical
        velocity of an SI sweep), with CF attributes.  Missing points (a running sweep)
        are NaN.

        ``lazy=False`` (default): the NetCDF file (or the subset ``sel``/``isel``/
        ``variables``, cut on the server) read into memory (needs xarray, h5netcdf).
        ``lazy=True``: opened from the sweep's Zarr store over HTTP (GET .../zarr/...):
        nothing but the metadata is read until a computation touches data, and then only
        the chunks it touches, e.g. ``ds.critical_size.sel(ba=2.0).mean().compute()``
        (needs xarray, zarr, fsspec, aiohttp: ``pip install 'rsf-stability[xarray]'``);
        ``sel``/``isel``/``variables`` do not apply (index the Dataset instead)."""
        xr = need("xarray")
        if lazy:
            need("zarr")
            need("fsspec")
            need("aiohttp")
            headers = {
                k: v for k, v in self._http.client.headers.items() if k.lower() == "authorization"
            }
            return xr.open_zarr(
                f"{self._http.base_url}{self._path('/zarr')}",
                storage_options={"headers": headers},
                consolidated=True,
                zarr_format=2,
            )
        need("h5netcdf")
        data = self.data("netcdf", sel, isel, variables)
        return xr.open_dataset(io.BytesIO(data), engine="h5netcdf").load()

    def to_pandas(self) -> Any:
        """The result as a pandas.DataFrame, one row per point (GET .../data?format=csv)."""
        pd = need("pandas")
        return pd.read_csv(io.BytesIO(self.data("csv")))

    def diagram(self, slice: str | None = None) -> dict[str, Any]:  # noqa: A002
        """A 2-D slice of a grid sweep laid out as a stability diagram (GET .../diagram):
        ``slice`` fixes the other axes, e.g. 'ba:2.0,vo:1' (nearest grid value)."""
        params = {} if slice is None else {"slice": slice}
        return self._http.json("GET", self._path("/diagram"), params=params)

    def diagram_png(self, slice: str | None = None) -> bytes:  # noqa: A002
        """The stability diagram of a 2-D slice as a PNG image."""
        params = {"format": "png", **({} if slice is None else {"slice": slice})}
        return self._http.request("GET", self._path("/diagram"), params=params).content

    def cancel(self) -> SweepStatus:
        """Cancel (DELETE); a second cancel changes nothing (``changed`` False)."""
        self.last = SweepStatus.from_json(self._http.json("DELETE", self._path()))
        return self.last

    def delete(self) -> None:
        """Delete the sweep and all its data (DELETE ?purge=true)."""
        self._http.request("DELETE", self._path(), params={"purge": "true"})
