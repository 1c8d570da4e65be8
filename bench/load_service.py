#!/usr/bin/env python3
"""Load test of the service on loopback (bounded in requests and time).

    python bench/load_service.py                 # starts `rsf serve` (embedded worker) itself
    python bench/load_service.py --url http://127.0.0.1:8000   # an already running server
    python bench/load_service.py --api-scaling   # `rsf api --workers 1` then `--workers 2`

Prints p50/p99 latency [ms] and throughput [req/s] for: cached lookups (repeated
classify queries), closed-form queries (analytic U at fresh points), fresh
classifications (new parameters each time).  Targets (2-core machine): cached >= 500
req/s with p99 <= 50 ms.  Every phase stops at --max-requests or --seconds.  Sweep
throughput (10^6 points through the workers against rsfcore's batch call, 100 x 100
latency, bytes per point) is measured by bench/bench_sweep.py.

``--api-scaling`` measures the API alone: for 1 and 2 API processes (`rsf api
--workers N`, SQLite under a temporary data directory, no worker) it prints the
throughput of cached lookups (repeated POST /v1/classify, answered from the result store)
next to the trivial endpoint GET /health/live (no I/O) in the same run.  Targets (issue
12): cached >= 0.8x trivial; 2 API processes >= 1.6x one.  The load generator runs on
the same machine, so on 2 cores it competes with the API processes for the CPU.  With
``--with-key`` it also measures the cached lookups sent with an API key (made with the
real `rsf keys create`, revoked after the phase): every such request verifies the key
in the database (revocation is immediate), the cost every deployment with keys pays.
"""

from __future__ import annotations

import argparse
import http.client
import json
import multiprocessing as mp
import os
import random
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from urllib.parse import urlparse

ROOT = Path(__file__).resolve().parents[1]


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _client_loop(args: tuple) -> tuple[list[float], int]:
    """One client process: keep-alive connection, closed loop; (latencies [s], errors)."""
    host, port, kind, n_max, t_end, seed, bodies, headers = args
    rnd = random.Random(seed)
    conn = http.client.HTTPConnection(host, port, timeout=30)
    lat: list[float] = []
    errors = 0
    i = 0
    while i < n_max and time.perf_counter() < t_end:
        if kind == "trivial":
            t0 = time.perf_counter()
            conn.request("GET", "/health/live")
            r = conn.getresponse()
            r.read()
            lat.append(time.perf_counter() - t0)
            errors += r.status != 200
            i += 1
            continue
        if kind in ("cached", "cached_key"):
            path, body = "/v1/classify", bodies[i % len(bodies)]
        elif kind == "closed":
            path, body = (
                "/v1/analytic/u",
                {
                    "eps": rnd.random(),
                    "ba": 1.5 + rnd.random(),
                    "points": [{"phi": rnd.uniform(-3, 3), "psi": rnd.uniform(-3, 3)}],
                },
            )
        else:
            path, body = (
                "/v1/classify",
                {
                    "ba": 1.5 + 2 * rnd.random(),
                    "kappa": 3 * rnd.random(),
                    "eps": rnd.random(),
                    "size": rnd.uniform(0.1, 3),
                },
            )
        data = json.dumps(body)
        t0 = time.perf_counter()
        conn.request("POST", path, data, {"Content-Type": "application/json", **headers})
        r = conn.getresponse()
        r.read()
        lat.append(time.perf_counter() - t0)
        if r.status != 200 or (kind.startswith("cached") and r.getheader("X-Cache") != "hit"):
            errors += 1
        i += 1
    conn.close()
    return lat, errors


def _pct(xs: list[float], q: float) -> float:
    xs = sorted(xs)
    return xs[min(len(xs) - 1, int(q * len(xs)))] if xs else float("nan")


