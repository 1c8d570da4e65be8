"""Names of a package imported from their module on first access (PEP 562).

:mod:`rsfapp.requests` and :mod:`rsfapp.adapter` re-export one name per question; a CLI
command that asks one question imports (and builds the pydantic models of) only that
question's module.  Each package states where each name lives and installs
``__getattr__ = lazy_getattr(__name__, modules, where, globals())``.
"""

from __future__ import annotations

import importlib
from collections.abc import Callable, Mapping, MutableMapping
from typing import Any

__all__ = ["lazy_getattr"]


def lazy_getattr(
    package: str,
    modules: frozenset[str],
    where: Mapping[str, str],
    namespace: MutableMapping[str, Any],
) -> Callable[[str], Any]:
    """The module ``__getattr__`` of ``package``: a submodule in ``modules`` is imported;
    a name in ``where`` is read from its submodule and kept in ``namespace`` (the
    package's globals, so the next access is a plain lookup); anything else is an
    AttributeError as for any module."""

    def __getattr__(name: str) -> Any:
        if name in modules:
            return importlib.import_module(f"{package}.{name}")
        module = where.get(name)
        if module is None:
            raise AttributeError(f"module {package!r} has no attribute {name!r}")
        value = getattr(importlib.import_module(f"{package}.{module}"), name)
        namespace[name] = value
        return value

    return __getattr__
