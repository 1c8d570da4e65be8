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

The first time a process has to compile a kernel (one not in the directory yet), it
prints one line to stderr saying that the kernels are being compiled and where
(:func:`announce_compile`, called by rsfcore/_kernel_load.py at the cache miss): about a
minute in all, once per version; later processes load them in a fraction of a second.
A process that loads no kernel, or finds every kernel it asks compiled, prints nothing.
"""

from __future__ import annotations

import hashlib
import os
import sys
from pathlib import Path

__all__ = ["announce_compile", "cache_dir", "configure", "source_digest"]

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


_announced = False


def announce_compile() -> None:
    """Say on stderr, once per process, that the kernels are being compiled and where."""
    global _announced
    if _announced:
        return
    _announced = True
    sys.stderr.write(
        f"rsfcore: compiling the numerical kernels into {cache_dir()} (once per "
        "version of rsfcore, about a minute in all; later runs load them in a "
        "fraction of a second)\n"
    )
    sys.stderr.flush()


def configure() -> Path:
    """Point numba at :func:`cache_dir` (sets ``NUMBA_CACHE_DIR``; if numba was already
    imported, its config too); returns the path."""
    path = cache_dir()
    os.environ["NUMBA_CACHE_DIR"] = str(path)
    numba = sys.modules.get("numba")
    if numba is not None:  # imported before rsfcore: numba's config read the old value
        numba.config.CACHE_DIR = str(path)
    return path
