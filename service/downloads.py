"""Sweep downloads in bounded memory: per-process admission and streams that always end.

A download of a sweep (``GET /v1/sweeps/{id}/data``) holds about one slab of the
selection at a time (:data:`rsfapp.sweepselect.SLAB_POINTS` points), whatever the
sweep's size; measured on a 10^8-point sweep (bench/bench_sweep_e2e.py, README): +70 MB
over the API's idle size for a NetCDF file being built (h5py loaded at first use, a slab,
a stored block decoded beside it, one chunk compressed), +62 MB for CSV, +54 MB for
JSON; two NetCDF builds at once were +292 MB.
So that the API process's resident memory stays within ~256 MB of its idle size, each
API process admits at most

* :data:`DOWNLOADS_AT_ONCE` downloads at once, of any format (and JSON diagrams of more
  than ``DIAGRAM_FREE_POINTS`` points, service.routes.sweeps), and
* :data:`NETCDF_BUILDS_AT_ONCE` NetCDF file being built at once (the heaviest),

and answers one more with 503 problem+json and ``Retry-After`` (for a NetCDF build: the
estimated time left of the build in progress, from its progress so far), with a hint to
ask for a subset or a streamed format; the Python client retries such a 503 after
Retry-After.  It makes at most :data:`ZARR_CHUNKS_AT_ONCE` chunks of the Zarr store at
once (a lazy xarray read asks for many chunks side by side, each up to one stored block,
~30 MB while made; more wait their turn, a chunk takes milliseconds).

:class:`SlotStream` is the response of an admitted download: it sends the pieces of a
synchronous iterator, each made in the thread pool, and however the response ends (sent,
failed, or the client gone) it closes the iterator once the piece being made is done,
gives the slot back and returns the freed memory to the system
(:func:`rsfapp.memory.give_back`).  Starlette's own StreamingResponse leaves an abandoned
iterator suspended until the garbage collector happens to find it: measured before this
module, a CSV download abandoned by its client kept its last slab of text (+60-80 MB)
and its slot until the next download.
"""

from __future__ import annotations

import math
import threading
import time
from collections.abc import AsyncIterator, Callable, Iterator
from enum import StrEnum
from typing import Any

import anyio
from starlette.responses import StreamingResponse
from starlette.types import Receive, Scope, Send

from rsfapp.memory import give_back

__all__ = [
    "ZARR_CHUNKS_AT_ONCE",
    "zarr_chunk",
    "DOWNLOADS_AT_ONCE",
    "NETCDF_BUILDS_AT_ONCE",
    "Busy",
    "DownloadKind",
    "DownloadSlots",
    "Slot",
    "SlotStream",
    "SLOTS",
]

#: Downloads (``/data``, any format) served at once by one API process.
DOWNLOADS_AT_ONCE = 2
#: NetCDF files built at once by one API process (each holds up to ~95 MB while built).
NETCDF_BUILDS_AT_ONCE = 1
#: Zarr chunks made at once by one API process (each holds up to ~4 arrays of one block).
ZARR_CHUNKS_AT_ONCE = 4
_zarr_chunks = threading.BoundedSemaphore(ZARR_CHUNKS_AT_ONCE)
#: Longest Retry-After given for a NetCDF build in progress [s].
RETRY_AFTER_MAX_S = 300


class DownloadKind(StrEnum):
    """What a download does: stream as it reads (CSV, JSON) or build a file first."""

    STREAM = "stream"
    NETCDF = "netcdf"


class Busy(Exception):
    """No place free: ``reason`` (one sentence), ``retry_after_s`` [s] for the 503 (None:
    no estimate) and ``limit``: which limit was reached (NETCDF: the builds)."""

    def __init__(self, reason: str, retry_after_s: int | None, limit: DownloadKind) -> None:
        super().__init__(reason)
        self.reason, self.retry_after_s, self.limit = reason, retry_after_s, limit


class Slot:
    """An admitted download: holds its place until :meth:`release` (idempotent).  A
    NetCDF build reports its progress with :meth:`progress` (done, total points)."""

    def __init__(self, owner: DownloadSlots, kind: DownloadKind) -> None:
        self._owner, self.kind = owner, kind
        self.started = time.monotonic()
        self._built: float | None = None if kind is DownloadKind.NETCDF else 1.0
        self._fraction = 0.0
        self._released = False
        self._lock = threading.Lock()

    def progress(self, done: int, total: int) -> None:
        """The build has written ``done`` of ``total`` points."""
        self._fraction = done / total if total > 0 else 1.0
        if done >= total and self._built is None:
            self._built = time.monotonic()
            self._owner._build_finished(self)

    def seconds_left(self) -> float | None:
        """Estimated seconds until the build ends (None: no estimate yet)."""
        if self._built is not None:
            return 0.0
        f = self._fraction
        if f <= 0.0:
            return None
        return (time.monotonic() - self.started) * (1.0 - f) / f

    def release(self) -> None:
        """Give the place back (a second call does nothing)."""
        with self._lock:
            if self._released:
                return
            self._released = True
        self._owner._release(self)


