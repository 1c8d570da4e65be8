"""Fault injection loaded *into real worker processes* by the sweep tests (``--include``).

A numerical failure of rsfcore cannot be produced on demand with valid parameters, and
sweeps of the fast core finish too quickly to be killed or cancelled half-way.  So the
tests start real Celery workers with ``--include test_worker_faultplugin`` and:

* ``RSF_TEST_FAIL_EPS=<eps>``: the compiled batch kernel (rsfcore.critical.critical_batch,
  as called by rsfcore.batch) flags the points with that eps for the per-point fallback,
  and the fallback (rsfcore.critical.bisect_critical) raises FloatingPointError for them:
  the real failure-isolation path of a chunk (the sweep must record them and go on);
* ``RSF_TEST_POINT_DELAY_S=<s>``: each batch call sleeps that long per point (so a sweep
  is still running when the test kills the worker or cancels it).

Nothing happens unless those variables are set; the module holds no tests itself.
"""

from __future__ import annotations

import os
import time
from typing import Any


def _install() -> None:
    fail_eps = os.environ.get("RSF_TEST_FAIL_EPS")
    delay = float(os.environ.get("RSF_TEST_POINT_DELAY_S", "0") or 0)
    if fail_eps is None and delay <= 0:
        return
    import numpy as np

    import rsfcore.critical as crit

    kernel, bisect = crit.critical_batch, crit.bisect_critical

    def slow_or_flagging(ba: Any, kappa: Any, eps: Any, *a: Any) -> Any:
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
