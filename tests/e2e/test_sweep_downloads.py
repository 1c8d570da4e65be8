"""Sweep downloads through a real uvicorn server, on SQLite and on PostgreSQL: the
per-process places (service.downloads) seen from outside.

* A second NetCDF download while a file is being built is answered 503 problem+json with
  Retry-After and a message naming the build; a CSV download is served meanwhile.
* Downloads abandoned by their clients mid-stream give their places back (the server
  closes their streams), so the next downloads are served.

The sweep is a large grid never computed (no worker): its downloads are fill values,
read slab by slab as computed results are."""

from __future__ import annotations

import threading
import time
from pathlib import Path
from typing import Any

import httpx
import pytest

from tests.conftest import Server

pytestmark = [pytest.mark.e2e, pytest.mark.timeout(600)]

#: 10^8 points (the default largest sweep): a NetCDF build of about a second of CPU when
#: nothing is computed, a CSV of ~8 GB (never read whole here).
BIG = {
    "axes": [
        {"name": "kappa_ratio", "start": 0.3, "stop": 0.95, "n": 100},
        {"name": "eps", "start": 0.0, "stop": 0.6, "n": 100},
        {"name": "ba", "start": 1.2, "stop": 20.0, "n": 10000},
    ],
    "fixed": {"vo": 1.0},
}
#: Attempts at sending a request while a build runs (each misses only if the whole build
#: ends before the next request is read: a few tries make a miss by chance negligible).
ATTEMPTS = 5


@pytest.fixture(params=["sqlite", "postgres"])
def server(request: pytest.FixtureRequest, tmp_path: Path, procs: list[Any]) -> Server:
    extra: dict[str, str] = {"RSF_QUOTA_POINTS_PER_DAY": str(10**9)}
    if request.param == "postgres":
        extra["RSF_CACHE_URL"] = request.getfixturevalue("postgres").url
    srv = Server(tmp_path, **extra)
    procs.append(srv)
    return srv


def _submit(c: httpx.Client) -> str:
    r = c.post("/v1/sweeps", json=BIG)
    assert r.status_code == 202, r.text
    return str(r.json()["id"])


def test_a_second_netcdf_build_waits_its_turn(server: Server) -> None:
    c = httpx.Client(base_url=server.url, timeout=300)
    sid = _submit(c)
    data = f"/v1/sweeps/{sid}/data"
    refused: httpx.Response | None = None
    for _ in range(ATTEMPTS):
        first: dict[str, Any] = {}

        def build(out: dict[str, Any] = first) -> None:
            r = c.get(data, params={"format": "netcdf"})
            out.update(status=r.status_code, size=len(r.content))

        t = threading.Thread(target=build)
        t.start()
        while t.is_alive() and refused is None:
            r = httpx.get(server.url + data, params={"format": "netcdf"}, timeout=300)
            if r.status_code == 503:
                refused = r
            else:  # the first had not started building yet, or was done: this one's turn
                assert r.status_code == 200, r.text
        if refused is not None:
            break
        t.join()
    assert refused is not None, "no request arrived while a file was being built"
    assert int(refused.headers["retry-after"]) >= 1
    assert refused.headers["content-type"].startswith("application/problem+json")
    body = refused.json()
    assert body["status"] == 503 and "NetCDF file is being built" in body["reason"], body
    assert "subset" in body["hint"] and "CSV" in body["hint"], body
    # a streamed format is served while the build runs (read its first piece only)
    with httpx.stream("GET", server.url + data, params={"format": "csv"}, timeout=300) as s:
        assert s.status_code == 200, s.read()
        assert next(s.iter_lines()).startswith("idx,kappa_ratio,eps,ba,")
    t.join()
    assert first["status"] == 200 and first["size"] > 0, first  # the first was served
    # the build is over: the next NetCDF download is served
    r = c.get(data, params={"format": "netcdf", "isel": "kappa_ratio:0:1"})
    assert r.status_code == 200 and r.content[:4] == b"\x89HDF"
    c.close()


def test_abandoned_downloads_give_their_places_back(server: Server) -> None:
    c = httpx.Client(base_url=server.url, timeout=300)
    sid = _submit(c)
    data = f"{server.url}/v1/sweeps/{sid}/data"
    for fmt in ("csv", "json", "csv", "json"):
        # fill both places, read a piece of each, hang up
        streams = [httpx.stream("GET", data, params={"format": fmt}, timeout=300) for _ in "ab"]
        try:
            for s in streams:
                resp = s.__enter__()
                assert resp.status_code == 200, resp.read()
                assert next(resp.iter_bytes())
        finally:
            for s in streams:
                s.__exit__(None, None, None)
        # both hung up: within a bounded time a new download is served again
        deadline = time.monotonic() + 60
        while True:
            r = c.get(f"/v1/sweeps/{sid}/data", params={"format": "json", "isel": "ba:0"})
            if r.status_code == 200:
                break
            assert r.status_code == 503 and "retry-after" in r.headers, r.text
            assert time.monotonic() < deadline, "the abandoned downloads kept their places"
            time.sleep(0.2)
        assert r.json()["shape"] == [100, 100, 1]
    c.close()
