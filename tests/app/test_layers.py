"""The layers point one way (docs/architecture.md), and no package imports itself in a
circle:

    rsfcli -> service | worker -> rsfapp -> rsfcore        service -> rsfplots -> rsfcore
    rsfcli -> rsfclient (the HTTP client: imports none of the others)

Checked on every ``import`` statement of every module (including imports inside
functions and under ``if TYPE_CHECKING``), so a lazy import can hide neither a back-edge
between packages nor a cycle between the modules of one package.  Also checked in a
fresh interpreter: importing the worker's tasks loads neither FastAPI nor matplotlib,
and importing the client loads none of the server's packages.
"""

from __future__ import annotations

import ast
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
OURS = {"rsfcore", "rsfapp", "rsfplots", "service", "worker", "rsfcli", "rsfclient"}
#: What each package may import (our packages and the third-party ones that matter).
ALLOWED: dict[str, set[str]] = {
    "rsfcore": {"rsfcore"},
    "rsfplots": {"rsfplots", "rsfcore"},
    "rsfapp": {"rsfapp", "rsfcore"},
    "worker": {"worker", "rsfapp", "rsfcore"},
    "service": {"service", "rsfapp", "rsfcore", "rsfplots"},
    "rsfcli": OURS,
    "rsfclient": {"rsfclient"},
}
_SERVER = {"fastapi", "starlette", "celery", "kombu", "redis", "sqlalchemy", "uvicorn"}
FORBIDDEN_THIRD_PARTY: dict[str, set[str]] = {
    "rsfcore": {"fastapi", "starlette", "celery", "sqlalchemy", "matplotlib", "uvicorn"},
    "rsfapp": {"fastapi", "starlette", "matplotlib", "uvicorn"},
    "worker": {"fastapi", "starlette", "matplotlib", "uvicorn"},
    # a light install: httpx (xarray and pandas optional, imported where used)
    "rsfclient": _SERVER | {"matplotlib", "numba", "scipy"},
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


# ---------------------------------------------------------------- cycles in a package


def _module_name(f: Path) -> str:
    parts = list(f.relative_to(ROOT).with_suffix("").parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def _targets(f: Path, modules: set[str]) -> Iterator[tuple[int, str]]:
    """(line, module of ours) for every import in ``f``: relative imports resolved,
    ``from package import name`` meaning the module ``package.name`` when there is one
    and the package itself (its ``__init__``) otherwise."""
    name = _module_name(f)
    package = name if f.name == "__init__.py" else name.rpartition(".")[0]
    for node in ast.walk(ast.parse(f.read_text(), str(f))):
        if isinstance(node, ast.Import):
            for a in node.names:
                yield node.lineno, a.name
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                parts = package.split(".")
                parts = parts[: len(parts) - (node.level - 1)]
                stem = ".".join(parts + ([node.module] if node.module else []))
            else:
                stem = node.module or ""
            for a in node.names:
                sub = f"{stem}.{a.name}"
                yield node.lineno, sub if sub in modules else stem


def _graph(package: str) -> dict[str, dict[str, int]]:
    """module -> {module of the same package it imports: line of the first import}."""
    files = {_module_name(f): f for f in (ROOT / package).rglob("*.py")}
    graph: dict[str, dict[str, int]] = {}
    for mod, f in files.items():
        edges: dict[str, int] = {}
        for line, target in _targets(f, set(files)):
            if target in files and target != mod:
                edges.setdefault(target, line)
        graph[mod] = edges
    return graph


def _cycles(graph: dict[str, dict[str, int]]) -> list[list[str]]:
    """The strongly connected components of more than one module (Tarjan, iterative),
    each as one cycle through all of them where one exists (else the component)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on: set[str] = set()
    comps: list[list[str]] = []
    for root in sorted(graph):
        if root in index:
            continue
        work: list[tuple[str, Iterator[str]]] = [(root, iter(sorted(graph[root])))]
        index[root] = low[root] = len(index)
        stack.append(root)
        on.add(root)
        while work:
            v, it = work[-1]
            w = next(it, None)
            if w is not None:
                if w not in index:
                    index[w] = low[w] = len(index)
                    stack.append(w)
                    on.add(w)
                    work.append((w, iter(sorted(graph[w]))))
                elif w in on:
                    low[v] = min(low[v], index[w])
                continue
            work.pop()
            if work:
                low[work[-1][0]] = min(low[work[-1][0]], low[v])
            if low[v] == index[v]:
                comp = []
                while True:
                    x = stack.pop()
                    on.discard(x)
                    comp.append(x)
                    if x == v:
                        break
                if len(comp) > 1:
                    comps.append(sorted(comp))
    return comps


def _describe(comp: list[str], graph: dict[str, dict[str, int]]) -> str:
    """The import lines inside one component (where to cut)."""
    inside = set(comp)
    lines = [
        f"  {m.replace('.', '/')}.py:{graph[m][t]} imports {t}"
        for m in comp
        for t in sorted(graph[m])
        if t in inside
    ]
    return " <-> ".join(comp) + "\n" + "\n".join(lines)


@pytest.mark.parametrize("package", sorted(ALLOWED))
def test_no_import_cycle_inside_a_package(package: str) -> None:
    graph = _graph(package)
    assert len(graph) > 1
    found = _cycles(graph)
    assert not found, "import cycles:\n" + "\n".join(_describe(c, graph) for c in found)


def test_the_cycle_finder_finds_cycles() -> None:
    """The check itself: a lazy two-module cycle, a three-module one through a package
    __init__, and an acyclic diamond."""
    g = {
        "p.a": {"p.b": 1},
        "p.b": {"p.a": 9},  # e.g. an import inside a function
        "p": {"p.c": 1},
        "p.c": {"p.d": 1},
        "p.d": {"p": 3},
        "p.e": {"p.f": 1, "p.g": 1},
        "p.f": {"p.h": 1},
        "p.g": {"p.h": 1},
        "p.h": {},
    }
    assert sorted(_cycles(g)) == [["p", "p.c", "p.d"], ["p.a", "p.b"]]


# ---------------------------------------------------------------- what a process loads


def _loaded(statement: str, names: tuple[str, ...]) -> str:
    code = f"import sys; {statement}; print(sorted(m for m in {names!r} if m in sys.modules))"
    out = subprocess.run(
        [sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, timeout=300
    )
    assert out.returncode == 0, out.stderr[-2000:]
    return out.stdout.strip()


def test_worker_process_loads_no_web_or_plot_code() -> None:
    names = ("fastapi", "starlette", "matplotlib", "service", "rsfplots")
    assert _loaded("import worker.tasks", names) == "[]"


def test_client_loads_no_server_or_numerics_code() -> None:
    names = ("fastapi", "celery", "sqlalchemy", "numba", "scipy", "rsfcore", "rsfapp", "service")
    assert _loaded("import rsfclient", names) == "[]"
