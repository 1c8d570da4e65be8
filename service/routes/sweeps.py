"""Sweep endpoints: submit (202 + Location), list, status, spec, points (paged), the whole
result (NetCDF, CSV or JSON, streamed), a 2-D diagram slice (JSON or PNG), cancel and
delete.

A sweep is an N-D grid (1-5 ``axes``), scattered ``points`` or the 2-D ``x``/``y`` form
(:mod:`rsfapp.requests.sweeps`).  Its id is derived from its canonical spec and the
numerics version, so submitting the same sweep twice returns the same sweep.

Lifecycle:

* ``POST`` of a new sweep: 202, ``created: true``; of a running or queued one: 202,
  ``created: false``; of a finished one: 200 with ``X-Cache: hit``; of a cancelled one:
  it is **resumed** (its unfinished chunks are queued again), 202 with ``resumed: true``;
* ``DELETE /v1/sweeps/{id}`` cancels an active sweep (chunks not started are dropped, a
  running chunk finishes: work stops within one chunk per worker process); on a sweep
  that is already cancelled or done it changes nothing (``changed: false``);
* ``DELETE /v1/sweeps/{id}?purge=true`` deletes the sweep with all its data (cancelling
  it first if active): 204.

Timestamps are ISO 8601 UTC.  Status polls are small (no axis values: ``GET .../spec``
has them).
"""

from __future__ import annotations

import contextlib
import json
import logging
import os
import tempfile
from collections.abc import Iterator
from typing import Annotated, Any

import numpy as np
from fastapi import APIRouter, Path, Query
from starlette.concurrency import run_in_threadpool
from starlette.responses import Response

from rsfapp import sweepdata, sweepselect
from rsfapp.adapter import numerics_version
from rsfapp.grid import SweepSpec, expand, plan_chunks
from rsfapp.keys import cache_key
from rsfapp.memory import give_back
from rsfapp.queue import Queue
from rsfapp.requests import SweepRequest
from rsfapp.store import SweepStore
from rsfcore.critical import KINDS, METHODS

from .. import downloads, images
from ..auth import PrincipalDep, admit_sweep, check_owner, sweep_submitted
from ..deps import QueueDep, SettingsDep, StoresDep
from ..downloads import Busy, DownloadKind, SlotStream
from ..errors import ProblemError, unavailable
from ..images import choice, format_query, image, image_response, png_content

router = APIRouter(prefix="/v1/sweeps", tags=["sweeps"])
log = logging.getLogger("rsf.service")
SweepId = Annotated[str, Path(pattern=r"^[0-9a-f]{32}$", description="Sweep id (32 hex).")]
_R: dict[int | str, dict[str, Any]] = {
    422: {"description": "Invalid input (problem+json naming the field and its range)."}
}
_N: dict[int | str, dict[str, Any]] = {404: {"description": "Unknown sweep (problem+json)."}}


def _json(obj: object, status: int = 200, headers: dict[str, str] | None = None) -> Response:
    return Response(
        json.dumps(obj), status_code=status, media_type="application/json", headers=headers
    )


def _unknown(sweep_id: str) -> ProblemError:
    return ProblemError(404, "Not found", f"no sweep with id {sweep_id}")


def _enqueue(queue: Queue, sweep_id: str, chunk_ids: list[int]) -> str | None:
    try:
        for c in chunk_ids:
            queue.send_chunk(sweep_id, c)
    except Exception as exc:  # noqa: BLE001 - chunks stay queued; a worker start requeues
        log.exception("could not enqueue sweep %s", sweep_id)
        return (
            f"broker unavailable ({type(exc).__name__}); queued chunks are sent when "
            "a worker starts"
        )
    return None


