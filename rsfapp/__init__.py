"""rsfapp: the shared application core of the service and the workers.

Settings (:mod:`rsfapp.config`), the database engine and tables (:mod:`rsfapp.db`), the
result/job/sweep stores (:mod:`rsfapp.store`), the HTTP request models
(:mod:`rsfapp.requests`), the one adapter to :mod:`rsfcore` (:mod:`rsfapp.adapter`),
sweep grid planning (:mod:`rsfapp.grid`), the Celery producer (:mod:`rsfapp.queue`) and
the kernel warm-up (:mod:`rsfapp.warmup`).

Layering (enforced by tests/app/test_layers.py): ``rsfcli -> service | worker -> rsfapp ->
rsfcore``.  rsfapp imports neither fastapi nor rsfplots nor service nor worker.
"""
