"""A large sweep end to end on the multi-host stack, then every way of reading it back.

Stack (all on this machine, loopback only): PostgreSQL, Redis, ``rsf api`` and two Celery
workers acting as two hosts (solo pool, one process each), as tests/e2e/test_multihost.py
starts them.  Steps:

1. rsfcore alone: ``rsfcore.batch.critical_points`` on the same points, two processes in
   parallel (the worker cores) with a worker's memory setting
   (:func:`rsfapp.memory.keep_freed_memory`), parameters generated first and not timed,
   blocks dealt out alternately, in 10^6-point blocks and in 2^16-point parts (those of
   the unfused chunk path, :data:`rsfapp.sweepdata.PART_POINTS`; a worker computes a
   grid's chunk fused, :func:`rsfcore.batch.critical_grid`, in one call); run before the sweep and again after it (the ratios are against the mean: the
   machine is shared and its load moves).  The primary reference is the faster of the
   two per CPU second (the best a library user gets from the public batch call); the
   other is printed too.
2. The sweep: critical sizes over a 3-D grid (kappa_ratio, eps, ba; default "cheap"
   points: kappa_ratio < 1, decided in closed form), submitted and timed to ``done`` (the server's created_at -> finished_at);
   points/s against step 1, bytes stored per point (result blobs; PostgreSQL table size),
   peak RSS of the API and of each worker (psutil, sampled every 0.1 s, process trees),
   CPU seconds of each process tree during the sweep and, per worker, of its main thread
   (the task) against its other threads (lease renewal, reaper, Celery's timers).
3. Reads, one at a time, each with the API's peak RSS over its idle RSS (measured just
   before it) and over the idle RSS before the sweep, time to first byte and total time:
   the whole sweep as NetCDF, CSV and JSON; a 1 % slice (NetCDF); the /diagram PNG of one
   2-D slice; a lazy xarray read of one 2-D slice through the Zarr store (zarr + fsspec)
   and of one whole variable (``kind``: every chunk);
   then two NetCDF downloads at once (the second is refused 503 with Retry-After while the
   first is built: one build per API process) and two CSV downloads at once.  The API's
   idle RSS (settled 1 s after each step) is recorded before the sweep, after it and after
   every read (``api_idle_mb``), to see whether anything is kept.

    python bench/bench_sweep_e2e.py --shape 100 100 100 [--formats netcdf,csv,json]
    python bench/bench_sweep_e2e.py --shape 100 100 10000 --no-reference --max-download-s 30

Prints the figures and writes them as JSON to bench/out/bench_sweep_e2e_<kind>_<n>.json.  Timing
only: correctness of the same paths is tested in tests/ (multihost e2e, subsets, lazy).
"""

from __future__ import annotations

import argparse
import contextlib
import json
import os
import sys
import tempfile
import threading
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path
from typing import Any

import httpx
import psutil

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from tests.conftest import (  # noqa: E402
    Postgres,
    Proc,
    Redis,
    Worker,
    free_port,
    postgres_bindir,
    service_env,
)


def _epoch(iso: str) -> float:
    from datetime import datetime

    return datetime.fromisoformat(iso.replace("Z", "+00:00")).timestamp()


def body(shape: tuple[int, int, int], cheap: bool) -> dict[str, Any]:
    lo, hi = (0.3, 0.95) if cheap else (1.01, 5.0)
    return {
        "axes": [
            {"name": "kappa_ratio", "start": lo, "stop": hi, "n": shape[0]},
            {"name": "eps", "start": 0.0, "stop": 0.6, "n": shape[1]},
            {"name": "ba", "start": 1.2, "stop": 20.0, "n": shape[2]},
        ],
        "fixed": {"vo": 1.0},
    }


def _core_init() -> None:
    """A reference process gets the memory setting of a worker process
    (:func:`rsfapp.memory.keep_freed_memory`, set in worker.celery_app): without it each
    call's fresh arrays are page-faulted in again (~14 ms more per 10^6 points in one
    call), which would make the reference unfairly slow."""
    from rsfapp.memory import keep_freed_memory

    keep_freed_memory()


