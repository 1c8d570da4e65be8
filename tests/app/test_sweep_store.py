"""The sweep store on SQLite and on PostgreSQL: flat indices beyond 2^31, reads of every
block without a sentinel bound, one lock order under racing workers, cancels, resumes,
purges and reapers (no deadlock), and purge giving the disk back.

The PostgreSQL variants start a real throw-away cluster (tests/conftest.py ``postgres``),
so they are marked e2e; the SQLite variants run everywhere."""

from __future__ import annotations

import random
import threading
import time
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest

from rsfapp.db.engine import Database
from rsfapp.grid import Axis, SweepSpec
from rsfapp.store.sweeps import (
    ChunkRange,
    Completed,
    RunCompleted,
    SweepStore,
    decode_block,
    encode_block,
    owner_id,
)

pytestmark = pytest.mark.timeout(300)


@pytest.fixture(params=["sqlite", pytest.param("postgres", marks=pytest.mark.e2e)])
def db(request: pytest.FixtureRequest, tmp_path: Path) -> Iterator[Database]:
    if request.param == "postgres":
        url = request.getfixturevalue("postgres").url
    else:
        url = f"sqlite:///{tmp_path / 'store.sqlite3'}"
    d = Database(url, pool_size=24, max_overflow=8, pool_timeout=60.0)
    try:
        yield d
    finally:
        d.dispose()


def grid(n0: int, n1: int, stop: float = 0.9) -> SweepSpec:
    """A 2-D (eps, vo) grid spec of n0 x n1 points (never computed here)."""
    return SweepSpec(
        "grid",
        [Axis("eps", n0, None, 0.1, stop), Axis("vo", n1, None, 0.5, 2.0)],
        None,
        {"ba": 2.0, "kappa_ratio": 0.5},
        "kappa_ratio",
        "velocity-jump",
        1e-10,
        "critical",
    )


def block(n: int, seed: int = 0) -> dict[str, np.ndarray]:
    rng = np.random.default_rng(seed)
    return {
        "critical_size": rng.random(n),
        "rel_accuracy": np.full(n, 1e-11),
        "kind": np.ones(n, np.int8),
        "method": np.zeros(n, np.int8),
        "failed": np.zeros(n, np.bool_),
        "on_boundary": np.zeros(n, np.bool_),
    }


def test_indices_beyond_2_31(db: Database) -> None:
    """A sweep of 2.5e9 points (> 2^31): chunk rows, a stored block near its end, the
    status counts and reads of every block (no bound) and of a range all hold the
    64-bit indices exactly (on PostgreSQL an INTEGER column or a 2^62 sentinel bound
    fails with 'integer out of range')."""
    st = SweepStore(db)
    spec = grid(50_000, 50_000)
    assert spec.n_total == 2_500_000_000 > 2**31
    cp = 1_000_000
    cr = st.create("big", spec, cp, "t", window=2)
    assert cr.created and cr.todo == [0, 1]
    last = spec.n_total // cp - 1
    i0, i1 = last * cp, spec.n_total
    assert i0 > 2**31
    arrays = block(16)  # only the first 16 points carry data: enough for the indices
    assert st.store_block("big", last, i0, i1, encode_block(arrays), {3: "E: x"})
    s = st.status("big")
    assert s is not None
    assert (s["n_total"], s["n_done"], s["n_failed"], s["n_chunks"]) == (
        2_500_000_000,
        cp,
        1,
        2500,
    )
    got = list(st.blocks("big"))
    assert [(b.i0, b.i1) for b in got] == [(i0, i1)]
    assert np.array_equal(got[0].arrays["critical_size"], arrays["critical_size"])
    assert [(b.i0, b.i1) for b in st.blocks("big", i0 + 5, i0 + 6)] == [(i0, i1)]
    assert list(st.blocks("big", 0, i0)) == []
    assert st.failures("big") == [(i0 + 3, "E: x")]
    assert st.delete("big")


