"""JSON-safe conversion of results (numpy types -> Python, nan/inf -> None)."""
from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np

__all__ = ["jsonsafe"]


def jsonsafe(x: Any) -> Any:
    """Convert numpy arrays/scalars to lists/floats, nan and +-inf to None, recursively."""
    if isinstance(x, dict):
        return {str(k): jsonsafe(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [jsonsafe(v) for v in x]
    if isinstance(x, np.ndarray):
        if x.dtype.kind in "fc":
            return [jsonsafe(v) for v in x.tolist()]
        return x.tolist()
    if isinstance(x, (np.bool_, bool)):
        return bool(x)
    if isinstance(x, (np.integer,)):
        return int(x)
    if isinstance(x, (float, np.floating)):
        v = float(x)
        return v if math.isfinite(v) else None
    if isinstance(x, Path):
        return str(x)
    return x
