"""Fault injection loaded *into real worker processes* by the sweep tests (``--include``).

A numerical failure of rsfcore cannot be produced on demand with valid parameters, and
sweeps of the fast core finish too quickly to be killed or cancelled half-way.  So the
tests start real Celery workers with ``--include test_worker_faultplugin`` and:

* ``RSF_TEST_FAIL_EPS=<eps>``: the compiled batch loop (rsfcore.batchloop.points_kernel,
  as called by rsfcore.batch, fused or not) lists the points with that eps for the
  per-point fallback (:func:`list_as_fallback`),
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

import numpy as np


def list_as_fallback(kernel: Any, args: tuple[Any, ...], n_sp: int, eps_flagged: float) -> int:
    """After ``kernel(*args)`` (rsfcore.batchloop.points_kernel) returned ``n_sp``: also
    list every point of the range whose eps is ``eps_flagged`` as a separatrix failure
    (FLAG_FALLBACK) with its parameters, in index order, as the loop lists them; returns
    the new count.  The parameters follow the tables' map (value at flat index i:
    ``t[(i // stride) % len(t)]``)."""
    from rsfcore.decision import FLAG_FALLBACK

    ba_t, kappa_t, eps_t, vo_t, size_t, strides, i0, i1, ratio = args[:9]
    sp_idx, sp_flags, sp_par = args[-3:]
    listed = set(sp_idx[:n_sp].tolist())
    for j in range(i1 - i0):
        i = i0 + j
        e = eps_t[(i // strides[2]) % eps_t.size]
        if abs(e - eps_flagged) >= 1e-12 or j in listed:
            continue
        ba = ba_t[(i // strides[0]) % ba_t.size]
        k = kappa_t[(i // strides[1]) % kappa_t.size]
        sp_idx[n_sp], sp_flags[n_sp] = j, FLAG_FALLBACK
        sp_par[n_sp] = (
            ba,
            k * (ba - 1.0) if ratio else k,
            e,
            vo_t[(i // strides[3]) % vo_t.size],
            size_t[(i // strides[4]) % size_t.size],
        )
        n_sp += 1
    order = np.argsort(sp_idx[:n_sp], kind="stable")
    sp_idx[:n_sp], sp_flags[:n_sp], sp_par[:n_sp] = sp_idx[order], sp_flags[order], sp_par[order]
    return n_sp


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

    import rsfcore.batchloop as loop
    import rsfcore.critical as crit

    kernel, bisect = loop.points_kernel, crit.bisect_critical

    def slow_or_flagging(*args: Any) -> Any:
        delay = point_delay()
        if delay > 0:
            time.sleep(delay * (args[7] - args[6]))  # i1 - i0 points
        n_sp = kernel(*args)
        if fail_eps is not None:
            n_sp = list_as_fallback(kernel, args, n_sp, float(fail_eps))
        return n_sp

    def failing(params: Any, *a: Any, **kw: Any) -> Any:
        if fail_eps is not None and abs(params.eps - float(fail_eps)) < 1e-12:
            raise FloatingPointError(f"injected failure at eps={params.eps}")
        return bisect(params, *a, **kw)

    loop.points_kernel = slow_or_flagging
    crit.bisect_critical = failing


_install()