async def _spec(stores: Any, sweep_id: str) -> SweepSpec:
    """The spec of an existing sweep; 410 for a sweep stored in the pre-array layout."""
    spec = await run_in_threadpool(stores.sweeps.get_spec, sweep_id)
    if spec is None:
        raise ProblemError(
            410,
            "Gone",
            f"sweep {sweep_id} was stored in the layout before "
            "N-D sweeps; submit it again to compute it with this version",
        )
    return spec  # type: ignore[no-any-return]


def _failures(
    sweeps: SweepStore, spec: SweepSpec | None, sweep_id: str, limit: int = 100
) -> list[dict[str, Any]]:
    out: list[dict[str, Any]] = []
    for idx, msg in sweeps.failures(sweep_id, limit):
        f: dict[str, Any] = {"idx": idx}
        if spec is not None:
            if spec.mode == "grid":
                f["index"] = [int(k) for k in np.unravel_index(idx, spec.shape)]
            f["params"] = {k: float(v[0]) for k, v in spec.swept_values(idx, idx + 1).items()}
        f["error"] = msg
        out.append(f)
    return out


@router.post(
    "",
    status_code=202,
    responses={**_R, 200: {"description": "Already done."}},
    summary="Submit a sweep",
)
async def submit(
    req: SweepRequest, stores: StoresDep, queue: QueueDep, s: SettingsDep, who: PrincipalDep
) -> Response:
    """Start a sweep: an N-D grid (``axes``: 1-5 of ba, kappa or kappa_ratio, eps, vo,
    size (or its SI form); each ``{name, values}`` or ``{name, start, stop, n, log}``),
    scattered ``points`` (equal-length arrays per parameter) or the 2-D ``x``/``y`` form,
    with ``fixed`` values for the rest: dimensionless, or the machine in SI as
    ``fixed.physical`` {a, b, Dc_m, sigma_Pa, k_Pa_per_m, V_star_m_s, V_load_m_s} (sets
    ba, kappa, vo; then only eps and the size may be swept; the data, CSV and points then
    carry SI scales and the critical slip rate or load-point velocity in m/s).  With
    ``fixed.physical`` the perturbation size may be given in SI as the single queries do,
    fixed (``fixed.factor``, ``fixed.new_slip_rate_m_s``,
    ``fixed.new_load_point_velocity_m_s``) or swept (an axis or points array of that
    name), converted once by rsfcore.units; a size given both ways, twice, in SI without
    ``fixed.physical``, or in the unit of the other perturbation kind is a 422 naming the
    field.  Per point: the critical size (kind, critical_size, rel_accuracy) or, when a
    size is fixed or swept, the outcome.  Up to
    RSF_SWEEP_MAX_POINTS points (default 1e8), chunked lazily.

    Answers 202 with a ``Location`` to poll; ``created`` (new sweep) and ``resumed`` (a
    cancelled sweep started again) say what happened.  A finished sweep answers 200 with
    ``X-Cache: hit``.  Invalid input: 422 problem+json naming the field (``axes[2].stop``,
    ``points.eps[17]``), nothing written."""
    sweeps = stores.sweeps
    spec = await run_in_threadpool(expand, req, s.sweep_max_points, s.sweep_max_scattered)
    version = numerics_version()
    sweep_id = cache_key("sweep", spec.to_json(), version)[:32]
    chunk = plan_chunks(spec, s, req.chunk_points)
    reserved = await admit_sweep(who, stores, sweep_id, spec.n_total)  # key quotas (429)
    created = await run_in_threadpool(
        sweeps.create, sweep_id, spec, chunk, version, s.sweep_window, s.lease_s
    )
    await sweep_submitted(who, stores, sweep_id, created.created or created.resumed, reserved)
    todo = created.todo
    warning = await run_in_threadpool(_enqueue, queue, sweep_id, todo) if todo else None
    st = await run_in_threadpool(sweeps.status, sweep_id)
    if st is None:  # pragma: no cover - created just above
        raise _unknown(sweep_id)
    st.update(created=created.created, resumed=created.resumed)
    if warning:
        st["warning"] = warning
    headers = {"Location": f"/v1/sweeps/{sweep_id}"}
    if st["status"] == "done":
        headers["X-Cache"] = "hit"
        return _json(st, 200, headers)
    if created.created:
        headers["X-Cache"] = "miss"
    return _json(st, 202, headers)


