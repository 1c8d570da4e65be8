"""Prometheus metrics scraped from a real uvicorn and real Celery workers during a sweep
(issue 25, item 1).

The API and each worker keep their own multi-process directory (as on separate hosts);
the workers serve ``/metrics`` on ``RSF_METRICS_PORT``.  A 300-point sweep runs on a
prefork worker (two pool processes, so the counters are added up over processes), which
is killed mid-sweep; a second worker finishes it.  Checked, against numbers the test
knows independently of the metrics code:

* the API counts exactly the requests this test sent, by route template and status, and
  times each one (histogram count = request count);
* cache lookups: a repeated query is one miss then one hit;
* the state gauges: one sweep running mid-sweep, done at the end; live workers per host;
  the queue depth is reported;
* the workers' points add up to the sweep's 300 (at most one 20-point chunk more: a chunk
  computed and counted by the killed worker just before its block was stored is computed
  again), chunks computed and timed; the killed worker's chunk is requeued (a lease
  expiry, or a take-back at the second worker's start) and counted there.
"""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any

import httpx
import pytest

from tests.conftest import Server, Worker, free_port
from tests.e2e.test_worker_sweeps import wait_for

pytestmark = [pytest.mark.e2e, pytest.mark.timeout(240)]

_LINE = re.compile(r"^([a-zA-Z_:][a-zA-Z0-9_:]*)(\{(.*)\})?\s+(\S+)$")


def scrape(url: str, headers: dict[str, str] | None = None) -> dict[tuple[str, frozenset], float]:
    """{(name, labels): value} of the text exposition at ``url``."""
    r = httpx.get(url, headers=headers, timeout=20)
    assert r.status_code == 200, r.text
    assert r.headers["content-type"].startswith("text/plain")
    return parse(r.text)


def scrape_dir(path: Path) -> dict[tuple[str, frozenset], float]:
    """The metrics left in a multi-process directory (they outlive a killed worker)."""
    from prometheus_client import CollectorRegistry, generate_latest
    from prometheus_client.multiprocess import MultiProcessCollector

    reg = CollectorRegistry()
    MultiProcessCollector(reg, path=str(path))
    return parse(generate_latest(reg).decode())


def parse(text: str) -> dict[tuple[str, frozenset], float]:
    out: dict[tuple[str, frozenset], float] = {}
    for line in text.splitlines():
        if not line or line.startswith("#"):
            continue
        m = _LINE.match(line)
        assert m, line
        labels = frozenset(re.findall(r'(\w+)="([^"]*)"', m.group(3) or ""))
        out[(m.group(1), labels)] = float(m.group(4))
    return out


def val(m: dict[tuple[str, frozenset], float], name: str, **labels: str) -> float:
    """Sum of ``name`` over the series whose labels include ``labels``."""
    want = set(labels.items())
    return sum(v for (n, ls), v in m.items() if n == name and want <= ls)


