"""Batch queries: ``POST /v1/classify/batch`` and ``POST /v1/critical/batch``.

Body ``{"items": [...]}``, each item what the single endpoint takes (dimensionless or SI);
answer ``{"results": [...], "n_items", "n_ok", "n_failed"}`` in item order.  A result is
the single endpoint's answer plus ``index``, or ``{"index", "error": {"field", "message",
"valid"}}`` for an item that is invalid or could not be computed: one bad item never
fails the others.  At most ``RSF_BATCH_MAX_ITEMS`` items (default 10^5; more: 422 naming
``items``).

Critical sizes run in rsfcore's compiled loop (10^4 items in 0.18 s on one core, see
bench/bench_batch.py) and are not cached (recomputing is about as cheap as a lookup);
classify batches integrate item by item and go through the result cache like a single
query (answered 202 + Location when still computing after ``RSF_INLINE_BUDGET_S``).
"""

from __future__ import annotations

from functools import partial
from typing import Any

import orjson
from fastapi import APIRouter
from starlette.concurrency import run_in_threadpool
from starlette.responses import Response

from rsfapp.adapter import batch as batch_adapter
from rsfapp.requests.batch import BatchRequest, ClassifyBatchRequest, CriticalBatchRequest

from ..context import CtxDep
from ..errors import ProblemError

__all__ = ["router"]

router = APIRouter(prefix="/v1", tags=["batch"])
_R: dict[int | str, dict[str, Any]] = {
    422: {
        "description": 'Too many items, or a body that is not {"items": [objects]}; '
        "invalid items are reported in their own result entries."
    }
}


def _check_size(req: BatchRequest, limit: int) -> None:
    if len(req.items) > limit:
        raise ProblemError(
            422,
            "Invalid input",
            f"items: {len(req.items)} items, at most {limit} per request (RSF_BATCH_MAX_ITEMS)",
            field="items",
            valid=f"1..{limit} objects",
        )


@router.post("/critical/batch", responses=_R, summary="Critical sizes of many items")
async def critical_batch(req: CriticalBatchRequest, ctx: CtxDep) -> Response:
    """Critical perturbation size of every item (as POST /v1/critical), computed by the
    vectorised core; per-item errors name the item's index and field."""
    _check_size(req, ctx.settings.batch_max_items)
    async with ctx.inflight.limiter:
        result = await run_in_threadpool(batch_adapter.critical_batch, req.items)
        text = await run_in_threadpool(_dumps, result)
    return Response(text, media_type="application/json")


@router.post("/classify/batch", responses=_R, summary="Outcomes of many items")
async def classify_batch(req: ClassifyBatchRequest, ctx: CtxDep) -> Response:
    """Stable or unstable for every item (as POST /v1/classify, quick step budget per
    item: an item needing a long integration is reported as an error entry; ask it alone).
    Cached as a whole (field `cached`, header `X-Cache`)."""
    _check_size(req, ctx.settings.batch_max_items)
    fn = partial(_classify_items, quick_steps=ctx.settings.quick_steps)
    return await ctx.answer("classify_batch", req, fn)


def _classify_items(req: ClassifyBatchRequest, quick_steps: int) -> dict[str, object]:
    return batch_adapter.classify_batch(req.items, max_steps=quick_steps)


def _dumps(result: dict[str, Any]) -> bytes:
    """Compact JSON (orjson: 10^4 results in ~5 ms, the stdlib takes ~50 ms).  orjson
    would write a non-finite float as null; the adapter never returns one (a size beyond
    double range goes through the single path, whose answer is JSON-safe)."""
    return orjson.dumps(result)
