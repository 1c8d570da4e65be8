"""Schemathesis fuzzing of the whole OpenAPI schema against a real uvicorn: no 5xx.

Bounded: a few examples per operation, fixed seed, coverage + fuzzing phases.  The
server has no worker (submitted sweeps just wait in the filesystem queue).
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from tests.conftest import Server

pytestmark = pytest.mark.timeout(240)

MAX_EXAMPLES = os.environ.get("RSF_FUZZ_EXAMPLES", "5")


def test_schemathesis_finds_no_server_error(tmp_path: Path, procs: list) -> None:
    procs.append(srv := Server(tmp_path, RSF_INLINE_BUDGET_S="1"))
    st = Path(sys.executable).with_name("st")
    cmd = [
        str(st),
        "run",
        srv.url + "/openapi.json",
        "--checks",
        "not_a_server_error",
        "--max-examples",
        MAX_EXAMPLES,
        "--phases",
        "coverage,fuzzing",
        "--workers",
        "2",
        "--seed",
        "20261122",
        "--generation-database",
        "none",
        "--no-color",
        "--request-timeout",
        "20",
        "--max-failures",
        "5",
    ]
    r = subprocess.run(cmd, capture_output=True, text=True, timeout=220, cwd=tmp_path)
    assert r.returncode == 0, r.stdout[-6000:] + r.stderr[-2000:]
    assert "5xx" not in r.stdout and "Server error" not in r.stdout
