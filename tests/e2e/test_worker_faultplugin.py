"""Fault injection loaded *into real worker processes* by the sweep tests (``--include``).

A numerical failure of rsfcore cannot be produced on demand with valid parameters, and
sweeps of the fast core finish too quickly to be killed or cancelled half-way.  So the
tests start real Celery workers with ``--include test_worker_faultplugin`` and:

* ``RSF_TEST_FAIL_EPS=<eps>``: the compiled batch kernel (rsfcore.critical.critical_batch,
  as called by rsfcore.batch) flags the points with that eps for the per-point fallback,
  and the fallback (rsfcore.critical.bisect_critical) raises FloatingPointError for them:
  the real failure-isolation path of a chunk (the sweep must record them and go on);
* ``RSF_TEST_POINT_DELAY_S=<s>``: each batch call sleeps that long per point (so a sweep
  is still running when the test kills the worker or cancels it);
* ``RSF_TEST_POINT_DELAY_FILE=<path>``: the same, the delay read from that file at every
  batch call (absent, empty or unreadable: none), so that a test slows down only the
  sweeps it watches half-way (tests/e2e/test_ui_browser.py).

Nothing happens unless those variables are set; the module holds no tests itself.
"""

from __future__ import annotations

import os
import time
from pathlib import Path
from typing import Any


def _install() -> None:
    fail_eps = os.environ.get("RSF_TEST_FAIL_EPS")
    fixed_delay = float(os.environ.get("RSF_TEST_POINT_DELAY_S", "0") or 0)
    delay_file = os.environ.get("RSF_TEST_POINT_DELAY_FILE")
    if fail_eps is None and fixed_delay <= 0 and not delay_file:
        return

    def point_delay() -> float:
        if not delay_file:
            return fixed_delay
        try:
            return float(Path(delay_file).read_text().strip() or 0)
        except (OSError, ValueError):
            return 0.0

    import numpy as np

    import rsfcore.critical as crit

    kernel, bisect = crit.critical_batch, crit.bisect_critical

    def slow_or_flagging(ba: Any, kappa: Any, eps: Any, *a: Any) -> Any:
        delay = point_delay()
        if delay > 0:
            time.sleep(delay * len(ba))
        out = kernel(ba, kappa, eps, *a)
        if fail_eps is not None:
            flags = a[-1]
            flags[np.abs(eps - float(fail_eps)) < 1e-12] |= crit.FLAG_FALLBACK
        return out

    def failing(params: Any, *a: Any, **kw: Any) -> Any:
        if fail_eps is not None and abs(params.eps - float(fail_eps)) < 1e-12:
            raise FloatingPointError(f"injected failure at eps={params.eps}")
        return bisect(params, *a, **kw)

    crit.critical_batch = slow_or_flagging
    crit.bisect_critical = failing


_install()