def test_complete_chunk_stores_finishes_and_dispatches_once(db: Database) -> None:
    """complete_chunk = store_block + finish_chunk + next_chunks in one transaction: the
    block is stored once (a redelivered chunk stores nothing), the next pending chunk is
    marked queued within the window, the last chunk closes the sweep, and a chunk whose
    block is already stored is reported by the claim and only marked done."""
    st = SweepStore(db)
    spec = grid(3, 10)  # 30 points, chunks of 10
    assert st.create("s", spec, 10, "t", window=1).todo == [0]
    r0 = st.claim("s", 0, 30.0)
    assert r0 is not None and (r0.i0, r0.i1, r0.stored) == (0, 10, False)
    b0 = block(10, 0)
    done = st.complete_chunk("s", 0, (0, 10, encode_block(b0), {4: "E: four"}), 1)
    assert done.stored and done.todo == [1]
    again = st.complete_chunk("s", 0, (0, 10, encode_block(block(10, 9)), {}), 1)
    assert not again.stored and again.todo == []  # chunk 1 is in flight: window full
    blk = st.read_block("s", 0)
    assert blk is not None and np.array_equal(blk.arrays["critical_size"], b0["critical_size"])
    assert blk.errors == {4: "E: four"}
    # chunk 2's block was stored by an earlier attempt that died before its bookkeeping
    assert st.store_block("s", 2, 20, 30, encode_block(block(10, 2)), {})
    r1 = st.claim("s", 1, 30.0)
    assert r1 is not None and not r1.stored
    assert st.complete_chunk("s", 1, (10, 20, encode_block(block(10, 1)), {}), 1).todo == [2]
    r2 = st.claim("s", 2, 30.0)
    assert r2 is not None and r2.stored
    assert st.complete_chunk("s", 2, None, 1) == Completed(False, [])
    s = st.status("s")
    assert s is not None and (s["status"], s["n_done"], s["n_failed"]) == ("done", 30, 1)
    # a cancelled sweep dispatches nothing; a purged one stores nothing
    assert st.create("c", grid(3, 10, 0.8), 10, "t", window=1).todo == [0]
    assert st.claim("c", 0, 30.0) is not None
    st.cancel("c")
    assert st.complete_chunk("c", 0, (0, 10, encode_block(block(10)), {}), 1) == Completed(True, [])
    st.delete("c")
    assert st.complete_chunk("c", 1, (10, 20, encode_block(block(10)), {}), 1) == Completed(
        False, []
    )


def test_constant_arrays_are_stored_once(db: Database) -> None:
    """A block whose arrays are each one repeated value (a region decided in closed
    form, NaN included) is stored as one element per array and read back bit for bit,
    mixed with ordinary arrays, through the store."""
    st = SweepStore(db)
    n = 100_000
    arrays = {
        "critical_size": np.zeros(n),
        "rel_accuracy": np.full(n, np.nan),
        "kind": np.zeros(n, np.int8),
        "method": np.full(n, 3, np.int8),
        "failed": np.zeros(n, np.bool_),
        "on_boundary": np.r_[np.zeros(n - 1, np.bool_), True],  # not constant
    }
    st.create("k", grid(1, n), n, "t", window=1)
    data = encode_block(arrays)
    assert len(data) < 2000  # one element per constant array (zip entries ~150 B each)
    assert st.store_block("k", 0, 0, n, data, {})
    blk = st.read_block("k", 0)
    assert blk is not None and set(blk.arrays) == set(arrays)
    for name, a in arrays.items():
        got = blk.arrays[name]
        assert got.dtype == a.dtype and got.tobytes() == a.tobytes(), name
    some = st.read_block("k", 0, ("kind", "on_boundary"))
    assert some is not None and set(some.arrays) == {"kind", "on_boundary"}


