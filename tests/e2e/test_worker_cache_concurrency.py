"""Several processes write the same SQLite cache at once: nothing lost, nothing corrupt."""

from __future__ import annotations

import json
import sqlite3
import subprocess
import sys
from pathlib import Path

import pytest

from tests.conftest import ROOT, service_env

pytestmark = pytest.mark.timeout(120)

WRITER = r"""
import json, sys, time
from rsfapp.config import get_settings
from rsfapp.keys import cache_key
from rsfapp.store import stores_for
st = stores_for(get_settings())
wid, n = int(sys.argv[1]), int(sys.argv[2])
while time.time() < float(sys.argv[3]):   # start together
    time.sleep(0.001)
# Overlapping keys: writer w writes keys [w*n/2, w*n/2 + n): half shared with the next.
for k in range(wid * n // 2, wid * n // 2 + n):
    key = cache_key("test", {"k": k}, "v")
    st.results.put(key, "test", "v", {"k": k}, {"value": k * k, "by": "any"})
# Overlapping sweep chunks (result blocks), each written once whoever comes first.
from rsfapp.store.sweeps import encode_block
import numpy as np
for k in range(wid * n // 2, wid * n // 2 + n):
    st.sweeps.store_block("s" * 32, k, k, k + 1,
                          encode_block({"critical_size": np.array([float(k)])}), {})
print("ok", wid)
"""


def test_concurrent_writers_lose_nothing(tmp_path: Path) -> None:
    import time

    env = service_env(tmp_path)
    # Create the schema and one sweep (blocks reference it).
    subprocess.run(
        [
            sys.executable,
            "-c",
            "from rsfapp.config import get_settings; from rsfapp.store import stores_for; "
            "from rsfapp.grid import expand; from rsfapp.requests import SweepRequest; "
            "spec = expand(SweepRequest(axes=[{'name': 'eps', 'start': 0, 'stop': 1, "
            "'n': 10000}]), 10**8); "
            "stores_for(get_settings()).sweeps.create('s'*32, spec, 1, 'v')",
        ],
        env=env,
        cwd=ROOT,
        check=True,
    )
    n_proc, n = 4, 200
    start = str(time.time() + 1.5)
    ps = [
        subprocess.Popen(
            [sys.executable, "-c", WRITER, str(w), str(n), start],
            env=env,
            cwd=ROOT,
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
        )
        for w in range(n_proc)
    ]
    for p in ps:
        out, err = p.communicate(timeout=100)
        assert p.returncode == 0, err.decode()[-3000:]
    expected = set(range(0, (n_proc - 1) * n // 2 + n))
    con = sqlite3.connect(tmp_path / "cache.sqlite3")
    try:
        assert con.execute("PRAGMA integrity_check").fetchone()[0] == "ok"
        assert con.execute("PRAGMA journal_mode").fetchone()[0] == "wal"
        rows = con.execute("SELECT request, result FROM results WHERE kind='test'").fetchall()
        got = {json.loads(r)["k"]: json.loads(v)["value"] for r, v in rows}
        assert len(rows) == len(expected) and set(got) == expected
        assert all(v == k * k for k, v in got.items())
        cnt, distinct = con.execute(
            "SELECT count(*), count(DISTINCT idx) FROM sweep_blocks"
        ).fetchone()
        assert cnt == distinct == len(expected)
    finally:
        con.close()
