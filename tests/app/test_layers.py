"""The layers point one way (docs/architecture.md):

    rsfcli -> service | worker -> rsfapp -> rsfcore        service -> rsfplots -> rsfcore

Checked on every ``import`` statement of every module (including imports inside
functions), so a lazy import cannot hide a back-edge.  Also checked in a fresh
interpreter: importing the worker's tasks loads neither FastAPI nor matplotlib.
"""

from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
OURS = {"rsfcore", "rsfapp", "rsfplots", "service", "worker", "rsfcli"}
#: What each package may import (our packages and the third-party ones that matter).
ALLOWED: dict[str, set[str]] = {
    "rsfcore": {"rsfcore"},
    "rsfplots": {"rsfplots", "rsfcore"},
    "rsfapp": {"rsfapp", "rsfcore"},
    "worker": {"worker", "rsfapp", "rsfcore"},
    "service": {"service", "rsfapp", "rsfcore", "rsfplots"},
    "rsfcli": OURS,
}
FORBIDDEN_THIRD_PARTY: dict[str, set[str]] = {
    "rsfcore": {"fastapi", "starlette", "celery", "sqlalchemy", "matplotlib", "uvicorn"},
    "rsfapp": {"fastapi", "starlette", "matplotlib", "uvicorn"},
    "worker": {"fastapi", "starlette", "matplotlib", "uvicorn"},
}


def _imports(path: Path) -> list[tuple[int, str]]:
    tree = ast.parse(path.read_text(), str(path))
    out: list[tuple[int, str]] = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            out += [(node.lineno, a.name) for a in node.names]
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            out.append((node.lineno, node.module))
    return out


@pytest.mark.parametrize("package", sorted(ALLOWED))
def test_imports_point_one_way(package: str) -> None:
    bad = []
    files = sorted((ROOT / package).rglob("*.py"))
    assert files, f"package {package} has no modules"
    for f in files:
        for line, mod in _imports(f):
            top = mod.split(".")[0]
            if top in OURS and top not in ALLOWED[package]:
                bad.append(f"{f.relative_to(ROOT)}:{line} imports {mod}")
            if top in FORBIDDEN_THIRD_PARTY.get(package, set()):
                bad.append(f"{f.relative_to(ROOT)}:{line} imports {mod}")
    assert not bad, "layering violations:\n" + "\n".join(bad)


def test_worker_process_loads_no_web_or_plot_code() -> None:
    code = (
        "import sys, worker.tasks; "
        "print(sorted(m for m in ('fastapi', 'starlette', 'matplotlib', 'service', "
        "'rsfplots') if m in sys.modules))"
    )
    out = subprocess.run(
        [sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, timeout=300
    )
    assert out.returncode == 0, out.stderr[-2000:]
    assert out.stdout.strip() == "[]"
