#!/usr/bin/env python3
"""Bootstrap and run the project from a fresh clone with nothing but Python >= 3.11.

    python3 dev.py serve [rsf serve options]   # start API + embedded Celery worker
    python3 dev.py test  [pytest options]      # run the whole test suite

Both create ``.venv`` on first use and install the project (editable, with test
extras) into it; later runs reuse it and only reinstall when pyproject.toml changed.
"""
from __future__ import annotations

import hashlib
import os
import subprocess
import sys
import venv
from pathlib import Path

ROOT = Path(__file__).resolve().parent
VENV = ROOT / ".venv"
BIN = VENV / ("Scripts" if os.name == "nt" else "bin")
PY = BIN / "python"
STAMP = VENV / ".rsf-installed"


def _ensure_env() -> None:
    if sys.version_info < (3, 11):
        sys.exit("Python >= 3.11 is required (found %s)" % sys.version.split()[0])
    if not PY.exists():
        print("[dev] creating virtual environment in .venv", flush=True)
        venv.EnvBuilder(with_pip=True).create(VENV)
    digest = hashlib.sha256((ROOT / "pyproject.toml").read_bytes()).hexdigest()
    if STAMP.exists() and STAMP.read_text() == digest:
        return
    print("[dev] installing the project and its test dependencies", flush=True)
    subprocess.check_call([str(PY), "-m", "pip", "install", "-q", "--upgrade", "pip"])
    subprocess.check_call([str(PY), "-m", "pip", "install", "-q", "-e", f"{ROOT}[test]"])
    STAMP.write_text(digest)


def main(argv: list[str]) -> int:
    if not argv or argv[0] not in {"serve", "test"}:
        print(__doc__)
        return 2
    _ensure_env()
    cmd, rest = argv[0], argv[1:]
    env = dict(os.environ)
    env.setdefault("NUMBA_CACHE_DIR", str(ROOT / ".numba_cache"))
    if cmd == "serve":
        return subprocess.call([str(BIN / "rsf"), "serve", *rest], env=env)
    return subprocess.call([str(PY), "-m", "pytest", *rest], cwd=ROOT, env=env)


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
