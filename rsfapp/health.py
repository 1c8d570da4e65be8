"""What a deployment needs to know about its parts: database, broker, workers.

Used by ``GET /health`` and by the start-up checks of ``rsf api`` / ``rsf serve`` /
``rsf worker``.  Every check is bounded in time (1 s socket timeouts, a SQLite page
check within ``RSF_HEALTH_CHECK_BUDGET_S``, cached for a minute) so /health never hangs.
"""

from __future__ import annotations

import threading
import time
from pathlib import Path
from typing import Any

from sqlalchemy import delete, select, update

from .config import Settings
from .db import migrate, ops
from .db.engine import Database, diagnose, insert_ignore

__all__ = [
    "check_broker",
    "check_database",
    "health_report",
    "live_workers",
    "register_worker",
    "unregister_worker",
]

_qc_lock = threading.Lock()
_qc_cache: dict[str, tuple[float, str | None]] = {}
_QC_TTL_S = 60.0


def check_database(db: Database, settings: Settings) -> dict[str, Any]:
    """{'ok', 'dialect', 'schema_version'} plus 'reason' and 'hint' when not ok.

    Reachable: one ``SELECT 1``.  Sound: the schema is at this code's Alembic revision, and (SQLite)
    ``PRAGMA quick_check`` finds nothing within the budget (re-run at most every 60 s).
    """
    out: dict[str, Any] = {"ok": False, "dialect": db.dialect}
    try:
        db.ping()
        out["schema_version"] = v = db.schema_version()
        if v != migrate.head():
            db.ensure_schema()  # creates or migrates; raises SchemaTooNew
            out["schema_version"] = db.schema_version()
        with _qc_lock:
            t, bad = _qc_cache.get(db.url, (0.0, None))
            if time.monotonic() - t > _QC_TTL_S or bad:
                bad = db.quick_check(settings.health_check_budget_s)
                _qc_cache[db.url] = (time.monotonic(), bad)
        if bad:
            p = diagnose(RuntimeError(f"database disk image is malformed: {bad}"), db.url)
            assert p is not None
            out.update(reason=p.reason, hint=p.hint)
            return out
    except Exception as exc:  # noqa: BLE001 - every failure is reported, none raised
        p = diagnose(exc, db.url)
        out.update(
            reason=p.reason if p else f"{type(exc).__name__}: {exc}",
            hint=p.hint if p else "see the server log",
        )
        return out
    out["ok"] = True
    return out


_redis_clients: dict[str, Any] = {}


def check_broker(settings: Settings) -> dict[str, Any]:
    """{'ok', 'transport', 'queue_length'} plus 'reason' when the broker is unreachable."""
    url = settings.effective_broker_url
    transport = url.split("://", 1)[0]
    out: dict[str, Any] = {"ok": False, "transport": transport, "queue": settings.queue}
    try:
        if transport in ("redis", "rediss"):
            import redis

            r = _redis_clients.get(url)
            if r is None:
                r = _redis_clients[url] = redis.Redis.from_url(
                    url, socket_timeout=1, socket_connect_timeout=1
                )
            out["queue_length"] = int(r.llen(settings.queue))
        elif transport == "filesystem":
            folder = Path(str(settings.broker_transport_options["data_folder_in"]))
            out["queue_length"] = sum(
                1 for p in folder.iterdir() if p.name.endswith(f".{settings.queue}.msg")
            )
        else:
            out["queue_length"] = None
    except Exception as exc:  # noqa: BLE001
        out["reason"] = (
            f"broker {url.split('@')[-1]} unreachable: {str(exc).strip() or type(exc).__name__}"
        )
        return out
    out["ok"] = True
    return out


def register_worker(
    db: Database, name: str, node: str, pid: int, concurrency: int, stale_after_s: float
) -> None:
    """Insert or refresh this worker's row; forget rows silent for ``stale_after_s``."""
    now = time.time()
    with db.write() as conn:
        n = conn.execute(
            update(ops.workers).where(ops.workers.c.name == name).values(heartbeat=now)
        ).rowcount
        if not n:
            insert_ignore(
                conn,
                ops.workers,
                {
                    "name": name,
                    "node": node,
                    "pid": pid,
                    "concurrency": concurrency,
                    "started_at": now,
                    "heartbeat": now,
                },
            )
        conn.execute(delete(ops.workers).where(ops.workers.c.heartbeat < now - stale_after_s))


def unregister_worker(db: Database, name: str) -> None:
    """Remove this worker's row (clean shutdown)."""
    with db.write() as conn:
        conn.execute(delete(ops.workers).where(ops.workers.c.name == name))


def live_workers(db: Database, lease_s: float) -> list[dict[str, Any]]:
    """Workers whose heartbeat is younger than the lease."""
    now = time.time()
    with db.read() as conn:
        rows = conn.execute(
            select(ops.workers)
            .where(ops.workers.c.heartbeat >= now - lease_s)
            .order_by(ops.workers.c.node, ops.workers.c.pid)
        ).all()
    return [
        {
            "name": r.name,
            "node": r.node,
            "pid": r.pid,
            "concurrency": r.concurrency,
            "heartbeat_age_s": round(now - r.heartbeat, 3),
        }
        for r in rows
    ]


def health_report(db: Database, settings: Settings) -> dict[str, Any]:
    """The whole report; ``status`` is 'ok' or 'degraded' (then ``reasons`` says why).

    No live worker is a warning, not a degradation: the API answers, and queued work
    waits for a worker."""
    dbr = check_database(db, settings)
    br = check_broker(settings)
    reasons = [x["reason"] for x in (dbr, br) if not x["ok"]]
    workers: list[dict[str, Any]] = []
    if dbr["ok"]:
        try:
            workers = live_workers(db, settings.lease_s)
        except Exception as exc:  # noqa: BLE001
            reasons.append(f"worker registry unreadable: {exc}")
    warnings = (
        []
        if workers
        else [
            "no live worker: sweeps and long queries wait in the "
            "queue until one starts (rsf worker)"
        ]
    )
    return {
        "status": "degraded" if reasons else "ok",
        "reasons": reasons,
        "warnings": warnings,
        "database": dbr,
        "broker": br,
        "workers": {
            "live": len(workers),
            "hosts": sorted({w["node"] for w in workers}),
            "processes": sum(int(w["concurrency"]) for w in workers),
            "list": workers,
        },
    }


def main(argv: list[str]) -> int:
    """``python -m rsfapp.health [--worker]``: exit status 0 when the deployment is
    healthy (with ``--worker``: when a worker of this node, RSF_NODE, is alive), else 1
    with the reasons on stderr.  Used by container healthchecks."""
    import sys

    from .config import get_settings
    from .db.engine import database

    s = get_settings()
    db = database(s.effective_cache_url)
    if "--worker" in argv:
        try:
            mine = [w for w in live_workers(db, s.lease_s) if w["node"] == s.node]
        except Exception as exc:  # noqa: BLE001
            print(f"worker registry unreadable: {exc}", file=sys.stderr)
            return 1
        if not mine:
            print(f"no live worker on node {s.node}", file=sys.stderr)
        return 0 if mine else 1
    rep = health_report(db, s)
    for r in rep["reasons"]:
        print(r, file=sys.stderr)
    return 0 if rep["status"] == "ok" else 1


if __name__ == "__main__":
    import sys

    sys.exit(main(sys.argv[1:]))
