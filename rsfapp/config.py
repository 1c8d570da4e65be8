"""Deployment settings of every process, read from ``RSF_*`` environment variables.

Every process (API, Celery worker, ``rsf serve``) reads the same settings, so one
environment describes one deployment.
"""
from __future__ import annotations

import os
from functools import lru_cache
from pathlib import Path

from pydantic import Field
from pydantic_settings import BaseSettings, SettingsConfigDict

__all__ = ["Settings", "get_settings"]


class Settings(BaseSettings):
    """Deployment settings.

    Attributes:
        data_dir: directory holding the SQLite files and the filesystem broker queues.
        broker_url: Celery broker; empty = kombu filesystem transport under data_dir,
            ``redis://host:port/db`` switches to Redis with the same code.
        cache_url: SQLAlchemy URL of the result cache and sweep bookkeeping; empty =
            ``sqlite:///<data_dir>/cache.sqlite3``.  Use ``postgresql+psycopg://...``
            when workers run on several hosts (SQLite needs one shared local disk).
        chunk_seconds: target duration of one sweep chunk [s], (0, 600].
        sweep_max_points: largest accepted sweep grid (points), >= 1.
        queue: Celery queue used by the API and the workers.
        inline_budget_s: a single query still computing after this long [s] is answered
            202 + Location /v1/results/{key} and finishes in the background.
        lease_s: a running chunk whose worker has not reported for this long [s] is
            requeued when a worker starts.
        quick_steps: step budget of an in-process single query; one that needs more
            is a long integration and goes through the queue.
    """

    model_config = SettingsConfigDict(env_prefix="RSF_", extra="ignore")

    data_dir: Path = Field(default=Path("rsf-data"))
    broker_url: str = ""
    cache_url: str = ""
    chunk_seconds: float = Field(default=2.0, gt=0, le=600)
    sweep_max_points: int = Field(default=40_000, ge=1)
    queue: str = "rsf"
    lease_s: float = Field(default=600.0, gt=0)
    inline_budget_s: float = Field(default=2.0, gt=0, le=3600)
    quick_steps: int = Field(default=300_000, ge=10)

    @property
    def data_path(self) -> Path:
        """Absolute data directory (created on first use)."""
        p = Path(self.data_dir).expanduser().resolve()
        p.mkdir(parents=True, exist_ok=True)
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
        """Folders of the filesystem transport (ignored by other transports)."""
        if not self.effective_broker_url.startswith("filesystem"):
            return {}
        base = self.data_path / "broker"
        folders = {k: base / k for k in ("queue", "processed", "control")}
        for f in folders.values():
            f.mkdir(parents=True, exist_ok=True)
        return {
            "data_folder_in": str(folders["queue"]),
            "data_folder_out": str(folders["queue"]),
            "processed_folder": str(folders["processed"]),
            "control_folder": str(folders["control"]),
            "store_processed": False,
            "polling_interval": 0.1,
        }


@lru_cache(maxsize=1)
def _cached(pid: int, env_key: tuple[tuple[str, str], ...]) -> Settings:
    return Settings()


def get_settings() -> Settings:
    """Settings of this process (re-read when the RSF_* environment changes)."""
    key = tuple(sorted((k, v) for k, v in os.environ.items() if k.startswith("RSF_")))
    return _cached(os.getpid(), key)
