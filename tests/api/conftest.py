"""In-process API tests: the real FastAPI app and a real SQLite database in a temporary
directory, driven by FastAPI's TestClient (no uvicorn, no subprocess).  The Celery queue
is replaced by :class:`RecordingQueue` (the only part that cannot run in-process; the e2e
tests use real workers)."""

from __future__ import annotations

import os
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from fastapi.testclient import TestClient

from rsfapp.config import get_settings
from service.app import create_app
from service.deps import get_queue


class RecordingQueue:
    """Stands in for :class:`rsfapp.queue.Queue`: records what would be sent."""

    def __init__(self) -> None:
        self.chunks: list[tuple[str, int]] = []
        self.singles: list[tuple[str, dict[str, Any], str, str]] = []
        self.fits: list[tuple[dict[str, Any], str, str]] = []

    def send_chunk(self, sweep_id: str, idx: int) -> None:
        self.chunks.append((sweep_id, idx))

    def send_single(self, kind: str, request: dict[str, Any], key: str, version: str) -> None:
        self.singles.append((kind, request, key, version))

    def send_fit(self, request: dict[str, Any], key: str, version: str) -> None:
        self.fits.append((request, key, version))


@pytest.fixture(scope="module")
def api_stack(tmp_path_factory: pytest.TempPathFactory) -> Iterator[tuple[TestClient, Path]]:
    """(client, data_dir): the app on a fresh data directory, generous inline budget."""
    d = tmp_path_factory.mktemp("rsf-api")
    saved = {k: v for k, v in os.environ.items() if k.startswith("RSF_")}
    for k in saved:
        del os.environ[k]
    os.environ.update(RSF_DATA_DIR=str(d), RSF_INLINE_BUDGET_S="120")
    try:
        app = create_app()
        queue = RecordingQueue()
        app.dependency_overrides[get_queue] = lambda: queue
        app.state.recording_queue = queue
        assert get_settings().data_path == d.resolve()
        with TestClient(app, raise_server_exceptions=False) as client:
            yield client, d
    finally:
        for k in [k for k in os.environ if k.startswith("RSF_")]:
            del os.environ[k]
        os.environ.update(saved)


@pytest.fixture(scope="module")
def c(api_stack: tuple[TestClient, Path]) -> TestClient:
    """The in-process client."""
    return api_stack[0]
