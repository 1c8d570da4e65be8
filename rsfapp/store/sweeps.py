"""Sweep bookkeeping in the application database: sweeps, chunks and result blocks.

Layout (:mod:`rsfapp.db.tables`):

* ``sweeps``: one row per sweep, its compact spec (:class:`rsfapp.grid.SweepSpec` JSON:
  axes as start/stop/n, never the expanded points) and status;
* ``sweep_inputs``: the scattered points of a ``points`` sweep (one compressed blob);
* ``sweep_chunks``: one row per chunk, a range [i0, i1) of flat point indices;
* ``sweep_blocks``: one row per finished chunk: its results as compressed numpy arrays
  (:func:`encode_block`) plus a JSON side table of the failed points' messages.

Guarantees:

* every point is stored exactly once: a chunk's block is written once (primary key
  (sweep_id, idx), idempotent insert), whoever computes it first;
* a chunk is claimed by one live worker at a time (owner = node:pid, RSF_NODE); its
  worker renews the lease (``heartbeat``) while computing it, and the reaper in every
  worker (:mod:`rsfapp.reaper`) requeues a chunk whose lease expired
  (:meth:`SweepStore.reap_expired`) and closes sweeps whose chunks are all done
  (:meth:`SweepStore.close_finished`); at worker start, chunks with no live owner are
  requeued as well;
* one lock order for every operation (no deadlock between workers, cancels, purges and
  reapers on PostgreSQL): a write transaction that touches a sweep's chunks or blocks
  first locks the sweep's row (``SELECT ... FOR NO KEY UPDATE``, which still lets
  foreign-key checks of other inserts through), several sweeps in id order, and only then
  its chunk and block rows (SQLite: ``BEGIN IMMEDIATE`` write transactions are exclusive
  anyway).  Completion is decided under that lock, so two chunks finishing together on
  PostgreSQL (READ COMMITTED) cannot both see the other unfinished (write skew) and leave
  the sweep running; a purge cannot interleave with a block being stored;
* flat indices and counts are BIGINT (sweeps of more than 2^31 points);
* lazy dispatch: chunk rows start ``pending``; only ``sweep_window`` of them (at most as
  many as the live worker processes in the registry, when ``lease_s`` is given: the
  sweep's lanes) are sent to the queue (``queued``), so a sweep of 10^8 points costs a
  few thousand small rows and never floods the broker;
* chunk chaining: a worker that finishes a chunk may claim the sweep's next pending
  chunks (a work unit) in the same transaction (:meth:`SweepStore.complete_run` with
  ``claim``), compute them without a broker message and complete the whole unit in one
  transaction (its blocks, one per chunk, each written once); a lane that stops chaining
  sends the next pending chunk to the queue instead.  A chained chunk is claimed like
  any other (running, owner, lease; :meth:`SweepStore.heartbeat` renews a unit's
  leases in one statement): a worker that dies holding a unit loses it to the reaper
  after its lease;
* progress is counted in the sweep's row (``chunks_done``, ``points_done``,
  ``points_failed``) in the transaction that stores a block or marks a chunk done, so a
  completion, the sweep's closing and its status cost the same at any number of chunks;
* cancel marks the sweep and its pending/queued chunks; a running chunk or work unit
  finishes and is stored, so work stops within one unit per worker process;
* failures are flagged per point in the block, with their messages; the sweep goes on.

Chunk states: pending -> queued -> running -> done, or cancelled (resumed to pending).
"""

from __future__ import annotations

import io
import json
import os
import socket
import time
import zipfile
from collections.abc import Callable, Iterator, Sequence
from datetime import UTC, datetime
from typing import Any, NamedTuple

import numpy as np
from numpy.typing import NDArray
from sqlalchemy import (
    BindParameter,
    Connection,
    Row,
    and_,
    bindparam,
    case,
    delete,
    func,
    select,
    update,
)

from ..db.engine import Database, insert_ignore, inserted_keys
from ..db.ops import workers
from ..db.tables import chunks, points, sweep_blocks, sweep_inputs, sweeps
from ..grid import SPEC_VERSION, SweepSpec

__all__ = [
    "Block",
    "BlockData",
    "BlockWriter",
    "ChunkRange",
    "Completed",
    "Created",
    "RunCompleted",
    "SweepStore",
    "decode_block",
    "encode_block",
    "iso",
    "owner_id",
]

ACTIVE = ("queued", "running")


def _node() -> str:
    from ..config import get_settings

    return get_settings().node


def owner_id() -> str:
    """This process as a chunk owner: 'node:pid' (node = RSF_NODE, default host name)."""
    return f"{_node()}:{os.getpid()}"


def iso(t: float | None) -> str | None:
    """A Unix time as ISO 8601 UTC with milliseconds (``2026-11-23T19:02:11.123Z``)."""
    if t is None:
        return None
    return datetime.fromtimestamp(t, UTC).isoformat(timespec="milliseconds").replace("+00:00", "Z")


def _owner_alive(owner: str | None, heartbeat: float | None, lease_s: float) -> bool:
    if not owner:
        return False
    host, _, pid = owner.rpartition(":")
    if host == _node() == socket.gethostname():
        try:
            os.kill(int(pid), 0)
        except (ProcessLookupError, ValueError):
            return False
        except PermissionError:
            return True
        return True
    return heartbeat is not None and time.time() - heartbeat < lease_s


#: Entry-name marker of an array stored as its one repeated value (see encode_block).
_CONST = "@const"


