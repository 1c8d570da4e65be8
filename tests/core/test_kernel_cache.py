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


def _run(code: str, env: dict[str, str], timeout: float = 120) -> subprocess.CompletedProcess[str]:
    base = {k: v for k, v in os.environ.items() if k not in ("NUMBA_CACHE_DIR", "RSF_CACHE_DIR")}
    base.update(PYTHONPATH=str(ROOT), **env)
    return subprocess.run(
        [sys.executable, "-c", code], env=base, capture_output=True, text=True, timeout=timeout
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
    """An empty cache: importing a kernel module compiles nothing and says nothing; the
    first kernel compiled prints one line naming the directory, once however many kernels
    compile; with the kernels compiled there, nothing is printed."""
    env = {"RSF_CACHE_DIR": str(tmp_path)}
    r = _run("from rsfcore import laws", env)
    assert r.returncode == 0 and "compiling" not in r.stderr, r.stderr
    code = "from rsfcore.laws import G, L_star\nprint(float(G(0.3, 0.7) + L_star(2.0, 1.0, 0.5)))"
    r = _run(code, env, timeout=600)  # compiles G and L_star
    assert r.returncode == 0, r.stderr
    assert r.stderr.count("compiling the numerical kernels into") == 1, r.stderr
    assert str(tmp_path / "numba") in r.stderr
    r = _run(code, env)
    assert r.returncode == 0 and "compiling" not in r.stderr, r.stderr


_LOAD = (
    "import sys, rsfcore{pre}\n"
    "from rsfcore import Params, classify, critical_perturbation\n"
    "r = classify(Params(2.0, 2.0, 0.25, 1.0), size=3.0)\n"
    "c = critical_perturbation(Params(2.0, 1.5, 0.5, 1.0))\n"
    "print(r.outcome, float(r.peak_phi).hex(), float(r.return_time or 0).hex(), "
    "float(c.critical_size).hex())\n"
    "print('numba.np.arraymath' in sys.modules, 'scipy.linalg' in sys.modules)\n"
)


def test_cached_kernels_load_lean_and_bit_identical() -> None:
    """rsfcore/_kernel_load.py: with the kernels in the cache (the session's cache,
    warmed by the first run here), loading them does not set up numba's compiler (numpy's
    linear algebra and scipy.linalg stay unimported), and the answers are bit for bit
    those of a process that did numba's full set-up first (the same machine code)."""
    env = {k: os.environ[k] for k in ("RSF_CACHE_DIR", "NUMBA_CACHE_DIR") if k in os.environ}
    # compiles into the cache if it is cold: minutes on a loaded machine
    warm = _run(_LOAD.format(pre=""), env, timeout=1800)
    assert warm.returncode == 0, warm.stderr
    lean = _run(_LOAD.format(pre=""), env)
    full = _run(
        _LOAD.format(
            pre="\nfrom numba.core.registry import cpu_target\ncpu_target.target_context.refresh()"
        ),
        env,
    )
    assert lean.returncode == 0 and full.returncode == 0, lean.stderr + full.stderr
    lean_values, lean_mods = lean.stdout.splitlines()
    full_values, full_mods = full.stdout.splitlines()
    assert lean_values == full_values == warm.stdout.splitlines()[0]
    assert lean_mods == "False False"  # the lean path was taken
    assert full_mods == "True True"  # the reference run did the full set-up


def test_a_cache_miss_still_compiles(tmp_path: Path) -> None:
    """An empty cache: the lean loader finds nothing and hands over to numba, which
    compiles (and caches) the kernel; the next process loads it."""
    code = "from rsfcore.laws import G\nprint(float(G(0.3, 0.7)).hex())"
    first = _run(code, {"RSF_CACHE_DIR": str(tmp_path)}, timeout=600)  # compiles G
    assert first.returncode == 0, first.stderr
    second = _run(code, {"RSF_CACHE_DIR": str(tmp_path)})
    assert second.returncode == 0 and second.stdout == first.stdout, second.stderr
    assert "compiling" not in second.stderr


def test_lean_loading_installed_whichever_is_imported_first(tmp_path: Path) -> None:
    """numba imported before rsfcore (patched at once) or after it (patched when numba
    is imported, through the import hook): the cache's loader is rsfcore's either way."""
    check = (
        "from numba.core import caching; "
        "print(getattr(caching.Cache.load_overload, '_rsfcore_lean_load', False))"
    )
    for first in ("import numba, rsfcore; ", "import rsfcore, numba; "):
        r = _run(first + check, {"RSF_CACHE_DIR": str(tmp_path)})
        assert r.returncode == 0, r.stderr
        assert r.stdout.strip() == "True", first
