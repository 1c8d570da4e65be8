"""FastAPI application factory: ``uvicorn service.app:app``."""

from __future__ import annotations

import logging
from collections.abc import AsyncIterator
from contextlib import asynccontextmanager

from fastapi import Depends, FastAPI
from starlette.concurrency import run_in_threadpool

from rsfapp.config import get_settings
from rsfapp.memory import return_large_blocks
from rsfapp.store import stores_for
from rsfapp.warmup import warm_up

from . import auth, contract, limits
from . import metrics as metrics_api
from .deps import Inflight
from .errors import install_handlers
from .routes import batch as batch_routes
from .routes import compute, docs, figures, meta, sweeps, ui
from .routes import fits as fit_routes
from .routes import protocols as protocol_routes

__all__ = ["create_app", "app"]
log = logging.getLogger("rsf.service")


@asynccontextmanager
async def _lifespan(app: FastAPI) -> AsyncIterator[None]:
    app.state.inflight = Inflight()
    return_large_blocks()  # downloads' slabs go back to the system when freed
    await run_in_threadpool(lambda: stores_for(get_settings()).results.stats())
    await run_in_threadpool(warm_up)
    yield
    # Close the pooled connections on shutdown: SQLite folds its WAL back into the file
    # when the last connection closes, so a stopped service leaves one self-contained file
    # (a WAL left behind would hold pages, page 1 included, that the file alone lacks).
    await run_in_threadpool(lambda: stores_for(get_settings()).db.dispose())


def create_app() -> FastAPI:
    """The API with all routers and problem+json error handlers."""
    a = FastAPI(
        title="rsf-stability service",
        lifespan=_lifespan,
        docs_url=None,  # served by routes.docs with local assets (works offline)
        redoc_url=None,
        version="1",
        description="Non-linear slip-stability analysis of rate-and-state friction "
        "(spring-slider). Dimensionless quantities unless stated; errors are "
        "application/problem+json.",
        # API keys on every route of the schema (service.auth; open: page, docs)
        dependencies=[Depends(auth.guard)],
    )
    install_handlers(a)
    auth.install(a)
    limits.install(a)  # body/header limits, per-key rate limits, CORS if configured
    contract.install(a)  # exact OpenAPI: problem+json, 202/400/401/403/413/429/431
    a.include_router(meta.router)
    a.include_router(compute.router)
    a.include_router(batch_routes.router)
    a.include_router(protocol_routes.router)
    a.include_router(fit_routes.router)
    a.include_router(sweeps.router)
    a.include_router(figures.router)
    a.include_router(ui.router)
    a.include_router(docs.router)
    metrics_api.install(a)  # /metrics and request counts (outermost middleware)
    return a


app = create_app()