def _same_bits(a: NDArray[Any], first: NDArray[Any] | None = None) -> bool:
    """True if every element of the 1-D contiguous array ``a`` has the bits of
    ``first[0]`` (default: of ``a[0]``), NaN and -0.0 included.

    The bytes are read as 64-bit words (the element's bytes repeated to fill one) and
    compared by their minimum and maximum: no temporary array, ~4x faster than an
    elementwise test of 1-byte elements (2^16 points: 4 us int8, 24 us float64)."""
    pattern = (a if first is None else first)[:1].tobytes()
    if a.nbytes % 8 == 0 and 8 % len(pattern) == 0:
        words = a.view(np.uint64)
        w = np.frombuffer(pattern * (8 // len(pattern)), np.uint64)[0]
        return bool(words.min() == w == words.max())
    word = {1: np.uint8, 2: np.uint16, 4: np.uint32, 8: np.uint64}.get(a.itemsize)
    if word is None:
        bits = a.view(np.uint8).reshape(a.size, a.itemsize)
        return not bool((bits != np.frombuffer(pattern, np.uint8)).any())
    return not bool((a.view(word) != np.frombuffer(pattern, word)[0]).any())


class BlockWriter:
    """One block's arrays given in parts, in index order, encoded as :func:`encode_block`
    encodes the whole arrays (the same entries and bytes), without assembling them.

    :meth:`add` takes the next part of every array (the parts of one call have one
    length) and tests right away, while the part is still in the CPU's cache, whether
    the array so far is one repeated value; such an array keeps only that value and its
    length (so the parts' memory is reused for the next part and stays in the cache),
    others keep their parts.  :meth:`finish` writes each array as its one value
    (``<name>@const<n>``) or as its parts one after the other (deflate level 1).  A chunk
    of 10^6 cheap points (every array constant) from its 2^16-point parts: ~1 ms, against
    ~2 ms testing the assembled arrays plus ~4 ms assembling them."""

    def __init__(self) -> None:
        #: per array: its first element, the length of its constant run so far (every
        #: element so far has the first's bits), then the parts that follow the run
        self._first: dict[str, NDArray[Any]] = {}
        self._run: dict[str, int] = {}
        self._parts: dict[str, list[NDArray[Any]]] = {}

    def add(self, arrays: dict[str, NDArray[Any]]) -> None:
        """Append the next part of each array (every call gives the same names and
        dtypes; an array of another dimension than 1 comes in one part, as it is)."""
        for name, arr in arrays.items():
            a = np.ascontiguousarray(arr)
            parts = self._parts.setdefault(name, [])
            if name not in self._first:
                if a.ndim != 1 or a.size == 0:  # kept as it is
                    self._first[name], self._run[name] = a[:0].reshape(-1), 0
                    parts.append(a)
                    continue
                self._first[name], self._run[name] = a[:1].copy(), 0
            if a.ndim != 1:
                raise ValueError(f"{name}: only 1-D arrays can be given in parts")
            if not parts and a.size and _same_bits(a, self._first[name]):
                self._run[name] += a.size
            elif a.size:
                parts.append(a)

    def add_whole(self, name: str, arr: NDArray[Any], n: int, repeated: bool | None) -> None:
        """Array ``name`` of ``n`` elements whole, in one part, when the caller knows
        whether it is one repeated value (bit for bit): ``repeated`` True (``arr[0]`` is
        every element; ``arr`` may hold just that one), False (it varies: not tested),
        None (not known: tested as :meth:`add` tests).  The same entry as :meth:`add`
        of the whole array writes."""
        if repeated is None:
            self.add({name: arr})
            return
        if name in self._parts:
            raise ValueError(f"{name}: already added")
        a = np.ascontiguousarray(arr)
        self._first[name] = a[:1].copy()
        self._run[name] = n if repeated else 0
        self._parts[name] = [] if repeated else [a]

    def finish(self) -> bytes:
        """The block as a compressed .npz (read by :func:`decode_block`)."""
        buf = io.BytesIO()
        with zipfile.ZipFile(buf, "w", zipfile.ZIP_DEFLATED, compresslevel=1) as z:
            for name, parts in self._parts.items():
                first, run = self._first[name], self._run[name]
                n = run + sum(p.size for p in parts)
                if not parts and n > 1:  # one repeated value
                    with z.open(f"{name}{_CONST}{n}.npy", "w", force_zip64=True) as fh:
                        np.lib.format.write_array(fh, first, allow_pickle=False)
                    continue
                if run == 0 and len(parts) == 1:
                    with z.open(f"{name}.npy", "w", force_zip64=True) as fh:
                        np.lib.format.write_array(fh, parts[0], allow_pickle=False)
                    continue
                head = {
                    "descr": np.lib.format.dtype_to_descr(first.dtype),
                    "fortran_order": False,
                    "shape": (n,),
                }
                with z.open(f"{name}.npy", "w", force_zip64=True) as fh:
                    np.lib.format.write_array_header_1_0(fh, head)
                    if run:
                        fh.write(np.repeat(first, run).data.cast("B"))
                    for p in parts:
                        fh.write(p.data.cast("B"))
        return buf.getvalue()


def encode_block(arrays: dict[str, NDArray[Any]]) -> bytes:
    """Arrays of one chunk as a compressed .npz (deflate level 1: 3-5x faster than
    numpy's savez_compressed at level 6 for a few percent more bytes); ~4-8 bytes per
    point.  An array whose elements are all the same bits (common: ``failed`` and
    ``on_boundary`` everywhere, every array of a region decided in closed form) is
    stored as that one element under ``<name>@const<n>`` instead of n compressed
    copies (deflating 8 MB of zeros costs ~50 ms; the test costs ~1 ms).
    :func:`decode_block` reads both forms; :class:`BlockWriter` writes the same from
    parts."""
    w = BlockWriter()
    w.add(arrays)
    return w.finish()


def decode_block(data: bytes, names: tuple[str, ...] | None = None) -> dict[str, NDArray[Any]]:
    """Inverse of :func:`encode_block`; only the arrays ``names`` (those stored) if given."""
    out: dict[str, NDArray[Any]] = {}
    with np.load(io.BytesIO(data), allow_pickle=False) as z:
        for k in z.files:
            name, const, n = k.partition(_CONST)
            if names is not None and name not in names:
                continue
            a = z[k]
            out[name] = np.full(int(n), a[0], dtype=a.dtype) if const else a
    return out


class ChunkRange(NamedTuple):
    """Flat indices [i0, i1) of a claimed chunk; ``stored``: its block is already stored
    (an earlier attempt finished; only its bookkeeping is left); ``idx``: the chunk's
    number (-1 where the caller named it)."""

    i0: int
    i1: int
    stored: bool = False
    idx: int = -1


class Completed(NamedTuple):
    """Outcome of :meth:`SweepStore.complete_chunk`: was the block new (False: stored
    before, or the sweep was purged), which chunks to send to the queue now, and the
    sweep's next chunk claimed for this process in the same transaction (``chain``
    asked for it and a pending chunk was left; None otherwise)."""

    stored: bool
    todo: list[int]
    next: ChunkRange | None = None


class RunCompleted(NamedTuple):
    """Outcome of :meth:`SweepStore.complete_run`: how many of the run's blocks were new
    (the others were stored before, or the sweep was purged), which chunks to send to
    the queue now, and the sweep's next chunks claimed for this process in the same
    transaction (in index order; empty unless asked for and pending chunks were left)."""

    stored: int
    todo: list[int]
    next: list[ChunkRange]


#: A computed chunk handed to :meth:`SweepStore.complete_run`: (i0, i1, encoded block,
#: {offset: message} of its failed points), or None when its block was stored before.
BlockData = tuple[int, int, bytes, dict[int, str]]


class Created(NamedTuple):
    """Outcome of :meth:`SweepStore.create`: was the sweep new, was it resumed (it had been
    cancelled), which chunks to send to the queue now."""

    created: bool
    resumed: bool
    todo: list[int]


class Block(NamedTuple):
    """A stored chunk: points [i0, i1), their arrays and {offset: message} of failures."""

    i0: int
    i1: int
    arrays: dict[str, NDArray[Any]]
    errors: dict[int, str]


def _chunk(sweep_id: str, idx: int) -> Any:
    return and_(chunks.c.sweep_id == sweep_id, chunks.c.idx == idx)


# The statements of a chunk's completion, built once with bound parameters (``sid``,
# ``idx``, ``now``, ...): SQLAlchemy keeps a statement object's cache key and compiled
# form, so executing one costs its parameters and the round trip only (built anew,
# each cost ~0.3-0.5 ms of a worker's CPU: ~3 ms of a completion's 3.3).
_SID: BindParameter[str] = bindparam("sid")
_IDXS: BindParameter[list[int]] = bindparam("idxs", expanding=True)
_NOW: BindParameter[float] = bindparam("now")
_LOCK = select(sweeps.c.status).where(sweeps.c.id == _SID).with_for_update(key_share=True)
#: chunks ``idxs`` done, each only if its block is stored (a correlated EXISTS)
_MARK_DONE = (
    update(chunks)
    .where(
        and_(
            chunks.c.sweep_id == _SID,
            chunks.c.idx.in_(_IDXS),
            chunks.c.status != "done",
            select(sweep_blocks.c.idx)
            .where(and_(sweep_blocks.c.sweep_id == _SID, sweep_blocks.c.idx == chunks.c.idx))
            .exists(),
        )
    )
    .values(status="done", heartbeat=_NOW)
)
_COMPLETE = sweeps.c.chunks_done + bindparam("d_chunks") >= sweeps.c.n_chunks
_COUNT = (
    update(sweeps)
    .where(sweeps.c.id == _SID)
    .values(
        chunks_done=sweeps.c.chunks_done + bindparam("d_chunks"),
        points_done=sweeps.c.points_done + bindparam("d_points"),
        points_failed=sweeps.c.points_failed + bindparam("d_failed"),
        status=case((_COMPLETE, "done"), else_=sweeps.c.status),
        finished_at=case(
            (and_(_COMPLETE, sweeps.c.status != "done"), _NOW), else_=sweeps.c.finished_at
        ),
    )
    .returning(sweeps.c.status)
)
_NEXT = chunks.alias("next_pending")
#: the sweep's ``k`` lowest pending chunks claimed for ``owner``
_CLAIM_NEXT = (
    update(chunks)
    .where(
        and_(
            chunks.c.sweep_id == _SID,
            chunks.c.idx.in_(
                select(_NEXT.c.idx)
                .where(and_(_NEXT.c.sweep_id == _SID, _NEXT.c.status == "pending"))
                .order_by(_NEXT.c.idx)
                .limit(bindparam("k"))
            ),
            chunks.c.status == "pending",
        )
    )
    .values(
        status="running",
        owner=bindparam("owner"),
        heartbeat=_NOW,
        attempts=chunks.c.attempts + 1,
    )
    .returning(chunks.c.idx, chunks.c.i0, chunks.c.i1)
)


class SweepStore:
    """Sweeps, their chunks and result blocks in ``db``."""

    def __init__(self, db: Database) -> None:
        self.db = db
        self._specs: dict[str, SweepSpec] = {}

    # -- submit / resume -----------------------------------------------------------------
    def create(
        self,
        sweep_id: str,
        spec: SweepSpec,
        chunk_points: int,
        numerics_version: str,
        window: int = 64,
        lease_s: float | None = None,
    ) -> Created:
        """Create the sweep and its (pending) chunks unless it exists; dispatch the first
        ``window`` chunks (with ``lease_s``: at most one per live worker process,
        :meth:`_dispatch`).

        An existing cancelled sweep is resumed (its unfinished chunks pending again, the
        first ``window`` dispatched); an existing active or done sweep dispatches nothing.
        """
        now = time.time()
        n_total = spec.n_total
        with self.db.write() as conn:
            row = self._lock_sweep(conn, sweep_id)
            n_chunks = -(-n_total // chunk_points)
            if row is None and insert_ignore(
                conn,
                sweeps,
                {
                    "id": sweep_id,
                    "spec": json.dumps(spec.to_json(), sort_keys=True),
                    "status": "queued",
                    "n_total": n_total,
                    "n_chunks": n_chunks,
                    "numerics_version": numerics_version,
                    "created_at": now,
                    "started_at": None,
                    "finished_at": None,
                },
            ):
                # new (a concurrent create of the same id inserted nothing: it waits on
                # this row and then sees it)
                if spec.points is not None:
                    conn.execute(
                        sweep_inputs.insert().values(
                            sweep_id=sweep_id, data=encode_block(spec.points)
                        )
                    )
                conn.execute(
                    chunks.insert(),
                    [
                        {
                            "sweep_id": sweep_id,
                            "idx": c,
                            "i0": c * chunk_points,
                            "i1": min(n_total, (c + 1) * chunk_points),
                            "status": "pending",
                            "attempts": 0,
                        }
                        for c in range(n_chunks)
                    ],
                )
                return Created(True, False, self._dispatch(conn, sweep_id, window, None, lease_s))
            if row is None:
                row = self._lock_sweep(conn, sweep_id)
            if row is None or row != "cancelled":
                return Created(False, False, [])
            conn.execute(
                update(sweeps)
                .where(sweeps.c.id == sweep_id)
                .values(status="queued", finished_at=None)
            )
            conn.execute(
                update(chunks)
                .where(and_(chunks.c.sweep_id == sweep_id, chunks.c.status == "cancelled"))
                .values(status="pending", owner=None)
            )
            return Created(False, True, self._dispatch(conn, sweep_id, window, None, lease_s))

    @staticmethod
    def _lanes(conn: Connection, window: int, lease_s: float | None) -> int:
        """Chunks of one sweep to keep in flight: ``window``, capped at the processes of
        the live workers in the registry (heartbeat within ``lease_s``; none registered,
        or no ``lease_s``: ``window``).  A chaining worker keeps its lane busy without
        messages, so a message more than there are processes to take it would only
        wait in the broker (and cost its own claim when it comes)."""
        if lease_s is None:
            return window
        procs = int(
            conn.execute(
                select(func.coalesce(func.sum(workers.c.concurrency), 0)).where(
                    workers.c.heartbeat >= time.time() - lease_s
                )
            ).scalar()
            or 0
        )
        return min(window, procs) if procs > 0 else window

    @classmethod
    def _dispatch(
        cls,
        conn: Connection,
        sweep_id: str,
        window: int,
        busy: int | None = None,
        lease_s: float | None = None,
    ) -> list[int]:
        """Mark up to the sweep's lanes (:meth:`_lanes` of ``window``) minus the chunks in
        flight (queued/running: ``busy`` if the caller counted them) pending chunks
        queued, lowest index first; returns them (the caller sends them).  The count and
        the pick read the index of chunks by status (the chunks in flight and the first
        pending ones, not the sweep's other chunks); one UPDATE of the first pending
        chunks, RETURNING them."""
        window = cls._lanes(conn, window, lease_s)
        if busy is None:
            busy = int(
                conn.execute(
                    select(func.count())
                    .select_from(chunks)
                    .where(and_(chunks.c.sweep_id == sweep_id, chunks.c.status.in_(ACTIVE)))
                ).scalar()
                or 0
            )
        k = window - busy
        if k <= 0:
            return []
        first = chunks.alias("first_pending")
        pick = (
            select(first.c.idx)
            .where(and_(first.c.sweep_id == sweep_id, first.c.status == "pending"))
            .order_by(first.c.idx)
            .limit(k)
        )
        rows = conn.execute(
            update(chunks)
            .where(
                and_(
                    chunks.c.sweep_id == sweep_id,
                    chunks.c.status == "pending",
                    chunks.c.idx.in_(pick),
                )
            )
            .values(status="queued")
            .returning(chunks.c.idx)
        ).scalars()
        return sorted(int(i) for i in rows)

    def next_chunks(self, sweep_id: str, window: int, lease_s: float | None = None) -> list[int]:
        """Chunks to send now to keep ``window`` in flight (none unless the sweep is
        active)."""
        with self.db.write() as conn:
            if self._lock_sweep(conn, sweep_id) not in ACTIVE:
                return []
            return self._dispatch(conn, sweep_id, window, None, lease_s)

    def get_spec(self, sweep_id: str) -> SweepSpec | None:
        """The stored spec of a sweep; cached per process (immutable).  None if unknown or
        stored in the pre-array layout (before N-D sweeps; its points are in
        ``sweep_points`` and it cannot be computed further: re-submit it)."""
        sp = self._specs.get(sweep_id)
        if sp is not None:
            return sp
        with self.db.read() as conn:
            row = conn.execute(select(sweeps.c.spec).where(sweeps.c.id == sweep_id)).first()
            if row is None:
                return None
            d = json.loads(row[0])
            if d.get("v") != SPEC_VERSION:
                return None
            pts = None
            if d.get("mode") == "points":
                blob = conn.execute(
                    select(sweep_inputs.c.data).where(sweep_inputs.c.sweep_id == sweep_id)
                ).scalar()
                pts = decode_block(blob) if blob is not None else None
                if pts is not None:
                    pts = {n: pts[n] for n in d["points"]["names"]}
        sp = SweepSpec.from_json(d, pts)
        if len(self._specs) > 64:
            self._specs.clear()
        self._specs[sweep_id] = sp
        return sp

    # -- workers ---------------------------------------------------------------------------
    def claim(self, sweep_id: str, idx: int, lease_s: float) -> ChunkRange | None:
        """Claim chunk ``idx`` for this process; None if there is nothing to do.  One
        transaction of three statements (the sweep's lock; the chunk with whether its
        block is already stored; its update), a fourth at the sweep's first claim; one
        (the lock) when the sweep is done.

        Nothing to do: the sweep is unknown, done or cancelled, the chunk is done or
        cancelled, or another live worker holds it.
        """
        me = owner_id()
        now = time.time()
        with self.db.write() as conn:
            s = self._lock_sweep(conn, sweep_id)  # sweep row first: the one lock order
            if s is None or s == "done":  # every chunk done (a message left behind)
                return None
            # the chunk and whether its block is stored, read after the lock (a fresh
            # snapshot on PostgreSQL: a completion that held the lock is seen)
            stored_q = (
                select(sweep_blocks.c.idx)
                .where(and_(sweep_blocks.c.sweep_id == sweep_id, sweep_blocks.c.idx == idx))
                .exists()
            )
            c = conn.execute(
                select(
                    chunks.c.i0,
                    chunks.c.i1,
                    chunks.c.status,
                    chunks.c.owner,
                    chunks.c.heartbeat,
                    stored_q.label("stored"),
                ).where(_chunk(sweep_id, idx))
            ).first()
            if s is None or c is None or c.status in ("done", "cancelled"):
                return None
            if s == "cancelled":
                conn.execute(update(chunks).where(_chunk(sweep_id, idx)).values(status="cancelled"))
                return None
            if (
                c.status == "running"
                and c.owner != me
                and _owner_alive(c.owner, c.heartbeat, lease_s)
            ):
                return None
            conn.execute(
                update(chunks)
                .where(_chunk(sweep_id, idx))
                .values(status="running", owner=me, heartbeat=now, attempts=chunks.c.attempts + 1)
            )
            if s == "queued":  # the sweep's first claim (its status is read under the lock)
                conn.execute(
                    update(sweeps)
                    .where(and_(sweeps.c.id == sweep_id, sweeps.c.status == "queued"))
                    .values(status="running", started_at=func.coalesce(sweeps.c.started_at, now))
                )
            return ChunkRange(int(c.i0), int(c.i1), bool(c.stored), idx)

    def heartbeat(self, sweep_id: str, idx: int, *more: int) -> bool:
        """Refresh the lease of running chunks held by this process (``idx`` and
        ``more``: a task's work unit, one UPDATE); False once none of them is held (the
        reaper took them back after their lease expired), so the chunks of a unit still
        held keep their lease."""
        idxs = [idx, *more]
        with self.db.write() as conn:
            n = conn.execute(
                update(chunks)
                .where(
                    and_(
                        chunks.c.sweep_id == sweep_id,
                        chunks.c.idx.in_(idxs),
                        chunks.c.owner == owner_id(),
                        chunks.c.status == "running",
                    )
                )
                .values(heartbeat=time.time())
            ).rowcount
        return n > 0

    def release_chunk(self, sweep_id: str, idx: int, others: Sequence[int] = ()) -> None:
        """Put a running chunk back in the queue (its worker hit an infrastructure error
        and retries it); ``others``, the rest of the worker's work unit, go back to
        pending (no message: a lane or the retry claims them)."""
        with self.db.write() as conn:
            self._lock_sweep(conn, sweep_id)
            conn.execute(
                update(chunks)
                .where(and_(_chunk(sweep_id, idx), chunks.c.status == "running"))
                .values(status="queued", owner=None)
            )
            rest = [i for i in others if i != idx]
            if rest:
                conn.execute(
                    update(chunks)
                    .where(
                        and_(
                            chunks.c.sweep_id == sweep_id,
                            chunks.c.idx.in_(rest),
                            chunks.c.status == "running",
                            chunks.c.owner == owner_id(),
                        )
                    )
                    .values(status="pending", owner=None)
                )

    def has_block(self, sweep_id: str, idx: int) -> bool:
        """True if chunk ``idx``'s results are stored (an earlier attempt finished)."""
        with self.db.read() as conn:
            return (
                conn.execute(
                    select(sweep_blocks.c.idx).where(
                        and_(sweep_blocks.c.sweep_id == sweep_id, sweep_blocks.c.idx == idx)
                    )
                ).first()
                is not None
            )

    @staticmethod
    def _block_row(
        sweep_id: str, idx: int, i0: int, i1: int, data: bytes, errors: dict[int, str]
    ) -> dict[str, Any]:
        return {
            "sweep_id": sweep_id,
            "idx": idx,
            "i0": i0,
            "i1": i1,
            "n_failed": len(errors),
            "data": data,
            "errors": json.dumps({str(k): v for k, v in errors.items()}) if errors else None,
            "created_at": time.time(),
        }

    def store_block(
        self, sweep_id: str, idx: int, i0: int, i1: int, data: bytes, errors: dict[int, str]
    ) -> bool:
        """Store chunk ``idx``'s results once (a second write is ignored); True if new."""
        with self.db.write() as conn:
            if self._lock_sweep(conn, sweep_id) is None:  # purged meanwhile
                return False
            return self._insert_block(conn, sweep_id, idx, (i0, i1, data, errors), time.time())

    @classmethod
    def _insert_block(
        cls,
        conn: Connection,
        sweep_id: str,
        idx: int,
        block: tuple[int, int, bytes, dict[int, str]],
        now: float,
        count: bool = True,
    ) -> bool:
        """Store a block once and (with ``count``) count its points in the sweep's row;
        True if new."""
        i0, i1, data, errors = block
        row = cls._block_row(sweep_id, idx, i0, i1, data, errors)
        if insert_ignore(conn, sweep_blocks, row) == 0:
            return False
        if count:
            cls._count(conn, sweep_id, now, points=i1 - i0, failed=len(errors))
        return True

    @staticmethod
    def _count(
        conn: Connection,
        sweep_id: str,
        now: float,
        chunks_done: int = 0,
        points: int = 0,
        failed: int = 0,
    ) -> str | None:
        """Add to the sweep's progress counters (one UPDATE) and close it (``done``,
        finished now) when its last chunk is done; returns its status after (None: no
        such sweep).  The caller holds the sweep's row lock."""
        params = {
            "sid": sweep_id,
            "now": now,
            "d_chunks": chunks_done,
            "d_points": points,
            "d_failed": failed,
        }
        s = conn.execute(_COUNT, params).scalar()
        return None if s is None else str(s)

    def is_cancelled(self, sweep_id: str) -> bool:
        """True once the sweep has been cancelled (or deleted)."""
        with self.db.read() as conn:
            s = conn.execute(select(sweeps.c.status).where(sweeps.c.id == sweep_id)).scalar()
        return s is None or s == "cancelled"

    def finish_chunk(self, sweep_id: str, idx: int, complete: bool) -> None:
        """Mark the chunk done (or, if incomplete, cancelled); close the sweep when all done.

        A chunk becomes done only if its block is stored (:meth:`_mark_done`).  An
        incomplete chunk of a sweep that is active again (cancelled, then resumed while
        this worker ran) goes back to pending instead of cancelled, so the resumed sweep
        can still finish.
        """
        now = time.time()
        with self.db.write() as conn:
            s = self._lock_sweep(conn, sweep_id)
            if s is None:
                return
            if complete:
                self._mark_done(conn, sweep_id, [idx], now)
                return
            conn.execute(
                update(chunks)
                .where(and_(_chunk(sweep_id, idx), chunks.c.status == "running"))
                .values(
                    status="pending" if s in ACTIVE else "cancelled",
                    owner=None,
                    heartbeat=now,
                )
            )

    @classmethod
    def _mark_done(
        cls,
        conn: Connection,
        sweep_id: str,
        idxs: list[int],
        now: float,
        points: int = 0,
        failed: int = 0,
    ) -> bool:
        """Mark chunks ``idxs`` done, each if its block is stored, count them in the
        sweep's row and close the sweep when every chunk is done; returns True if the
        sweep is done.
        Done only with the block: a worker that finishes a chunk of a sweep purged and
        re-submitted meanwhile (the same id) must not mark the new sweep's chunk done
        without its block.  A chunk already done is counted once (the update's
        condition).  ``points`` and ``failed`` (blocks just stored) are counted with them.
        Two statements (the mark, the counters); the caller holds the sweep's row lock."""
        n = conn.execute(_MARK_DONE, {"sid": sweep_id, "idxs": idxs, "now": now}).rowcount
        if not n and not points:
            return False
        return cls._count(conn, sweep_id, now, n, points, failed) == "done"

    @staticmethod
    def _claim_next(conn: Connection, sweep_id: str, now: float, k: int) -> list[ChunkRange]:
        """Claim the sweep's ``k`` lowest pending chunks for this process (running,
        owner, lease from now; one UPDATE RETURNING them), in index order; empty if none
        is pending.  The caller holds the sweep's row lock.  Their blocks are taken as
        not stored: a pending chunk has none unless a block was stored without completing
        its chunk (:meth:`store_block` alone), and then the block computed again is not
        stored twice."""
        rows = conn.execute(
            _CLAIM_NEXT, {"sid": sweep_id, "now": now, "owner": owner_id(), "k": k}
        ).all()
        return sorted(ChunkRange(int(r.i0), int(r.i1), False, int(r.idx)) for r in rows)

    def complete_chunk(
        self,
        sweep_id: str,
        idx: int,
        block: BlockData | None,
        window: int,
        chain: bool = False,
        lease_s: float | None = None,
    ) -> Completed:
        """:meth:`complete_run` of one chunk ``idx`` (its ``block``, none if it was
        stored before) that, with ``chain``, claims one next chunk."""
        r = self.complete_run(sweep_id, [(idx, block)], window, int(chain), lease_s)
        return Completed(r.stored > 0, r.todo, r.next[0] if r.next else None)

    def complete_run(
        self,
        sweep_id: str,
        run: Sequence[tuple[int, BlockData | None]],
        window: int,
        claim: int = 0,
        lease_s: float | None = None,
    ) -> RunCompleted:
        """Everything after a worker computed a run of chunks (its work unit), in one
        transaction: store each block ``(i0, i1, data, errors)`` of ``run`` (pairs
        (chunk, block); a block None was stored before) once, mark the chunks done,
        count them in the sweep's row and close the sweep when every chunk is done;
        then, for an active sweep, claim up to ``claim`` of its next pending chunks for
        this process (:attr:`RunCompleted.next`: the caller computes them without a
        broker message; chunk chaining), else (``claim`` 0, or none pending) mark the
        next pending chunks queued to keep the sweep's lanes in flight (``window``,
        capped by the live worker processes with ``lease_s``; the caller sends them).
        The same as :meth:`store_block`, :meth:`finish_chunk`, :meth:`next_chunks` and
        :meth:`claim` in a row with one lock of the sweep's row and one commit,
        whatever the run's length.  Statements: the lock, the blocks (one INSERT of
        every row), the done marks (one UPDATE), the counters, then the next chunks
        claimed (one UPDATE) or the dispatch (the lanes with ``lease_s``, the count of
        chunks in flight, the pick); every one reads the sweep's row or the chunks by
        index, none all of the sweep's chunks."""
        now = time.time()
        with self.db.write() as conn:
            s = self._lock_sweep(conn, sweep_id)
            if s is None:  # purged meanwhile
                return RunCompleted(0, [], [])
            blocks = {idx: b for idx, b in run if b is not None}
            new = (
                inserted_keys(
                    conn,
                    sweep_blocks,
                    [self._block_row(sweep_id, i, *b) for i, b in blocks.items()],
                    "idx",
                )
                if blocks
                else []
            )
            points = sum(blocks[i][1] - blocks[i][0] for i in new)
            failed = sum(len(blocks[i][3]) for i in new)
            idxs = [idx for idx, _ in run]
            if self._mark_done(conn, sweep_id, idxs, now, points, failed) or s not in ACTIVE:
                return RunCompleted(len(new), [], [])  # done, or cancelled: nothing to send
            if claim > 0:
                nxt = self._claim_next(conn, sweep_id, now, claim)
                if nxt:
                    return RunCompleted(len(new), [], nxt)
            return RunCompleted(len(new), self._dispatch(conn, sweep_id, window, None, lease_s), [])

    # -- API -------------------------------------------------------------------------------
    def cancel(self, sweep_id: str) -> tuple[str, bool] | None:
        """Cancel a sweep: (its status, whether this call changed anything); None if
        unknown.  Done and already cancelled sweeps are left as they are."""
        with self.db.write() as conn:
            s = self._lock_sweep(conn, sweep_id)
            if s is None:
                return None
            if s not in ACTIVE:
                return str(s), False
            conn.execute(
                update(sweeps)
                .where(sweeps.c.id == sweep_id)
                .values(status="cancelled", finished_at=time.time())
            )
            conn.execute(
                update(chunks)
                .where(
                    and_(chunks.c.sweep_id == sweep_id, chunks.c.status.in_(("pending", "queued")))
                )
                .values(status="cancelled")
            )
            return "cancelled", True

    def delete(self, sweep_id: str, reclaim: bool = True) -> bool:
        """Delete a sweep with its chunks, inputs and results; False if unknown.  With
        ``reclaim`` the disk space is given back (:meth:`rsfapp.db.engine.Database.reclaim`:
        SQLite incremental vacuum and WAL truncation, PostgreSQL VACUUM of the sweep
        tables)."""
        with self.db.write() as conn:
            if self._lock_sweep(conn, sweep_id) is None:
                return False
            for t in (sweep_blocks, sweep_inputs, chunks, points):
                conn.execute(delete(t).where(t.c.sweep_id == sweep_id))
            n = conn.execute(delete(sweeps).where(sweeps.c.id == sweep_id)).rowcount
        self._specs.pop(sweep_id, None)
        if n and reclaim:
            self.db.reclaim([t.name for t in (sweep_blocks, sweep_inputs, chunks, points)])
        return bool(n)

    @staticmethod
    def _summary(row: Row[Any]) -> dict[str, Any]:
        """Status of the sweep's row (its progress counters: no read of its blocks)."""
        n_done, n_failed = int(row.points_done), int(row.points_failed)
        now = time.time()
        eta = None
        if row.status in ACTIVE and row.started_at and n_done:
            eta = (now - row.started_at) / n_done * (row.n_total - n_done)
        elif row.status == "done":
            eta = 0.0
        spec = json.loads(row.spec)
        try:
            summ = SweepSpec.from_json(spec).summary() if spec.get("v") else {}
        except (KeyError, TypeError, ValueError):
            summ = {}
        return {
            "id": row.id,
            "status": row.status,
            "n_done": n_done,
            "n_total": int(row.n_total),
            "n_failed": n_failed,
            "n_chunks": int(row.n_chunks),
            "eta_s": eta,
            "created_at": iso(row.created_at),
            "started_at": iso(row.started_at),
            "finished_at": iso(row.finished_at),
            "numerics_version": row.numerics_version,
            **summ,
        }

    def status(self, sweep_id: str) -> dict[str, Any] | None:
        """Status, progress, ETA [s] (no axis values)."""
        with self.db.read() as conn:
            row = conn.execute(select(sweeps).where(sweeps.c.id == sweep_id)).first()
            return None if row is None else self._summary(row)

    def list_sweeps(self, limit: int, offset: int) -> list[dict[str, Any]]:
        """Sweeps, newest first, with progress."""
        with self.db.read() as conn:
            rows = conn.execute(
                select(sweeps).order_by(sweeps.c.created_at.desc()).limit(limit).offset(offset)
            ).all()
            return [self._summary(r) for r in rows]

    def failures(self, sweep_id: str, limit: int = 100) -> list[tuple[int, str]]:
        """(flat index, message) of the first ``limit`` failed points."""
        out: list[tuple[int, str]] = []
        with self.db.read() as conn:
            rows = conn.execute(
                select(sweep_blocks.c.i0, sweep_blocks.c.errors)
                .where(and_(sweep_blocks.c.sweep_id == sweep_id, sweep_blocks.c.n_failed > 0))
                .order_by(sweep_blocks.c.i0)
            ).all()
        for i0, errs in rows:
            for k, msg in sorted(json.loads(errs or "{}").items(), key=lambda kv: int(kv[0])):
                out.append((int(i0) + int(k), str(msg)))
                if len(out) >= limit:
                    return out
        return out

    def blocks(self, sweep_id: str, i0: int = 0, i1: int | None = None) -> Iterator[Block]:
        """Stored blocks overlapping [i0, i1), in index order (read a few at a time)."""
        cond = [sweep_blocks.c.sweep_id == sweep_id, sweep_blocks.c.i1 > i0]
        if i1 is not None:  # no sentinel bound: any bound parameter must fit the column
            cond.append(sweep_blocks.c.i0 < i1)
        with self.db.read() as conn:
            keys = (
                conn.execute(
                    select(sweep_blocks.c.idx).where(and_(*cond)).order_by(sweep_blocks.c.i0)
                )
                .scalars()
                .all()
            )
        for k in keys:
            with self.db.read() as conn:
                r = conn.execute(
                    select(sweep_blocks).where(
                        and_(sweep_blocks.c.sweep_id == sweep_id, sweep_blocks.c.idx == k)
                    )
                ).first()
            if r is None:  # deleted meanwhile
                return
            errs = {int(a): str(b) for a, b in json.loads(r.errors or "{}").items()}
            yield Block(int(r.i0), int(r.i1), decode_block(r.data), errs)

    def block_index(
        self, sweep_id: str, i0: int = 0, i1: int | None = None
    ) -> tuple[NDArray[np.int64], ...]:
        """(chunk numbers, i0, i1) of the stored blocks overlapping [i0, i1), in index
        order (int64 arrays)."""
        cond = [sweep_blocks.c.sweep_id == sweep_id, sweep_blocks.c.i1 > i0]
        if i1 is not None:
            cond.append(sweep_blocks.c.i0 < i1)
        with self.db.read() as conn:
            rows = conn.execute(
                select(sweep_blocks.c.idx, sweep_blocks.c.i0, sweep_blocks.c.i1)
                .where(and_(*cond))
                .order_by(sweep_blocks.c.i0)
            ).all()
        a = np.array(rows, dtype=np.int64).reshape(-1, 3)
        return a[:, 0].copy(), a[:, 1].copy(), a[:, 2].copy()

    def block_points(self, sweep_id: str) -> int | None:
        """Points of the sweep's first chunk (every chunk but the last has as many)."""
        with self.db.read() as conn:
            r = conn.execute(select(chunks.c.i0, chunks.c.i1).where(_chunk(sweep_id, 0))).first()
        return None if r is None else int(r.i1) - int(r.i0)

    def read_block(
        self, sweep_id: str, idx: int, names: tuple[str, ...] | None = None
    ) -> Block | None:
        """Block ``idx`` (only the arrays ``names`` if given); None if not stored."""
        with self.db.read() as conn:
            r = conn.execute(
                select(sweep_blocks).where(
                    and_(sweep_blocks.c.sweep_id == sweep_id, sweep_blocks.c.idx == idx)
                )
            ).first()
        if r is None:
            return None
        errs = {int(a): str(b) for a, b in json.loads(r.errors or "{}").items()}
        return Block(int(r.i0), int(r.i1), decode_block(r.data, names), errs)

    def disk_bytes(self, sweep_id: str) -> int:
        """Bytes of stored result blobs of a sweep (payload only)."""
        with self.db.read() as conn:
            return int(
                conn.execute(
                    select(func.coalesce(func.sum(func.length(sweep_blocks.c.data)), 0)).where(
                        sweep_blocks.c.sweep_id == sweep_id
                    )
                ).scalar()
                or 0
            )

    # -- recovery ----------------------------------------------------------------------------
    def stale_chunks(self, lease_s: float, window: int = 64) -> list[tuple[str, int]]:
        """Chunks of active sweeps to send again: queued ones, running ones whose owner is
        dead (reset to queued) and, for a sweep with nothing in flight, the next pending
        ones.  Used at worker start to requeue work lost with a killed worker (the
        filesystem broker deletes a message once delivered)."""
        out: list[tuple[str, int]] = []
        with self.db.write() as conn:
            self._lock_active(conn)
            rows = conn.execute(
                select(
                    chunks.c.sweep_id,
                    chunks.c.idx,
                    chunks.c.status,
                    chunks.c.owner,
                    chunks.c.heartbeat,
                )
                .join(sweeps, sweeps.c.id == chunks.c.sweep_id)
                .where(and_(sweeps.c.status.in_(ACTIVE), chunks.c.status.in_(ACTIVE)))
            ).all()
            active: set[str] = set()
            for r in rows:
                if r.status == "running":
                    if _owner_alive(r.owner, r.heartbeat, lease_s):
                        active.add(str(r.sweep_id))
                        continue
                    conn.execute(
                        update(chunks)
                        .where(_chunk(r.sweep_id, r.idx))
                        .values(status="queued", owner=None)
                    )
                out.append((str(r.sweep_id), int(r.idx)))
                active.add(str(r.sweep_id))
            idle = (
                conn.execute(select(sweeps.c.id).where(sweeps.c.status.in_(ACTIVE))).scalars().all()
            )
            for sid in idle:
                if sid not in active:
                    out += [
                        (str(sid), i) for i in self._dispatch(conn, str(sid), window, None, lease_s)
                    ]
        return out

    @staticmethod
    def _lock_sweep(conn: Connection, sweep_id: str) -> str | None:
        """Row lock on the sweep until the transaction ends (PostgreSQL ``FOR NO KEY
        UPDATE``; SQLite write transactions are already exclusive); its status, None if
        there is no such sweep.  Taken first by every write that touches the sweep's
        chunks or blocks: the one lock order (sweep, then its chunks and blocks)."""
        s = conn.execute(_LOCK, {"sid": sweep_id}).scalar()
        return None if s is None else str(s)

    @staticmethod
    def _lock_active(conn: Connection) -> list[str]:
        """Lock every active sweep's row, in id order (the one lock order for writes
        spanning several sweeps); returns their ids."""
        return [
            str(i)
            for i in conn.execute(
                select(sweeps.c.id)
                .where(sweeps.c.status.in_(ACTIVE))
                .order_by(sweeps.c.id)
                .with_for_update(key_share=True)
            ).scalars()
        ]

    def reap_expired(self, lease_s: float) -> list[tuple[str, int]]:
        """Running chunks of active sweeps whose lease expired (no heartbeat for
        ``lease_s`` seconds) are put back to ``queued``; returns them (the caller sends
        them).  One conditional update per chunk, so of several reapers exactly one
        takes a given chunk back."""
        now = time.time()
        cutoff = now - lease_s
        out: list[tuple[str, int]] = []
        with self.db.write() as conn:
            if not self._lock_active(conn):
                return out
            rows = conn.execute(
                select(chunks.c.sweep_id, chunks.c.idx)
                .join(sweeps, sweeps.c.id == chunks.c.sweep_id)
                .where(
                    and_(
                        sweeps.c.status.in_(ACTIVE),
                        chunks.c.status == "running",
                        func.coalesce(chunks.c.heartbeat, 0.0) < cutoff,
                    )
                )
            ).all()
            for r in rows:
                n = conn.execute(
                    update(chunks)
                    .where(
                        and_(
                            _chunk(r.sweep_id, r.idx),
                            chunks.c.status == "running",
                            func.coalesce(chunks.c.heartbeat, 0.0) < cutoff,
                        )
                    )
                    .values(status="queued", owner=None, heartbeat=now)
                ).rowcount
                if n:
                    out.append((str(r.sweep_id), int(r.idx)))
        return out

    def close_finished(
        self, window: int = 64, lease_s: float | None = None
    ) -> tuple[int, list[tuple[str, int]]]:
        """Self-repair of active sweeps: close those whose chunks are all done (under the
        sweep's row lock); for those with pending chunks but none in flight (the sender
        of the next chunks died), dispatch the next ones.  Returns (sweeps closed,
        chunks to send).  Reads the sweeps' counters and their chunks in flight (by
        index); only a sweep with nothing in flight and chunks left by its counter is
        recounted from its rows (:meth:`_recount`, which also repairs its counters)."""
        now = time.time()
        closed = 0
        send: list[tuple[str, int]] = []
        with self.db.write() as conn:
            if not self._lock_active(conn):
                return closed, send
            busy = (
                select(func.count())
                .select_from(chunks)
                .where(and_(chunks.c.sweep_id == sweeps.c.id, chunks.c.status.in_(ACTIVE)))
                .scalar_subquery()
            )
            rows = conn.execute(
                select(sweeps.c.id, sweeps.c.n_chunks, sweeps.c.chunks_done, busy).where(
                    sweeps.c.status.in_(ACTIVE)
                )
            ).all()
            for sid, n_chunks, n_done, n_busy in rows:
                if n_done < n_chunks and n_busy == 0:  # stalled: trust a recount
                    n_done = self._recount(conn, str(sid))
                if n_done >= n_chunks:
                    closed += (
                        conn.execute(
                            update(sweeps)
                            .where(and_(sweeps.c.id == sid, sweeps.c.status.in_(ACTIVE)))
                            .values(status="done", finished_at=now)
                        ).rowcount
                        or 0
                    )
                elif n_busy == 0:
                    send += [
                        (str(sid), i) for i in self._dispatch(conn, str(sid), window, 0, lease_s)
                    ]
        return closed, send

    @staticmethod
    def _recount(conn: Connection, sweep_id: str) -> int:
        """Count a sweep's done chunks, stored points and failed points from its rows and
        write them to its counters (self-repair of a sweep whose rows were written
        without them); returns the chunks done.  The caller holds the sweep's lock."""
        done = int(
            conn.execute(
                select(func.count())
                .select_from(chunks)
                .where(and_(chunks.c.sweep_id == sweep_id, chunks.c.status == "done"))
            ).scalar()
            or 0
        )
        pts, failed = conn.execute(
            select(
                func.coalesce(func.sum(sweep_blocks.c.i1 - sweep_blocks.c.i0), 0),
                func.coalesce(func.sum(sweep_blocks.c.n_failed), 0),
            ).where(sweep_blocks.c.sweep_id == sweep_id)
        ).one()
        conn.execute(
            update(sweeps)
            .where(sweeps.c.id == sweep_id)
            .values(chunks_done=done, points_done=int(pts), points_failed=int(failed))
        )
        return done

    @staticmethod
    def requeue(pairs: list[tuple[str, int]], send: Callable[[str, int], None]) -> int:
        """Send ``send(sweep_id, idx)`` for each pair; returns how many were sent."""
        for sid, idx in pairs:
            send(sid, idx)
        return len(pairs)
