"""Admission of a request that may compute: the key's token bucket, its in-flight lease,
and what the layers of one request tell each other about it.

One :class:`Admission` per HTTP request.  The rate-limit middleware
(:class:`service.limits.Limits`) makes it for a request to a computing endpoint
(:func:`is_computing`) and keeps it in the ASGI scope; every layer after it receives the
same object as a FastAPI dependency (:data:`AdmissionDep`) and passes it on explicitly:

1. :func:`service.auth.guard` authenticates the key and calls :meth:`Admission.authorized`,
   which attaches the key's :class:`FreshGate` (its fresh-computation bucket and its
   in-flight leases, both in the database, shared by every API process and host) and, on
   the computing endpoints that cannot tell before their work whether it will be fresh
   (all but :data:`SELF_ADMITTED`), refuses 429 while the bucket is empty and takes a
   lease for the whole request;
2. a single query (:func:`service.answer.answer`) records its cache key
   (:meth:`Admission.validated`) and, once the answer is known not to be cached, takes a
   lease and a token (:meth:`Admission.admit`), or is refused 429;
3. the middleware gives the lease back just before the last byte of the answer is sent
   (:meth:`Admission.answered`) and, when the request ends, charges one token to a fresh
   answer (``X-Cache: miss`` or 202) that did not take one before (:meth:`Admission.finish`).

A request to any other endpoint gets an inert :class:`Admission` (no key id: nothing is
attached, taken or charged).  Anonymous requests (loopback without keys, ``RSF_AUTH=off``)
are not limited.  The stores are those of the request's database bundle
(:class:`rsfapp.store.Stores`: ``rates``, ``leases``).
"""

from __future__ import annotations

import asyncio
import hashlib
import logging
import math
from typing import Annotated

import anyio
from fastapi import Depends, Request
from starlette.concurrency import run_in_threadpool
from starlette.types import Scope as AsgiScope

from rsfapp.store import Stores
from rsfapp.store.inflight import InflightStore
from rsfapp.store.keys import Quotas
from rsfapp.store.ratelimits import RateLimitStore

__all__ = [
    "COMPUTING_PREFIXES",
    "SCOPE_KEY",
    "SELF_ADMITTED",
    "Admission",
    "AdmissionDep",
    "FreshGate",
    "QuotaError",
    "get_admission",
    "is_computing",
]
log = logging.getLogger("rsf.service")

#: Paths whose answers may be computed (and so count as fresh computations).
COMPUTING_PREFIXES = (
    "/v1/classify",
    "/v1/trajectory",
    "/v1/critical",
    "/v1/analytic",
    "/v1/boundaries",
    "/v1/stiffness",
    "/v1/figures/",
    "/v1/fit",
)
#: Single-query paths answered by :func:`service.answer.answer`, which takes a token
#: itself just before a fresh computation (no read of the bucket before).
SELF_ADMITTED = frozenset(
    {
        "/v1/classify",
        "/v1/classify/points",
        "/v1/trajectory",
        "/v1/critical",
        "/v1/analytic/u",
        "/v1/boundaries",
        "/v1/stiffness",
    }
)
#: Key of a request's :class:`Admission` in its ASGI scope.
SCOPE_KEY = "rsf.admission"


def is_computing(path: str) -> bool:
    """True for the endpoints subject to the fresh-computation quota."""
    return path.startswith(COMPUTING_PREFIXES) or path.endswith("/batch")


class QuotaError(Exception):
    """429 answered as problem+json with ``Retry-After`` (handler in :mod:`service.auth`).

    Args:
        detail: the reason, naming the quota.
        retry_after: seconds until a retry may succeed, >= 1.
    """

    def __init__(self, detail: str, retry_after: int) -> None:
        super().__init__(detail)
        self.detail, self.retry_after = detail, retry_after