@router.get("", summary="List sweeps")
async def list_all(
    stores: StoresDep,
    limit: Annotated[int, Query(ge=1, le=1000)] = 100,
    offset: Annotated[int, Query(ge=0, le=10**9)] = 0,
) -> Response:
    """Sweeps, newest first, with status and progress (as the status endpoint, without
    failures)."""
    return _json({"sweeps": await run_in_threadpool(stores.sweeps.list_sweeps, limit, offset)})


async def _status(stores: Any, sweep_id: str) -> dict[str, Any]:
    st = await run_in_threadpool(stores.sweeps.status, sweep_id)
    if st is None:
        raise _unknown(sweep_id)
    return dict(st)


@router.get("/{sweep_id}", responses=_N, summary="Sweep status")
async def get_status(sweep_id: SweepId, stores: StoresDep) -> Response:
    """status (queued|running|done|cancelled), n_done, n_total, n_failed, eta_s [s],
    created_at/started_at/finished_at (ISO 8601 UTC), dims (names and lengths, no values),
    fixed, output, and ``failures``: the first 100 failed points {idx, index, params,
    error}."""
    st = await _status(stores, sweep_id)
    spec = await run_in_threadpool(stores.sweeps.get_spec, sweep_id)
    st["failures"] = await run_in_threadpool(_failures, stores.sweeps, spec, sweep_id)
    return _json(st)


@router.get("/{sweep_id}/spec", responses=_N, summary="Sweep spec")
async def get_spec(sweep_id: SweepId, stores: StoresDep) -> Response:
    """The stored spec: axes (``start/stop/n/log`` or explicit ``values``), fixed values,
    perturbation, rtol, output; scattered sweeps give their parameter names and digest
    (the points themselves are in ``/data``)."""
    await _status(stores, sweep_id)
    spec = await _spec(stores, sweep_id)
    return _json(spec.to_json())


