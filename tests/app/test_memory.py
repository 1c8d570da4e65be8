"""rsfapp.memory: glibc keeps freed chunk arrays for reuse (fewer page faults per chunk),
checked in a fresh process by counting minor page faults over repeated allocations."""

from __future__ import annotations

import subprocess
import sys

_PROBE = """
import resource, sys
import numpy as np
if sys.argv[1] == "1":
    from rsfapp.memory import keep_freed_memory
    assert keep_freed_memory()
def faults():
    return resource.getrusage(resource.RUSAGE_SELF).ru_minflt
def chunk():  # a chunk's arrays, alive together, then all freed
    arrays = [np.ones(1 << 20) for _ in range(6)]  # 6 x 8 MiB
    del arrays
for _ in range(3):
    chunk()  # warms the heap (and glibc's dynamic thresholds)
f0 = faults()
for _ in range(10):
    chunk()
print(faults() - f0)
"""


def _faults(on: bool) -> int:
    out = subprocess.run(
        [sys.executable, "-c", _PROBE, "1" if on else "0"],
        capture_output=True,
        text=True,
        check=True,
    )
    return int(out.stdout.split()[-1])


def test_freed_arrays_are_reused_without_page_faults() -> None:
    """Ten chunks of six 8 MiB arrays, freed after each chunk: by default the 48 MiB are
    given back (beyond glibc's dynamic trim threshold) and touched afresh by the next
    chunk (measured: 30,580 faults, ~1.5 arrays of 2048 pages a chunk); with the
    thresholds raised the heap is reused (measured: 0)."""
    if not sys.platform.startswith("linux"):
        return
    default, reused = _faults(False), _faults(True)
    assert default > 10 * 2048  # at least 8 MiB touched afresh per chunk: what this fixes
    assert reused < default / 10


_TRIM = """
import threading
import numpy as np
import psutil
from rsfapp.memory import give_back
def work():
    arrays = [np.ones(512) for _ in range(50_000)]  # 4 KiB each, ~200 MiB in this thread's arena
    del arrays
t = threading.Thread(target=work)
t.start()
t.join()
before = psutil.Process().memory_info().rss
give_back()
print(before - psutil.Process().memory_info().rss)
"""


def test_give_back_returns_a_threads_freed_memory() -> None:
    """~200 MiB freed by a finished thread stay in its malloc arena (resident) until
    give_back returns them: more than half must go back."""
    if not sys.platform.startswith("linux"):
        return
    out = subprocess.run([sys.executable, "-c", _TRIM], capture_output=True, text=True, check=True)
    assert int(out.stdout.split()[-1]) > 100 * 2**20
