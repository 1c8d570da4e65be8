"""Version of the numerical results (a leaf module: imports nothing from rsfcore)."""

from __future__ import annotations

__all__ = ["NUMERICS_VERSION"]

#: Bumped whenever any numerical result may change; part of every cache key
#: (rsfapp.keys.cache_key).  Record the reason for each bump in CHANGELOG.md.
NUMERICS_VERSION = "1"
