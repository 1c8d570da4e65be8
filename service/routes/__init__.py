"""API routers: computations, sweeps, health and cache statistics."""
