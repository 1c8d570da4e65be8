"""A large sweep end to end on the multi-host stack, then every way of reading it back.

Stack (all on this machine, loopback only): PostgreSQL, Redis, ``rsf api`` and two Celery
workers acting as two hosts (solo pool, one process each), as tests/e2e/test_multihost.py
starts them.  Steps:

1. rsfcore alone: ``rsfcore.batch.critical_points`` on the same points, two processes in
   parallel (the worker cores), parameters generated first and not timed.
2. The sweep: critical sizes over a 3-D grid (kappa_ratio, eps, ba; default "cheap"
   points: kappa_ratio < 1, decided in closed form), submitted and timed to ``done``;
   points/s against step 1, bytes stored per point (result blobs; PostgreSQL table size),
   peak RSS of the API and of each worker (psutil, sampled every 0.1 s, process trees).
3. Downloads, one at a time, each with the API's peak RSS over its idle RSS, time to first
   byte and total time: the whole sweep as NetCDF, CSV and JSON; a 1 % slice (NetCDF);
   two NetCDF downloads at once; a lazy xarray read of one 2-D slice through the Zarr
   store (zarr + fsspec).

    python bench/bench_sweep_e2e.py --shape 100 100 100 [--formats netcdf,csv,json]

Prints the figures and writes them as JSON to bench/out/bench_sweep_e2e.json.  Timing
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
import numpy as np
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


def _core_part(args: tuple[dict[str, Any], int, int]) -> tuple[int, float]:
    b, i0, i1 = args
    from rsfapp.grid import expand
    from rsfapp.requests import SweepRequest
    from rsfcore import batch

    spec = expand(SweepRequest(**b), 10**9)
    p = spec.params(0, 8)
    batch.critical_points(p["ba"], p["kappa"], p["eps"], p["vo"], rtol=spec.rtol)  # compile
    t_all = 0.0
    step = 1_000_000
    for a in range(i0, i1, step):
        p = spec.params(a, min(i1, a + step))
        t = time.perf_counter()
        batch.critical_points(p["ba"], p["kappa"], p["eps"], p["vo"], rtol=spec.rtol)
        t_all += time.perf_counter() - t
    return i1 - i0, t_all


def rsfcore_rate(b: dict[str, Any], n: int, procs: int) -> float:
    """Points/s of the batch kernel in ``procs`` processes (kernel time only)."""
    cuts = np.linspace(0, n, procs + 1).astype(int)
    with ProcessPoolExecutor(procs) as ex:
        res = list(ex.map(_core_part, [(b, int(cuts[k]), int(cuts[k + 1])) for k in range(procs)]))
    return sum(m for m, _ in res) / max(t for _, t in res)


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


def download(url: str, params: dict[str, str], api_pid: int) -> dict[str, Any]:
    idle = RssSampler.tree_rss(api_pid)
    t0 = time.perf_counter()
    ttfb = None
    n = 0
    with (
        RssSampler({"api": api_pid}) as s,
        httpx.stream("GET", url, params=params, timeout=3600) as r,
    ):
        assert r.status_code == 200, r.read()[:300]
        for piece in r.iter_bytes(1 << 20):
            if ttfb is None:
                ttfb = time.perf_counter() - t0
            n += len(piece)
    return {
        "bytes": n,
        "ttfb_s": round(ttfb or 0.0, 3),
        "total_s": round(time.perf_counter() - t0, 2),
        "api_idle_rss_mb": round(idle / 2**20, 1),
        "api_peak_over_idle_mb": round((s.peak["api"] - idle) / 2**20, 1),
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--shape", type=int, nargs=3, default=[100, 100, 100], metavar="N")
    ap.add_argument("--expensive", action="store_true", help="kappa_ratio 1.01..5 (slow points)")
    ap.add_argument("--formats", default="netcdf,csv,json")
    ap.add_argument("--timeout", type=float, default=3600.0)
    ap.add_argument("--no-pair", action="store_true", help="skip two downloads at once")
    a = ap.parse_args()
    shape = (a.shape[0], a.shape[1], a.shape[2])
    n = shape[0] * shape[1] * shape[2]
    b = body(shape, not a.expensive)
    out: dict[str, Any] = {"shape": shape, "n_points": n, "cheap": not a.expensive}
    out["load_before"] = os.getloadavg()
    print(f"sweep {shape} = {n:.3g} points ({'cheap' if not a.expensive else 'expensive'})")

    rate_core = rsfcore_rate(b, n, 2)
    out["rsfcore_points_per_s_2_procs"] = round(rate_core)
    print(f"rsfcore batch kernel, 2 processes: {rate_core:,.0f} points/s")

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
        deadline = time.monotonic() + 60
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
                time.sleep(0.5)
            dt = time.perf_counter() - t0
        out["sweep_s"] = round(dt, 1)
        out["n_chunks"] = st["n_chunks"]
        out["service_points_per_s"] = round(n / dt)
        out["service_over_rsfcore"] = round(n / dt / rate_core, 3)
        out["peak_rss_mb"] = {k: round(v / 2**20, 1) for k, v in rss.peak.items()}
        print(
            f"service: {n / dt:,.0f} points/s in {dt:.1f} s ({st['n_chunks']} chunks) = "
            f"{out['service_over_rsfcore']:.2f} x rsfcore; peak RSS MB {out['peak_rss_mb']}"
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

        data = f"{url}/v1/sweeps/{sid}/data"
        dl: dict[str, Any] = {}
        for fmt in a.formats.split(","):
            dl[fmt] = download(data, {"format": fmt}, api.pid)
            print(f"download {fmt}: {dl[fmt]}")
        k = max(1, shape[0] // 100)
        dl["netcdf_1pct_slice"] = download(
            data, {"format": "netcdf", "isel": f"kappa_ratio:0:{k}"}, api.pid
        )
        print(f"download 1% slice: {dl['netcdf_1pct_slice']}")
        # two at once
        if a.no_pair:
            ts = []
        idle = RssSampler.tree_rss(api.pid)
        res: list[dict[str, Any]] = []
        with RssSampler({"api": api.pid}) as s2:
            ts = [
                threading.Thread(
                    target=lambda: res.append(download(data, {"format": "netcdf"}, api.pid))
                )
                for _ in range(0 if a.no_pair else 2)
            ]
            for t in ts:
                t.start()
            for t in ts:
                t.join()
        dl["two_netcdf_at_once_peak_over_idle_mb"] = round((s2.peak["api"] - idle) / 2**20, 1)
        print(
            f"two NetCDF downloads at once: API peak over idle {dl['two_netcdf_at_once_peak_over_idle_mb']} MB"
        )
        out["downloads"] = dl
        # lazy read of one 2-D slice
        import xarray as xr

        t = time.perf_counter()
        ds = xr.open_zarr(f"{url}/v1/sweeps/{sid}/zarr", consolidated=True, zarr_format=2)
        sl = ds["critical_size"].isel(kappa_ratio=shape[0] // 2).values
        out["lazy_slice_s"] = round(time.perf_counter() - t, 3)
        out["lazy_slice_points"] = int(sl.size)
        print(f"lazy xarray read of one 2-D slice ({sl.size} points): {out['lazy_slice_s']} s")
        c.close()
    finally:
        for p in reversed(started):
            p.stop()
        pg.destroy()
    out["load_after"] = os.getloadavg()
    (ROOT / "bench" / "out").mkdir(exist_ok=True)
    (ROOT / "bench" / "out" / "bench_sweep_e2e.json").write_text(json.dumps(out, indent=1))
    print(json.dumps(out))


if __name__ == "__main__":
    main()
