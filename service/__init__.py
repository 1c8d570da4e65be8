"""HTTP service for rate-and-state slip-stability analysis (FastAPI).

Flow: request -> :mod:`service.schemas` -> (cache hit | computation) -> :mod:`rsfcore`
-> result -> cache (:mod:`worker.cache`) -> response.  Sweeps go through Celery
(:mod:`worker.tasks`).
"""