def _worker(st: SweepStore, ids: list[str], stop: float, errors: list[BaseException]) -> None:
    rng = random.Random(threading.get_ident())
    while time.monotonic() < stop:
        sid = rng.choice(ids)
        try:
            spec = st.get_spec(sid)
            if spec is None:
                continue
            for idx in st.next_chunks(sid, 4) or [rng.randrange(4)]:
                rng_ = st.claim(sid, idx, lease_s=0.2)
                if rng_ is None:
                    continue
                st.heartbeat(sid, idx)
                n = rng_.i1 - rng_.i0
                data = encode_block(block(n, idx))
                r = rng.random()
                if r < 0.2:  # the worker's path: one transaction
                    st.complete_chunk(sid, idx, (rng_.i0, rng_.i1, data, {}), 4)
                elif r < 0.4:  # a task chaining work units of up to 3 chunks
                    unit = [rng_]
                    while unit:
                        st.heartbeat(sid, *[u.idx for u in unit])
                        if rng.random() < 0.1:  # an error: the unit is given back
                            st.release_chunk(sid, unit[0].idx, [u.idx for u in unit])
                            break
                        run = [
                            (u.idx, (u.i0, u.i1, encode_block(block(u.i1 - u.i0, u.idx)), {}))
                            for u in unit
                        ]
                        unit = st.complete_run(sid, run, 4, rng.randrange(4)).next
                elif r < 0.55:  # a chaining task: each completion claims the next chunk
                    done = st.complete_chunk(sid, idx, (rng_.i0, rng_.i1, data, {}), 4, True)
                    while done.next is not None:
                        nx = done.next
                        data = encode_block(block(nx.i1 - nx.i0, nx.idx))
                        done = st.complete_chunk(sid, nx.idx, (nx.i0, nx.i1, data, {}), 4, True)
                else:
                    st.store_block(sid, idx, rng_.i0, rng_.i1, data, {})
                    st.finish_chunk(sid, idx, complete=True)
        except BaseException as exc:  # noqa: BLE001 - reported by the test
            errors.append(exc)
            return


def _canceller(st: SweepStore, ids: list[str], stop: float, errors: list[BaseException]) -> None:
    rng = random.Random(threading.get_ident())
    while time.monotonic() < stop:
        sid = rng.choice(ids)
        try:
            op = rng.random()
            if op < 0.4:
                st.cancel(sid)
            elif op < 0.6:
                st.cancel(sid)
                st.delete(sid)
            else:
                st.create(sid, grid(4, 10), 10, "t", window=2)  # resumes or re-creates
            st.status(sid)
        except BaseException as exc:  # noqa: BLE001 - reported by the test
            errors.append(exc)
            return


def _reaper(st: SweepStore, stop: float, errors: list[BaseException]) -> None:
    while time.monotonic() < stop:
        try:
            st.reap_expired(0.05)
            st.close_finished(4)
            st.stale_chunks(0.05, 4)
        except BaseException as exc:  # noqa: BLE001 - reported by the test
            errors.append(exc)
            return


def test_racing_workers_cancels_purges_reapers(db: Database) -> None:
    """Six workers claiming, storing and finishing chunks, two threads cancelling,
    purging and resuming, one reaper, on three small sweeps for 6 s: no deadlock (on
    PostgreSQL a deadlock is an error 'deadlock detected' raised in one of them), no
    foreign-key violation, and afterwards every sweep is consistent: its blocks are
    disjoint chunks, a done sweep has every block."""
    st = SweepStore(db)
    ids = [f"s{k}" for k in range(3)]
    for sid in ids:
        st.create(sid, grid(4, 10), 10, "t", window=2)
    stop = time.monotonic() + 6.0
    errors: list[BaseException] = []
    threads = [threading.Thread(target=_worker, args=(st, ids, stop, errors)) for _ in range(6)]
    threads += [threading.Thread(target=_canceller, args=(st, ids, stop, errors)) for _ in range(2)]
    threads.append(threading.Thread(target=_reaper, args=(st, stop, errors)))
    for t in threads:
        t.start()
    for t in threads:
        t.join(120)
    assert not any(t.is_alive() for t in threads), "a thread hangs (lock wait)"
    assert not errors, "".join(f"{type(e).__name__}: {e}\n" for e in errors)
    for sid in ids:
        s = st.status(sid)
        if s is None:
            continue
        spans = sorted((b.i0, b.i1) for b in st.blocks(sid))
        assert all(a[1] <= b[0] for a, b in zip(spans, spans[1:], strict=False))
        if s["status"] == "done":
            assert sum(b - a for a, b in spans) == s["n_total"] == 40
        assert _counters(db, sid) == _recount(db, sid)  # every path counted once


