"""Load (or compile, on a fresh checkout) rsfcore's kernels once per process, so the
first queries are not delayed by JIT compilation.  Used by the API's lifespan and the
Celery ``worker_init`` signal (before the pool forks)."""

from __future__ import annotations

import logging

__all__ = ["warm_up"]
log = logging.getLogger("rsf.warmup")


def warm_up() -> None:
    """Run one small query of each kernel family; a failure is logged, never raised."""
    try:
        from rsfcore import critical, trajectory
        from rsfcore.params import Params

        trajectory.classify(Params(2.0, 0.5, 0.5, 1.0), "velocity-jump", 0.1)
        trajectory.simulate(Params(2.0, 1.2, 0.5, 1.0), "velocity-jump", 0.5, n_points=5)
        critical.critical_perturbation(Params(2.0, 1.5, 0.5, 1.0))
        from rsfcore import batch

        batch.critical_points([2.0, 2.0], [1.5, 3.0], [0.5, 0.2], [1.0, 0.0])
    except Exception:  # noqa: BLE001 - serving must not depend on the warm-up
        log.exception("rsfcore warm-up failed")
