#!/usr/bin/env python3
"""Scaling of sweeps with worker processes on PostgreSQL + Redis (one run, one machine).

    python bench/bench_scaling.py                    # 100 x 100 x 100 = 10^6 points
    python bench/bench_scaling.py --n 60 --workers 1 2 4

Starts a throw-away PostgreSQL cluster and a Redis server (as the tests do), an API
process (``uvicorn service.app:app``) and, for each count in ``--workers``, that many
worker processes acting as different hosts (``RSF_NODE``, own data directories, solo
pool: one process each).  For each count it submits the same kind of critical-size sweep
(kappa_ratio x eps x b/a, n^3 points; the b/a range is nudged by 1e-9 per run so that
the sweep is new rather than a cache hit) and times submit -> status ``done``.

Prints points/s, points/s per worker and the speed-up over one worker, next to rsfcore's
own batch call (:func:`rsfcore.batch.critical_points`) on one core in this process, on a
random 2 % sample of the same grid.  Target (issue 12): 2 workers >= 1.8x one worker on a
2-core machine for >= 10^6 points.  The machine must be otherwise idle for the ratio to
mean anything (each worker wants a core of its own).
"""

from __future__ import annotations

import argparse
import os
import shutil
import sys
import tempfile
import time
from pathlib import Path

import httpx
import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from tests.conftest import (  # noqa: E402 - the test fixtures' process helpers
    Postgres,
    Redis,
    Server,
    Worker,
    postgres_bindir,
)


def body(n: int, nudge: float) -> dict[str, object]:
    """The critical-size sweep: n^3 points over (kappa_ratio, eps, ba)."""
    return {
        "axes": [
            {"name": "kappa_ratio", "start": 0.3, "stop": 3.0, "n": n},
            {"name": "eps", "start": 0.05, "stop": 0.95, "n": n},
            {"name": "ba", "start": 1.5 + nudge, "stop": 4.0, "n": n},
        ],
        "fixed": {"vo": 1.0},
    }


def core_rate(n: int, sample: float = 0.02) -> float:
    """rsfcore.batch.critical_points on one core: points/s on a random sample of the grid."""
    from rsfcore.batch import critical_points

    kr = np.linspace(0.3, 3.0, n)
    ep = np.linspace(0.05, 0.95, n)
    ba = np.linspace(1.5, 4.0, n)
    K, E, B = (a.ravel() for a in np.meshgrid(kr, ep, ba, indexing="ij"))
    rng = np.random.default_rng(1)
    idx = rng.choice(K.size, size=max(1000, int(sample * K.size)), replace=False)
    kappa = K[idx] * (B[idx] - 1.0)
    critical_points(B[idx][:100], kappa[:100], E[idx][:100], 1.0)  # compile / load
    t0 = time.perf_counter()
    critical_points(B[idx], kappa, E[idx], 1.0)
    return idx.size / (time.perf_counter() - t0)


def run(api: Server, n: int, nudge: float, timeout: float) -> tuple[float, int]:
    """Submit, wait for done; (seconds, points)."""
    with httpx.Client(base_url=api.url, timeout=30) as c:
        t0 = time.perf_counter()
        r = c.post("/v1/sweeps", json=body(n, nudge))
        if r.status_code != 202:
            raise RuntimeError(f"submit: {r.status_code} {r.text[:300]}")
        sid = r.headers["location"].rsplit("/", 1)[1]
        while time.perf_counter() - t0 < timeout:
            s = c.get(f"/v1/sweeps/{sid}").json()
            if s["status"] == "done":
                return time.perf_counter() - t0, int(s["n_total"])
            time.sleep(0.1)
    raise RuntimeError(f"sweep not done after {timeout} s: {s}")


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--n", type=int, default=100, help="points per axis (n^3 in all)")
    ap.add_argument("--workers", type=int, nargs="+", default=[1, 2])
    ap.add_argument("--timeout", type=float, default=600.0)
    a = ap.parse_args()
    os.environ.setdefault("NUMBA_CACHE_DIR", str(ROOT / ".numba_cache"))
    bindir = postgres_bindir()
    if bindir is None:
        print("PostgreSQL server programs not found (apt-get install postgresql)")
        return 1
    base = Path(tempfile.mkdtemp(prefix="rsf-scaling-"))
    pg = Postgres(bindir)
    (base / "redis").mkdir()
    red = Redis("redis-server", base / "redis", persist=True)
    env = {"RSF_CACHE_URL": pg.url}
    procs: list = [red]
    try:
        (base / "api").mkdir()
        api = Server(base / "api", red.url, **env)
        procs.append(api)
        rate1 = core_rate(a.n)
        print(
            f"cpus: {os.cpu_count()}; sweep: {a.n}^3 = {a.n**3:,} critical sizes "
            f"(kappa_ratio x eps x b/a), PostgreSQL + Redis"
        )
        print(f"rsfcore.batch.critical_points, 1 core, this process: {rate1:,.0f} points/s")
        print(
            f"{'workers':>7} {'seconds':>8} {'points/s':>11} {'per worker':>11} "
            f"{'speed-up':>8} {'vs core x workers':>17}"
        )
        base_rate = None
        for k, nw in enumerate(a.workers):
            ws = []
            for j in range(nw):
                d = base / f"run{k}-host{j}"
                d.mkdir()
                ws.append(Worker(d, red.url, RSF_NODE=f"host{j}", **env))
            try:
                secs, npts = run(api, a.n, 1e-9 * (k + 1), a.timeout)
            finally:
                for w in ws:
                    w.stop()
            rate = npts / secs
            if base_rate is None:  # one worker's rate, from the first run
                base_rate = rate / nw
            up = rate / base_rate
            print(
                f"{nw:>7} {secs:>8.2f} {rate:>11,.0f} {rate / nw:>11,.0f} {up:>7.2f}x "
                f"{rate / (rate1 * nw):>16.2f}x",
                flush=True,
            )
    finally:
        for p in reversed(procs):
            p.stop()
        pg.destroy()
        shutil.rmtree(base, ignore_errors=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
