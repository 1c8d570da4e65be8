"""Loaded into real worker processes by test_multihost (``--include chunk_delay_plugin``).

``RSF_TEST_CHUNK_DELAY_S=<s>``: every sweep chunk takes that much longer (before its
compiled batch call), so a sweep of the fast core is still running when a test kills a
worker or restarts Redis or PostgreSQL.  Nothing happens unless the variable is set.
"""

from __future__ import annotations

import os
import time
from typing import Any


def _install() -> None:
    delay = float(os.environ.get("RSF_TEST_CHUNK_DELAY_S", "0") or 0)
    if delay <= 0:
        return
    import worker.tasks as tasks

    orig = tasks.compute_block

    def slow(*a: Any, **kw: Any) -> Any:
        time.sleep(delay)
        return orig(*a, **kw)

    tasks.compute_block = slow  # type: ignore[assignment]


_install()
