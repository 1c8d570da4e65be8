"""Metrics of the deployment's shared state, read from the database and the broker at
each scrape (so every API process and host reports the same numbers, and nothing is kept
between scrapes): gauges

* ``rsf_queue_depth{queue}``: messages waiting in the broker queue (sweep chunks, long
  queries, fits);
* ``rsf_sweeps{status}``: sweeps by status (queued, running, done, cancelled);
* ``rsf_sweep_chunks{status}``: chunks of unfinished sweeps by status;
* ``rsf_workers_live{node}``, ``rsf_worker_processes{node}``: live worker processes
  (heartbeat younger than the lease) and their pool sizes, per host;
* ``rsf_state_up``: 1 if the state above could be read, else 0 (then the rest is absent).
"""

from __future__ import annotations

import logging
from collections.abc import Iterable

from prometheus_client.core import GaugeMetricFamily
from prometheus_client.metrics_core import Metric
from prometheus_client.registry import Collector
from sqlalchemy import func, select

from .config import Settings
from .db.engine import database
from .db.tables import chunks, sweeps
from .health import check_broker, live_workers

__all__ = ["SWEEP_STATUSES", "StateCollector"]
log = logging.getLogger("rsf.metrics")

#: every status a sweep or chunk row can have (reported at 0 when absent)
SWEEP_STATUSES = ("queued", "running", "done", "cancelled")


class StateCollector(Collector):
    """Reads the shared state of the deployment of ``settings`` at each scrape."""

    def __init__(self, settings: Settings) -> None:
        self.settings = settings

    def collect(self) -> Iterable[Metric]:
        s = self.settings
        up = GaugeMetricFamily("rsf_state_up", "1 if the database state could be read.")
        try:
            out = list(self._read())
        except Exception as exc:  # noqa: BLE001 - a scrape never fails on an outage
            log.warning("metrics: state unreadable: %s", exc)
            up.add_metric([], 0.0)
            return [up]
        up.add_metric([], 1.0)
        out.append(up)
        br = check_broker(s)
        q = GaugeMetricFamily(
            "rsf_queue_depth", "Messages waiting in the broker queue.", labels=["queue"]
        )
        if br.get("ok") and br.get("queue_length") is not None:
            q.add_metric([s.queue], float(br["queue_length"]))
        out.append(q)
        return out

    def _read(self) -> Iterable[Metric]:
        s = self.settings
        db = database(s.effective_cache_url)
        with db.read() as conn:
            by_status: dict[str, int] = dict(
                conn.execute(select(sweeps.c.status, func.count()).group_by(sweeps.c.status)).all()
            )
            active = select(sweeps.c.id).where(sweeps.c.status.in_(("queued", "running")))
            by_chunk: dict[str, int] = dict(
                conn.execute(
                    select(chunks.c.status, func.count())
                    .where(chunks.c.sweep_id.in_(active))
                    .group_by(chunks.c.status)
                ).all()
            )
        sw = GaugeMetricFamily("rsf_sweeps", "Sweeps by status.", labels=["status"])
        ch = GaugeMetricFamily(
            "rsf_sweep_chunks", "Chunks of unfinished sweeps by status.", labels=["status"]
        )
        for st in SWEEP_STATUSES:
            sw.add_metric([st], float(by_status.get(st, 0)))
            ch.add_metric([st], float(by_chunk.get(st, 0)))
        workers = live_workers(db, s.lease_s)
        live = GaugeMetricFamily(
            "rsf_workers_live", "Live worker processes (main processes) per host.", labels=["node"]
        )
        procs = GaugeMetricFamily(
            "rsf_worker_processes", "Pool processes of the live workers per host.", labels=["node"]
        )
        for node in sorted({w["node"] for w in workers}):
            mine = [w for w in workers if w["node"] == node]
            live.add_metric([node], float(len(mine)))
            procs.add_metric([node], float(sum(int(w["concurrency"]) for w in mine)))
        return [sw, ch, live, procs]
