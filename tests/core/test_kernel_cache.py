"""Where the compiled kernels live (rsfcore/_cache.py): one per-user (or configured)
directory keyed by the sources' digest, never inside the source tree; the first compile
says so on stderr.  Each case runs in a fresh interpreter (numba reads its cache setting
when it is imported)."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def _run(code: str, env: dict[str, str]) -> subprocess.CompletedProcess[str]:
    base = {k: v for k, v in os.environ.items() if k not in ("NUMBA_CACHE_DIR", "RSF_CACHE_DIR")}
    base.update(PYTHONPATH=str(ROOT), **env)
    return subprocess.run(
        [sys.executable, "-c", code], env=base, capture_output=True, text=True, timeout=120
    )


def test_per_user_default_keyed_by_digest(tmp_path: Path) -> None:
    r = _run(
        "import os, rsfcore, numba; from rsfcore._cache import source_digest as s; "
        "print(os.environ['NUMBA_CACHE_DIR'], numba.config.CACHE_DIR, s())",
        {"XDG_CACHE_HOME": str(tmp_path), "HOME": str(tmp_path)},
    )
    assert r.returncode == 0, r.stderr
    env_dir, numba_dir, digest = r.stdout.split()
    assert env_dir == numba_dir == str(tmp_path / "rsf-stability" / "numba" / digest)
    assert not Path(env_dir).is_relative_to(ROOT)
    assert len(digest) == 12 and int(digest, 16) >= 0


def test_rsf_cache_dir_and_numba_cache_dir(tmp_path: Path) -> None:
    r = _run(
        "import rsfcore, numba; print(numba.config.CACHE_DIR)", {"RSF_CACHE_DIR": str(tmp_path)}
    )
    assert r.returncode == 0, r.stderr
    assert Path(r.stdout.strip()).parent == tmp_path / "numba"
    given = tmp_path / "given"
    r = _run(
        "import rsfcore, numba; print(numba.config.CACHE_DIR)",
        {"RSF_CACHE_DIR": str(tmp_path), "NUMBA_CACHE_DIR": str(given)},
    )
    assert r.stdout.strip() == str(given)


def test_numba_imported_first_is_pointed_there_too(tmp_path: Path) -> None:
    r = _run(
        "import numba, rsfcore; print(numba.config.CACHE_DIR)", {"RSF_CACHE_DIR": str(tmp_path)}
    )
    assert Path(r.stdout.strip()).parent == tmp_path / "numba"


def test_first_compile_says_so_once(tmp_path: Path) -> None:
    """An empty cache: importing a kernel module prints one line naming the directory;
    with a compiled kernel there, nothing is printed."""
    code = "from rsfcore import laws"
    r = _run(code, {"RSF_CACHE_DIR": str(tmp_path)})
    assert r.returncode == 0, r.stderr
    assert "compiling the numerical kernels into" in r.stderr
    assert str(tmp_path / "numba") in r.stderr
    # a compiled-kernel index present: silent
    d = Path(r.stderr.split(" into ")[1].split(" (")[0])
    (d / "x").mkdir(parents=True, exist_ok=True)
    (d / "x" / "k.nbi").write_bytes(b"")
    r = _run(code, {"RSF_CACHE_DIR": str(tmp_path)})
    assert r.returncode == 0 and "compiling" not in r.stderr, r.stderr
