"""Lab protocols in SI units: velocity step, slide-hold-slide, any piecewise load history.

``POST /v1/protocols/{velocity-step,slide-hold-slide,load-history}`` with the machine
(``physical`` SI set, ``eps``, ``f_star``) and the protocol's parameters; the answer is
rsfcore.protocols' result (true per-segment peaks, runaway if any, sampled history against
t [s]) plus ``friction_changes`` (steady-state and peak friction changes, also in Pa).
``?format=csv`` gives the sampled history as CSV (one row per sample), ``?format=png`` a
plot (friction and slip rate against time, peaks marked).  Cached like every single query
(field `cached`, header `X-Cache`); a long history still computing after
``RSF_INLINE_BUDGET_S`` is answered 202 + Location and lands in the cache.
"""

from __future__ import annotations

import json
from collections.abc import Callable
from typing import Annotated, Any

from fastapi import APIRouter
from pydantic import BaseModel
from starlette.responses import Response

from rsfapp.adapter import protocols as protocols_adapter
from rsfapp.requests.protocols import LoadHistoryRequest, SlideHoldSlideRequest, VelocityStepRequest

from .. import images
from ..context import Ctx, CtxDep
from ..images import choice, format_query, image, image_response
from ..tables import csv_table

__all__ = ["router"]

router = APIRouter(prefix="/v1/protocols", tags=["protocols"])
_FORMATS = ("json", "csv", "png")
_R: dict[int | str, dict[str, Any]] = {
    422: {
        "description": "Invalid input (problem+json naming the field and its range) "
        "or a computation that could not be completed."
    },
    202: {"description": "Still computing: poll the Location, then repeat the request."},
    200: {
        "description": "JSON (default), CSV of the sampled history, or a PNG plot.",
        "content": {"application/json": {}, "text/csv": {}, "image/png": {}},
    },
}
_FMT_HELP = (
    "'csv': the sampled history (t_s, friction, tau_change_Pa, V_m_s, ...); "
    "'png': friction and slip rate against time."
)


def _plot(result: dict[str, Any]) -> bytes:
    from rsfplots.lab import plot_protocol

    return images.render_locked(plot_protocol, result, "png")


async def _answer(
    kind: str, req: BaseModel, fn: Callable[[Any], dict[str, Any]], ctx: Ctx, fmt: str
) -> Response:
    fmt = choice(fmt, _FORMATS, "format")
    resp: Response = await ctx.answer(kind, req, fn)
    if fmt == "json" or resp.status_code != 200:
        return resp
    result = json.loads(bytes(resp.body))
    key = result["cache_key"]
    if fmt == "csv":
        return Response(
            csv_table(protocols_adapter.protocol_table(result)),
            media_type="text/csv",
            headers={
                "X-Cache-Key": key,
                "X-Cache": resp.headers.get("X-Cache", "miss"),
                "Content-Disposition": f'attachment; filename="{kind}.csv"',
            },
        )
    data, hit = await image(f"{key}.png", lambda: _plot(result))
    return image_response(data, "png", hit, headers={"X-Cache-Key": key})


@router.post("/velocity-step", responses=_R, summary="Velocity step V1 -> V2 (SI)")
async def velocity_step(
    req: VelocityStepRequest,
    ctx: CtxDep,
    format: Annotated[
        str,
        format_query(  # noqa: A002
            _FORMATS, "json", _FMT_HELP
        ),
    ] = "json",
) -> Response:
    """Load-point velocity step from steady state at V1: the response against slip and
    time, the true peak, steady-state and peak friction changes (also in Pa), and the
    deviation from the infinitely stiff closed form `eq: delta tau`."""
    return await _answer(
        "protocol_velocity_step", req, protocols_adapter.protocol_velocity_step, ctx, format
    )


@router.post("/slide-hold-slide", responses=_R, summary="Slide-hold-slide test (SI)")
async def slide_hold_slide(
    req: SlideHoldSlideRequest,
    ctx: CtxDep,
    format: Annotated[
        str,
        format_query(  # noqa: A002
            _FORMATS, "json", _FMT_HELP
        ),
    ] = "json",
) -> Response:
    """Slide at V, hold, reslide at V: healing (true peak on reslide minus f_ss) and
    relaxation during the hold, as friction and in Pa."""
    return await _answer(
        "protocol_slide_hold_slide", req, protocols_adapter.protocol_slide_hold_slide, ctx, format
    )


@router.post("/load-history", responses=_R, summary="Piecewise load history (SI)")
async def load_history(
    req: LoadHistoryRequest,
    ctx: CtxDep,
    format: Annotated[
        str,
        format_query(  # noqa: A002
            _FORMATS, "json", _FMT_HELP
        ),
    ] = "json",
) -> Response:
    """Any piecewise-constant load-point velocity history (velocity steps, holds): true
    per-segment peaks, per-segment steady-state and peak friction changes, runaway."""
    return await _answer(
        "protocol_load_history", req, protocols_adapter.protocol_load_history, ctx, format
    )
