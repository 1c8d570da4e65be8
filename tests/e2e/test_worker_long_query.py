"""A long single integration goes through the queue to a real worker, not the API process."""

from __future__ import annotations

import time
from pathlib import Path

import httpx

from rsfcore import Params, classify
from tests.conftest import Server, Worker


def test_long_classification_is_queued_to_a_worker(tmp_path: Path, procs: list) -> None:
    # The API's quick in-process budget is set to 20 steps, so this classification
    # (~60 DOP853 steps, undecided after 20) is a long integration for this server: it
    # must go to the queue and be computed by the worker with the full budget.
    body = {"ba": 2.0, "kappa": 2.0, "eps": 0.25, "vo": 1.0, "size": 2.7}
    procs.append(srv := Server(tmp_path, RSF_QUICK_STEPS="20"))
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
        lib = classify(Params(2.0, 2.0, 0.25, 1.0), "velocity-jump", 2.7)
        assert d["outcome"] == lib.outcome == "stable"
        assert d["return_time"] == lib.return_time
        assert c.post("/v1/classify", json=body).headers["x-cache"] == "hit"
