"""Optional conversions of answers to pandas and xarray (imported only when asked; the
client itself needs neither)."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

__all__ = ["columns_of", "need", "to_frame"]


def need(module: str) -> Any:
    """Import ``module`` (pandas, xarray) or say how to install it."""
    import importlib

    try:
        return importlib.import_module(module)
    except ImportError as exc:
        raise ImportError(
            f"this conversion needs {module}: pip install {module} (rsfclient itself needs "
            "only httpx)"
        ) from exc


def _scalar(v: Any) -> bool:
    return v is None or isinstance(v, str | int | float | bool)


def columns_of(d: Mapping[str, Any], length_of: str | None = None) -> dict[str, list[Any]]:
    """The equal-length lists of scalars in ``d`` (the columns of a table): those as long
    as ``d[length_of]`` when given, else as long as the longest list."""
    lists = {
        k: v
        for k, v in d.items()
        if isinstance(v, list) and all(_scalar(x) for x in v) and (v or length_of == k)
    }
    if not lists:
        return {}
    n = len(lists[length_of]) if length_of in lists else max(len(v) for v in lists.values())
    return {k: v for k, v in lists.items() if len(v) == n}


def to_frame(cols: Mapping[str, Sequence[Any]]) -> Any:
    """A pandas.DataFrame of columns (None -> NaN in numeric columns)."""
    pd = need("pandas")
    return pd.DataFrame({k: list(v) for k, v in cols.items()})
