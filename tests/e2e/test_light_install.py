"""The bare install is the library alone (issue 25, item 7).

Builds the project's wheel, installs it with ``--no-deps`` into a fresh virtual
environment whose only other packages are the wheel's own requirements (their installed
files linked in from this environment, so no download beyond the build backend), then
checks there that

* ``pip check`` finds every requirement of the bare wheel satisfied (so the bare
  requirements are exactly those packages: numpy, scipy, numba, httpx and what they need);
* FastAPI, Celery, SQLAlchemy, pydantic, uvicorn, redis and matplotlib are absent;
* ``rsfcore`` computes a classification and ``rsfclient`` imports.
"""

from __future__ import annotations

import importlib.metadata as md
import json
import re
import shutil
import subprocess
import sys
import venv
from pathlib import Path

import pytest

pytestmark = [pytest.mark.e2e, pytest.mark.timeout(600)]

ROOT = Path(__file__).resolve().parents[2]
#: what the bare install must not bring (the service, its database layer, the figures)
SERVER_ONLY = ["fastapi", "celery", "sqlalchemy", "pydantic", "uvicorn", "redis", "matplotlib"]
_NAME = re.compile(r"^[A-Za-z0-9][A-Za-z0-9._-]*")


def _norm(name: str) -> str:
    return re.sub(r"[-_.]+", "-", name).lower()


def _closure(requirements: list[str]) -> set[str]:
    """Distributions (installed here) that ``requirements`` need, transitively; extras
    and environment-marked requirements are followed only when they apply."""
    seen: set[str] = set()
    todo = list(requirements)
    while todo:
        req = todo.pop()
        if ";" in req:
            req, marker = req.split(";", 1)
            if "extra" in marker:
                continue
            if not _marker_holds(marker):
                continue
        m = _NAME.match(req.strip())
        assert m, req
        name = _norm(m.group(0))
        if name in seen:
            continue
        seen.add(name)
        todo.extend(md.distribution(name).requires or [])
    return seen


def _marker_holds(marker: str) -> bool:
    from packaging.markers import Marker

    return Marker(marker.strip()).evaluate()


def _wheel(tmp: Path) -> Path:
    src = tmp / "src"
    ignore = shutil.ignore_patterns("__pycache__", "*.pyc", ".numba_cache")
    for d in ["rsfcore", "rsfapp", "rsfplots", "service", "worker", "rsfcli", "rsfclient"]:
        shutil.copytree(ROOT / d, src / d, ignore=ignore)
    for f in ["pyproject.toml", "README.md", "LICENSE"]:
        shutil.copy2(ROOT / f, src / f)
    out = tmp / "dist"
    subprocess.run(
        [sys.executable, "-m", "pip", "wheel", "-q", "--no-deps", "-w", str(out), str(src)],
        check=True,
        timeout=400,
    )
    (whl,) = out.glob("rsf_stability-*.whl")
    return whl


def _link_distributions(names: set[str], into: Path) -> None:
    """Link every top-level file and folder of the installed distributions ``names``."""
    into.mkdir()
    for name in names:
        dist = md.distribution(name)
        base = Path(str(dist.locate_file("")))
        tops = {Path(str(f)).parts[0] for f in dist.files or []}
        for top in tops:
            if top in {"..", "__pycache__"} or top.endswith(".pth"):
                continue
            target = base / top
            if target.exists() and not (into / top).exists():
                (into / top).symlink_to(target)


def test_bare_wheel_installs_the_library_alone(tmp_path: Path) -> None:
    whl = _wheel(tmp_path)
    reqs = [r for r in md.PathDistribution.at(_unzip_metadata(whl, tmp_path)).requires or []]
    bare = [r for r in reqs if "extra ==" not in r]
    closure = _closure(bare)
    assert {"numpy", "scipy", "numba", "httpx"} <= closure, closure
    assert not closure & set(SERVER_ONLY), closure & set(SERVER_ONLY)

    env = tmp_path / "venv"
    venv.EnvBuilder(with_pip=True).create(env)
    py = env / "bin" / "python"
    site = Path(
        subprocess.run(
            [str(py), "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])"],
            capture_output=True,
            text=True,
            check=True,
        ).stdout.strip()
    )
    deps = tmp_path / "deps"
    _link_distributions(closure, deps)
    (site / "rsf_bare_deps.pth").write_text(str(deps) + "\n")
    subprocess.run(
        [str(py), "-m", "pip", "install", "-q", "--no-deps", "--no-index", str(whl)],
        check=True,
        timeout=120,
    )
    check = subprocess.run(
        [str(py), "-m", "pip", "check"], capture_output=True, text=True, timeout=120
    )
    assert check.returncode == 0, check.stdout + check.stderr

    # the numba kernels are imported, not compiled (a compile is a minute of CPU and
    # tests numba, not the install); the closed forms need numpy/scipy only
    probe = f"""
import importlib.util, json
absent = {{m: importlib.util.find_spec(m) is None for m in {SERVER_ONLY!r}}}
import rsfclient, rsfcore.trajectory, rsfcore.phase
from rsfcore import Params, kappa_crit, stiffness_summary
Params(ba=2.0, kappa=2.0, eps=0.25, vo=1.0)
print(json.dumps({{"absent": absent, "client": rsfclient.Client.__name__,
                  "kappa_crit": kappa_crit(2.5)}}))
"""
    env_vars = {"PATH": str(env / "bin"), "NUMBA_CACHE_DIR": str(tmp_path / "numba")}
    out = subprocess.run(
        [str(py), "-c", probe],
        capture_output=True,
        text=True,
        timeout=300,
        cwd=tmp_path,
        env=env_vars,
    )
    assert out.returncode == 0, out.stderr[-3000:]
    got = json.loads(out.stdout.strip().splitlines()[-1])
    assert all(got["absent"].values()), got["absent"]
    assert got["client"] == "Client"
    assert got["kappa_crit"] == 1.5  # b/a - 1 (eq: dimensionless critical stiffness), exact


def _unzip_metadata(whl: Path, tmp: Path) -> Path:
    import zipfile

    with zipfile.ZipFile(whl) as z:
        names = [n for n in z.namelist() if n.endswith(".dist-info/METADATA")]
        z.extract(names[0], tmp / "meta")
    return tmp / "meta" / Path(names[0]).parent
