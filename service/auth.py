"""API keys on every endpoint of the OpenAPI schema: ``Authorization: Bearer <key>``.

One app-level dependency, :func:`guard`, runs before every route.  Routes outside the
schema (the dashboard page, its static files, the /docs pages, /openapi.json) are open,
so a browser can load the page and then enter a key.  Every other route needs:

* ``read``: every GET, and the single queries (classify, trajectory, critical, analytic
  U, boundaries, stiffness, figures), cached results and sweeps;
* ``submit``: submitting and cancelling sweeps, batch queries and fits (long work);
* ``admin``: everything, including cancelling other keys' sweeps.

Modes (``RSF_AUTH``): ``on`` always needs a key; ``off`` never does (every request is
an anonymous admin); ``auto`` needs one once any key exists and, until then, serves
anonymous requests only when they come from this host: on a loopback interface, and
not forwarded by a reverse proxy for someone else (:mod:`service.proxies`,
``RSF_TRUSTED_PROXIES``).

Answers: 401 (no key, malformed, unknown or revoked key: one message for all, with
``WWW-Authenticate: Bearer``), 403 (scope too small, or another key's sweep), both
``application/problem+json``.  Keys are compared through their SHA-256 in constant time
(:meth:`rsfapp.store.keys.KeyStore.verify`) and never logged or echoed.
"""

from __future__ import annotations

import logging
import math
import time
from dataclasses import dataclass, field
from typing import Annotated, Any

from fastapi import Depends, FastAPI, Request, Security
from fastapi.security import HTTPAuthorizationCredentials, HTTPBearer
from starlette.concurrency import run_in_threadpool
from starlette.responses import Response

from rsfapp.config import Settings
from rsfapp.store import Stores
from rsfapp.store.keys import KeyStore, Quotas, Scope, WouldBlock, hash_key, utc_day

from .admission import AdmissionDep, QuotaError
from .deps import SettingsDep, StoresDep
from .errors import ProblemError, problem
from .proxies import from_this_host

__all__ = [
    "AuthError",
    "Principal",
    "PrincipalDep",
    "RESPONSES",
    "admit_sweep",
    "authorize",
    "bearer",
    "check_owner",
    "current",
    "guard",
    "install",
    "needed_scope",
    "quotas_of",
    "scope_for",
    "sweep_submitted",
]
log = logging.getLogger("rsf.service")

#: The security scheme shown in OpenAPI (and the Swagger UI "Authorize" button).
bearer = HTTPBearer(
    auto_error=False,
    scheme_name="ApiKey",
    bearerFormat="rsf_<43 URL-safe characters>",
    description="An API key made by `rsf keys create --name NAME --scope read|submit|admin`, "
    "sent as `Authorization: Bearer <key>`.  Needed on every endpoint once the "
    "server has a key (or with RSF_AUTH=on).",
)

#: Answers every protected operation may give (documented on each one).
RESPONSES: dict[int | str, dict[str, Any]] = {
    401: {
        "description": "No API key, or an unknown, malformed or revoked one "
        "(problem+json; header `WWW-Authenticate: Bearer`)."
    },
    403: {
        "description": "The key's scope does not allow this request, or the sweep "
        "belongs to another key (problem+json)."
    },
}


@dataclass(frozen=True)
class Principal:
    """Who is asking.

    Attributes:
        name: key name, or None for an anonymous request (auth off, or loopback
            without any key in ``auto`` mode).
        scope: what the request may do (anonymous requests are admin).
        quotas: limits of the key (defaults for anonymous requests, not enforced).
        key_id: SHA-256 of the key (identifies its rate-limit bucket), None if anonymous.
    """

    name: str | None
    scope: Scope
    quotas: Quotas = field(default_factory=Quotas)
    key_id: str | None = None

    @property
    def anonymous(self) -> bool:
        """True when no key was used (no quotas, no ownership)."""
        return self.name is None


class AuthError(Exception):
    """401 or 403 answered as problem+json."""

    def __init__(self, status: int, detail: str) -> None:
        super().__init__(detail)
        self.status, self.detail = status, detail


_UNAUTHORIZED = (
    "a valid API key is required: send 'Authorization: Bearer <key>' "
    "(keys are made with 'rsf keys create')"
)
_NO_KEYS_REMOTE = (
    "this server has no API key yet and answers requests without a key only "
    "on its loopback interface; create one with 'rsf keys create --name NAME' "
    "and send it as 'Authorization: Bearer <key>'"
)


_defaults_of: list[tuple[Settings, Quotas]] = []


def quotas_of(settings: Settings, overrides: dict[str, Any] | None = None) -> Quotas:
    """The default quotas of ``settings`` with a key's ``overrides``."""
    held = _defaults_of[0] if _defaults_of else None
    if held is not None and held[0] is settings:  # Quotas are frozen: shared safely
        return held[1].with_overrides(overrides) if overrides else held[1]
    q = Quotas(
        concurrent_sweeps=settings.quota_concurrent_sweeps,
        points_per_day=settings.quota_points_per_day,
        fresh_per_s=settings.quota_fresh_per_s,
        concurrent_requests=settings.quota_concurrent_requests,
        trajectory_points=settings.quota_trajectory_points,
        step_budget=settings.quota_step_budget,
    )
    _defaults_of[:] = [(settings, q)]  # settings objects change when RSF_* change
    return q.with_overrides(overrides) if overrides else q