def test_schema_1_database_is_upgraded(db: Database) -> None:
    """A database at revision 0001 (schema version 1: sweep indices INTEGER on
    PostgreSQL) is upgraded at start: the columns become BIGINT and a 2.5e9-point sweep
    fits."""
    from alembic import command
    from sqlalchemy import text

    from rsfapp.db import migrate
    from rsfapp.db.migrations.versions.v0002_sweep_bigint import BIGINT_COLUMNS

    assert db.ensure_schema() is None
    pg = db.dialect == "postgresql"
    with db.writer.begin() as conn:
        command.downgrade(migrate.config(conn), "0001")
    again = Database(db.url)
    try:
        assert again.ensure_schema() == "0001"
        assert again.schema_version() == migrate.head() >= "0003"  # later revisions too
        if pg:
            with again.reader.connect() as conn:
                types = dict(
                    conn.execute(
                        text(
                            "SELECT table_name || '.' || column_name, data_type "
                            "FROM information_schema.columns "
                            "WHERE table_name LIKE 'sweep%' OR table_name = 'key_usage'"
                        )
                    ).all()
                )
            for table, cols in BIGINT_COLUMNS.items():
                for c in cols:
                    assert types[f"{table}.{c}"] == "bigint", (table, c)
            assert types["key_usage.points"] == "bigint"  # revision 0003
        st = SweepStore(again)
        assert st.create("big", grid(50_000, 50_000), 1_000_000, "t", window=1).created
    finally:
        again.dispose()


def _disk_bytes(db: Database) -> int:
    """SQLite: the database file plus its WAL; PostgreSQL: sweep_blocks with its TOAST
    table and indexes (pg_total_relation_size)."""
    from sqlalchemy import text

    if db.dialect == "sqlite":
        path = Path(db.url.split("///", 1)[1])
        wal = Path(str(path) + "-wal")
        return path.stat().st_size + (wal.stat().st_size if wal.exists() else 0)
    with db.reader.connect() as conn:
        return int(conn.execute(text("SELECT pg_total_relation_size('sweep_blocks')")).scalar())


def test_purge_gives_the_disk_back(db: Database) -> None:
    """A sweep of 300 blocks of 20 000 incompressible float64 (~48 MB stored), then a
    purge: the database shrinks back to within 10 % of that growth (SQLite: file + WAL;
    PostgreSQL: the table with its TOAST data).  Before, SQLite kept the file and WAL at
    full size and PostgreSQL kept the table."""
    st = SweepStore(db)
    st.create("keep", grid(2, 5), 10, "t", window=1)  # another sweep stays
    before = _disk_bytes(db)
    n = 20_000
    st.create("big", grid(300, n), n, "t", window=1)
    rng = np.random.default_rng(1)
    for idx in range(300):
        data = encode_block({"critical_size": rng.random(n)})
        assert st.store_block("big", idx, idx * n, (idx + 1) * n, data, {})
    full = _disk_bytes(db)
    grown = full - before
    assert grown > 40e6, grown
    assert st.delete("big")
    after = _disk_bytes(db)
    assert after - before < 0.1 * grown, (before, full, after)
    assert st.status("keep") is not None


def test_purge_converts_an_old_sqlite_file_once(tmp_path: Path) -> None:
    """A SQLite file made before incremental auto-vacuum (mode NONE) is converted by its
    first purge (one full VACUUM) and shrinks; later purges vacuum incrementally."""
    import sqlite3

    path = tmp_path / "old.sqlite3"
    con = sqlite3.connect(path)
    con.execute("CREATE TABLE older (a)")  # the file exists with auto_vacuum = NONE
    con.close()
    db = Database(f"sqlite:///{path}")
    try:
        st = SweepStore(db)
        n = 20_000
        st.create("big", grid(50, n), n, "t", window=1)
        rng = np.random.default_rng(2)
        for idx in range(50):
            data = encode_block({"critical_size": rng.random(n)})
            assert st.store_block("big", idx, idx * n, (idx + 1) * n, data, {})
        assert st.delete("big")
        assert path.stat().st_size < 1e6
        con = sqlite3.connect(path)
        assert con.execute("PRAGMA auto_vacuum").fetchone()[0] == 2
        con.close()
    finally:
        db.dispose()