@router.get("/{sweep_id}/points", responses=_N, summary="Sweep points (paged)")
async def get_points(
    sweep_id: SweepId,
    stores: StoresDep,
    offset: Annotated[int, Query(ge=0, le=10**9)] = 0,
    limit: Annotated[int, Query(ge=1, le=10_000)] = 1000,
) -> Response:
    """Points ``offset`` .. ``offset + limit - 1`` in flat-index order (C order over the
    axes), available while running.  Each point: idx, index (grid), the swept parameter
    values, computed, kind, critical_size (null if infinite or missing), outcome,
    rel_accuracy, method, failed, error.  A sweep in SI (``fixed.physical``) also gives,
    after critical_size, ``critical_slip_rate_m_s`` (velocity jump) or
    ``critical_load_point_velocity_m_s`` (load-point jump) in m/s (null if infinite or
    missing; the NetCDF variable of the same name), and when its size is swept in SI
    (``factor``, ``new_slip_rate_m_s``, ``new_load_point_velocity_m_s``) the dimensionless
    ``size`` of each point."""
    st = await _status(stores, sweep_id)
    spec = await _spec(stores, sweep_id)
    i0, i1 = min(offset, spec.n_total), min(offset + limit, spec.n_total)

    size_col, si_col = sweepdata.si_names(spec)
    phys = spec.physical_inputs()

    def page() -> list[dict[str, Any]]:
        vals = spec.swept_values(i0, i1)
        sizes = sweepdata.si_sizes(spec, vals)
        pts: list[dict[str, Any]] = []
        for k in range(i0, i1):
            p: dict[str, Any] = {"idx": k}
            if spec.mode == "grid":
                p["index"] = [int(v) for v in np.unravel_index(k, spec.shape)]
            p.update({n: float(v[k - i0]) for n, v in vals.items()})
            if size_col and sizes is not None:
                p[size_col] = float(sizes[k - i0])
            p.update(computed=False, kind=None, critical_size=None)
            if si_col:
                p[si_col] = None
            p.update(
                outcome=None,
                rel_accuracy=None,
                method=None,
                failed=None,
                error=None,
            )
            pts.append(p)
        for b in stores.sweeps.blocks(sweep_id, i0, i1):
            lo, hi = max(b.i0, i0), min(b.i1, i1)
            si = (
                sweepdata.critical_si(
                    phys, spec.perturbation, b.arrays["critical_size"][lo - b.i0 : hi - b.i0]
                )
                if phys is not None and si_col and hi > lo
                else None
            )
            for k in range(lo, hi):
                o = k - b.i0
                a = b.arrays
                if si is not None and si_col:
                    v = float(si[k - lo])
                    pts[k - i0][si_col] = v if np.isfinite(v) else None
                kd = int(a["kind"][o])
                oc = int(a["outcome"][o]) if "outcome" in a else -1
                cs, ra = float(a["critical_size"][o]), float(a["rel_accuracy"][o])
                pts[k - i0].update(
                    computed=True,
                    kind=KINDS[kd] if kd >= 0 else None,
                    critical_size=cs if np.isfinite(cs) else None,
                    outcome=("stable", "unstable")[oc] if oc >= 0 else None,
                    rel_accuracy=ra if np.isfinite(ra) else None,
                    method=METHODS[int(a["method"][o])] if a["method"][o] >= 0 else None,
                    failed=bool(a["failed"][o]),
                    error=b.errors.get(o),
                )
        return pts

    pts = await run_in_threadpool(page)
    nxt = i1 if i1 < spec.n_total else None
    return _json(
        {
            "id": sweep_id,
            "status": st["status"],
            "n_done": st["n_done"],
            "n_total": st["n_total"],
            "offset": offset,
            "limit": limit,
            "next_offset": nxt,
            "points": pts,
        }
    )


_DATA_FORMATS = ("netcdf", "csv", "json")

_SEL_DOC = (
    "Subset by coordinate value, comma-separated <dim>:<value> (nearest) or "
    "<dim>:<lo>:<hi> (lo <= value <= hi), e.g. 'eps:0.1:0.5,ba:2'. Dimensions: the grid "
    "axes, or 'point' for scattered sweeps. A dimension kept at one value stays with "
    "length 1. Valid range: each dimension at most once in sel and isel together."
)
_ISEL_DOC = (
    "Subset by index, comma-separated <dim>:<i> or <dim>:<start>:<stop>[:<step>] (0-based, "
    "Python slice rules, negative from the end), e.g. 'vo:3' or 'point:0:1000'. Valid "
    "range: indices within the dimension, step >= 1, a non-empty result."
)
_VARS_DOC = (
    "Comma-separated result variables to send (default all): critical_size, kind, "
    "outcome, rel_accuracy, failed, method, outcome_uncertain, computed, and for a sweep "
    "in SI its critical_slip_rate_m_s or critical_load_point_velocity_m_s."
)
SelQuery = Annotated[str | None, Query(description=_SEL_DOC, max_length=2000)]
IselQuery = Annotated[str | None, Query(description=_ISEL_DOC, max_length=2000)]
VarsQuery = Annotated[str | None, Query(description=_VARS_DOC, max_length=1000)]


def _busy(exc: Busy) -> Response:
    return unavailable(
        "Too many downloads",
        exc.reason,
        "retry after Retry-After seconds, or ask for a subset (sel, isel, variables)"
        + (
            "; CSV, JSON and the Zarr store stream without a build"
            if exc.limit is DownloadKind.NETCDF
            else ""
        ),
        exc.retry_after_s,
    )


