"""Deployment settings of every process, read from ``RSF_*`` environment variables.

Every process (API, Celery worker, ``rsf serve``) reads the same settings, so one
environment describes one deployment.
"""

from __future__ import annotations

import ipaddress
import os
import socket
from functools import lru_cache
from pathlib import Path
from typing import Literal

from pydantic import Field, field_validator
from pydantic_settings import BaseSettings, SettingsConfigDict

__all__ = ["IPNetwork", "Settings", "get_settings"]

#: An IPv4 or IPv6 network (a single address is a /32 or /128 network).
IPNetwork = ipaddress.IPv4Network | ipaddress.IPv6Network


class Settings(BaseSettings):
    """Deployment settings.

    Attributes:
        data_dir: directory holding the SQLite files and the filesystem broker queues.
        broker_url: Celery broker; empty = kombu filesystem transport under data_dir,
            ``redis://host:port/db`` switches to Redis with the same code.
        cache_url: SQLAlchemy URL of the result cache and sweep bookkeeping; empty =
            ``sqlite:///<data_dir>/cache.sqlite3``.  Use ``postgresql+psycopg://...``
            when workers run on several hosts (SQLite needs one shared local disk).
        chunk_seconds: target duration of one sweep chunk [s], (0, 600], at the cost per
            point estimated from a sample of the sweep (rsfapp.grid.plan_chunks; chunks of
            at most 10^6 points); also how long a worker's task goes on with the sweep's
            next pending chunks (chunk chaining, worker.tasks.run_chunk).
        sweep_max_points: largest accepted sweep (points), >= 1; default 1e8 (a sweep
            is chunked lazily: nothing per point is created before it is computed).
        sweep_max_scattered: largest number of scattered points in one request (they
            travel in the request body), >= 1.
        sweep_max_chunks: largest number of chunks of one sweep (chunks grow to fit).
        sweep_window: chunks of one sweep sent to the queue ahead of the workers, at most
            one per live worker process; a task that stops chaining sends the next one (a
            10^8-point sweep never floods the broker).
        queue: Celery queue used by the API and the workers.
        inline_budget_s: a single query still computing after this long [s] is answered
            202 + Location /v1/results/{key} and finishes in the background.
        lease_s: lease of a running sweep chunk [s], (0, 3600], default 30.  The worker
            computing a chunk renews it every ``lease_s / 3`` (heartbeat); the reaper in
            every worker requeues a chunk whose lease has expired, so a lost worker host
            costs at most ``lease_s`` plus one chunk.  The Redis visibility timeout is
            derived from it (:attr:`visibility_timeout_s`).
        batch_max_items: largest ``items`` list of a batch query (/v1/*/batch).
        quick_steps: step budget of an in-process single query; one that needs more
            is a long integration and goes through the queue.
        node: name of this host in chunk owners and the worker registry; default the
            host name.  Workers on different machines must have different names.
        db_pool_size: connections kept open per process (PostgreSQL), [1, 100].
        db_max_overflow: extra connections allowed under load (PostgreSQL), [0, 200].
        db_pool_timeout_s: wait for a free pooled connection before giving up [s].
        db_connect_timeout_s: TCP connect timeout to the database server [s].
        db_retry_s: how long one operation keeps retrying to (re)connect to a database
            that is down, with exponential backoff from 0.05 s [s], [0, 600].  After
            that the API answers 503 + Retry-After and a worker retries its task later.
        retry_after_s: the ``Retry-After`` of a 503 answered while the database or the
            broker is unavailable [s], [1, 3600].
        health_check_budget_s: time /health may spend checking SQLite pages
            (``PRAGMA quick_check``, re-run at most every minute) [s]; 0 disables it.
        auth: API keys (``Authorization: Bearer``): ``on`` = every request needs a key;
            ``off`` = no keys (everyone is admin; say so explicitly); ``auto`` (default) =
            keys are required once one exists, and until then only requests arriving on
            a loopback interface are served (``rsf serve`` refuses a non-loopback host
            without a key).
        max_body_bytes: largest request body [bytes], else 413 before it is read.
        max_body_bytes_batch: largest body of the batch, fit and sweep endpoints [bytes].
        max_header_bytes: largest total size of the request headers [bytes], else 431.
        cors_origins: comma-separated origins allowed by CORS (empty: CORS off).
        trusted_proxies: comma-separated addresses or networks (``127.0.0.1``,
            ``10.0.0.0/8``, ``::1``) of the reverse proxies in front of the API; empty
            (default) = none.  A request carrying forwarding headers (``Forwarded``,
            ``X-Forwarded-For``, ``X-Real-IP``) counts as a loopback request (``auth =
            auto`` without keys) only if it comes from one of these and the original
            client those headers name is loopback (docs/security.md).
        request_lease_s: lease of a computing request of an API key in flight [s],
            (0, 3600], default 30 (the ``concurrent_requests`` quota, counted in the
            database: :mod:`rsfapp.store.inflight`).  The API process renews it every
            ``request_lease_s / 3`` while the request runs, so a longer request keeps
            counting; a lease left by an API process that died stops counting after at
            most ``request_lease_s``.
        quota_concurrent_sweeps, quota_points_per_day, quota_fresh_per_s,
        quota_concurrent_requests, quota_trajectory_points, quota_step_budget: default
            quotas of every key
            (:class:`rsfapp.store.keys.Quotas`); ``rsf keys create --quota`` overrides them
            per key.
        metrics_port: a port where `rsf api`, `rsf serve` and `rsf worker` also serve
            Prometheus ``/metrics`` without a key (0 = off, the default; the API's
            ``/metrics`` needs a key with scope ``read`` whenever keys are on);
            docs/operations.md.
        metrics_host: interface of that port (default 127.0.0.1; 0.0.0.0 inside a
            container network that is not published).
    """

    model_config = SettingsConfigDict(env_prefix="RSF_", extra="ignore")

    data_dir: Path = Field(default=Path("rsf-data"))
    broker_url: str = ""
    cache_url: str = ""
    chunk_seconds: float = Field(default=2.0, gt=0, le=600)
    sweep_max_points: int = Field(default=100_000_000, ge=1)
    sweep_max_scattered: int = Field(default=1_000_000, ge=1)
    sweep_max_chunks: int = Field(default=100_000, ge=1)
    sweep_window: int = Field(default=64, ge=1)
    queue: str = "rsf"
    lease_s: float = Field(default=30.0, gt=0, le=3600)
    inline_budget_s: float = Field(default=2.0, gt=0, le=3600)
    quick_steps: int = Field(default=300_000, ge=10)
    batch_max_items: int = Field(default=100_000, ge=1)
    node: str = Field(default_factory=socket.gethostname, min_length=1, max_length=100)
    db_pool_size: int = Field(default=5, ge=1, le=100)
    db_max_overflow: int = Field(default=10, ge=0, le=200)
    db_pool_timeout_s: float = Field(default=10.0, gt=0, le=600)
    db_connect_timeout_s: float = Field(default=5.0, gt=0, le=600)
    db_retry_s: float = Field(default=2.0, ge=0, le=600)
    retry_after_s: int = Field(default=5, ge=1, le=3600)
    health_check_budget_s: float = Field(default=1.0, ge=0, le=600)
    auth: Literal["auto", "on", "off"] = "auto"
    max_body_bytes: int = Field(default=4 * 2**20, ge=1024)
    max_body_bytes_batch: int = Field(default=64 * 2**20, ge=1024)
    max_header_bytes: int = Field(default=16 * 2**10, ge=1024)
    cors_origins: str = ""
    trusted_proxies: str = ""
    request_lease_s: float = Field(default=30.0, gt=0, le=3600)
    quota_concurrent_sweeps: int = Field(default=4, ge=0)
    quota_points_per_day: int = Field(default=1_000_000, ge=0)
    quota_fresh_per_s: float = Field(default=10.0, gt=0)
    quota_concurrent_requests: int = Field(default=8, ge=1)
    quota_trajectory_points: int = Field(default=100_000, ge=2)
    quota_step_budget: int = Field(default=10_000_000, ge=10)
    metrics_port: int = Field(default=0, ge=0, le=65535)
    metrics_host: str = "127.0.0.1"

    @property
    def heartbeat_s(self) -> float:
        """Interval of chunk lease renewal and of the reaper's scan [s]: lease_s / 3."""
        return self.lease_s / 3.0

    @property
    def visibility_timeout_s(self) -> int:
        """Redis visibility timeout [s]: a message delivered to a worker that dies without
        acknowledging it is delivered again after this long.  It equals the lease (at
        least 1 s), so a lost message and a lost lease are recovered on the same time
        scale; a redelivered chunk still held by a live worker is skipped (exactly-once
        storage), so an early redelivery is harmless."""
        return max(1, int(round(self.lease_s)))

    @property
    def cors_origin_list(self) -> list[str]:
        """The CORS origins as a list (empty: CORS off)."""
        return _split(self.cors_origins)

    @field_validator("trusted_proxies")
    @classmethod
    def _check_proxies(cls, v: str) -> str:
        for item in _split(v):
            try:
                ipaddress.ip_network(item, strict=False)
            except ValueError:
                raise ValueError(
                    f"RSF_TRUSTED_PROXIES: {item!r} is not an IP address or network "
                    "(e.g. 127.0.0.1, ::1, 10.0.0.0/8)"
                ) from None
        return v

    @property
    def trusted_proxy_networks(self) -> tuple[IPNetwork, ...]:
        """:attr:`trusted_proxies` as networks (empty: no proxy is trusted)."""
        return tuple(ipaddress.ip_network(i, strict=False) for i in _split(self.trusted_proxies))

    @property
    def data_path(self) -> Path:
        """Absolute data directory (created on first use; memoised per process, as it
        is on every request's path)."""
        p = _data_paths.get(self.data_dir)
        if p is None or not p.is_dir():
            p = Path(self.data_dir).expanduser().resolve()
            p.mkdir(parents=True, exist_ok=True)
            _data_paths[self.data_dir] = p
        return p

    @property
    def effective_cache_url(self) -> str:
        """The cache URL, defaulting to a SQLite file under the data directory."""
        return self.cache_url or f"sqlite:///{self.data_path / 'cache.sqlite3'}"

    @property
    def effective_broker_url(self) -> str:
        """The broker URL, defaulting to the filesystem transport."""
        return self.broker_url or "filesystem://"

    @property
    def broker_transport_options(self) -> dict[str, object]:
        """Transport options: the visibility timeout for Redis (= the lease), the
        folders of the filesystem transport, nothing for other transports."""
        if self.effective_broker_url.startswith(("redis", "rediss")):
            return {"visibility_timeout": self.visibility_timeout_s}
        if not self.effective_broker_url.startswith("filesystem"):
            return {}
        base = self.data_path / "broker"
        folders = {k: base / k for k in ("queue", "processed", "control", "quarantine")}
        for f in folders.values():
            f.mkdir(parents=True, exist_ok=True)
        return {
            "data_folder_in": str(folders["queue"]),
            "data_folder_out": str(folders["queue"]),
            "processed_folder": str(folders["processed"]),
            "control_folder": str(folders["control"]),
            "quarantine_folder": str(folders["quarantine"]),
            "store_processed": False,
            "polling_interval": 0.1,
        }


def _split(v: str) -> list[str]:
    """The non-empty items of a comma-separated list."""
    return [o.strip() for o in v.split(",") if o.strip()]


@lru_cache(maxsize=1)
def _cached(pid: int, env_key: tuple[tuple[str, str], ...]) -> Settings:
    return Settings()


_data_paths: dict[Path, Path] = {}


def get_settings() -> Settings:
    """Settings of this process (re-read when the RSF_* environment changes)."""
    raw = getattr(os.environ, "_data", None)  # bytes on POSIX: no decoding per request
    if isinstance(raw, dict):
        key = tuple(sorted((str(k), str(v)) for k, v in raw.items() if k.startswith(b"RSF_")))
    else:
        key = tuple(sorted((k, v) for k, v in os.environ.items() if k.startswith("RSF_")))
    return _cached(os.getpid(), key)
