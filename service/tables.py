"""Columns of an answer as CSV text (``?format=csv`` of trajectories, protocols, fits)."""

from __future__ import annotations

import csv
import io
from typing import Any

__all__ = ["csv_table"]


def csv_table(columns: dict[str, list[Any]]) -> str:
    """Columns of equal length -> CSV text with a header row (empty cell for null; a
    float as its ``repr``, which reads back to the same float)."""
    keys = list(columns)
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(keys)
    for row in zip(*(columns[k] for k in keys), strict=True):
        w.writerow(["" if v is None else repr(v) if isinstance(v, float) else v for v in row])
    return buf.getvalue()