@pytest.mark.parametrize("path", ["finish_chunk", "complete_chunk"])
def test_a_purged_and_resubmitted_sweep_is_not_closed_by_an_old_worker(
    db: Database, path: str
) -> None:
    """A worker that stored chunk 0 of a sweep that was then purged and submitted again
    (same id) finishes its chunk (through either way a worker finishes one; with
    ``complete_chunk`` as a worker whose claim said the block was stored): the new
    sweep's chunk 0 has no block, so it must stay to be computed, and the sweep must not
    be 'done' with 10 of 20 points (found by the race test above: a 'done' sweep with 30
    of its 40 points)."""
    st = SweepStore(db)
    st.create("s", grid(2, 10), 10, "t", window=2)
    rng = st.claim("s", 0, lease_s=30.0)
    assert rng is not None
    assert st.store_block("s", 0, rng.i0, rng.i1, encode_block(block(10)), {})
    assert st.delete("s")
    st.create("s", grid(2, 10), 10, "t", window=2)
    r1 = st.claim("s", 1, lease_s=30.0)
    assert r1 is not None
    assert st.store_block("s", 1, r1.i0, r1.i1, encode_block(block(10, 1)), {})
    st.finish_chunk("s", 1, complete=True)
    if path == "finish_chunk":  # the old worker, after the purge
        st.finish_chunk("s", 0, complete=True)
    else:
        assert st.complete_chunk("s", 0, None, window=2).todo == []
    s = st.status("s")
    assert s is not None and s["status"] != "done"
    assert [(b.i0, b.i1) for b in st.blocks("s")] == [(10, 20)]
    r0 = st.claim("s", 0, lease_s=30.0)
    assert r0 is not None  # still to compute
    assert st.store_block("s", 0, r0.i0, r0.i1, encode_block(block(10)), {})
    st.finish_chunk("s", 0, complete=True)
    s = st.status("s")
    assert s is not None and s["status"] == "done"


def test_an_unfinished_chunk_of_a_resumed_sweep_goes_back_to_pending(db: Database) -> None:
    """Cancel while a worker runs chunk 0, resume, then the worker gives up its chunk
    (it saw the cancel): the chunk is pending again, not cancelled, so the resumed sweep
    can finish."""
    st = SweepStore(db)
    st.create("s", grid(1, 10), 10, "t", window=1)
    assert st.claim("s", 0, lease_s=30.0) is not None
    assert st.cancel("s") == ("cancelled", True)
    st.create("s", grid(1, 10), 10, "t", window=1)  # resume
    st.finish_chunk("s", 0, complete=False)
    assert st.next_chunks("s", 1) == [0]
    r0 = st.claim("s", 0, lease_s=30.0)
    assert r0 is not None
    assert st.store_block("s", 0, r0.i0, r0.i1, encode_block(block(10)), {})
    st.finish_chunk("s", 0, complete=True)
    s = st.status("s")
    assert s is not None and s["status"] == "done"


def test_claims_and_completions_keep_the_window_and_the_start_time(db: Database) -> None:
    """The slimmed claim (one read of the chunk with its stored flag, the sweep's update
    only at its first claim) and completion (one count of the chunks left and in flight,
    the next ones queued by one UPDATE ... RETURNING): the sweep starts running at its
    first claim and keeps that start time; each completion queues the lowest pending
    chunks up to the window, in index order; the last completion closes the sweep."""
    st = SweepStore(db)
    created = st.create("w", grid(7, 10), 10, "v", window=3)
    assert created.todo == [0, 1, 2]
    r0 = st.claim("w", 0, 60.0)
    assert r0 is not None and not r0.stored
    first = st.status("w")
    assert first is not None and first["status"] == "running" and first["started_at"]
    r1 = st.claim("w", 1, 60.0)
    assert r1 is not None
    assert st.status("w")["started_at"] == first["started_at"]  # type: ignore[index]
    # chunks 0 and 1 running, 2 queued: one completion frees one place
    assert st.complete_chunk("w", 0, (0, 10, encode_block(block(10)), {}), 3).todo == [3]
    # a wider window now: 2 and 3 queued, so the three lowest pending chunks, in order
    assert st.complete_chunk("w", 1, (10, 20, encode_block(block(10)), {}), 5).todo == [4, 5, 6]
    for idx in (2, 3, 4, 5, 6):
        assert st.claim("w", idx, 60.0) is not None
        st.complete_chunk("w", idx, (10 * idx, 10 * idx + 10, encode_block(block(10)), {}), 5)
    final = st.status("w")
    assert final is not None and final["status"] == "done" and final["n_done"] == 70


