"""Fault injection loaded *into real worker processes* by the sweep tests (``--include``).

A numerical failure of rsfcore cannot be produced on demand with valid parameters, and
sweeps of the fast core finish too quickly to be killed or cancelled half-way.  So the
tests start real Celery workers with ``--include test_worker_faultplugin`` and:

* ``RSF_TEST_FAIL_EPS=<eps>``: rsfcore's critical_perturbation / classify raise
  FloatingPointError for points with that eps (the sweep must record it and go on);
* ``RSF_TEST_POINT_DELAY_S=<s>``: each point takes that much longer (so a sweep is still
  running when the test kills the worker or cancels it).

Nothing happens unless those variables are set; the module holds no tests itself.
"""
from __future__ import annotations

import os
import time


def _install() -> None:
    fail_eps = os.environ.get("RSF_TEST_FAIL_EPS")
    delay = float(os.environ.get("RSF_TEST_POINT_DELAY_S", "0") or 0)
    if fail_eps is None and delay <= 0:
        return
    import rsfcore.trajectory as traj
    targets = [(traj, "classify")]
    try:
        import rsfcore.critical as crit
        targets.append((crit, "critical_perturbation"))
    except ImportError:
        pass

    for mod, name in targets:
        orig = getattr(mod, name)

        def wrapped(params, *a, __orig=orig, **kw):  # noqa: ANN001, ANN002, ANN003
            if delay > 0:
                time.sleep(delay)
            if fail_eps is not None and abs(params.eps - float(fail_eps)) < 1e-12:
                raise FloatingPointError(f"injected failure at eps={params.eps}")
            return __orig(params, *a, **kw)

        setattr(mod, name, wrapped)


_install()