def _core_part(args: tuple[dict[str, Any], list[tuple[int, int]]]) -> tuple[int, float, float]:
    b, parts = args
    from rsfapp.grid import expand
    from rsfapp.requests import SweepRequest
    from rsfcore import batch

    spec = expand(SweepRequest(**b), 10**9)
    p = spec.params(0, 8)
    batch.critical_points(p["ba"], p["kappa"], p["eps"], p["vo"], rtol=spec.rtol)  # compile
    t_all = cpu = 0.0
    m = 0
    for i0, i1 in parts:
        p = spec.params(i0, i1)
        t, c = time.perf_counter(), time.process_time()
        batch.critical_points(p["ba"], p["kappa"], p["eps"], p["vo"], rtol=spec.rtol)
        t_all += time.perf_counter() - t
        cpu += time.process_time() - c
        m += i1 - i0
    return m, t_all, cpu


def rsfcore_rate(
    b: dict[str, Any], n: int, procs: int, blk: int | None = None
) -> tuple[float, float]:
    """Points/s of the batch kernel in ``procs`` processes (kernel time only, parameters
    generated outside the timing).  The points are dealt out in blocks of ``blk``
    (default min(10^6, n/100)) points, block k to process k mod procs, so both processes
    get the same mix of cheap and slow parts of the grid (contiguous halves would make
    the slower half the bottleneck and flatter the service).  Returns (points/s of wall
    time, points per CPU second)."""
    blk = blk or max(1, min(1_000_000, n // 100))
    blocks = [(i, min(n, i + blk)) for i in range(0, n, blk)]
    with ProcessPoolExecutor(procs, initializer=_core_init) as ex:
        res = list(ex.map(_core_part, [(b, blocks[k::procs]) for k in range(procs)]))
    pts = sum(r[0] for r in res)
    return pts / max(r[1] for r in res), pts / sum(r[2] for r in res)


def reference_blocks(n: int) -> dict[str, int]:
    """The reference's block sizes: {name: points per batch call}: 10^6-point blocks
    (or n/100) and, when that is larger, the part size of the unfused chunk path
    (:data:`rsfapp.sweepdata.PART_POINTS`: cheap points run faster in parts, their data
    stay in the core's cache)."""
    from rsfapp.sweepdata import PART_POINTS

    blk = max(1, min(1_000_000, n // 100))
    out = {f"blocks of {blk}": blk}
    if blk > PART_POINTS:
        out[f"parts of {PART_POINTS}"] = PART_POINTS
    return out


def reference_rates(b: dict[str, Any], n: int) -> dict[str, list[tuple[float, float]]]:
    """rsfcore's batch kernel on the sweep's points at each block size of
    :func:`reference_blocks`: {name: [(points/s of wall time, points per CPU second)]}."""
    out = {}
    for name, blk in reference_blocks(n).items():
        out[name] = [rsfcore_rate(b, n, 2, blk)]
        print(
            f"rsfcore batch kernel, 2 processes, {name} points: {out[name][0][0]:,.0f} "
            f"points/s, {out[name][0][1]:,.0f} points per CPU second"
        )
    return out


def compare(
    refs: dict[str, list[tuple[float, float]]], n: int, dt: float, all_cpu: float, work_cpu: float
) -> dict[str, Any]:
    """The service against each reference (the mean of its runs): points/s of wall time
    and points per CPU second of the stack (workers, API, PostgreSQL, Redis) and of the
    workers alone.  The primary reference is the fastest per CPU second: the best a
    library user gets from rsfcore's public batch call on these points (same memory
    setting as a worker, parameters generated outside the timing)."""
    per: dict[str, dict[str, Any]] = {}
    for k, runs in refs.items():
        wall = sum(r[0] for r in runs) / len(runs)
        cpu = sum(r[1] for r in runs) / len(runs)
        per[k] = {
            "points_per_s": round(wall),
            "points_per_cpu_s": round(cpu),
            "service_over_wall": round(n / dt / wall, 3),
            "stack_over_cpu": round(n / all_cpu / cpu, 3),
            "workers_over_cpu": round(n / work_cpu / cpu, 3),
        }
    best = max(per, key=lambda k: per[k]["points_per_cpu_s"])
    return {
        "rsfcore": per,
        "rsfcore_primary": best,
        "service_over_rsfcore": per[best]["service_over_wall"],
        "service_over_rsfcore_cpu": per[best]["stack_over_cpu"],
        "workers_over_rsfcore_cpu": per[best]["workers_over_cpu"],
    }


def thread_cpu(pid: int) -> dict[int, float]:
    """CPU seconds (user + system) of each thread of a process, by thread id (the main
    thread's id is the process id)."""
    try:
        return {t.id: t.user_time + t.system_time for t in psutil.Process(pid).threads()}
    except psutil.NoSuchProcess:
        return {}


def tree_cpu(pid: int) -> float:
    """CPU seconds (user + system) of a process, its live descendants and the children it
    has waited for."""
    try:
        p = psutil.Process(pid)
        ps = [p, *p.children(recursive=True)]
    except psutil.NoSuchProcess:
        return 0.0
    total = 0.0
    for q in ps:
        with contextlib.suppress(psutil.NoSuchProcess):
            c = q.cpu_times()
            total += c.user + c.system + c.children_user + c.children_system
    return total


class RssSampler:
    """Peak resident memory [bytes] of process trees, sampled every ``dt`` seconds."""

    def __init__(self, pids: dict[str, int], dt: float = 0.1) -> None:
        self.pids, self.dt = pids, dt
        self.peak: dict[str, int] = {k: 0 for k in pids}
        self._stop = threading.Event()
        self._t = threading.Thread(target=self._run, daemon=True)

    @staticmethod
    def tree_rss(pid: int) -> int:
        try:
            p = psutil.Process(pid)
            ps = [p, *p.children(recursive=True)]
        except psutil.NoSuchProcess:
            return 0
        total = 0
        for q in ps:
            with contextlib.suppress(psutil.NoSuchProcess):
                total += q.memory_info().rss
        return total

    def _run(self) -> None:
        while not self._stop.is_set():
            for k, pid in self.pids.items():
                self.peak[k] = max(self.peak[k], self.tree_rss(pid))
            time.sleep(self.dt)

    def __enter__(self) -> RssSampler:
        self._t.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self._stop.set()
        self._t.join()


def settled_rss(pid: int, wait_s: float = 1.0) -> int:
    """RSS [bytes] of the process tree after ``wait_s`` seconds of quiet."""
    time.sleep(wait_s)
    return RssSampler.tree_rss(pid)


def download(
    url: str,
    params: dict[str, str],
    api_pid: int,
    max_s: float | None = None,
    base: int | None = None,
    refused: list[dict[str, Any]] | None = None,
) -> dict[str, Any]:
    """One download: bytes, time to first byte, total time, the API's idle RSS and peak
    over it (and over ``base``, the idle RSS before the sweep).  With ``max_s`` reading
    stops after that many seconds (the figures are then those of the part read:
    ``complete`` false, CSV rows per second).  A 503 is recorded in ``refused`` (status,
    Retry-After, reason) when given, else it fails."""
    idle = RssSampler.tree_rss(api_pid)
    t0 = time.perf_counter()
    ttfb = None
    n = rows = 0
    complete = True
    with (
        RssSampler({"api": api_pid}) as s,
        httpx.stream("GET", url, params=params, timeout=3600) as r,
    ):
        if r.status_code == 503 and refused is not None:
            refused.append(
                {
                    "status": 503,
                    "retry_after_s": int(r.headers.get("retry-after", "0")),
                    "after_s": round(time.perf_counter() - t0, 3),
                    "reason": json.loads(r.read()).get("reason"),
                }
            )
            return {"refused": refused[-1]}
        assert r.status_code == 200, r.read()[:300]
        for piece in r.iter_bytes(1 << 20):
            if ttfb is None:
                ttfb = time.perf_counter() - t0
            n += len(piece)
            rows += piece.count(b"\n")
            if max_s is not None and time.perf_counter() - t0 > max_s:
                complete = False
                break
    total = time.perf_counter() - t0
    out = {
        "bytes": n,
        "complete": complete,
        "ttfb_s": round(ttfb or 0.0, 3),
        "total_s": round(total, 2),
        "mb_per_s": round(n / 1e6 / max(total - (ttfb or 0.0), 1e-9), 2),
        "api_idle_rss_mb": round(idle / 2**20, 1),
        "api_peak_over_idle_mb": round((s.peak["api"] - idle) / 2**20, 1),
    }
    if base is not None:
        out["api_peak_over_pre_sweep_idle_mb"] = round((s.peak["api"] - base) / 2**20, 1)
    if params.get("format") == "csv":
        out["rows_per_s"] = round(rows / max(total - (ttfb or 0.0), 1e-9))
    return out


#: Where a worker's on-CPU samples go, by the innermost frame that matches (file
#: substring, function name or None for any): the first match from the innermost frame
#: outwards names the sample's category.
PROFILE_CATEGORIES: tuple[tuple[str, str, str | None], ...] = (
    ("kernel", "rsfcore/", None),
    ("parameters", "rsfapp/grid.py", None),
    ("block encoding", "rsfapp/store/sweeps.py", "add"),
    ("block encoding", "rsfapp/store/sweeps.py", "add_whole"),
    ("block encoding", "rsfapp/store/sweeps.py", "finish"),
    ("block encoding", "rsfapp/store/sweeps.py", "_same_bits"),
    ("result arrays", "rsfapp/sweepdata.py", None),
    ("store transactions", "rsfapp/store/", None),
    ("store transactions", "rsfapp/db/", None),
    ("lease thread", "rsfapp/reaper.py", None),
    ("task (worker.tasks)", "worker/tasks.py", None),
    ("metrics", "prometheus_client/", None),
    ("Celery and broker", "celery/", None),
    ("Celery and broker", "kombu/", None),
    ("Celery and broker", "redis/", None),
    ("Celery and broker", "billiard/", None),
)


def start_profiles(workers: dict[str, Any]) -> dict[str, tuple[Any, Path]]:
    """Start ``py-spy record`` (raw collapsed stacks, 250 samples/s, idle threads left
    out) on each worker; returns {node: (process, output file)}."""
    import shutil
    import subprocess

    spy = shutil.which("py-spy") or str(Path(sys.executable).with_name("py-spy"))
    (ROOT / "bench" / "out").mkdir(exist_ok=True)
    out = {}
    for node, w in workers.items():
        f = ROOT / "bench" / "out" / f"profile_{node}.txt"
        cmd = [spy, "record", "-p", str(w.pid), "-r", "250", "-f", "raw", "-o", str(f)]
        out[node] = (subprocess.Popen([*cmd, "--nonblocking"], stdout=subprocess.DEVNULL), f)
    time.sleep(1.0)  # py-spy attaches
    return out


def stop_profiles(spies: dict[str, tuple[Any, Path]]) -> dict[str, dict[str, float]]:
    """Stop the samplers and return, per worker, the share [%] of its busy samples in
    each category of :data:`PROFILE_CATEGORIES` (the rest: "other").  py-spy's idle test
    counts a thread blocked on a socket (the database, the broker) as busy, so the
    store's and the broker's shares include their round trips."""
    import signal

    shares: dict[str, dict[str, float]] = {}
    for node, (p, f) in spies.items():
        p.send_signal(signal.SIGINT)
        p.wait(30)
        counts: dict[str, int] = {}
        for line in f.read_text().splitlines():
            stack, _, n = line.rpartition(" ")
            frames = stack.split(";")
            cat = "other"
            for fr in reversed(frames):
                fn, _, where = fr.partition(" (")
                hit = next(
                    (
                        c
                        for c, path, name in PROFILE_CATEGORIES
                        if path in where and (name is None or fn == name)
                    ),
                    None,
                )
                if hit:
                    cat = hit
                    break
            counts[cat] = counts.get(cat, 0) + int(n)
        total = max(1, sum(counts.values()))
        shares[node] = {
            "samples": total,
            **{
                k: round(100 * v / total, 1)
                for k, v in sorted(counts.items(), key=lambda kv: -kv[1])
            },
        }
        print(f"profile of {node} (% of busy samples): {shares[node]}")
    return shares


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--shape", type=int, nargs=3, default=[100, 100, 100], metavar="N")
    ap.add_argument("--expensive", action="store_true", help="kappa_ratio 1.01..5 (slow points)")
    ap.add_argument("--formats", default="netcdf,csv,json")
    ap.add_argument("--timeout", type=float, default=3600.0)
    ap.add_argument("--no-pair", action="store_true", help="skip two downloads at once")
    ap.add_argument(
        "--no-downloads", action="store_true", help="stop after the sweep (throughput only)"
    )
    ap.add_argument(
        "--no-reference",
        action="store_true",
        help="skip rsfcore's batch kernel reference (throughput ratios; saves shared CPU "
        "when only the downloads are measured)",
    )
    ap.add_argument(
        "--profile",
        action="store_true",
        help="sample each worker with py-spy during the sweep and print where its busy "
        "samples go (the kernel, parameters, block encoding, the store's transactions, "
        "Celery and the broker); py-spy counts a thread waiting for the database as busy, "
        "so these are shares of wall time, not of CPU; the stacks go to bench/out/",
    )
    ap.add_argument(
        "--max-download-s",
        type=float,
        default=None,
        help="stop reading a whole-sweep download after this many seconds (peak RSS and "
        "first byte are still measured; the rate gives the projected total)",
    )
    a = ap.parse_args()
    shape = (a.shape[0], a.shape[1], a.shape[2])
    n = shape[0] * shape[1] * shape[2]
    b = body(shape, not a.expensive)
    out: dict[str, Any] = {"shape": shape, "n_points": n, "cheap": not a.expensive}
    out["load_before"] = os.getloadavg()
    print(f"sweep {shape} = {n:.3g} points ({'cheap' if not a.expensive else 'expensive'})")

    refs: dict[str, list[tuple[float, float]]] = {}
    if not a.no_reference:
        refs = reference_rates(b, n)
    base = Path(tempfile.mkdtemp(prefix="rsf-bench-e2e-"))
    bindir = postgres_bindir()
    assert bindir is not None, "PostgreSQL server programs not found"
    pg = Postgres(bindir)
    started: list[Proc] = []
    try:
        red = Redis(str(__import__("shutil").which("redis-server")), base)
        started.append(red)
        env = {"RSF_CACHE_URL": pg.url}
        port = free_port()
        api = Proc(
            [sys.executable, "-m", "rsfcli.main", "api", "--port", str(port), "--wait-db", "0"],
            service_env(base / "api", red.url, RSF_NODE="api-host", **env),
            base / "api.log",
        )
        (base / "api").mkdir(exist_ok=True)
        started.append(api)
        url = f"http://127.0.0.1:{port}"
        deadline = time.monotonic() + 300  # a loaded machine starts it slowly
        while True:
            try:
                if httpx.get(url + "/health", timeout=2).status_code == 200:
                    break
            except httpx.HTTPError:
                pass
            assert time.monotonic() < deadline, api.tail()
            time.sleep(0.2)
        workers = {}
        for node in ("host-a", "host-b"):
            d = base / node
            d.mkdir()
            workers[node] = Worker(d, red.url, RSF_NODE=node, **env)
            started.append(workers[node])
        pids = {"api": api.pid, **{k: w.pid for k, w in workers.items()}}
        c = httpx.Client(base_url=url, timeout=60)
        # warm-up: compile in each worker
        w = c.post("/v1/sweeps", json=body((4, 4, 4), not a.expensive)).json()
        while c.get(f"/v1/sweeps/{w['id']}").json()["status"] != "done":
            time.sleep(0.2)
        pg_pid = int((pg.data / "postmaster.pid").read_text().split()[0])
        cpu_pids = {**pids, "postgres": pg_pid, "redis": red.pid}
        cpu0 = {k: tree_cpu(v) for k, v in cpu_pids.items()}
        thr0 = {k: thread_cpu(w.pid) for k, w in workers.items()}
        idle_mb: dict[str, float] = {}
        base = settled_rss(api.pid)
        idle_mb["before_sweep"] = round(base / 2**20, 1)
        spies = start_profiles(workers) if a.profile else {}
        with RssSampler(pids) as rss:
            t0 = time.perf_counter()
            r = c.post("/v1/sweeps", json=b)
            assert r.status_code == 202, r.text
            sid = r.json()["id"]
            while True:
                st = c.get(f"/v1/sweeps/{sid}").json()
                if st["status"] == "done":
                    break
                assert time.perf_counter() - t0 < a.timeout, st
                time.sleep(0.5)  # as the client polls (timing: the server's clock)
            wall = time.perf_counter() - t0
        if spies:
            out["worker_profile"] = stop_profiles(spies)
        # submitted -> last chunk stored, by the server's clock (ms; no polling delay)
        dt = _epoch(st["finished_at"]) - _epoch(st["created_at"])
        out["sweep_wall_s"] = round(wall, 2)
        cpu = {k: round(tree_cpu(v) - cpu0[k], 2) for k, v in cpu_pids.items()}
        out["sweep_cpu_s"] = cpu
        # per worker: CPU of its main thread (the task) and of its other threads (lease
        # renewal, reaper, Celery's timers)
        thr: dict[str, dict[str, float]] = {}
        for k, w in workers.items():
            t1 = thread_cpu(w.pid)
            d = {t: c - thr0[k].get(t, 0.0) for t, c in t1.items()}
            thr[k] = {
                "main": round(d.get(w.pid, 0.0), 3),
                "other_threads": round(sum(c for t, c in d.items() if t != w.pid), 3),
            }
        out["worker_thread_cpu_s"] = thr
        print(f"worker threads, CPU seconds: {thr}")
        out["sweep_s"] = round(dt, 3)
        out["n_chunks"] = st["n_chunks"]
        out["service_points_per_s"] = round(n / dt)
        idle_mb["after_sweep"] = round(settled_rss(api.pid) / 2**20, 1)
        out["peak_rss_mb"] = {k: round(v / 2**20, 1) for k, v in rss.peak.items()}
        if a.no_reference:
            print(
                f"service: {n / dt:,.0f} points/s in {dt:.2f} s ({st['n_chunks']} chunks); "
                f"CPU seconds {cpu}; peak RSS MB {out['peak_rss_mb']}"
            )
        else:
            # the reference again, right after the sweep (the machine is shared: its load
            # moves); the ratios are taken against the mean of the two
            for k, v in reference_rates(b, n).items():
                refs[k] += v
            all_cpu = sum(cpu.values())
            work_cpu = sum(v for k, v in cpu.items() if k.startswith("host-"))
            out.update(compare(refs, n, dt, all_cpu, work_cpu))
            print(
                f"service: {n / dt:,.0f} points/s in {dt:.2f} s ({st['n_chunks']} chunks); "
                f"peak RSS MB {out['peak_rss_mb']}; CPU seconds {cpu}"
            )
            for k, r in out["rsfcore"].items():
                star = " (primary)" if k == out["rsfcore_primary"] else ""
                print(
                    f"against rsfcore {k}{star} ({r['points_per_cpu_s']:,} points per CPU s, "
                    f"{r['points_per_s']:,} points/s): per CPU second stack "
                    f"{r['stack_over_cpu']:.3f} x, workers {r['workers_over_cpu']:.3f} x; "
                    f"wall {r['service_over_wall']:.3f} x"
                )
        from sqlalchemy import create_engine, text

        eng = create_engine(pg.url)
        with eng.connect() as conn:
            blob = conn.execute(
                text("SELECT sum(length(data)) FROM sweep_blocks WHERE sweep_id = :s"), {"s": sid}
            ).scalar()
            table = conn.execute(text("SELECT pg_total_relation_size('sweep_blocks')")).scalar()
        eng.dispose()
        out["stored_bytes_per_point"] = round(int(blob) / n, 3)
        out["sweep_blocks_table_bytes_per_point"] = round(int(table) / n, 3)
        print(
            f"stored: {out['stored_bytes_per_point']} B/point (blobs), table {table / n:.2f} B/point"
        )

        if a.no_downloads:
            out["api_idle_mb"] = idle_mb
            c.close()
            return save(out, a.expensive)  # the stack is stopped in `finally`
        data = f"{url}/v1/sweeps/{sid}/data"
        dl: dict[str, Any] = {}
        for fmt in a.formats.split(","):
            dl[fmt] = download(data, {"format": fmt}, api.pid, a.max_download_s, base)
            idle_mb[f"after_{fmt}"] = round(settled_rss(api.pid) / 2**20, 1)
            print(f"download {fmt}: {dl[fmt]}")
        k = max(1, shape[0] // 100)
        dl["netcdf_1pct_slice"] = download(
            data, {"format": "netcdf", "isel": f"kappa_ratio:0:{k}"}, api.pid, None, base
        )
        idle_mb["after_1pct_slice"] = round(settled_rss(api.pid) / 2**20, 1)
        print(f"download 1% slice: {dl['netcdf_1pct_slice']}")
        # the diagram of one 2-D slice (PNG)
        idle = RssSampler.tree_rss(api.pid)
        with RssSampler({"api": api.pid}) as sd:
            t = time.perf_counter()
            r = c.get(
                f"/v1/sweeps/{sid}/diagram",
                params={"format": "png", "slice": f"ba:{b['axes'][2]['start']}"},
                timeout=600,
            )
            assert r.status_code == 200, r.text[:300]
            dl["diagram_png"] = {
                "bytes": len(r.content),
                "total_s": round(time.perf_counter() - t, 3),
                "api_peak_over_idle_mb": round((sd.peak["api"] - idle) / 2**20, 1),
                "api_peak_over_pre_sweep_idle_mb": round((sd.peak["api"] - base) / 2**20, 1),
            }
        idle_mb["after_diagram"] = round(settled_rss(api.pid) / 2**20, 1)
        print(f"diagram PNG of one slice: {dl['diagram_png']}")
        # lazy read of one 2-D slice
        import xarray as xr

        idle = RssSampler.tree_rss(api.pid)
        with RssSampler({"api": api.pid}) as sz:
            t = time.perf_counter()
            ds = xr.open_zarr(f"{url}/v1/sweeps/{sid}/zarr", consolidated=True, zarr_format=2)
            sl = ds["critical_size"].isel(kappa_ratio=shape[0] // 2).values
            out["lazy_slice_s"] = round(time.perf_counter() - t, 3)
        out["lazy_slice_points"] = int(sl.size)
        dl["zarr_lazy_slice"] = {
            "points": int(sl.size),
            "total_s": out["lazy_slice_s"],
            "api_peak_over_idle_mb": round((sz.peak["api"] - idle) / 2**20, 1),
            "api_peak_over_pre_sweep_idle_mb": round((sz.peak["api"] - base) / 2**20, 1),
        }
        # lazy read of a whole variable (every chunk, fetched side by side by zarr)
        idle = RssSampler.tree_rss(api.pid)
        with RssSampler({"api": api.pid}) as sz:
            t = time.perf_counter()
            kinds = ds["kind"].values
            dl["zarr_lazy_whole_kind"] = {
                "points": int(kinds.size),
                "total_s": round(time.perf_counter() - t, 3),
            }
        del kinds
        dl["zarr_lazy_whole_kind"].update(
            api_peak_over_idle_mb=round((sz.peak["api"] - idle) / 2**20, 1),
            api_peak_over_pre_sweep_idle_mb=round((sz.peak["api"] - base) / 2**20, 1),
        )
        idle_mb["after_zarr"] = round(settled_rss(api.pid) / 2**20, 1)
        print(f"lazy xarray read of the whole 'kind' variable: {dl['zarr_lazy_whole_kind']}")
        print(f"lazy xarray read of one 2-D slice ({sl.size} points): {dl['zarr_lazy_slice']}")
        # two at once: NetCDF (one build per API process: the second is refused while the
        # first is built) and CSV (both streamed)
        for fmt in [] if a.no_pair else ["netcdf", "csv"]:
            idle = RssSampler.tree_rss(api.pid)
            res: list[dict[str, Any]] = []
            refused: list[dict[str, Any]] = []

            def one(fmt: str = fmt) -> None:
                res.append(
                    download(data, {"format": fmt}, api.pid, a.max_download_s, base, refused)
                )

            with RssSampler({"api": api.pid}) as s2:
                ts = [threading.Thread(target=one) for _ in range(2)]
                for t2 in ts:
                    t2.start()
                    time.sleep(0.2)  # the first one's request arrives first
                for t2 in ts:
                    t2.join()
            dl[f"two_{fmt}_at_once"] = {
                "api_peak_over_idle_mb": round((s2.peak["api"] - idle) / 2**20, 1),
                "api_peak_over_pre_sweep_idle_mb": round((s2.peak["api"] - base) / 2**20, 1),
                "served": sum(1 for x in res if "refused" not in x),
                "refused": refused,
            }
            idle_mb[f"after_two_{fmt}"] = round(settled_rss(api.pid) / 2**20, 1)
            print(f"two {fmt} downloads at once: {dl[f'two_{fmt}_at_once']}")
        out["downloads"] = dl
        out["api_idle_mb"] = idle_mb
        print(f"API idle RSS (MB, settled 1 s after each step): {idle_mb}")
        c.close()
    finally:
        for p in reversed(started):
            p.stop()
        pg.destroy()
    save(out, a.expensive)


def save(out: dict[str, Any], expensive: bool) -> None:
    """Write the figures to bench/out/bench_sweep_e2e_<kind>_<n>.json and print them."""
    out["load_after"] = os.getloadavg()
    (ROOT / "bench" / "out").mkdir(exist_ok=True)
    tag = f"{'expensive' if expensive else 'cheap'}_{out['n_points']:.0e}".replace("+", "")
    (ROOT / "bench" / "out" / f"bench_sweep_e2e_{tag}.json").write_text(json.dumps(out, indent=1))
    print(json.dumps(out))


if __name__ == "__main__":
    main()