class FreshGate:
    """The fresh-computation bucket and the in-flight lease of one key, for one request
    (attached by :meth:`Admission.authorized` once the key is authenticated).

    Args:
        store: the token buckets.
        key_id: SHA-256 of the key.
        rate: the key's quota ``fresh_per_s`` [1/s], > 0.
        slots: the in-flight leases (None: ``concurrent_requests`` not enforced).
        quota: the key's quota ``concurrent_requests``, >= 1.
        lease_s: lease length [s], > 0 (``RSF_REQUEST_LEASE_S``).
    """

    def __init__(
        self,
        store: RateLimitStore,
        key_id: str,
        rate: float,
        slots: InflightStore | None = None,
        quota: int = 1,
        lease_s: float = 30.0,
    ) -> None:
        self.store, self.key_id, self.rate = store, key_id, rate
        self.slots, self.quota, self.lease_s = slots, quota, lease_s
        #: True once this request took or was charged its token.
        self.taken = False
        #: the lease this request holds, if any
        self.lease_id: str | None = None
        self._renewer: asyncio.Task[None] | None = None

    async def hold(self) -> None:
        """Take a lease on one of the key's ``concurrent_requests`` (at most once per
        request; renewed every ``lease_s / 3`` until :meth:`release`).

        Raises:
            QuotaError: the key already has ``concurrent_requests`` leases (429 with
                ``Retry-After: 1``).
        """
        if self.slots is None or self.lease_id is not None:
            return
        lease = await run_in_threadpool(self.slots.acquire, self.key_id, self.quota, self.lease_s)
        if not lease.admitted:
            raise QuotaError(
                "too many requests of this key in flight (quota "
                f"concurrent_requests = {self.quota})",
                retry_after=1,
            )
        self.lease_id = lease.lease_id
        self._renewer = asyncio.get_running_loop().create_task(self._renew(lease.lease_id))

    async def _renew(self, lease_id: str | None) -> None:
        slots = self.slots
        assert slots is not None and lease_id is not None
        while True:
            await asyncio.sleep(self.lease_s / 3.0)
            try:
                if not await run_in_threadpool(slots.renew, lease_id, self.lease_s):
                    return  # expired (the database was out of reach for a whole lease)
            except Exception:  # noqa: BLE001 - try again at the next beat
                log.warning("could not renew the lease of a request in flight", exc_info=True)

    async def release(self) -> None:
        """Give the lease back (if one is held); never raises, and runs to the end even
        when the request is cancelled (a lease that could not be deleted expires)."""
        lease_id, self.lease_id = self.lease_id, None
        if self._renewer is not None:
            self._renewer.cancel()
            self._renewer = None
        if lease_id is None or self.slots is None:
            return
        with anyio.CancelScope(shield=True):
            try:
                await run_in_threadpool(self.slots.release, lease_id)
            except Exception:  # noqa: BLE001 - the lease expires by itself
                log.warning("could not release the lease of a request", exc_info=True)

    def _refusal(self, wait_s: float) -> QuotaError:
        return QuotaError(
            f"fresh computations of this key exceed its quota (fresh_per_s = {self.rate:g})",
            retry_after=max(1, math.ceil(wait_s)),
        )

    async def admit(self) -> None:
        """Take a lease (:meth:`hold`), then one token, before a fresh computation (each
        at most once per request); the lease is given back if there is no token.

        Raises:
            QuotaError: too many requests of the key in flight, or its bucket is empty
                (429 with ``Retry-After``).
        """
        if self.taken:
            return
        await self.hold()
        adm = await run_in_threadpool(self.store.take, self.key_id, self.rate)
        if not adm.admitted:
            await self.release()
            raise self._refusal(adm.wait_s)
        self.taken = True

    async def check(self) -> None:
        """Refuse (QuotaError) while the bucket is empty; reads only."""
        wait = await run_in_threadpool(self.store.wait_s, self.key_id, self.rate)
        if wait > 0:
            raise self._refusal(wait)

    async def charge(self) -> None:
        """Charge one token after a fresh answer (unless one was taken before)."""
        if not self.taken:
            self.taken = True
            await run_in_threadpool(self.store.charge, self.key_id, self.rate)


