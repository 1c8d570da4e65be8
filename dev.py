#!/usr/bin/env python3
"""Bootstrap and run the project from a fresh clone with nothing but Python >= 3.11.

    python3 dev.py serve [rsf serve options]   # start API + embedded Celery worker
    python3 dev.py test  [pytest options]      # lint, types, then the whole test suite

Both create ``.venv`` on first use, install the project (editable, with the all, test, dev
and postgres extras) into it and compile rsfcore's kernels once (into rsfcore's per-user
kernel cache, ``~/.cache/rsf-stability/numba/<digest>``, or ``$RSF_CACHE_DIR/numba/<digest>``,
the one every ``rsf`` command uses); later runs reuse it and only reinstall when pyproject.toml changed.

``test`` runs, in order and stopping at the first failure: ``ruff check``,
``ruff format --check``, ``mypy``, ``pytest -m "not e2e"`` (numerics, application core,
API in process) and ``pytest -m e2e`` (real uvicorn, Celery workers, redis-server,
PostgreSQL, chromium).  Extra arguments go to both pytest stages.  When the kernels
still have to be compiled (a fresh clone), the compile runs beside the lint and type
stages (it is single-threaded; they need no kernels); the tests start once it is done.
The test stages let Python cache bytecode (``__pycache__``, git-ignored) even when
``PYTHONDONTWRITEBYTECODE`` is set: the suite starts a few hundred Python processes
(uvicorn, Celery workers, ``rsf`` commands) and pytest rewrites every test module.
"""

from __future__ import annotations

import hashlib
import os
import subprocess
import sys
import time
import venv
from pathlib import Path

ROOT = Path(__file__).resolve().parent
VENV = ROOT / ".venv"
BIN = VENV / ("Scripts" if os.name == "nt" else "bin")
PY = BIN / "python"
STAMP = VENV / ".rsf-installed"


def _env() -> dict[str, str]:
    return dict(os.environ)


def _ensure_env(kernels: bool = True) -> None:
    if not PY.exists():
        print("[dev] creating virtual environment in .venv", flush=True)
        venv.EnvBuilder(with_pip=True).create(VENV)
    digest = hashlib.sha256((ROOT / "pyproject.toml").read_bytes()).hexdigest()
    if not (STAMP.exists() and STAMP.read_text() == digest):
        print("[dev] installing the project and its test dependencies", flush=True)
        subprocess.check_call([str(PY), "-m", "pip", "install", "-q", "--upgrade", "pip"])
        subprocess.check_call(
            [str(PY), "-m", "pip", "install", "-q", "-e", f"{ROOT}[all,test,dev,postgres]"]
        )
        STAMP.write_text(digest)
    if kernels:
        _ensure_kernels()


#: Prints "1 <dir>" when rsfcore's kernel cache directory holds a compiled kernel's index
#: (``*.nbi``), else "0 <dir>" (run by the venv's Python; tests/app/test_dev_script.py).
WARM_PROBE = (
    "from rsfcore._cache import cache_dir; d = cache_dir(); "
    "print(int(d.is_dir() and any(True for _ in d.rglob('*.nbi'))), d)"
)


class _Kernels:
    """Compiling rsfcore's kernels once per version of its sources, saying so: started by
    :meth:`start` (nothing to do when the cache is warm), awaited by :meth:`wait`.  The
    cache is rsfcore's own (rsfcore/_cache.py: per user, keyed by the sources' digest;
    the same one ``rsf``, the API and the workers use), never inside the source tree."""

    def __init__(self) -> None:
        self.proc: subprocess.Popen[bytes] | None = None
        self.t0 = 0.0

    def start(self) -> None:
        warm, _, cache = (
            subprocess.check_output([str(PY), "-c", WARM_PROBE], text=True).strip().partition(" ")
        )
        if warm == "1":
            return
        print(
            f"[dev] compiling rsfcore's kernels into {cache} (once per version of the core, "
            "about a minute; later starts load them in about a second)",
            flush=True,
        )
        self.t0 = time.monotonic()
        self.proc = subprocess.Popen(
            [str(PY), "-c", "from rsfapp.warmup import warm_up; warm_up()"], env=_env(), cwd=ROOT
        )

    def wait(self) -> int:
        """The compile's exit status (0 when there was nothing to compile)."""
        if self.proc is None:
            return 0
        rc = self.proc.wait()
        self.proc = None
        if rc == 0:
            print(f"[dev] kernels ready in {time.monotonic() - self.t0:.0f} s", flush=True)
        else:
            print(f"[dev] compiling the kernels failed (exit {rc})", flush=True)
        return rc

    def stop(self) -> None:
        """Stop a compile still running (a stage before the tests failed)."""
        if self.proc is not None and self.proc.poll() is None:
            self.proc.terminate()
            self.proc.wait()
        self.proc = None


def _ensure_kernels() -> None:
    """Compile rsfcore's kernels now if their cache is cold (see :class:`_Kernels`)."""
    k = _Kernels()
    k.start()
    if k.wait() != 0:
        raise SystemExit(1)


def _test_env() -> dict[str, str]:
    """The test stages' environment: as given, but with bytecode caching on (module
    docstring)."""
    env = _env()
    env.pop("PYTHONDONTWRITEBYTECODE", None)
    return env


def _stage(name: str, cmd: list[str], env: dict[str, str] | None = None) -> int:
    print(f"[dev] {name}: {' '.join(cmd)}", flush=True)
    rc = subprocess.call(cmd, cwd=ROOT, env=_env() if env is None else env)
    if rc != 0:
        print(f"[dev] {name} failed (exit {rc})", flush=True)
    return rc


def _test(rest: list[str]) -> int:
    checks = [
        ("lint", [str(BIN / "ruff"), "check", "."]),
        ("format", [str(BIN / "ruff"), "format", "--check", "."]),
        ("types", [str(BIN / "mypy")]),
    ]
    tests = [
        ("tests (core, app, api)", [str(PY), "-m", "pytest", "-m", "not e2e", *rest]),
        ("tests (e2e: real processes)", [str(PY), "-m", "pytest", "-m", "e2e", *rest]),
    ]
    kernels = _Kernels()
    kernels.start()  # beside the checks, which need no kernels
    try:
        for name, cmd in checks:
            rc = _stage(name, cmd)
            if rc != 0:
                return rc
        rc = kernels.wait()
        if rc != 0:
            return rc
    finally:
        kernels.stop()
    for name, cmd in tests:
        rc = _stage(name, cmd, _test_env())
        if rc != 0:
            return rc
    return 0


def main(argv: list[str]) -> int:
    if not argv or argv[0] not in {"serve", "test"}:
        print(__doc__)
        return 2
    cmd, rest = argv[0], argv[1:]
    _ensure_env(kernels=cmd != "test")  # `test` compiles them beside its first stages
    if cmd == "serve":
        return subprocess.call([str(BIN / "rsf"), "serve", *rest], env=_env())
    return _test(rest)


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
