"""Every test in this directory runs real processes (uvicorn, Celery, redis-server,
PostgreSQL, chromium, the ``rsf`` CLI): all are marked ``e2e`` and run as the second
stage of .ci/run."""

from __future__ import annotations

from pathlib import Path

import pytest

_HERE = Path(__file__).resolve().parent


def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    for item in items:
        if _HERE in Path(str(item.fspath)).resolve().parents:
            item.add_marker(pytest.mark.e2e)
