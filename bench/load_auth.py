#!/usr/bin/env python3
"""One key floods fresh computations: do another key's cached lookups and /health stay fast?

    python bench/load_auth.py [--seconds 8] [--flooders 16]

Starts two uvicorn servers on loopback with RSF_AUTH=on, each on its own temporary data
directory, and the same two keys on each:

* ``quota``: the default per-key quota (``RSF_QUOTA_FRESH_PER_S``, default 10/s,
  ``RSF_QUOTA_CONCURRENT_REQUESTS``, default 8);
* ``no quota``: the obvious alternative, quotas so large they never bind.

In each, a *reader* key measures latency of cached classify lookups and of /health
(one request at a time), first alone, then while a *flooder* key sends fresh classify
queries (new parameters every time) from ``--flooders`` concurrent connections.
Printed: p50 / p99 latency [ms] of the reader, and the flooder's answers (200 / 429)
and fresh computations per second.  Target (issue 14): reader p99 < 100 ms under flood
with the quota.  Separate client processes, so the client's GIL does not distort it.
"""

from __future__ import annotations

import argparse
import http.client
import json
import multiprocessing as mp
import os
import random
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))


def _free_port() -> int:
    import socket

    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def _start(data: Path, quota: bool) -> tuple[subprocess.Popen[bytes], int, str, str]:
    env = {k: v for k, v in os.environ.items() if not k.startswith("RSF_")}
    env.update(
        RSF_DATA_DIR=str(data),
        RSF_AUTH="on",
        PYTHONPATH=str(ROOT),
        NUMBA_CACHE_DIR=os.environ.get("NUMBA_CACHE_DIR", str(ROOT / ".numba_cache")),
        RSF_INLINE_BUDGET_S="30",
    )
    if not quota:
        env.update(RSF_QUOTA_FRESH_PER_S="1e9", RSF_QUOTA_CONCURRENT_REQUESTS="1000000")
    rsf = str(Path(sys.executable).with_name("rsf"))
    keys = []
    for name, scope in (("reader", "read"), ("flooder", "read")):
        out = subprocess.run(
            [rsf, "keys", "create", "--name", name, "--scope", scope, "--data-dir", str(data)],
            env=env,
            capture_output=True,
            text=True,
            check=True,
        )
        keys.append(out.stdout.strip())
    port = _free_port()
    log = open(data / "uvicorn.log", "ab")  # noqa: SIM115
    p = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "uvicorn",
            "service.app:app",
            "--host",
            "127.0.0.1",
            "--port",
            str(port),
            "--log-level",
            "warning",
        ],
        env=env,
        stdout=log,
        stderr=log,
        cwd=ROOT,
        start_new_session=True,
    )
    deadline = time.monotonic() + 90
    while time.monotonic() < deadline:
        try:
            c = http.client.HTTPConnection("127.0.0.1", port, timeout=2)
            c.request("GET", "/health", headers={"Authorization": f"Bearer {keys[0]}"})
            if c.getresponse().status == 200:
                return p, port, keys[0], keys[1]
        except OSError:
            time.sleep(0.2)
    p.kill()
    raise RuntimeError("server did not start: " + (data / "uvicorn.log").read_text()[-2000:])


def _request(
    c: http.client.HTTPConnection,
    method: str,
    path: str,
    key: str,
    body: dict[str, object] | None = None,
) -> tuple[int, float]:
    t = time.perf_counter()
    data = None if body is None else json.dumps(body).encode()
    c.request(
        method,
        path,
        body=data,
        headers={"Authorization": f"Bearer {key}", "Content-Type": "application/json"},
    )
    r = c.getresponse()
    r.read()
    return r.status, time.perf_counter() - t


