"""Several API processes keep no state another one needs (``rsf api --workers N``).

Two app instances on one database stand for two API processes: a computation deferred
by the first (202 + Location, still computing) is answered by the second from the job
store (202 while it runs, then the result), never a 404 because the second process did
not start it.
"""

from __future__ import annotations

import os
import time
from collections.abc import Iterator
from pathlib import Path

import pytest
from fastapi.testclient import TestClient

from service.app import create_app

pytestmark = pytest.mark.timeout(120)


@pytest.fixture
def two_apps(tmp_path: Path) -> Iterator[tuple[TestClient, TestClient]]:
    saved = {k: v for k, v in os.environ.items() if k.startswith("RSF_")}
    for k in saved:
        del os.environ[k]
    os.environ.update(RSF_DATA_DIR=str(tmp_path), RSF_INLINE_BUDGET_S="0.001")
    try:
        with (
            TestClient(create_app(), raise_server_exceptions=False) as a,
            TestClient(create_app(), raise_server_exceptions=False) as b,
        ):
            yield a, b
    finally:
        for k in [k for k in os.environ if k.startswith("RSF_")]:
            del os.environ[k]
        os.environ.update(saved)


def test_deferred_computation_is_visible_to_another_api_process(
    two_apps: tuple[TestClient, TestClient],
) -> None:
    a, b = two_apps
    body = {"ba": 2.0, "kappa": 1.2, "eps": 0.4, "size": 2.0, "n_points": 10000}
    r = a.post("/v1/trajectory", json=body)
    assert r.status_code == 202, r.text[:300]
    loc = r.headers["location"]
    first = b.get(loc)
    assert first.status_code in (200, 202), first.text  # never 404 in the other process
    deadline = time.monotonic() + 60
    g = first
    while g.status_code == 202 and time.monotonic() < deadline:
        time.sleep(0.05)
        g = b.get(loc)
    assert g.status_code == 200 and g.headers["x-cache"] == "hit"
    assert g.json()["cache_key"] == r.json()["cache_key"]
