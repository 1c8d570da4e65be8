"""Batch queries: many classify or critical questions in one request.

Each item is exactly what the single endpoint takes (dimensionless or SI, see
:mod:`rsfapp.requests.single`).  Items are validated one by one (by
:func:`rsfapp.adapter.validate_items`): an invalid item gets its own error entry naming its
index and field, and the others are answered.  The largest accepted list is the setting
``RSF_BATCH_MAX_ITEMS`` (default 10^5).
"""

from __future__ import annotations

from typing import Any

from ._base import F
from ._base import Model as _Model

__all__ = ["BatchRequest", "ClassifyBatchRequest", "CriticalBatchRequest"]


class BatchRequest(_Model):
    """``{"items": [...]}``: a list of single-query objects, answered in the same order."""

    items: list[dict[str, Any]] = F(
        ...,
        "1..RSF_BATCH_MAX_ITEMS objects (default 1e5)",
        "The queries, each an object as the single endpoint "
        "takes it (dimensionless or with 'physical').",
        name="items",
        min_length=1,
    )


class ClassifyBatchRequest(BatchRequest):
    """Items as for POST /v1/classify (ClassifyRequest)."""


class CriticalBatchRequest(BatchRequest):
    """Items as for POST /v1/critical (CriticalRequest)."""