@router.get(
    "/{sweep_id}/data",
    summary="Sweep result or a subset of it (NetCDF, CSV or JSON)",
    responses={
        **_N,
        200: {
            "description": "The result (or the selected subset), also while running "
            "(missing points are fill values / empty).",
            "content": {"application/x-netcdf": {}, "text/csv": {}, "application/json": {}},
        },
        422: {"description": "Invalid format, sel, isel or variables (problem+json)."},
        503: {
            "description": "Too many downloads at once on this API process, or a NetCDF "
            "file being built (problem+json, Retry-After)."
        },
    },
)
async def get_data(
    sweep_id: SweepId,
    stores: StoresDep,
    format: Annotated[
        str,
        format_query(  # noqa: A002
            _DATA_FORMATS,
            "netcdf",
            "'netcdf': a NetCDF-4 file with CF-1.10 metadata, compressed (xarray.open_dataset "
            "opens it with h5netcdf or netCDF4; grid axes as named coordinates, scattered "
            "sweeps on a 'point' dimension); 'csv': one row per point with a header; "
            "'json': flat arrays.",
        ),
    ] = "netcdf",
    sel: SelQuery = None,
    isel: IselQuery = None,
    variables: VarsQuery = None,
) -> Response:
    """The whole result or a subset (``sel``, ``isel``: by coordinate value or index
    range on any dimension; ``variables``), streamed in bounded memory, also while the
    sweep runs (points not computed yet are NaN / -1 / empty).  Variables per point:
    ``critical_size`` (0 zero, inf infinite), ``kind`` (0 zero, 1 finite, 2 infinite,
    -1 missing/failed), ``outcome`` (0 stable, 1 unstable, -1 missing or no size asked),
    ``rel_accuracy``, ``failed``, ``method`` (index into rsfcore.critical.METHODS),
    ``outcome_uncertain``, ``computed``; a sweep in SI also ``critical_slip_rate_m_s``
    or ``critical_load_point_velocity_m_s`` [m/s] (NetCDF variable, CSV column after
    critical_size, JSON data), and with its size swept in SI the dimensionless ``size``
    (NetCDF, CSV).  Example: ``?format=netcdf&sel=eps:0.1:0.5&isel=vo:3&variables=
    critical_size,kind``.  Headers ``X-Sweep-Status``, ``X-Sweep-Progress:
    n_done/n_total`` and ``X-Sweep-Selection`` (points selected).  The NetCDF file is
    written to a temporary file first (HDF5 places its index after the data: the time
    to first byte grows with the selection); CSV and JSON start at once.  Per API
    process at most 2 downloads at once and 1 NetCDF file being built
    (service.downloads); one more is answered 503 with Retry-After (for a build: its
    estimated time left)."""
    fmt = choice(format, _DATA_FORMATS, "format")
    st = await _status(stores, sweep_id)
    spec = await _spec(stores, sweep_id)
    selection = sweepselect.parse_selection(
        spec, sel, isel, variables, sweepdata.netcdf_variables(spec)
    )
    h = {
        "X-Sweep-Status": st["status"],
        "X-Sweep-Progress": f"{st['n_done']}/{st['n_total']}",
        "X-Sweep-Selection": str(selection.n),
        "Content-Disposition": f'attachment; filename="sweep-{sweep_id}.'
        f'{ {"netcdf": "nc"}.get(fmt, fmt) }"',
    }
    kind = DownloadKind.NETCDF if fmt == "netcdf" else DownloadKind.STREAM
    try:
        slot = downloads.SLOTS.admit(kind)
    except Busy as exc:
        return _busy(exc)
    try:
        if fmt == "csv":
            pieces: Iterator[Any] = sweepdata.csv_rows(stores.sweeps, spec, sweep_id, selection)
            return SlotStream(pieces, slot, media_type="text/csv", headers=h)
        if fmt == "json":
            fails = await run_in_threadpool(stores.sweeps.failures, sweep_id, 100)
            pieces = sweepdata.json_chunks(stores.sweeps, spec, st, selection, fails)
            return SlotStream(pieces, slot, media_type="application/json", headers=h)
        fd, path = tempfile.mkstemp(prefix=f"rsf-sweep-{sweep_id}-", suffix=".nc")
        os.close(fd)
        query = "&".join(
            f"{k}={v}" for k, v in (("sel", sel), ("isel", isel), ("variables", variables)) if v
        )
        how = f"GET /v1/sweeps/{sweep_id}/data?format=netcdf{'&' + query if query else ''}"
        try:
            await run_in_threadpool(
                sweepdata.write_netcdf,
                stores.sweeps,
                spec,
                st,
                selection,
                path,
                how,
                slot.progress,
            )
            h["Content-Length"] = str(os.path.getsize(path))
        except BaseException:
            os.unlink(path)
            raise
        return SlotStream(
            sweepdata.file_pieces(path),
            slot,
            media_type="application/x-netcdf",
            headers=h,
            finally_=lambda: _unlink(path),
        )
    except BaseException:
        slot.release()
        give_back()
        raise