class DownloadSlots:
    """The download places of one API process (module docstring)."""

    def __init__(
        self, downloads: int = DOWNLOADS_AT_ONCE, builds: int = NETCDF_BUILDS_AT_ONCE
    ) -> None:
        if downloads < 1 or builds < 1:
            raise ValueError("downloads and builds must be >= 1")
        self.downloads, self.builds = downloads, builds
        self._lock = threading.Lock()
        self._active: list[Slot] = []
        self._building: list[Slot] = []

    @property
    def in_use(self) -> int:
        """Downloads admitted and not yet released."""
        with self._lock:
            return len(self._active)

    def admit(self, kind: DownloadKind) -> Slot:
        """A place for a download of ``kind``, or :class:`Busy` (never waits)."""
        with self._lock:
            if len(self._active) >= self.downloads:
                raise Busy(
                    f"{self.downloads} sweep downloads are being served by this API process",
                    None,
                    DownloadKind.STREAM,
                )
            if kind is DownloadKind.NETCDF and len(self._building) >= self.builds:
                left = [s.seconds_left() for s in self._building]
                est = min((x for x in left if x is not None), default=None)
                after = None if est is None else max(1, min(RETRY_AFTER_MAX_S, math.ceil(est + 1)))
                raise Busy(
                    f"{self.builds} NetCDF file{'s are' if self.builds > 1 else ' is'} being "
                    "built by this API process (a NetCDF file is written whole before it is "
                    "sent; one build at a time keeps the memory bounded)",
                    after,
                    DownloadKind.NETCDF,
                )
            slot = Slot(self, kind)
            self._active.append(slot)
            if kind is DownloadKind.NETCDF:
                self._building.append(slot)
            return slot

    def _build_finished(self, slot: Slot) -> None:
        with self._lock:
            if slot in self._building:
                self._building.remove(slot)

    def _release(self, slot: Slot) -> None:
        with self._lock:
            if slot in self._building:
                self._building.remove(slot)
            if slot in self._active:
                self._active.remove(slot)


#: The places of this process.
SLOTS = DownloadSlots()


def zarr_chunk(make: Callable[[str], bytes | None], key: str) -> bytes | None:
    """``make(key)`` once fewer than :data:`ZARR_CHUNKS_AT_ONCE` chunks are being made
    (blocks the calling worker thread until then)."""
    with _zarr_chunks:
        return make(key)


_END = object()


class SlotStream(StreamingResponse):
    """Streams ``pieces`` (a synchronous iterator of str or bytes, each made in the
    thread pool) and, however the response ends, closes ``pieces`` after the piece
    being made, releases ``slot``, runs ``finally_`` (e.g. deleting a temporary file)
    and gives the freed memory back to the system."""

    def __init__(
        self,
        pieces: Iterator[Any],
        slot: Slot,
        *,
        media_type: str,
        headers: dict[str, str],
        finally_: Callable[[], None] | None = None,
    ) -> None:
        self._pieces = pieces
        self._slot = slot
        self._finally = finally_
        self._step = threading.Lock()  # one next() or close() at a time
        self._done = False
        super().__init__(self._iterate(), media_type=media_type, headers=headers)

    def _next(self) -> Any:
        with self._step:
            if self._done:
                return _END
            try:
                return next(self._pieces)
            except StopIteration:
                return _END

    async def _iterate(self) -> AsyncIterator[Any]:
        while True:
            piece = await anyio.to_thread.run_sync(self._next)
            if piece is _END:
                return
            yield piece

    def _end(self) -> None:
        with self._step:  # waits for a next() in progress in another thread
            if self._done:
                return
            self._done = True
            try:
                close = getattr(self._pieces, "close", None)
                if close is not None:
                    close()
            finally:
                self._pieces = iter(())
                self._slot.release()
                try:
                    if self._finally is not None:
                        self._finally()
                finally:
                    give_back()

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        try:
            await super().__call__(scope, receive, send)
        finally:
            with anyio.CancelScope(shield=True):
                await anyio.to_thread.run_sync(self._end)