def test_counters_move_during_a_sweep(tmp_path: Path, procs: list) -> None:
    env: dict[str, Any] = {"RSF_LEASE_S": "3", "RSF_INLINE_BUDGET_S": "60"}
    api_dir, wa_dir, wb_dir = (tmp_path / d for d in ("mp-api", "mp-wa", "mp-wb"))
    for d in (api_dir, wa_dir, wb_dir):
        d.mkdir()
    procs.append(srv := Server(tmp_path, PROMETHEUS_MULTIPROC_DIR=str(api_dir), **env))
    port_a, port_b = free_port(), free_port()
    wa = Worker(
        tmp_path,
        pool="prefork",
        concurrency=2,
        plugin=True,
        RSF_TEST_POINT_DELAY_S="0.01",
        RSF_METRICS_PORT=str(port_a),
        PROMETHEUS_MULTIPROC_DIR=str(wa_dir),
        **env,
    )
    procs.append(wa)
    api = srv.url + "/metrics"
    sent: dict[tuple[str, str, str], int] = {}  # (method, route, status): requests sent

    def call(method: str, route: str, path: str, **kw: Any) -> httpx.Response:
        r = httpx.request(method, srv.url + path, timeout=60, **kw)
        k = (method, route, str(r.status_code))
        sent[k] = sent.get(k, 0) + 1
        return r

    # cache: the same query twice is a miss, then a hit
    q = {"ba": 2.0, "kappa": 2.0, "eps": 0.25}
    m0 = scrape(api)
    assert call("POST", "/v1/critical", "/v1/critical", json=q).status_code == 200
    assert call("POST", "/v1/critical", "/v1/critical", json=q).headers.get("x-cache") == "hit"
    m1 = scrape(api)
    assert (
        val(m1, "rsf_cache_lookups_total", result="miss")
        - val(m0, "rsf_cache_lookups_total", result="miss")
        == 1
    )
    assert (
        val(m1, "rsf_cache_lookups_total", result="hit")
        - val(m0, "rsf_cache_lookups_total", result="hit")
        == 1
    )

    body = {
        "axes": [
            {"name": "kappa_ratio", "start": 0.5, "stop": 4.0, "n": 20},
            {"name": "eps", "start": 0.0, "stop": 0.9, "n": 15},
        ],
        "fixed": {"vo": 0.9},
        "chunk_points": 20,
    }
    r = call("POST", "/v1/sweeps", "/v1/sweeps", json=body)
    assert r.status_code == 202, r.text
    sid = r.headers["location"].rsplit("/", 1)[1]

    def status() -> dict[str, Any]:
        r = call("GET", "/v1/sweeps/{sweep_id}", f"/v1/sweeps/{sid}")
        assert r.status_code == 200, r.text
        return dict(r.json())

    wait_for(lambda: status()["n_done"] >= 60, 90, "progress", dt=0.1)
    # mid-sweep: the worker's counters moved, the API sees one running sweep
    mw = scrape(f"http://127.0.0.1:{port_a}/metrics")
    assert val(mw, "rsf_sweep_points_total", result="ok") >= 60
    assert val(mw, "rsf_sweep_chunks_total", result="computed") >= 3
    assert val(mw, "rsf_sweep_chunk_duration_seconds_count") >= 3
    mid = scrape(api)
    assert val(mid, "rsf_sweeps", status="running") == 1
    assert val(mid, "rsf_workers_live") == 1
    assert ("rsf_queue_depth", frozenset({("queue", "rsf")})) in mid
    assert val(mid, "rsf_state_up") == 1

    wa.kill()  # SIGKILL of the whole worker, mid-chunk
    wa.p.wait(10)
    final_a = scrape_dir(wa_dir)  # its counters, as its processes left them
    wb = Worker(
        tmp_path,
        RSF_METRICS_PORT=str(port_b),
        PROMETHEUS_MULTIPROC_DIR=str(wb_dir),
        **env,
    )
    procs.append(wb)
    wait_for(lambda: status()["status"] == "done", 120, "sweep done", dt=0.2)
    mb = scrape(f"http://127.0.0.1:{port_b}/metrics")
    end = scrape(api)

    # the API counted exactly what this test sent, and timed each request
    for (method, route, code), n in sent.items():
        got = val(end, "rsf_http_requests_total", method=method, route=route, status=code)
        got -= val(m0, "rsf_http_requests_total", method=method, route=route, status=code)
        assert got == n, (method, route, code, got, n)
    for method, route in {(k[0], k[1]) for k in sent}:
        n = sum(v for k, v in sent.items() if k[:2] == (method, route))
        hist = val(end, "rsf_http_request_duration_seconds_count", method=method, route=route)
        hist -= val(m0, "rsf_http_request_duration_seconds_count", method=method, route=route)
        assert hist == n, (method, route)
    assert val(end, "rsf_sweeps", status="done") == 1
    assert val(end, "rsf_sweeps", status="running") == 0
    assert val(end, "rsf_workers_live") >= 1

    # points: every one of the 300 counted once when its chunk finished computing; a
    # chunk counted by the killed worker but not yet stored is computed again (at most
    # one 20-point chunk per pool process: 2 x 20)
    ok_a = val(final_a, "rsf_sweep_points_total", result="ok")
    ok_b = val(mb, "rsf_sweep_points_total", result="ok")
    assert ok_a >= val(mw, "rsf_sweep_points_total", result="ok")
    assert ok_a < 300 and ok_b > 0
    assert 300 <= ok_a + ok_b <= 340, (ok_a, ok_b)
    assert val(mb, "rsf_sweep_points_total", result="failed") == 0
    assert val(mb, "rsf_sweep_chunks_total", result="computed") >= 1
    # the chunk the killed worker held was sent again by the second worker
    assert val(mb, "rsf_chunk_requeues_total") >= 1
    expiries = val(mb, "rsf_lease_expiries_total")
    assert val(mb, "rsf_chunk_requeues_total", reason="lease_expired") == expiries
