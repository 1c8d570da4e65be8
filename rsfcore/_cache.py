"""Where numba keeps rsfcore's compiled kernels: one directory per user and per version of
rsfcore's sources, used by every entry point (library, ``rsf`` CLI, API, workers, tests)
wherever the package is installed, never inside the source tree.

Resolution, first match wins (done once, by ``rsfcore/__init__.py``, before numba is
imported, because numba reads ``NUMBA_CACHE_DIR`` when it is imported):

1. ``NUMBA_CACHE_DIR`` already set: used as given (numba's own setting; e.g. a container
   image that compiled its kernels at build time);
2. ``RSF_CACHE_DIR`` set: ``$RSF_CACHE_DIR/numba/<digest>``;
3. the per-user cache: ``$XDG_CACHE_HOME/rsf-stability/numba/<digest>`` (default
   ``~/.cache``; ``%LOCALAPPDATA%`` on Windows, ``~/Library/Caches`` on macOS).

``<digest>`` is the first 12 hex digits of the SHA-256 of rsfcore's sources (file names
and contents): numba's own cache check does not notice edits to kernels that other
kernels inline (rsfcore/ode/rk.py), so each version of the sources gets its own directory
and a stale compiled kernel is never loaded.  Hashing the ~40 source files takes about a
millisecond.

When the directory holds no compiled kernel yet, the first import of numba (the first
use of a kernel module) prints one line to stderr saying that the kernels are being
compiled and where: about a minute in all, once per version; later processes load them
in a fraction of a second.
"""

from __future__ import annotations

import hashlib
import importlib.abc
import os
import sys
from collections.abc import Sequence
from importlib.machinery import ModuleSpec
from pathlib import Path
from types import ModuleType

__all__ = ["cache_dir", "configure", "source_digest"]

_PACKAGE = Path(__file__).resolve().parent


def source_digest() -> str:
    """First 12 hex digits of the SHA-256 of rsfcore's ``*.py`` files (names and bytes)."""
    h = hashlib.sha256()
    for f in sorted(_PACKAGE.rglob("*.py")):
        h.update(f.relative_to(_PACKAGE).as_posix().encode())
        h.update(f.read_bytes())
    return h.hexdigest()[:12]


def _user_cache_root() -> Path:
    if sys.platform == "win32":
        base = os.environ.get("LOCALAPPDATA") or str(Path.home() / "AppData" / "Local")
        return Path(base) / "rsf-stability"
    if sys.platform == "darwin":
        return Path.home() / "Library" / "Caches" / "rsf-stability"
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base) / "rsf-stability"


def cache_dir() -> Path:
    """The kernel cache directory of this process (rules in the module docstring)."""
    given = os.environ.get("NUMBA_CACHE_DIR")
    if given:
        return Path(given)
    root = os.environ.get("RSF_CACHE_DIR")
    base = Path(root) if root else _user_cache_root()
    return base / "numba" / source_digest()


def _is_warm(path: Path) -> bool:
    """True when ``path`` holds at least one compiled-kernel index (``*.nbi``)."""
    try:
        return any(True for _ in path.rglob("*.nbi"))
    except OSError:
        return False


class _Announce(importlib.abc.MetaPathFinder):
    """Prints the first-compile line when numba is first imported, then steps aside
    (finds nothing itself: the normal finders import numba)."""

    def __init__(self, path: Path) -> None:
        self.path = path

    def find_spec(
        self,
        fullname: str,
        path: Sequence[str] | None = None,
        target: ModuleType | None = None,
    ) -> ModuleSpec | None:
        if fullname == "numba":
            sys.meta_path.remove(self)
            sys.stderr.write(
                f"rsfcore: compiling the numerical kernels into {self.path} (once per "
                "version of rsfcore, about a minute in all; later runs load them in a "
                "fraction of a second)\n"
            )
            sys.stderr.flush()
        return None


def configure() -> Path:
    """Point numba at :func:`cache_dir` (sets ``NUMBA_CACHE_DIR``; if numba was already
    imported, its config too) and arrange the first-compile message; returns the path."""
    path = cache_dir()
    os.environ["NUMBA_CACHE_DIR"] = str(path)
    numba = sys.modules.get("numba")
    if numba is not None:  # imported before rsfcore: numba's config read the old value
        numba.config.CACHE_DIR = str(path)
    elif not _is_warm(path):
        sys.meta_path.insert(0, _Announce(path))
    return path
