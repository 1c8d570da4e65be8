"""A single query still computing after RSF_INLINE_BUDGET_S is answered 202 + Location
by a real uvicorn process, and its result appears at that location."""

from __future__ import annotations

from pathlib import Path

import httpx
import pytest

pytestmark = pytest.mark.timeout(120)


def test_long_query_is_deferred_with_location(tmp_path: Path, procs: list) -> None:
    """A query exceeding the inline budget answers 202 + Location, then the result."""
    from tests.conftest import Server

    procs.append(srv := Server(tmp_path, RSF_INLINE_BUDGET_S="0.001"))
    with httpx.Client(base_url=srv.url, timeout=60) as c:
        body = {
            "ba": 2.0,
            "kappa": 1.2,
            "eps": 0.4,
            "size": 2.0,
            "n_points": 10000,
            "physical": {"a": 0.01, "Dc": 1e-4, "sigma": 1e8, "V_star": 1e-6},
        }
        r = c.post("/v1/trajectory", json=body)
        assert r.status_code == 202, r.text[:300]
        loc = r.headers["location"]
        assert loc == "/v1/results/" + r.json()["cache_key"]
        import time

        deadline = time.monotonic() + 30
        while (g := c.get(loc)).status_code == 202 and time.monotonic() < deadline:
            time.sleep(0.05)
        assert g.status_code == 200 and g.headers["x-cache"] == "hit"
        assert 0 < len(g.json()["trajectory"]["T"]) <= 10000
        assert c.post("/v1/trajectory", json=body).headers["x-cache"] == "hit"
        assert c.get("/v1/results/" + "0" * 64).status_code == 404
