"""What an endpoint that computes receives: :data:`CtxDep`, one dependency.

:class:`Ctx` bundles the request's stores, queue, in-flight table, settings, principal
and admission (:class:`service.admission.Admission`), and answers a validated request
through the result store (:meth:`Ctx.answer`, i.e. :func:`service.answer.answer`) with
the key's step budget and queue rights.  Used by the single queries, the protocols, the
batch queries and the fits (``service/routes/``).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Annotated, Any

from fastapi import Depends
from pydantic import BaseModel
from starlette.responses import Response

from rsfapp.config import Settings
from rsfapp.queue import Queue
from rsfapp.store import Stores
from rsfapp.store.keys import Scope

from .admission import Admission, AdmissionDep
from .answer import answer
from .auth import Principal, PrincipalDep
from .deps import Inflight, InflightDep, QueueDep, SettingsDep, StoresDep

__all__ = ["Ctx", "CtxDep", "get_ctx"]


@dataclass(frozen=True)
class Ctx:
    """What every compute endpoint needs: stores, queue, in-flight table, settings, who
    asks and the request's admission."""

    stores: Stores
    queue: Queue
    inflight: Inflight
    settings: Settings
    principal: Principal
    admission: Admission

    @property
    def quick_steps(self) -> int:
        """Step budget of the in-process attempt: the setting, capped by the key's quota."""
        return min(self.settings.quick_steps, self.principal.quotas.step_budget)

    @property
    def queue_refusal(self) -> str | None:
        """Why a long integration of this key may not go to the queue (None: it may)."""
        p = self.principal
        if not p.scope.allows(Scope.submit):
            return (
                "this query needs a long integration through the queue, which needs a key "
                f"with scope 'submit' (this key has '{p.scope.value}')"
            )
        if p.quotas.step_budget <= self.settings.quick_steps:
            return (
                "this query needs more integrator steps than this key's step budget "
                f"({p.quotas.step_budget}; quota step_budget)"
            )
        return None

    async def answer(
        self, kind: str, req: BaseModel, fn: Callable[[Any], dict[str, Any]]
    ) -> Response:
        """The cached or computed answer (:func:`service.answer.answer`)."""
        return await answer(
            kind,
            req,
            fn,
            stores=self.stores,
            queue=self.queue,
            inflight=self.inflight,
            settings=self.settings,
            admission=self.admission,
            queue_refusal=self.queue_refusal,
        )


async def get_ctx(  # async: no thread hop for a dependency without I/O
    stores: StoresDep,
    queue: QueueDep,
    inflight: InflightDep,
    settings: SettingsDep,
    principal: PrincipalDep,
    admission: AdmissionDep,
) -> Ctx:
    """The :class:`Ctx` of this request."""
    return Ctx(stores, queue, inflight, settings, principal, admission)


CtxDep = Annotated[Ctx, Depends(get_ctx)]
