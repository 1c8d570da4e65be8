"""dev.py's kernel-cache probe runs against the rsfcore it ships with (it once imported a
private helper that rsfcore had removed, and `python dev.py test` failed on a fresh clone)."""

from __future__ import annotations

import importlib.util
import os
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def _dev_module():  # type: ignore[no-untyped-def]
    spec = importlib.util.spec_from_file_location("rsf_dev_script", ROOT / "dev.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _probe(cache_root: Path) -> tuple[str, Path]:
    env = {**os.environ, "RSF_CACHE_DIR": str(cache_root), "PYTHONPATH": str(ROOT)}
    env.pop("NUMBA_CACHE_DIR", None)
    out = subprocess.check_output(
        [sys.executable, "-c", _dev_module().WARM_PROBE], text=True, env=env, cwd=ROOT
    )
    warm, _, cache = out.strip().partition(" ")
    return warm, Path(cache)


def test_probe_reports_cold_then_warm(tmp_path: Path) -> None:
    warm, cache = _probe(tmp_path)
    assert warm == "0"
    assert tmp_path in cache.parents  # the configured root, never the source tree
    (cache / "sub").mkdir(parents=True)
    (cache / "sub" / "kernel.nbi").write_bytes(b"")
    assert _probe(tmp_path) == ("1", cache)