class Admission:
    """The admission of one request (see the module docstring).

    Args:
        key_id: SHA-256 of the bearer token the request carries (None: no token, or a
            request the middleware does not track; then nothing is ever attached).

    Attributes:
        key_id: as given.
        gate: the key's bucket and lease, attached by :meth:`authorized` when the key
            that authenticated is the one the middleware saw.
        need: the scope the guard checked (value of :class:`rsfapp.store.keys.Scope`).
        cache_key: the cache key of a validated single query (:meth:`validated`).
    """

    __slots__ = ("cache_key", "gate", "key_id", "need")

    def __init__(self, key_id: str | None = None) -> None:
        self.key_id = key_id
        self.gate: FreshGate | None = None
        self.need: str | None = None
        self.cache_key: str | None = None

    async def authorized(
        self,
        need: str,
        key_id: str | None,
        quotas: Quotas,
        stores: Stores,
        lease_s: float,
        path: str,
    ) -> None:
        """The guard authenticated the request as ``key_id`` for scope ``need``: attach
        the key's gate and, on a computing endpoint outside :data:`SELF_ADMITTED`, refuse
        while its bucket is empty, else take a lease for the whole request.

        Args:
            need: value of the scope checked.
            key_id: SHA-256 of the authenticated key (None: anonymous).
            quotas: the key's quotas (``fresh_per_s``, ``concurrent_requests``).
            stores: the database bundle (``rates``, ``leases``).
            lease_s: in-flight lease length [s] (``RSF_REQUEST_LEASE_S``).
            path: the request path.

        Raises:
            QuotaError: 429 (bucket empty, or every lease of the key taken).
        """
        self.need = need
        if key_id is None or key_id != self.key_id:
            return
        gate = self.gate = FreshGate(
            stores.rates,
            key_id,
            quotas.fresh_per_s,
            stores.leases,
            quotas.concurrent_requests,
            lease_s,
        )
        if is_computing(path) and path not in SELF_ADMITTED:
            await gate.check()
            await gate.hold()

    def validated(self, cache_key: str) -> None:
        """A single query validated to ``cache_key`` (the middleware may then answer the
        same request again from memory)."""
        self.cache_key = cache_key

    async def admit(self) -> None:
        """Before a fresh computation (or joining one, or queueing): a lease and a token
        of the key, if a gate is attached (:meth:`FreshGate.admit`).

        Raises:
            QuotaError: 429.
        """
        if self.gate is not None:
            await self.gate.admit()

    async def answered(self) -> None:
        """The last part of the answer is about to be sent: give the lease back first, so
        that the client's next request never finds it."""
        if self.gate is not None:
            await self.gate.release()

    async def finish(self, fresh: bool) -> None:
        """The request ended: charge a ``fresh`` answer (computed or deferred) that took no
        token before, then give the lease back (if still held).  Never raises."""
        gate = self.gate
        if gate is None:
            return
        try:
            if fresh and not gate.taken:
                await gate.charge()
        except Exception:  # noqa: BLE001 - the answer is sent; never fail it now
            log.warning("could not charge a fresh computation to its key", exc_info=True)
        finally:
            await gate.release()

    @classmethod
    def begin(cls, scope: AsgiScope) -> Admission:
        """The admission of a new request to a computing endpoint, kept in its ``scope``:
        its key id is the SHA-256 of the bearer token it carries (the id
        :func:`rsfapp.store.keys.hash_key` gives the key: Starlette decodes headers as
        latin-1, the key is hashed as UTF-8)."""
        key_id = None
        for k, v in scope.get("headers", ()):
            if k == b"authorization":
                scheme, _, token = bytes(v).partition(b" ")
                if scheme.lower() == b"bearer" and token.strip():
                    key_id = hashlib.sha256(token.strip().decode("latin-1").encode()).hexdigest()
                break
        return cls(key_id).install(scope)

    def install(self, scope: AsgiScope) -> Admission:
        """Keep this admission in ``scope`` (read by :func:`get_admission`); returns self."""
        scope[SCOPE_KEY] = self
        return self


async def get_admission(request: Request) -> Admission:  # async: no thread hop
    """The :class:`Admission` of this request: the one the middleware made, or an inert
    one (an endpoint that does not compute, or an app without the middleware)."""
    adm = request.scope.get(SCOPE_KEY)
    if isinstance(adm, Admission):
        return adm
    return Admission().install(request.scope)


AdmissionDep = Annotated[Admission, Depends(get_admission)]
