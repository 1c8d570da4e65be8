"""A long single integration goes through the queue to a real worker, not the API process."""

from __future__ import annotations

import time
from pathlib import Path

import httpx

from rsfcore import Params, classify
from tests.conftest import Server, Worker


def test_long_classification_is_queued_to_a_worker(tmp_path: Path, procs: list) -> None:
    # kappa = 1e4 kappa_crit: a creep on a stiff slow manifold needing ~2e6 explicit steps
    # (~5 s), far beyond the API's quick in-process budget (3e5 steps).
    body = {
        "ba": 100.0,
        "kappa": 990000.0,
        "eps": 0.0,
        "vo": 1.0,
        "perturbation": "load-point-jump",
        "size": 700.0,
    }
    procs.append(srv := Server(tmp_path))
    with httpx.Client(base_url=srv.url, timeout=60) as c:
        r = c.post("/v1/classify", json=body)
        assert r.status_code == 202, r.text[:300]
        loc = r.headers["location"]
        # no worker yet: it stays queued (persistently), and a repeat does not recompute
        time.sleep(1.0)
        assert c.get(loc).json()["status"] == "queued"
        assert c.post("/v1/classify", json=body).status_code == 202
        procs.append(Worker(tmp_path))
        deadline = time.monotonic() + 120
        while (g := c.get(loc)).status_code == 202 and time.monotonic() < deadline:
            time.sleep(0.25)
        assert g.status_code == 200, g.text[:300]
        d = g.json()
        lib = classify(Params(100.0, 990000.0, 0.0, 1.0), "load-point-jump", 700.0)
        assert d["outcome"] == lib.outcome == "stable"
        assert d["return_time"] == lib.return_time
        assert c.post("/v1/classify", json=body).headers["x-cache"] == "hit"
