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
throughput of cached lookups (POST /v1/classify cycling through 50 cached queries,
answered from memory) next to the trivial endpoint GET /health/live (no I/O) in the same
run.  Targets (issue 12): cached >= 0.8x trivial; 2 API processes >= 1.6x one.  With
``--with-key`` it also measures the cached lookups sent with an API key (made with the
real `rsf keys create`, revoked after the phase): every such request verifies the key
in the database (revocation is immediate), the cost every deployment with keys pays.

The load generator runs on the same machine.  When ``wrk`` is on PATH (``apt-get
install wrk``) it is used (``--generator auto``): one thread, ``--connections``
keep-alive connections, a Lua script generated into a temporary directory that cycles
through the pre-formatted requests; phases then last ``--seconds`` (no request bound).
Otherwise the Python generator (``--clients`` processes) is used; the printout names
the one used.  With wrk, the API processes and wrk are pinned (``taskset``, unless
``--no-pin``): n API processes on CPUs 0..n-1, wrk on the last CPU.  For every phase it
prints the CPU budget read from /proc: CPU time per request of the API processes and of
the generator, cores each used, the cores used by the rest of the machine (other users:
a non-zero figure means the run was disturbed), the share of each API process and the
load average; and, for 2 processes / 1, the ceiling the CPU allows:
``min(2 / s2, ncpu / (s2 + g2)) / (1 / s1)`` with ``s`` and ``g`` the server and
generator CPU time per request (one process uses at most one core; two processes share
the machine's cores with the generator).  On 2 cores the generator's share decides
whether 1.6x is reachable: wrk costs ~20-35 us per request, the Python generator ~150 us
(as much as the server), which caps it at ~1.0-1.2x.
"""

from __future__ import annotations

import argparse
import http.client
import json
import multiprocessing as mp
import os
import random
import resource
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


def start_api(data_dir: str, workers: int, cpus: str | None = None) -> tuple[subprocess.Popen, str]:
    """`rsf api --workers N` on a free port (SQLite + filesystem broker in data_dir),
    pinned to the CPU list ``cpus`` (``taskset -c``) if given."""
    port = _free_port()
    env = {k: v for k, v in os.environ.items() if not k.startswith("RSF_")}
    env["RSF_DATA_DIR"] = data_dir
    log = open(Path(data_dir) / "api.log", "wb")  # noqa: SIM115
    pin = ["taskset", "-c", cpus] if cpus is not None else []
    p = subprocess.Popen(
        [
            *pin,
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


_CLK_TCK = os.sysconf("SC_CLK_TCK") if hasattr(os, "sysconf") else 100


def _proc_fields(pid: int) -> list[str] | None:
    """Fields of /proc/PID/stat after the command name (index 0 = state), or None."""
    try:
        raw = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return None
    return raw[raw.rindex(")") + 2 :].split()


def _cpu_s(pids: list[int]) -> float:
    """CPU time (user + system, all threads) of ``pids`` so far [s]."""
    total = 0
    for pid in pids:
        f = _proc_fields(pid)
        if f is not None:
            total += int(f[11]) + int(f[12])  # utime, stime [clock ticks]
    return total / _CLK_TCK


def _tree(pid: int) -> list[int]:
    """``pid`` and its children (the uvicorn supervisor and its API processes)."""
    out = [pid]
    for d in Path("/proc").iterdir():
        if d.name.isdigit():
            f = _proc_fields(int(d.name))
            if f is not None and int(f[1]) == pid:
                out.append(int(d.name))
    return out


def _wait_ready(pid: int, workers: int, limit_s: float = 60.0) -> list[int]:
    """The process tree of ``rsf api --workers N`` once every API process is up and idle.

    /health answers as soon as the first process is ready; a second one still importing
    would accept no connection, and wrk opens all of its connections at once, so a phase
    started then measures one process (seen: split 1.00, 0.99x).
    """
    want = workers + (1 if workers > 1 else 0)  # the supervisor and its API processes
    t_end = time.monotonic() + limit_s
    pids = _tree(pid)
    while time.monotonic() < t_end:
        pids = _tree(pid)
        before = [_cpu_s([p]) for p in pids]
        time.sleep(0.5)
        busy = any(_cpu_s([p]) - b > 0.02 for p, b in zip(pids, before, strict=True))
        if len(pids) >= want and not busy:
            break
    return pids


def _machine_busy_s() -> float:
    """CPU time the whole machine spent busy so far (every CPU; /proc/stat) [s]."""
    try:
        cpu = Path("/proc/stat").read_text().splitlines()[0].split()[1:]
    except OSError:
        return float("nan")
    v = [int(x) for x in cpu]
    idle = v[3] + (v[4] if len(v) > 4 else 0)  # idle + iowait
    return (sum(v[:8]) - idle) / _CLK_TCK


def _loadavg() -> float:
    try:
        return float(Path("/proc/loadavg").read_text().split()[0])
    except OSError:
        return float("nan")


class _Meter:
    """CPU spent during one phase by the API processes, the load generator (every child
    of this process reaped meanwhile: wrk, or the Python client processes) and the rest
    of the machine (other users of the cores)."""

    def __init__(self, server_pids: list[int]) -> None:
        self.pids = server_pids

    def __enter__(self) -> _Meter:
        self.t0 = time.perf_counter()
        self.s0 = _cpu_s(self.pids)
        self.per0 = [_cpu_s([p]) for p in self.pids]
        self.g0 = resource.getrusage(resource.RUSAGE_CHILDREN)
        self.m0 = _machine_busy_s()
        self.load0 = _loadavg()
        return self

    def __exit__(self, *exc: object) -> None:
        self.wall = time.perf_counter() - self.t0
        self.server_s = _cpu_s(self.pids) - self.s0
        self.per_process_s = [_cpu_s([p]) - c for p, c in zip(self.pids, self.per0)]
        g1 = resource.getrusage(resource.RUSAGE_CHILDREN)
        self.gen_s = (g1.ru_utime - self.g0.ru_utime) + (g1.ru_stime - self.g0.ru_stime)
        self.machine_s = _machine_busy_s() - self.m0
        self.load = max(self.load0, _loadavg())

    def figures(self, n: int) -> dict:
        """CPU figures of the phase for ``n`` requests answered."""
        n = max(n, 1)
        other = max(0.0, self.machine_s - self.server_s - self.gen_s)
        return {
            "server_cpu_us_per_req": 1e6 * self.server_s / n,
            "gen_cpu_us_per_req": 1e6 * self.gen_s / n,
            "server_cores": self.server_s / self.wall,
            "gen_cores": self.gen_s / self.wall,
            "other_cores": other / self.wall,
            "server_split": [
                round(x / self.server_s, 2) if self.server_s else 0.0 for x in self.per_process_s
            ],
            "load": self.load,
        }


def _lua_str(text: str) -> str:
    """``text`` as a Lua long-bracket string literal."""
    eq = "="
    while f"]{eq}]" in text:
        eq += "="
    return f"[{eq}[{text}]{eq}]"


_WRK_DONE = """
done = function(summary, latency, requests)
  local e = summary.errors
  io.write(string.format("RSFWRK %d %d %d %d %d %d %d %.1f %.1f\\n", summary.requests,
    summary.duration, e.connect, e.read, e.write, e.status, e.timeout,
    latency:percentile(50), latency:percentile(99)))
end
"""


def _wrk_script(
    tmp: str, name: str, requests: list[tuple[str, str, str | None]], headers: dict[str, str]
) -> str:
    """A wrk Lua script (written to ``tmp``) cycling through ``requests`` (method, path,
    JSON body or None), pre-formatted once per wrk thread; its path."""
    hdr = ", ".join(f"[ {_lua_str(k)} ] = {_lua_str(v)}" for k, v in headers.items())
    items = ",\n  ".join(
        f"{{{_lua_str(m)}, {_lua_str(p)}, {'nil' if b is None else _lua_str(b)}}}"
        for m, p, b in requests
    )
    lua = f"""-- generated by bench/load_service.py
local items = {{
  {items}
}}
local reqs = {{}}
local i = 0
init = function(args)
  local h = {{ {hdr} }}
  for k, it in ipairs(items) do
    local hh = {{}}
    for a, b in pairs(h) do hh[a] = b end
    if it[3] == nil then hh["Content-Type"] = nil end
    reqs[k] = wrk.format(it[1], it[2], hh, it[3])
  end
  i = math.random(#reqs) - 1
end
request = function()
  i = i % #reqs + 1
  return reqs[i]
end
{_WRK_DONE}"""
    path = Path(tmp) / f"{name}.lua"
    path.write_text(lua)
    return str(path)


def _wrk_phase(
    url: str,
    kind: str,
    script: str,
    connections: int,
    seconds: float,
    pids: list[int],
    cpus: str | None,
) -> dict:
    """One wrk run (1 thread, ``connections`` keep-alive connections) of ``seconds``."""
    cmd = ["wrk", "-t1", f"-c{connections}", f"-d{seconds:g}s", "--timeout", "10s", "-s", script]
    if cpus is not None:
        cmd = ["taskset", "-c", cpus, *cmd]
    with _Meter(pids) as m:
        r = subprocess.run([*cmd, url], capture_output=True, text=True, timeout=seconds + 60)
    line = next((x for x in r.stdout.splitlines() if x.startswith("RSFWRK ")), None)
    if r.returncode != 0 or line is None:
        raise SystemExit(f"wrk failed ({r.returncode}): {r.stdout}\n{r.stderr}")
    n, dur_us, e_conn, e_read, e_write, e_status, e_timeout = (int(x) for x in line.split()[1:8])
    p50_us, p99_us = (float(x) for x in line.split()[8:10])
    out = {
        "kind": kind,
        "n": n,
        "errors": e_conn + e_read + e_write + e_status + e_timeout,
        "req_per_s": n / (dur_us * 1e-6),
        "p50_ms": p50_us / 1e3,
        "p99_ms": p99_us / 1e3,
    }
    out.update(m.figures(n))
    return out


def _py_phase(
    url: str,
    kind: str,
    clients: int,
    max_req: int,
    secs: float,
    bodies: list[dict],
    headers: dict[str, str] | None,
    pids: list[int],
) -> dict:
    with _Meter(pids) as m:
        out = phase(url, kind, clients, max_req, secs, bodies, headers)
    out.update(m.figures(out["n"]))
    return out


def _all_hits(url: str, bodies: list[dict], headers: dict[str, str] | None = None) -> bool:
    """Whether every body is answered 200 from the cache (X-Cache: hit)."""
    u = urlparse(url)
    c = http.client.HTTPConnection(u.hostname, u.port, timeout=30)
    ok = True
    for b in bodies:
        c.request(
            "POST",
            "/v1/classify",
            json.dumps(b),
            {"Content-Type": "application/json", **(headers or {})},
        )
        r = c.getresponse()
        r.read()
        ok = ok and r.status == 200 and r.getheader("X-Cache") == "hit"
    c.close()
    return ok


def api_scaling(
    clients: int,
    max_req: int,
    secs: float,
    with_key: bool = False,
    generator: str = "python",
    connections: int = 16,
    pin: bool = False,
) -> list[dict]:
    """Trivial vs cached throughput with 1 and 2 API processes (see the module doc)."""
    bodies = [{"ba": 2.0 + 0.01 * k, "kappa": 0.9, "eps": 0.5, "size": 1.0} for k in range(50)]
    texts = [json.dumps(b) for b in bodies]
    ncpu = os.cpu_count() or 1
    rows = []
    tmp = tempfile.mkdtemp(prefix="rsf-bench-api-")
    lua = Path(tmp) / "lua"
    lua.mkdir(mode=0o700)
    triv_s = cached_s = ""
    if generator == "wrk":
        triv_s = _wrk_script(str(lua), "trivial", [("GET", "/health/live", None)], {})
        cached_s = _wrk_script(
            str(lua),
            "cached",
            [("POST", "/v1/classify", t) for t in texts],
            {"Content-Type": "application/json"},
        )
    for n in (1, 2):
        # pinned: n API processes on CPUs 0..n-1, the generator on the last CPU
        srv_cpus = ",".join(str(c) for c in range(min(n, ncpu))) if pin else None
        gen_cpus = str(ncpu - 1) if pin else None
        proc, url = start_api(tmp, n, srv_cpus)
        pids = _wait_ready(proc.pid, n)
        try:
            for b in bodies:  # warm the cache (shared database: only the first run computes)
                _req(url, "POST", "/v1/classify", b)

            def run(
                kind: str, script: str, headers: dict[str, str] | None = None, t: float = secs
            ) -> dict:
                if generator == "wrk":
                    return _wrk_phase(url, kind, script, connections, t, pids, gen_cpus)
                return _py_phase(url, kind, clients, max_req, t, bodies, headers, pids)

            # warm every API process; every process learns the bodies
            run("trivial", triv_s, t=1.0)
            run("cached", cached_s, t=1.0)
            triv = run("trivial", triv_s)
            cached = run("cached", cached_s)
            cached["all_hits"] = _all_hits(url, bodies)
            keyed = None
            if with_key:  # after the anonymous phases: a key makes keys necessary
                name = f"bench{n}"
                key = _rsf_keys(tmp, "create", "--name", name, "--scope", "read")
                auth = {"Authorization": f"Bearer {key}"}
                key_s = ""
                if generator == "wrk":
                    key_s = _wrk_script(
                        str(lua),
                        f"cached_key{n}",
                        [("POST", "/v1/classify", t) for t in texts],
                        {"Content-Type": "application/json", **auth},
                    )
                run("cached_key", key_s, auth, 1.0)  # every process learns the bodies again
                keyed = run("cached_key", key_s, auth)
                keyed["all_hits"] = _all_hits(url, bodies, auth)
                _rsf_keys(tmp, "revoke", name)  # the next server serves loopback anonymously
        finally:
            os.killpg(proc.pid, signal.SIGTERM)
            try:
                proc.wait(30)
            except subprocess.TimeoutExpired:
                os.killpg(proc.pid, signal.SIGKILL)
        row = {
            "api_processes": n,
            "generator": generator,
            "server_cpus": srv_cpus,
            "generator_cpus": gen_cpus,
            "trivial": triv,
            "cached": cached,
        }
        if keyed is not None:
            row["cached_key"] = keyed
        rows.append(row)
    shutil.rmtree(tmp, ignore_errors=True)
    return rows


def print_api_scaling(rows: list[dict], clients: int, connections: int) -> None:
    ncpu = os.cpu_count() or 1
    gen = rows[0]["generator"]
    how = (
        f"wrk, 1 thread, {connections} keep-alive connections"
        if gen == "wrk"
        else f"Python load generator, {clients} client processes (wrk not on PATH)"
    )
    print(f"API alone (`rsf api --workers N`, SQLite), {ncpu} CPUs; load generator: {how}")
    for r in rows:
        if r["server_cpus"] is not None:
            print(
                f"  {r['api_processes']} API process(es) pinned to CPU(s) {r['server_cpus']}, "
                f"generator to CPU {r['generator_cpus']}"
            )
    print(
        f"{'API procs':>9} {'phase':<10} {'requests':>9} {'errors':>6} {'req/s':>7} "
        f"{'p50 ms':>7} {'p99 ms':>7} {'srv us/req':>10} {'gen us/req':>10} "
        f"{'srv cores':>9} {'gen cores':>9} {'others':>6} {'split':>9} {'load':>5}"
    )
    for r in rows:
        for k in ("trivial", "cached", "cached_key"):
            if k not in r:
                continue
            p = r[k]
            # the API processes (the supervisor's helper processes use no CPU)
            split = "/".join(f"{x:.2f}" for x in p["server_split"][1:] if x >= 0.01) or "-"
            print(
                f"{r['api_processes']:>9} {k:<10} {p['n']:>9} {p['errors']:>6} "
                f"{p['req_per_s']:>7.0f} {p['p50_ms']:>7.2f} {p['p99_ms']:>7.2f} "
                f"{p['server_cpu_us_per_req']:>10.0f} {p['gen_cpu_us_per_req']:>10.1f} "
                f"{p['server_cores']:>9.2f} {p['gen_cores']:>9.2f} {p['other_cores']:>6.2f} "
                f"{split:>9} {p['load']:>5.2f}"
            )
    print(
        "  srv/gen us/req: CPU time per request of the API processes / the load generator; "
        "cores: CPU time / wall time; others: the rest of the machine (other users); "
        "split: share of the server CPU per API process"
    )
    for r in rows:
        if not r["cached"].get("all_hits", True) or not r.get("cached_key", {}).get(
            "all_hits", True
        ):
            print(f"  WARNING: {r['api_processes']} API process(es): not every lookup was a hit")
    for r in rows:
        ratio = r["cached"]["req_per_s"] / r["trivial"]["req_per_s"]
        print(
            f"{r['api_processes']} API process(es): cached / trivial = {ratio:.2f} (target >= 0.8)"
        )
        if "cached_key" in r:
            rk = r["cached_key"]["req_per_s"] / r["trivial"]["req_per_s"]
            print(f"{r['api_processes']} API process(es): cached with a key / trivial = {rk:.2f}")

    def ceiling(p: dict, n: int, others: float) -> float:
        """Most req/s the CPU allows n single-threaded API processes plus the generator
        when ``others`` cores are taken by other users: X s <= n and X (s + g) <= free."""
        sv, g = p["server_cpu_us_per_req"], p["gen_cpu_us_per_req"]
        if sv <= 0:
            return float("nan")
        return min(n * 1e6 / sv, max(ncpu - others, 0.0) * 1e6 / (sv + g))

    for k in ("trivial", "cached", "cached_key"):
        if k not in rows[0] or k not in rows[1]:
            continue
        one, two = rows[0][k], rows[1][k]
        up = two["req_per_s"] / one["req_per_s"]
        s1, s2 = one["server_cpu_us_per_req"], two["server_cpu_us_per_req"]
        g1, g2 = one["gen_cpu_us_per_req"], two["gen_cpu_us_per_req"]
        free = ceiling(two, 2, 0.0) / ceiling(one, 1, 0.0)
        busy = ceiling(two, 2, two["other_cores"]) / ceiling(one, 1, one["other_cores"])
        print(
            f"2 API processes / 1, {k}: {up:.2f}x (target >= 1.6x); CPU ceiling {free:.2f}x on "
            f"a free machine = min(2 / {s2:.0f} us, {ncpu} / ({s2:.0f} + {g2:.0f}) us) / "
            f"min(1 / {s1:.0f} us, {ncpu} / ({s1:.0f} + {g1:.0f}) us), {busy:.2f}x with the "
            f"cores other users took ({one['other_cores']:.2f} / {two['other_cores']:.2f})"
        )
    worst = max(p["other_cores"] for r in rows for p in r.values() if isinstance(p, dict))
    if worst > 0.1:
        print(
            f"  NOTE: other processes took up to {worst:.2f} cores during this run: "
            "the figures are disturbed (see 'others'); repeat on a quiet machine"
        )


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
        "--generator",
        choices=("auto", "wrk", "python"),
        default="auto",
        help="with --api-scaling: load generator (auto: wrk if on PATH, else Python)",
    )
    ap.add_argument(
        "--connections", type=int, default=16, help="wrk keep-alive connections (1..256)"
    )
    ap.add_argument(
        "--no-pin",
        action="store_true",
        help="with --api-scaling and wrk: do not pin the API processes and wrk to CPUs",
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
        gen = a.generator
        if gen == "auto":
            gen = "wrk" if shutil.which("wrk") else "python"
        elif gen == "wrk" and not shutil.which("wrk"):
            raise SystemExit("--generator wrk: wrk is not on PATH (apt-get install wrk)")
        conns = min(max(a.connections, 1), 256)
        pin = gen == "wrk" and not a.no_pin and bool(shutil.which("taskset"))
        rows = api_scaling(clients, max_req, secs, a.with_key, gen, conns, pin)
        if a.json:
            print(json.dumps(rows))
        else:
            print_api_scaling(rows, clients, conns)
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