def _unlink(path: str) -> None:
    with contextlib.suppress(OSError):
        os.unlink(path)


ZarrKey = Annotated[
    str,
    Path(
        pattern=r"^[A-Za-z0-9_.]{1,64}$",
        description="A Zarr key part: .zmetadata, .zgroup, .zattrs, .zarray or a chunk "
        "index like 0.3.1.",
    ),
]
_ZARR_RESPONSES: dict[int | str, dict[str, Any]] = {
    **_N,
    200: {
        "description": "A Zarr (format 2) key: JSON metadata (.zmetadata, .zgroup, "
        ".zattrs, <var>/.zarray, <var>/.zattrs) or a zlib-compressed chunk.",
        "content": {"application/json": {}, "application/octet-stream": {}},
    },
}


async def _zarr(stores: Any, sweep_id: str, key: str) -> Response:
    from rsfapp.sweepzarr import ZarrSweep

    if await run_in_threadpool(stores.sweeps.get_spec, sweep_id) is None:
        await _status(stores, sweep_id)  # 404 if unknown
    spec = await _spec(stores, sweep_id)  # 410 if stored in the pre-array layout
    tail = key.rpartition("/")[2]
    meta_key = not tail[:1].isdigit()
    st = await _status(stores, sweep_id) if meta_key else {"id": sweep_id}
    k = await run_in_threadpool(stores.sweeps.block_points, sweep_id)
    z = ZarrSweep(stores.sweeps, spec, st, k or spec.n_total)
    if meta_key:
        data = await run_in_threadpool(z.get, key)
    else:  # a chunk: a few at a time (bounded memory)
        data = await run_in_threadpool(downloads.zarr_chunk, z.get, key)
    if data is None:
        raise ProblemError(404, "Not found", f"sweep {sweep_id} has no Zarr key {key!r}")
    media = "application/json" if meta_key else "application/octet-stream"
    return Response(data, media_type=media, headers={"Cache-Control": "no-cache"})


@router.get(
    "/{sweep_id}/zarr/{key}",
    summary="The sweep as a read-only Zarr store: group metadata",
    responses=_ZARR_RESPONSES,
)
async def get_zarr_group(sweep_id: SweepId, key: ZarrKey, stores: StoresDep) -> Response:
    """The sweep as a read-only Zarr store, for lazy access from xarray: only the
    chunks a computation touches are fetched, each one stored block where the sweep's
    chunking allows (rsfapp.sweepzarr).  Open it in a notebook with
    ``xr.open_zarr("<url>/v1/sweeps/<id>/zarr", storage_options={"headers":
    {"Authorization": "Bearer <key>"}}, consolidated=True, zarr_format=2)`` (needs zarr,
    fsspec and aiohttp), or ``rsfclient`` ``sweep.to_xarray(lazy=True)``.  Points not
    computed yet (a running sweep) are fill values (NaN after decoding).  Group keys:
    ``.zmetadata`` (consolidated metadata), ``.zgroup``, ``.zattrs``; array keys are
    ``<var>/...`` (next route); any other key is 404."""
    return await _zarr(stores, sweep_id, key)


