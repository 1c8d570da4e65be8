"""docs/architecture.md names every module where it actually lives, and nothing else.

* every module of the seven packages (``__init__.py`` aside) is named as a path in
  backticks (``service/admission.py``), or covered by a directory pattern
  (``rsfapp/db/migrations/versions/*.py``);
* every path and pattern it names exists;
* every dotted name in backticks that starts with one of our packages
  (``service.admission.Admission``, ``rsfapp.store.stores_for``) imports.
"""

from __future__ import annotations

import importlib
import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
DOC = ROOT / "docs" / "architecture.md"
PACKAGES = ("rsfcore", "rsfapp", "rsfplots", "service", "worker", "rsfcli", "rsfclient")
_TOP = "|".join(PACKAGES)
_PATH = re.compile(rf"`((?:{_TOP})/[\w/]*(?:\w+|\*)\.py)`")
_DOTTED = re.compile(rf"`((?:{_TOP})(?:\.\w+)+)`")


def _modules() -> set[str]:
    return {
        str(f.relative_to(ROOT))
        for p in PACKAGES
        for f in (ROOT / p).rglob("*.py")
        if f.name != "__init__.py"
    }


def test_every_module_is_named() -> None:
    named = set(_PATH.findall(DOC.read_text()))
    patterns = [n[: -len("*.py")] for n in named if n.endswith("/*.py")]
    missing = sorted(
        m for m in _modules() if m not in named and not any(m.startswith(p) for p in patterns)
    )
    assert not missing, f"modules docs/architecture.md does not name: {missing}"


def test_every_named_path_exists() -> None:
    gone = []
    for n in set(_PATH.findall(DOC.read_text())):
        target = ROOT / (n[: -len("*.py")] if n.endswith("/*.py") else n)
        if not target.exists():
            gone.append(n)
    assert not gone, f"docs/architecture.md names paths that do not exist: {sorted(gone)}"


def _resolves(dotted: str) -> bool:
    parts = dotted.split(".")
    for cut in range(len(parts), 0, -1):
        try:
            obj: object = importlib.import_module(".".join(parts[:cut]))
        except ModuleNotFoundError:
            continue
        for attr in parts[cut:]:
            if not hasattr(obj, attr):
                return False
            obj = getattr(obj, attr)
        return True
    return False


def test_every_named_object_exists() -> None:
    names = sorted(set(_DOTTED.findall(DOC.read_text())))
    assert len(names) > 10
    unknown = [n for n in names if not _resolves(n)]
    assert not unknown, f"docs/architecture.md names objects that do not exist: {unknown}"
