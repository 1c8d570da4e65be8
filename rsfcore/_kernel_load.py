"""Loading compiled kernels from the cache without numba's whole compiler set-up.

Before it loads a cached kernel, numba calls ``target_context.refresh()``, which imports
and installs every implementation numba has (numpy's linear algebra, which imports
``scipy.linalg``; random generators; polynomials; typed containers; ...): about 0.3 s of
CPU per process, paid by every ``rsf`` command, for machine code that is already compiled
and needs none of it.  Loading machine code needs only the symbols it links against:
numba's C helpers (installed when the target context is created), the runtime (NRT,
``rtsys.initialize``) and the hash secret (``numba.cpython.hashing``, the only other
module that adds symbols on import, apart from ``parallel=True`` kernels, which rsfcore
has none of).

:func:`install` replaces ``numba.core.caching.Cache.load_overload`` by
:func:`_load_overload`, which sets up just those and loads the cached kernel; on a cache
miss it says once that the kernels are being compiled (:func:`rsfcore._cache.announce_compile`)
and does what numba does (the full refresh, then numba compiles, and every compile
refreshes the contexts itself: ``CompilerBase.__init__``).  The loaded machine code is
the same bytes either way, so every answer is bit for bit the same (the whole test suite
runs through this path).  Measured (2-core machine, warm cache, ``rsf classify``): CPU of
the kernel set-up 0.43 s -> 0.13 s.

If numba's internals change (a numba without ``Cache.load_overload`` or
``_load_overload``), :func:`install` leaves numba as it is: slower, never wrong.
"""

from __future__ import annotations

import importlib.abc
import importlib.machinery
import sys
from collections.abc import Callable, Sequence
from importlib.machinery import ModuleSpec
from types import ModuleType
from typing import Any

__all__ = ["install"]

_PATCHED = "_rsfcore_lean_load"


def _patch(caching: ModuleType) -> None:
    """Replace ``caching.Cache.load_overload`` (once; nothing if numba's shape differs)."""
    cache_cls = getattr(caching, "Cache", None)
    original = getattr(cache_cls, "load_overload", None)
    if cache_cls is None or original is None or getattr(original, _PATCHED, False):
        return
    if not hasattr(cache_cls, "_load_overload"):
        return

    def load_overload(self: Any, sig: Any, target_context: Any) -> Any:
        import numba.cpython.hashing  # noqa: F401  (adds the hash-secret symbols)
        from numba.core.runtime import nrt

        nrt.rtsys.initialize(target_context)
        with self._guard_against_spurious_io_errors():
            data = self._load_overload(sig, target_context)
        if data is None:  # not cached: numba's own path (full refresh, then compile)
            from ._cache import announce_compile

            announce_compile()
            return original(self, sig, target_context)
        return data

    setattr(load_overload, _PATCHED, True)
    load_overload.__doc__ = original.__doc__
    cache_cls.load_overload = load_overload


class _PatchAfterImport(importlib.abc.MetaPathFinder):
    """Finds numba's spec through the other finders and patches numba once it is
    executed (numba imports ``numba.core.caching`` while it initialises)."""

    def find_spec(
        self,
        fullname: str,
        path: Sequence[str] | None = None,
        target: ModuleType | None = None,
    ) -> ModuleSpec | None:
        if fullname != "numba":
            return None
        sys.meta_path.remove(self)
        spec = None
        # a copy: a finder may remove itself while asked
        for finder in list(sys.meta_path):
            find = getattr(finder, "find_spec", None)
            if find is not None:
                spec = find(fullname, path, target)
                if spec is not None:
                    break
        loader = None if spec is None else spec.loader
        run: Callable[[ModuleType], None] | None = getattr(loader, "exec_module", None)
        if spec is None or loader is None or run is None:
            return spec
        inner = run

        def exec_module(module: ModuleType) -> None:
            inner(module)
            caching = sys.modules.get("numba.core.caching")
            if caching is not None:
                _patch(caching)

        loader.exec_module = exec_module  # type: ignore[method-assign]
        return spec


def install() -> None:
    """Make loading of cached kernels lean: now if numba is imported, else when it is."""
    caching = sys.modules.get("numba.core.caching")
    if caching is not None:
        _patch(caching)
    elif "numba" not in sys.modules and not any(
        isinstance(f, _PatchAfterImport) for f in sys.meta_path
    ):
        sys.meta_path.insert(0, _PatchAfterImport())
