"""Canonical JSON and cache keys: one request, one key, whatever process computes it."""

from __future__ import annotations

import hashlib
import json
from typing import Any

__all__ = ["canonical", "cache_key"]


def canonical(obj: Any) -> str:
    """Canonical JSON: sorted keys, no spaces, floats in repr form, no NaN."""
    return json.dumps(obj, sort_keys=True, separators=(",", ":"), allow_nan=False)


def cache_key(kind: str, request: Any, numerics_version: str) -> str:
    """Hex sha256 identifying (kind, request, numerics version)."""
    return hashlib.sha256(canonical([kind, request, numerics_version]).encode()).hexdigest()