def scope_for(path: str, method: str) -> Scope:
    """The scope an operation needs: read for GET/HEAD and the single queries; submit
    for sweep submission/cancellation, batch queries and fits (long work)."""
    if method.upper() in ("GET", "HEAD", "OPTIONS"):
        return Scope.read
    if path.startswith("/v1/sweeps") or path.endswith("/batch") or path.startswith("/v1/fit"):
        return Scope.submit
    return Scope.read


def needed_scope(request: Request) -> Scope:
    """The scope a request needs: the route's ``openapi_extra["x-required-scope"]`` if
    set, else :func:`scope_for` its path template and method."""
    route = request.scope.get("route")
    extra = getattr(route, "openapi_extra", None) or {}
    if "x-required-scope" in extra:
        return Scope(extra["x-required-scope"])
    return scope_for(getattr(route, "path_format", None) or request.url.path, request.method)


_ACTIVE_TTL_S = 1.0
_active_seen: dict[int, tuple[float, int, bool]] = {}


async def _any_active(keys: KeyStore) -> bool:
    """Whether any key is active, re-read at most once a second per process (this is on
    the path of every keyless request in ``auto`` mode).  So a key created while the
    server runs is enforced within 1 s by another process's ``rsf keys create`` (until
    then only loopback requests are served without a key) and at once when created in
    this process (``KeyStore.changes``); revocation of a key is always immediate
    (:meth:`KeyStore.verify_inline` or :meth:`KeyStore.verify` reads the database on
    every request that carries a key)."""
    now = time.monotonic()
    seen = _active_seen.get(id(keys))
    if seen is not None and now - seen[0] < _ACTIVE_TTL_S and seen[1] == KeyStore.changes:
        return seen[2]
    active = bool(await run_in_threadpool(keys.any_active))
    _active_seen[id(keys)] = (now, KeyStore.changes, active)
    return active


async def _authenticate(
    request: Request, creds: HTTPAuthorizationCredentials | None, settings: Settings, keys: KeyStore
) -> Principal:
    if settings.auth == "off":
        return Principal(None, Scope.admin, quotas_of(settings))
    given = "authorization" in request.headers
    if creds is None or not creds.credentials:
        if given:  # another scheme, or an empty token
            raise AuthError(401, _UNAUTHORIZED)
        if settings.auth == "auto" and not await _any_active(keys):
            if from_this_host(request.scope, settings.trusted_proxy_networks):
                return Principal(None, Scope.admin, quotas_of(settings))
            raise AuthError(401, _NO_KEYS_REMOTE)
        raise AuthError(401, _UNAUTHORIZED)
    try:  # SQLite: ~5 us on the event loop, cheaper than a thread hop (~50 us)
        key = keys.verify_inline(creds.credentials)
    except WouldBlock:
        key = await run_in_threadpool(keys.verify, creds.credentials)
    if key is None:
        raise AuthError(401, _UNAUTHORIZED)
    return Principal(
        key.name, key.scope, quotas_of(settings, key.quotas), hash_key(creds.credentials)
    )


async def authorize(
    request: Request,
    creds: HTTPAuthorizationCredentials | None,
    settings: Settings,
    keys: KeyStore,
    need: Scope,
) -> Principal:
    """Authenticate the request, check that its key allows ``need`` and, for a
    trajectory, the key's ``trajectory_points`` quota; the principal.

    Raises:
        AuthError: 401 or 403.
        ProblemError: 422 (n_points beyond the key's quota).
    """
    p = await _authenticate(request, creds, settings, keys)
    request.scope["rsf.principal"] = p
    if not p.scope.allows(need):
        raise AuthError(
            403, f"this key has scope '{p.scope.value}'; this request needs '{need.value}'"
        )
    path = str(request.scope.get("path", ""))  # not request.url: building it costs ~10 us
    if not p.anonymous and request.method == "POST" and path.endswith("/trajectory"):
        await _check_trajectory_points(request, p)
    return p


async def guard(
    request: Request,
    settings: SettingsDep,
    stores: StoresDep,
    admission: AdmissionDep,
    creds: Annotated[HTTPAuthorizationCredentials | None, Security(bearer)],
) -> Principal:
    """App-level dependency: authenticate, check the scope, bound the work of a request.

    Routes outside the OpenAPI schema are open.  The principal is left in
    ``request.scope["rsf.principal"]`` for handlers (:func:`current`).  The request's
    admission learns who it is (:meth:`service.admission.Admission.authorized`): on a
    computing endpoint the key's shared fresh-computation bucket and in-flight leases
    are attached and, on the endpoints that cannot take a token themselves before
    computing (all but the single queries), the request is refused 429 while that
    bucket is empty, or else takes a lease on one of the key's ``concurrent_requests``
    for its whole duration (429 if they are all taken; the single queries take theirs
    only when they compute).
    """
    route = request.scope.get("route")
    if route is not None and not getattr(route, "include_in_schema", True):
        return Principal(None, Scope.read)
    need = needed_scope(request)
    p = await authorize(request, creds, settings, stores.keys, need)
    await admission.authorized(
        need.value,
        p.key_id,
        p.quotas,
        stores,
        settings.request_lease_s,
        str(request.scope.get("path", "")),
    )
    return p