def phase(
    url: str,
    kind: str,
    clients: int,
    max_requests: int,
    seconds: float,
    bodies: list[dict],
    headers: dict[str, str] | None = None,
) -> dict:
    u = urlparse(url)
    t0 = time.perf_counter()
    t_end = t0 + seconds
    per = max(1, max_requests // clients)
    with mp.get_context("fork").Pool(clients) as pool:
        res = pool.map(
            _client_loop,
            [
                (u.hostname, u.port, kind, per, t_end, 1000 * k + 7, bodies, headers or {})
                for k in range(clients)
            ],
        )
    wall = time.perf_counter() - t0
    lat = [x for r in res for x in r[0]]
    return {
        "kind": kind,
        "n": len(lat),
        "errors": sum(r[1] for r in res),
        "req_per_s": len(lat) / wall,
        "p50_ms": 1e3 * _pct(lat, 0.5),
        "p99_ms": 1e3 * _pct(lat, 0.99),
    }


def _req(url: str, method: str, path: str, body: dict | None = None) -> tuple[int, dict, dict]:
    u = urlparse(url)
    c = http.client.HTTPConnection(u.hostname, u.port, timeout=60)
    c.request(
        method,
        path,
        None if body is None else json.dumps(body),
        {"Content-Type": "application/json"},
    )
    r = c.getresponse()
    data = json.loads(r.read() or b"{}")
    headers = dict(r.getheaders())
    c.close()
    return r.status, data, headers


def start_server(data_dir: str) -> tuple[subprocess.Popen, str]:
    port = _free_port()
    code = f"from rsfcli.serve import serve; serve('127.0.0.1', {port}, {data_dir!r})"
    env = {k: v for k, v in os.environ.items() if not k.startswith("RSF_")}
    log = open(Path(data_dir) / "serve.log", "wb")  # noqa: SIM115
    p = subprocess.Popen(
        [sys.executable, "-c", code],
        cwd=ROOT,
        env=env,
        stdout=log,
        stderr=log,
        start_new_session=True,
    )
    url = f"http://127.0.0.1:{port}"
    for _ in range(300):
        try:
            if _req(url, "GET", "/health")[0] == 200:
                break
        except OSError:
            time.sleep(0.1)
    else:
        raise SystemExit("server did not start; see " + str(Path(data_dir) / "serve.log"))
    # Wait for the embedded worker to be ready.
    wlog = Path(data_dir) / "worker.log"
    for _ in range(300):
        if wlog.exists() and " ready." in wlog.read_text(errors="replace"):
            break
        time.sleep(0.1)
    return p, url


def start_api(data_dir: str, workers: int) -> tuple[subprocess.Popen, str]:
    """`rsf api --workers N` on a free port (SQLite + filesystem broker in data_dir)."""
    port = _free_port()
    env = {k: v for k, v in os.environ.items() if not k.startswith("RSF_")}
    env["RSF_DATA_DIR"] = data_dir
    log = open(Path(data_dir) / "api.log", "wb")  # noqa: SIM115
    p = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "rsfcli.main",
            "api",
            "--port",
            str(port),
            "--workers",
            str(workers),
        ],
        cwd=ROOT,
        env=env,
        stdout=log,
        stderr=log,
        start_new_session=True,
    )
    url = f"http://127.0.0.1:{port}"
    for _ in range(600):
        try:
            if _req(url, "GET", "/health")[0] == 200:
                return p, url
        except OSError:
            pass
        time.sleep(0.1)
    raise SystemExit("API did not start; see " + str(Path(data_dir) / "api.log"))


def _rsf_keys(data_dir: str, *args: str) -> str:
    """`rsf keys ARGS` on ``data_dir`` (the real CLI in another process); its output."""
    env = {k: v for k, v in os.environ.items() if not k.startswith("RSF_")}
    env["RSF_DATA_DIR"] = data_dir
    r = subprocess.run(
        [sys.executable, "-m", "rsfcli.main", "keys", *args],
        cwd=ROOT,
        env=env,
        capture_output=True,
        text=True,
        timeout=120,
        check=True,
    )
    return r.stdout.strip()


def api_scaling(clients: int, max_req: int, secs: float, with_key: bool = False) -> list[dict]:
    """Trivial vs cached throughput with 1 and 2 API processes (see the module doc)."""
    bodies = [{"ba": 2.0 + 0.01 * k, "kappa": 0.9, "eps": 0.5, "size": 1.0} for k in range(50)]
    rows = []
    tmp = tempfile.mkdtemp(prefix="rsf-bench-api-")
    for n in (1, 2):
        proc, url = start_api(tmp, n)
        try:
            for b in bodies:  # warm the cache (shared database: only the first run computes)
                _req(url, "POST", "/v1/classify", b)
            phase(url, "trivial", clients, 200, 1.0, bodies)  # warm every API process
            phase(url, "cached", clients, 400, 1.0, bodies)  # every process learns the bodies
            triv = phase(url, "trivial", clients, max_req, secs, bodies)
            cached = phase(url, "cached", clients, max_req, secs, bodies)
            keyed = None
            if with_key:  # after the anonymous phases: a key makes keys necessary
                name = f"bench{n}"
                key = _rsf_keys(tmp, "create", "--name", name, "--scope", "read")
                auth = {"Authorization": f"Bearer {key}"}
                keyed = phase(url, "cached_key", clients, max_req, secs, bodies, auth)
                _rsf_keys(tmp, "revoke", name)  # the next server serves loopback anonymously
        finally:
            os.killpg(proc.pid, signal.SIGTERM)
            try:
                proc.wait(30)
            except subprocess.TimeoutExpired:
                os.killpg(proc.pid, signal.SIGKILL)
        row = {"api_processes": n, "trivial": triv, "cached": cached}
        if keyed is not None:
            row["cached_key"] = keyed
        rows.append(row)
    shutil.rmtree(tmp, ignore_errors=True)
    return rows