def _recount(db: Database, sid: str) -> tuple[int, int, int]:
    """(chunks done, points stored, failed points) of a sweep counted from its chunk and
    block rows: the independent check of its counters."""
    from sqlalchemy import and_, func, select

    from rsfapp.db.tables import chunks, sweep_blocks

    with db.reader.connect() as conn:
        done = conn.execute(
            select(func.count())
            .select_from(chunks)
            .where(and_(chunks.c.sweep_id == sid, chunks.c.status == "done"))
        ).scalar()
        pts, failed = conn.execute(
            select(
                func.coalesce(func.sum(sweep_blocks.c.i1 - sweep_blocks.c.i0), 0),
                func.coalesce(func.sum(sweep_blocks.c.n_failed), 0),
            ).where(sweep_blocks.c.sweep_id == sid)
        ).one()
    return int(done or 0), int(pts), int(failed)


def _counters(db: Database, sid: str) -> tuple[int, int, int]:
    """The sweep row's counters (chunks_done, points_done, points_failed); (0, 0, 0) if
    the sweep is gone, as its recount is."""
    from sqlalchemy import select

    from rsfapp.db.tables import sweeps

    with db.reader.connect() as conn:
        r = conn.execute(
            select(sweeps.c.chunks_done, sweeps.c.points_done, sweeps.c.points_failed).where(
                sweeps.c.id == sid
            )
        ).first()
    return (0, 0, 0) if r is None else (int(r[0]), int(r[1]), int(r[2]))


def _chunk_row(db: Database, sid: str, idx: int) -> tuple[str, str | None, int]:
    from sqlalchemy import and_, select

    from rsfapp.db.tables import chunks

    with db.reader.connect() as conn:
        r = conn.execute(
            select(chunks.c.status, chunks.c.owner, chunks.c.attempts).where(
                and_(chunks.c.sweep_id == sid, chunks.c.idx == idx)
            )
        ).one()
    return str(r[0]), r[1], int(r[2])


def test_completion_chains_to_the_next_pending_chunk(db: Database) -> None:
    """complete_chunk with ``chain`` claims the sweep's lowest *pending* chunk for this
    process in the same transaction (running, this owner, one attempt) and sends
    nothing; a queued chunk is left to its message; with nothing pending it falls back
    to the dispatch; a cancelled sweep chains nothing; a chained chunk whose worker dies
    is taken back by the reaper after its lease (no point lost), and a completion
    delivered twice stores and counts nothing twice."""
    st = SweepStore(db)
    assert st.create("c", grid(5, 10), 10, "t", window=2).todo == [0, 1]
    assert st.claim("c", 0, 30.0) is not None
    d0 = st.complete_chunk("c", 0, (0, 10, encode_block(block(10)), {}), 2, chain=True)
    assert d0 == Completed(True, [], ChunkRange(20, 30, False, 2))  # 1 waits for its message
    assert _chunk_row(db, "c", 2) == ("running", owner_id(), 1)
    assert _chunk_row(db, "c", 1)[0] == "queued"
    d2 = st.complete_chunk("c", 2, (20, 30, encode_block(block(10, 2)), {}), 2, chain=True)
    assert d2.next is not None and d2.next.idx == 3 and d2.todo == []
    d3 = st.complete_chunk("c", 3, (30, 40, encode_block(block(10, 3)), {}), 2, chain=True)
    assert d3.next is not None and d3.next.idx == 4
    # the worker holding chunk 4 dies: its lease expires and the reaper requeues it
    time.sleep(0.1)
    assert st.reap_expired(0.05) == [("c", 4)]
    assert _chunk_row(db, "c", 4)[:2] == ("queued", None)
    r4 = st.claim("c", 4, 30.0)
    assert r4 is not None and r4.idx == 4 and _chunk_row(db, "c", 4)[2] == 2
    d4 = st.complete_chunk("c", 4, (40, 50, encode_block(block(10, 4)), {}), 2, chain=True)
    assert d4 == Completed(True, [])  # nothing pending: 1 is queued (in flight)
    again = st.complete_chunk("c", 4, (40, 50, encode_block(block(10, 9)), {}), 2, chain=True)
    assert again == Completed(False, [])
    assert _counters(db, "c") == _recount(db, "c") == (4, 40, 0)
    assert st.claim("c", 1, 30.0) is not None
    assert st.complete_chunk("c", 1, (10, 20, encode_block(block(10, 1)), {}), 2, True) == (
        Completed(True, [])
    )
    s = st.status("c")
    assert s is not None and (s["status"], s["n_done"]) == ("done", 50) and s["finished_at"]
    assert st.claim("c", 1, 30.0) is None  # a message left behind: nothing to do
    # a cancelled sweep: the running chunk is stored, nothing chained
    assert st.create("k", grid(3, 10), 10, "t", window=1).todo == [0]
    assert st.claim("k", 0, 30.0) is not None
    st.cancel("k")
    assert st.complete_chunk("k", 0, (0, 10, encode_block(block(10)), {}), 1, True) == (
        Completed(True, [])
    )
    assert [_chunk_row(db, "k", i)[0] for i in (1, 2)] == ["cancelled", "cancelled"]