@router.get(
    "/{sweep_id}/zarr/{var}/{key}",
    summary="The sweep as a read-only Zarr store: array metadata and chunks",
    responses=_ZARR_RESPONSES,
)
async def get_zarr_array(
    sweep_id: SweepId, var: ZarrKey, key: ZarrKey, stores: StoresDep
) -> Response:
    """One array of the sweep's Zarr store: ``<var>/.zarray``, ``<var>/.zattrs`` or the
    chunk ``<var>/<i>.<j>...`` (C-order bytes, zlib; points not computed yet are the
    array's fill value).  Arrays: the dimensions (grid axes or ``point``), the result
    variables, and the swept parameters of a scattered sweep; any other key is 404."""
    return await _zarr(stores, sweep_id, f"{var}/{key}")


_JSON_OR_PNG = ("json", "png")
#: Most points per axis drawn in a diagram PNG (the image is 650 x 500 pixels): a longer
#: axis is drawn every k-th point (header ``X-Diagram-Step: <axis>:<k>``), so an image
#: never draws more than 600^2 points (measured: a slice of 100 x 10^4 points drawn
#: whole +220 MB and 12 s, thinned to 100 x 1000 +58 MB and 6 s).
PNG_AXIS_POINTS = 600
#: A JSON diagram of more points than this takes a download place (service.downloads:
#: ~100 bytes of Python objects a point, +95 MB measured for 10^6 points).
DIAGRAM_FREE_POINTS = 1 << 18


