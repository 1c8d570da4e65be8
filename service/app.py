"""FastAPI application factory: ``uvicorn service.app:app``."""
from __future__ import annotations

from fastapi import FastAPI

from .errors import install_handlers
from .routes import compute, meta, sweeps

__all__ = ["create_app", "app"]


def create_app() -> FastAPI:
    """The API with all routers and problem+json error handlers."""
    a = FastAPI(
        title="rsf-stability service",
        version="1",
        description="Non-linear slip-stability analysis of rate-and-state friction "
                    "(spring-slider). Dimensionless quantities unless stated; errors are "
                    "application/problem+json.",
    )
    install_handlers(a)
    a.include_router(meta.router)
    a.include_router(compute.router)
    a.include_router(sweeps.router)
    return a


app = create_app()