def test_work_units_complete_in_one_transaction(db: Database) -> None:
    """complete_run stores a work unit's blocks (one INSERT), marks them done and counts
    them in one transaction and claims the next unit of up to ``claim`` pending chunks
    (lowest first, running, this owner); a block stored before (by another worker) is
    not stored or counted twice, a unit delivered twice changes nothing; heartbeat
    renews a whole unit and tells when all of its chunks were taken back; release_chunk
    gives back the chunk being retried (queued: its retry message) and the rest of the
    unit (pending); the blocks read back bit for bit."""
    st = SweepStore(db)
    assert st.create("u", grid(10, 10), 10, "t", window=1).todo == [0]
    assert st.claim("u", 0, 30.0) is not None
    blocks = {i: block(10, i) for i in range(10)}

    def data(
        i: int, errors: dict[int, str] | None = None
    ) -> tuple[int, int, bytes, dict[int, str]]:
        return (10 * i, 10 * i + 10, encode_block(blocks[i]), errors or {})

    d0 = st.complete_run("u", [(0, data(0))], 1, claim=3)
    assert d0 == RunCompleted(1, [], [ChunkRange(10 * i, 10 * i + 10, False, i) for i in (1, 2, 3)])
    assert [_chunk_row(db, "u", i) for i in (1, 2, 3)] == [("running", owner_id(), 1)] * 3
    assert st.heartbeat("u", 1, 2, 3)
    # another worker stored chunk 2's block meanwhile (a chunk delivered twice)
    assert st.store_block("u", 2, 20, 30, encode_block(blocks[2]), {})
    d1 = st.complete_run("u", [(1, data(1, {3: "E: x"})), (2, data(2)), (3, data(3))], 1, 16)
    assert d1.stored == 2 and [r.idx for r in d1.next] == [4, 5, 6, 7, 8, 9]
    assert _counters(db, "u") == _recount(db, "u") == (4, 40, 1)
    again = st.complete_run("u", [(1, data(1)), (2, data(2)), (3, data(3))], 1, 2)
    assert again == RunCompleted(0, [], [])  # nothing pending: 4-9 are held
    assert _counters(db, "u") == _recount(db, "u") == (4, 40, 1)
    # a unit's chunk taken back by the reaper: the unit's heartbeat says so
    time.sleep(0.1)
    assert sorted(st.reap_expired(0.05)) == [("u", i) for i in range(4, 10)]
    assert not st.heartbeat("u", 4, 5)
    for i in (4, 5, 6):
        assert st.claim("u", i, 30.0) is not None
    assert st.heartbeat("u", 4, 5, 6) and st.heartbeat("u", 6, 7)  # 7 lost, 6 held
    st.release_chunk("u", 5, [4, 5, 6])  # an error while computing chunk 5
    assert [_chunk_row(db, "u", i)[:2] for i in (4, 5, 6)] == [
        ("pending", None),
        ("queued", None),
        ("pending", None),
    ]
    for i in (5, 4, 6, 7, 8, 9):
        assert st.claim("u", i, 30.0) is not None
    d2 = st.complete_run("u", [(i, data(i)) for i in (4, 5, 6, 7, 8, 9)], 1, 4)
    assert d2 == RunCompleted(6, [], [])
    s = st.status("u")
    assert s is not None and (s["status"], s["n_done"]) == ("done", 100)
    assert _counters(db, "u") == _recount(db, "u") == (10, 100, 1)
    got = {b.i0 // 10: b for b in st.blocks("u")}
    assert sorted(got) == list(range(10)) and got[1].errors == {3: "E: x"}
    for i, b in got.items():
        for name, a in blocks[i].items():
            assert b.arrays[name].tobytes() == a.tobytes(), (i, name)
    assert decode_block(data(0)[2])["kind"].tobytes() == blocks[0]["kind"].tobytes()
    # a purged sweep: a unit finishing afterwards stores nothing
    assert st.create("p", grid(2, 10), 10, "t", window=1).todo == [0]
    assert st.claim("p", 0, 30.0) is not None
    assert st.delete("p")
    assert st.complete_run("p", [(0, data(0))], 1, 4) == RunCompleted(0, [], [])
    assert st.read_block("p", 0) is None


def test_lanes_follow_the_live_worker_processes(db: Database) -> None:
    """With the lease given, a sweep keeps at most as many chunks in flight as the live
    workers in the registry have processes (a chaining worker keeps its lane busy
    without messages); no worker registered, or no lease given: the window; a worker
    silent for longer than the lease does not count."""
    from sqlalchemy import update

    from rsfapp.db.ops import workers
    from rsfapp.health import register_worker

    st = SweepStore(db)
    assert st.create("a", grid(10, 10), 10, "t", window=4, lease_s=30.0).todo == [0, 1, 2, 3]
    register_worker(db, "w1", "host-a", 11, 1, stale_after_s=3600)
    register_worker(db, "w2", "host-b", 12, 2, stale_after_s=3600)
    assert st.create("b", grid(10, 10), 10, "t", window=4, lease_s=30.0).todo == [0, 1, 2]
    assert st.create("c", grid(10, 10), 10, "t", window=2, lease_s=30.0).todo == [0, 1]
    assert st.create("d", grid(10, 10), 10, "t", window=4).todo == [0, 1, 2, 3]
    with db.write() as conn:
        conn.execute(
            update(workers).where(workers.c.name == "w2").values(heartbeat=time.time() - 60)
        )
    assert st.create("e", grid(10, 10), 10, "t", window=4, lease_s=30.0).todo == [0]
    # a completion that does not chain tops the lanes up the same way
    assert st.claim("e", 0, 30.0) is not None
    done = st.complete_chunk("e", 0, (0, 10, encode_block(block(10)), {}), 4, lease_s=30.0)
    assert done.todo == [1]


def test_progress_counters_match_a_recount(db: Database) -> None:
    """The sweep row's counters (chunks done, points stored, failed points) equal a
    recount of its chunk and block rows after every path that stores a block or marks a
    chunk done (the worker's completion, a completion delivered twice, a block stored
    alone then finished, a completion without a block), and the status reads them."""
    st = SweepStore(db)
    st.create("p", grid(6, 10), 10, "t", window=6)

    def check(expected: tuple[int, int, int]) -> None:
        assert _counters(db, "p") == _recount(db, "p") == expected
        s = st.status("p")
        assert s is not None and (s["n_done"], s["n_failed"]) == expected[1:]

    check((0, 0, 0))
    assert st.claim("p", 0, 30.0) is not None
    st.complete_chunk("p", 0, (0, 10, encode_block(block(10)), {1: "E: a", 7: "E: b"}), 6)
    check((1, 10, 2))
    st.complete_chunk("p", 0, (0, 10, encode_block(block(10, 5)), {}), 6)  # delivered again
    check((1, 10, 2))
    assert st.store_block("p", 1, 10, 20, encode_block(block(10, 1)), {0: "E: c"})
    check((1, 20, 3))  # stored, its chunk not yet done
    st.finish_chunk("p", 1, complete=True)
    st.finish_chunk("p", 1, complete=True)
    check((2, 20, 3))
    st.complete_chunk("p", 2, None, 6)  # no block stored: the chunk is not done
    check((2, 20, 3))
    for idx in range(2, 6):
        assert st.claim("p", idx, 30.0) is not None
        st.complete_chunk("p", idx, (10 * idx, 10 * idx + 10, encode_block(block(10)), {}), 6)
    check((6, 60, 3))
    s = st.status("p")
    assert s is not None and s["status"] == "done"
