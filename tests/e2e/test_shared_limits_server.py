"""One key's fresh-computation bucket shared by two real API processes (two uvicorn
servers on one database: a SQLite file, and PostgreSQL), as `rsf api --workers N` and
several API hosts run; the key is made by the real `rsf keys` CLI.  In-process version:
tests/api/test_shared_limits.py."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import httpx
import pytest

from tests.conftest import Postgres
from tests.e2e.test_auth_server import AuthServer, h, problem

pytestmark = [pytest.mark.e2e, pytest.mark.timeout(300)]


@pytest.fixture(params=["sqlite", "postgres"])
def pair(request: pytest.FixtureRequest, tmp_path: Path) -> Iterator[tuple[AuthServer, AuthServer]]:
    extra = {"RSF_QUOTA_FRESH_PER_S": "1000", "RSF_QUOTA_CONCURRENT_REQUESTS": "100"}
    if request.param == "postgres":
        pg: Postgres = request.getfixturevalue("postgres")
        extra["RSF_CACHE_URL"] = pg.url
    else:
        extra["RSF_CACHE_URL"] = f"sqlite:///{tmp_path / 'shared.sqlite3'}"
    servers: list[AuthServer] = []
    try:
        for name in ("a", "b"):  # own data directories: only the database is shared
            d = tmp_path / name
            d.mkdir()
            servers.append(AuthServer(d, **extra))
        yield servers[0], servers[1]
    finally:
        for s in servers:
            s.stop()


def test_two_api_processes_share_one_bucket(pair: tuple[AuthServer, AuthServer]) -> None:
    a, b = pair
    assert a.env["RSF_CACHE_URL"] == b.env["RSF_CACHE_URL"]
    # 0.2 per second: capacity 1, a token back only after 5 s (longer than these requests)
    key = a.rsf("keys", "create", "--name", "slow", "--quota", "fresh_per_s=0.2").stdout.strip()
    first = {"size": 0.211, "eps": 0.17}
    with httpx.Client(base_url=a.url, timeout=60, headers=h(key)) as ca:
        r = ca.post("/v1/classify", json=first)
        assert r.status_code == 200 and r.headers["x-cache"] == "miss", r.text
    with httpx.Client(base_url=b.url, timeout=60, headers=h(key)) as cb:
        r = cb.post("/v1/classify", json={"size": 0.212, "eps": 0.17})
        p = problem(r, 429)
        assert "fresh_per_s" in p["detail"]
        assert 1 <= int(r.headers["retry-after"]) <= 5
        # a cached answer needs no token
        r = cb.post("/v1/classify", json=first)
        assert r.status_code == 200 and r.headers["x-cache"] == "hit", r.text