async def _check_trajectory_points(request: Request, p: Principal) -> None:
    try:
        body = await request.json()
    except Exception:  # noqa: BLE001 - the endpoint reports unparsable bodies itself
        return
    n = body.get("n_points") if isinstance(body, dict) else None
    limit = p.quotas.trajectory_points
    if isinstance(n, int) and not isinstance(n, bool) and n > limit:
        raise ProblemError(
            422,
            "Invalid input",
            f"n_points: {n} exceeds this key's quota (valid range: [2, {limit}])",
            field="n_points",
            valid=f"[2, {limit}]",
        )


async def current(request: Request) -> Principal:  # async: no thread hop
    """The principal of this request (anonymous admin if :func:`guard` did not run)."""
    p = request.scope.get("rsf.principal")
    return p if isinstance(p, Principal) else Principal(None, Scope.admin)


PrincipalDep = Annotated[Principal, Depends(current)]


async def admit_sweep(who: Principal, stores: Stores, sweep_id: str, n_points: int) -> int:
    """Check the sweep quotas of ``who`` before a submission and reserve ``n_points`` of
    today's points; returns the points reserved (0 for anonymous requests, and for a
    sweep that exists and is not cancelled: submitting it again starts nothing).

    Raises:
        ProblemError: 429 (+ Retry-After) when the key already has ``concurrent_sweeps``
            sweeps queued or running, or today's ``points_per_day`` would be exceeded.
    """
    if who.anonymous or who.name is None:
        return 0
    st = await run_in_threadpool(stores.sweeps.status, sweep_id)
    if st is not None and st.get("status") != "cancelled":
        return 0
    ks, q = stores.keys, who.quotas
    active = await run_in_threadpool(ks.active_sweeps, who.name)
    if active >= q.concurrent_sweeps:
        raise QuotaError(
            f"this key has {active} sweeps queued or running (quota "
            f"concurrent_sweeps = {q.concurrent_sweeps}); wait for one to "
            "finish or cancel one",
            retry_after=30,
        )
    left = await run_in_threadpool(ks.reserve_points, who.name, n_points, q.points_per_day)
    if left < 0:
        used = await run_in_threadpool(ks.points_used, who.name)
        midnight = (utc_day() + 1) * 86400 - time.time()
        raise QuotaError(
            f"{n_points} points would exceed this key's daily quota "
            f"(points_per_day = {q.points_per_day}, used today {used}); the "
            "count resets at 00:00 UTC",
            retry_after=max(1, math.ceil(midnight)),
        )
    return n_points


async def sweep_submitted(
    who: Principal, stores: Stores, sweep_id: str, charged: bool, reserved: int
) -> None:
    """After a submission: record ``who`` as the owner of a new sweep; give the reserved
    points back when nothing new was started (an existing sweep was returned)."""
    if who.anonymous or who.name is None:
        return
    ks = stores.keys
    await run_in_threadpool(ks.set_owner, sweep_id, who.name)
    if not charged and reserved:
        await run_in_threadpool(ks.refund_points, who.name, reserved)


async def check_owner(who: Principal, stores: Stores, sweep_id: str) -> None:
    """403 unless ``who`` may cancel or delete ``sweep_id``: admin (or anonymous, i.e.
    auth off or loopback without keys) may touch any sweep, other keys only their own."""
    if who.scope.allows(Scope.admin):
        return
    owner = await run_in_threadpool(stores.keys.owner, sweep_id)
    if owner is None and await run_in_threadpool(stores.sweeps.status, sweep_id) is None:
        return  # unknown sweep: the route answers 404
    if owner != who.name:
        raise AuthError(
            403,
            "this sweep was submitted with another key; only that key or "
            "an admin key may cancel it",
        )


def install(app: FastAPI) -> None:
    """Register the 401/403 problem+json handler on ``app``."""

    @app.exception_handler(QuotaError)
    async def _quota(_req: Request, exc: QuotaError) -> Response:
        return problem(
            429, "Too many requests", exc.detail, headers={"Retry-After": str(exc.retry_after)}
        )

    @app.exception_handler(AuthError)
    async def _auth(_req: Request, exc: AuthError) -> Response:
        if exc.status == 401:
            return problem(
                401, "Unauthorized", exc.detail, headers={"WWW-Authenticate": 'Bearer realm="rsf"'}
            )
        return problem(exc.status, "Forbidden", exc.detail)