def print_api_scaling(rows: list[dict], clients: int) -> None:
    print(
        f"API alone (`rsf api --workers N`, SQLite), {clients} client processes, "
        f"{os.cpu_count()} CPUs"
    )
    print(
        f"{'API procs':>9} {'phase':<10} {'requests':>9} {'errors':>7} {'req/s':>9} "
        f"{'p50 ms':>8} {'p99 ms':>8}"
    )
    for r in rows:
        for k in ("trivial", "cached", "cached_key"):
            if k not in r:
                continue
            p = r[k]
            print(
                f"{r['api_processes']:>9} {k:<10} {p['n']:>9} {p['errors']:>7} "
                f"{p['req_per_s']:>9.0f} {p['p50_ms']:>8.2f} {p['p99_ms']:>8.2f}"
            )
    for r in rows:
        ratio = r["cached"]["req_per_s"] / r["trivial"]["req_per_s"]
        print(
            f"{r['api_processes']} API process(es): cached / trivial = {ratio:.2f} (target >= 0.8)"
        )
        if "cached_key" in r:
            rk = r["cached_key"]["req_per_s"] / r["trivial"]["req_per_s"]
            print(f"{r['api_processes']} API process(es): cached with a key / trivial = {rk:.2f}")
    up = rows[1]["cached"]["req_per_s"] / rows[0]["cached"]["req_per_s"]
    upt = rows[1]["trivial"]["req_per_s"] / rows[0]["trivial"]["req_per_s"]
    print(f"2 API processes / 1: cached {up:.2f}x, trivial {upt:.2f}x (target >= 1.6x)")


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--url", help="running server (default: start rsf serve on a free port)")
    ap.add_argument("--clients", type=int, default=4, help="client processes (1..32)")
    ap.add_argument("--max-requests", type=int, default=5000, help="per phase (<= 10^5)")
    ap.add_argument("--seconds", type=float, default=5.0, help="per phase (<= 60)")
    ap.add_argument("--json", action="store_true", help="print one JSON object")
    ap.add_argument(
        "--api-scaling",
        action="store_true",
        help="only the API: trivial vs cached with 1 and 2 API processes",
    )
    ap.add_argument(
        "--with-key",
        action="store_true",
        help="with --api-scaling: also cached lookups sent with an API key",
    )
    a = ap.parse_args()
    clients = min(max(a.clients, 1), 32)
    max_req = min(max(a.max_requests, 1), 100_000)
    secs = min(max(a.seconds, 0.5), 60.0)
    if a.api_scaling:
        rows = api_scaling(clients, max_req, secs, a.with_key)
        if a.json:
            print(json.dumps(rows))
        else:
            print_api_scaling(rows, clients)
        return 0
    proc = None
    url = a.url
    if url is None:
        tmp = tempfile.mkdtemp(prefix="rsf-bench-")
        proc, url = start_server(tmp)
    print(f"driving {url} ...", file=sys.stderr, flush=True)
    try:
        bodies = [{"ba": 2.0 + 0.01 * k, "kappa": 0.9, "eps": 0.5, "size": 1.0} for k in range(50)]
        for b in bodies:  # warm the cache
            _req(url, "POST", "/v1/classify", b)
        out = {
            "url": url,
            "clients": clients,
            "phases": [
                phase(url, k, clients, max_req, secs, bodies) for k in ("cached", "closed", "fresh")
            ],
        }
    finally:
        if proc is not None:
            os.killpg(proc.pid, signal.SIGTERM)
            try:
                proc.wait(30)
            except subprocess.TimeoutExpired:
                os.killpg(proc.pid, signal.SIGKILL)
    if a.json:
        print(json.dumps(out))
        return 0
    print(f"server {url}, {clients} client processes, <= {max_req} requests / {secs:g} s per phase")
    print(f"{'phase':<8} {'requests':>9} {'errors':>7} {'req/s':>9} {'p50 ms':>8} {'p99 ms':>8}")
    for p in out["phases"]:
        print(
            f"{p['kind']:<8} {p['n']:>9} {p['errors']:>7} {p['req_per_s']:>9.0f} "
            f"{p['p50_ms']:>8.2f} {p['p99_ms']:>8.2f}"
        )
    c = out["phases"][0]
    ok = c["req_per_s"] >= 500 and c["p99_ms"] <= 50
    print("targets (cached >= 500 req/s, p99 <= 50 ms):", "MET" if ok else "NOT MET")
    return 0


if __name__ == "__main__":
    sys.exit(main())
