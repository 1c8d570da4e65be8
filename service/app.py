"""FastAPI application factory: ``uvicorn service.app:app``."""
from __future__ import annotations

import logging
from contextlib import asynccontextmanager
from typing import AsyncIterator

from fastapi import FastAPI
from starlette.concurrency import run_in_threadpool

from .errors import install_handlers
from .routes import compute, figures, meta, sweeps, ui

__all__ = ["create_app", "app"]
log = logging.getLogger("rsf.service")


def warm_up() -> None:
    """Load (or compile, on a fresh checkout) rsfcore's kernels before serving, so the
    first queries are not deferred by JIT compilation; create the cache tables."""
    from worker import cache
    cache.stats()
    try:
        from rsfcore import critical, trajectory
        from rsfcore.params import Params
        trajectory.classify(Params(2.0, 0.5, 0.5, 1.0), "velocity-jump", 0.1)
        trajectory.simulate(Params(2.0, 1.2, 0.5, 1.0), "velocity-jump", 0.5, n_points=5)
        critical.critical_perturbation(Params(2.0, 1.5, 0.5, 1.0))
    except Exception:  # noqa: BLE001 - serving must not depend on the warm-up
        log.exception("rsfcore warm-up failed")


@asynccontextmanager
async def _lifespan(_app: FastAPI) -> AsyncIterator[None]:
    await run_in_threadpool(warm_up)
    yield


def create_app() -> FastAPI:
    """The API with all routers and problem+json error handlers."""
    a = FastAPI(
        title="rsf-stability service",
        lifespan=_lifespan,
        version="1",
        description="Non-linear slip-stability analysis of rate-and-state friction "
                    "(spring-slider). Dimensionless quantities unless stated; errors are "
                    "application/problem+json.",
    )
    install_handlers(a)
    a.include_router(meta.router)
    a.include_router(compute.router)
    a.include_router(sweeps.router)
    a.include_router(figures.router)
    a.include_router(ui.router)
    return a


app = create_app()
