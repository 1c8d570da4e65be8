"""HTTP service for rate-and-state slip-stability analysis (FastAPI).

Flow: request -> :mod:`rsfapp.requests` -> (result-store hit | computation through
:mod:`rsfapp.adapter` | the queue) -> :mod:`rsfcore` -> store -> response.  Sweeps go
through Celery (:mod:`rsfapp.queue`).  See docs/architecture.md.
"""