def _reader(port: int, key: str, seconds: float, q: mp.Queue) -> None:  # type: ignore[type-arg]
    c = http.client.HTTPConnection("127.0.0.1", port, timeout=60)
    cached: list[float] = []
    health: list[float] = []
    end = time.monotonic() + seconds
    i = 0
    while time.monotonic() < end:
        if i % 2:
            st, dt = _request(c, "GET", "/health", key)
            health.append(dt)
        else:
            st, dt = _request(c, "POST", "/v1/classify", key, {"size": 0.5, "eps": 0.25})
            cached.append(dt)
        assert st == 200, st
        i += 1
        time.sleep(0.005)
    q.put((cached, health))


def _flooder(port: int, key: str, seconds: float, seed: int, q: mp.Queue) -> None:  # type: ignore[type-arg]
    rnd = random.Random(seed)
    c = http.client.HTTPConnection("127.0.0.1", port, timeout=120)
    counts: dict[int, int] = {}
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        body = {
            "size": rnd.uniform(0.05, 3.0),
            "eps": rnd.uniform(0, 1),
            "ba": rnd.uniform(1.2, 4.0),
            "kappa": rnd.uniform(0.05, 3.0),
        }
        try:
            st, _ = _request(c, "POST", "/v1/classify", key, body)
        except (OSError, http.client.HTTPException):
            c.close()
            c = http.client.HTTPConnection("127.0.0.1", port, timeout=120)
            st = -1
        counts[st] = counts.get(st, 0) + 1
        if st == 429:
            time.sleep(0.01)  # a polite client would honour Retry-After; a flooder does not
    q.put(counts)


def _pct(xs: list[float], p: float) -> float:
    s = sorted(xs)
    return 1e3 * s[min(len(s) - 1, int(p / 100 * len(s)))] if s else float("nan")


def _phase(
    port: int, reader: str, flooder: str, seconds: float, n_flood: int
) -> tuple[list[float], list[float], dict[int, int]]:
    q: mp.Queue = mp.Queue()  # type: ignore[type-arg]
    procs = [mp.Process(target=_reader, args=(port, reader, seconds, q))]
    procs += [
        mp.Process(target=_flooder, args=(port, flooder, seconds, i, q)) for i in range(n_flood)
    ]
    for p in procs:
        p.start()
    results = [q.get(timeout=seconds + 300) for _ in procs]
    for p in procs:
        p.join()
    cached: list[float] = []
    health: list[float] = []
    counts: dict[int, int] = {}
    for r in results:
        if isinstance(r, tuple):
            cached, health = r
        else:
            for k, v in r.items():
                counts[k] = counts.get(k, 0) + v
    return cached, health, counts


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seconds", type=float, default=8.0)
    ap.add_argument("--flooders", type=int, default=16)
    a = ap.parse_args()
    print(
        f"{'server':9} {'phase':7} {'cached p50/p99 [ms]':>20} {'health p50/p99 [ms]':>20}"
        f" {'flood 200':>9} {'429':>6} {'fresh/s':>8}"
    )
    for quota in (True, False):
        with tempfile.TemporaryDirectory(prefix="rsf-load-auth-") as d:
            proc, port, reader, flooder = _start(Path(d), quota)
            try:
                c = http.client.HTTPConnection("127.0.0.1", port, timeout=60)
                _request(c, "POST", "/v1/classify", reader, {"size": 0.5, "eps": 0.25})
                for phase, n in (("alone", 0), ("flood", a.flooders)):
                    cached, health, counts = _phase(port, reader, flooder, a.seconds, n)
                    ok = counts.get(200, 0)
                    print(
                        f"{'quota' if quota else 'no quota':9} {phase:7} "
                        f"{_pct(cached, 50):9.1f}/{_pct(cached, 99):<9.1f} "
                        f"{_pct(health, 50):9.1f}/{_pct(health, 99):<9.1f} "
                        f"{ok:9d} {counts.get(429, 0):6d} {ok / a.seconds:8.1f}",
                        flush=True,
                    )
            finally:
                proc.terminate()
                proc.wait(30)


if __name__ == "__main__":
    main()