@router.get(
    "/{sweep_id}/diagram",
    summary="Stability diagram of a 2-D slice (JSON or PNG)",
    responses={
        **_N,
        **png_content(
            "The sweep (or a 2-D slice of it) on its grid (JSON), or with format=png "
            "the stability diagram image (critical size, or stable/unstable when a "
            "size is given).",
            {
                422: {"description": "Invalid format or slice (problem+json naming the field)."},
                503: {
                    "description": "A large JSON diagram while every download place of this "
                    "API process is taken (problem+json, Retry-After)."
                },
            },
        ),
    },
)
async def get_diagram(
    sweep_id: SweepId,
    stores: StoresDep,
    format: Annotated[
        str,
        format_query(  # noqa: A002
            _JSON_OR_PNG, "json", "'png': the stability diagram image."
        ),
    ] = "json",
    slice: Annotated[
        str | None,
        Query(  # noqa: A002
            description="Values of all but two grid axes, e.g. "
            "'ba:2.0' or 'ba:2.0,vo:1' (nearest grid value). Valid range: "
            "comma-separated <axis>:<number>; not needed for a 2-D grid.",
            max_length=500,
        ),
    ] = None,
    sel: SelQuery = None,
    isel: IselQuery = None,
) -> Response:
    """A finished or partial grid sweep as a stability diagram over two of its axes (the
    others fixed by ``slice``), laid out like ``rsfcore.diagram.DiagramResult.to_dict()``:
    ``critical_size[i][j]`` at (x[i], y[j]) (null where infinite or not yet computed),
    ``kind`` 0 zero / 1 finite / 2 infinite, ``outcome`` 0 stable / 1 unstable when the
    sweep classifies a size, ``present[i][j]`` (computed without error), ``slice`` (the
    values of the other axes), with status, n_done, n_total, n_failed.  ``sel``/``isel``
    (as for ``/data``) narrow the two free axes to a window (zoom); only the slice is
    read.  ``?format=png``:
    the image, points not computed yet (or failed) left blank; headers
    ``X-Sweep-Status`` and ``X-Sweep-Progress: n_done/n_total``; an axis of more than
    600 points is drawn every k-th point (``X-Diagram-Step: <axis>:<k>``: no more
    points than pixels).  Images of finished sweeps are cached.  A JSON diagram of more
    than 2^18 points takes one of the API process's download places (503 with
    Retry-After when none is free)."""
    fmt = choice(format, _JSON_OR_PNG, "format")
    st = await _status(stores, sweep_id)
    spec = await _spec(stores, sweep_id)
    fixed_idx = sweepdata.parse_slice(spec, slice)
    window = sweepselect.parse_selection(spec, sel, isel) if sel or isel else None
    steps: dict[str, int] = {}
    if fmt == "png":  # no more points per axis than the image has pixels
        free = [a.name for a in spec.axes if a.name not in fixed_idx]
        thin = sweepselect.thinned(
            window or sweepselect.parse_selection(spec), free, PNG_AXIS_POINTS
        )
        if thin is not None:
            window, steps = thin
    if fmt == "json":
        n = 1
        for a, idx in zip(
            spec.axes, (window or sweepselect.parse_selection(spec)).index, strict=True
        ):
            n *= 1 if a.name in fixed_idx else len(idx)
        try:
            slot = downloads.SLOTS.admit(DownloadKind.STREAM) if n > DIAGRAM_FREE_POINTS else None
        except Busy as exc:
            return _busy(exc)
        try:
            d = await run_in_threadpool(
                sweepdata.diagram, stores.sweeps, spec, st, fixed_idx, window
            )
            return await run_in_threadpool(_json, d)
        finally:
            if slot is not None:
                slot.release()
                give_back()
    d = await run_in_threadpool(sweepdata.diagram, stores.sweeps, spec, st, fixed_idx, window)
    final = d["status"] in ("done", "cancelled")
    tag = "-".join(f"{k}{v}" for k, v in sorted(fixed_idx.items()))
    if window is not None:
        tag += "-" + cache_key("window", window.to_json(), "")[:12]
    key = f"sweep-{sweep_id}-{tag}-{d['status']}-{d['n_done']}-{d['n_failed']}.png"
    data, hit = await image(key, lambda: images.diagram_png(d), store=final)
    return image_response(
        data,
        "png",
        hit,
        final=final,
        headers={
            "X-Sweep-Status": d["status"],
            "X-Sweep-Progress": f"{d['n_done']}/{d['n_total']}",
            **({"X-Diagram-Step": ",".join(f"{k}:{v}" for k, v in steps.items())} if steps else {}),
        },
    )


@router.delete(
    "/{sweep_id}",
    responses={**_N, 204: {"description": "Deleted (purge)."}},
    summary="Cancel a sweep, or delete it with ?purge=true",
)
async def cancel(
    sweep_id: SweepId,
    stores: StoresDep,
    who: PrincipalDep,
    purge: Annotated[
        bool,
        Query(
            description="Delete the sweep and all its "
            "data (cancelling it first if active). "
            "Valid range: true or false."
        ),
    ] = False,
) -> Response:
    """Without ``purge``: cancel an active sweep (chunks not started are dropped; a
    running chunk finishes, so work stops within one chunk per worker process).  On a
    sweep already cancelled or done nothing changes (``changed: false``).  Re-submitting
    a cancelled sweep resumes it.  With ``purge=true``: delete the sweep, its chunks and
    results; 204."""
    await check_owner(who, stores, sweep_id)  # other keys' sweeps: admin only (403)
    res = await run_in_threadpool(stores.sweeps.cancel, sweep_id)
    if res is None:
        raise _unknown(sweep_id)
    if purge:
        await run_in_threadpool(stores.sweeps.delete, sweep_id)
        return Response(status_code=204)
    st = await _status(stores, sweep_id)
    st["changed"] = res[1]
    return _json(st)
