"""Process memory: workers keep freed chunk arrays for the next chunk; the API gives
the memory of a finished download back to the system.

A chunk of 10^6 points allocates about twenty 1-8 MB numpy arrays (parameters, kernel
outputs, encoded block).  glibc's malloc serves each from a fresh ``mmap`` and gives it
back at ``free``, so every chunk pays the kernel's first-touch page faults again
(~3,000 minor faults per chunk; measured: 64-76 ms of CPU per 10^6 closed-form points
against 48-49 ms when the memory is reused, at the same peak RSS, ~300 MB).  Raising
the mmap threshold to its maximum (32 MiB on 64-bit) and the trim threshold to 1 GiB
keeps such blocks in the heap for reuse.  The resident size of an idle worker then
stays at its peak instead of shrinking between sweeps.  A no-op where the C library is
not glibc (``mallopt`` missing).

An API process serves downloads from a thread pool; glibc gives each thread its own
arena, and a download's freed slabs stay in those arenas, so the idle size of the API
grew by the slabs of every past download (measured: 256 -> 449 MB after four
downloads of a 10^8-point sweep).  :func:`give_back` (``malloc_trim``) returns the free
pages of every arena when a download ends, and :func:`return_large_blocks` (called once
by the API) fixes the mmap threshold at :data:`API_MMAP_THRESHOLD`: glibc otherwise
raises it to the size of the largest block freed so far (up to 32 MiB), so after the
first download every later slab array (4 MB) came from the arenas' heaps and stayed
there, fragmented, while downloads ran side by side (measured on a 10^8-point NetCDF
download: 43 MB free but held in the arenas after it, 7 MB with the fixed threshold).
"""

from __future__ import annotations

import ctypes
import ctypes.util
import logging
from typing import Any

__all__ = [
    "API_MMAP_THRESHOLD",
    "MMAP_THRESHOLD",
    "TRIM_THRESHOLD",
    "give_back",
    "keep_freed_memory",
    "return_large_blocks",
]
log = logging.getLogger("rsf.memory")

#: glibc mallopt parameters (malloc.h): M_TRIM_THRESHOLD = -1, M_MMAP_THRESHOLD = -3.
_M_TRIM_THRESHOLD, _M_MMAP_THRESHOLD = -1, -3
#: Allocations below this many bytes come from the heap (glibc's largest allowed value).
MMAP_THRESHOLD = 32 << 20
#: Free memory at the top of the heap beyond this many bytes goes back to the system.
TRIM_THRESHOLD = 1 << 30
#: API processes: allocations of at least this many bytes [B] are mapped on their own and
#: unmapped when freed (slab arrays, pieces of CSV and JSON text); a fixed value also
#: turns off glibc's dynamic threshold.
API_MMAP_THRESHOLD = 1 << 20


def _libc_fn(name: str) -> Any:
    try:
        return getattr(ctypes.CDLL(ctypes.util.find_library("c")), name)
    except (OSError, AttributeError, TypeError):
        return None


def keep_freed_memory() -> bool:
    """Set the two thresholds in this process (inherited by forked pool processes);
    True if the C library took them.  For worker processes only: an API process keeps
    glibc's defaults."""
    mallopt = _libc_fn("mallopt")
    if mallopt is None:
        return False
    ok = bool(mallopt(_M_MMAP_THRESHOLD, MMAP_THRESHOLD)) and bool(
        mallopt(_M_TRIM_THRESHOLD, TRIM_THRESHOLD)
    )
    if not ok:
        log.warning("mallopt refused the memory reuse thresholds; chunks run ~25%% slower")
    return ok


def give_back() -> bool:
    """Return the free memory of every malloc arena to the system (glibc
    ``malloc_trim(0)``, a few ms); True if anything was returned."""
    trim = _libc_fn("malloc_trim")
    return bool(trim(0)) if trim is not None else False


def return_large_blocks() -> bool:
    """API processes: allocations of :data:`API_MMAP_THRESHOLD` bytes or more are
    given back to the system as soon as they are freed (module docstring); True if
    the C library took it."""
    mallopt = _libc_fn("mallopt")
    return mallopt is not None and bool(mallopt(_M_MMAP_THRESHOLD, API_MMAP_THRESHOLD))
