"""What every adapter module shares: the error convention (:class:`ComputeError`,
:class:`NeedsQueue`, :func:`guard`), the quick step budget and the JSON-safe answer."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from rsfcore import NUMERICS_VERSION
from rsfcore.jsonsafe import jsonsafe
from rsfcore.params import ParameterError, Params

__all__ = [
    "ComputeError",
    "NeedsQueue",
    "QUICK_STEPS",
    "dim_params",
    "guard",
    "json_dict",
    "numerics_version",
]


class ComputeError(RuntimeError):
    """Valid input whose computation failed numerically (message says why)."""


class NeedsQueue(ComputeError):
    """The quick in-process attempt ran out of its step budget: a long integration,
    to be computed by a worker (service.answer routes it through the queue)."""


#: Default step budget of the in-process attempt at a single query (~0.2-0.5 s of
#: integration; the setting ``RSF_QUICK_STEPS`` overrides it); a query that needs more is
#: a long integration and goes through the Celery queue.
QUICK_STEPS = 300_000


def numerics_version() -> str:
    """rsfcore.NUMERICS_VERSION (part of every cache key)."""
    return str(NUMERICS_VERSION)


def guard(fn: Callable[..., Any], *args: Any, **kwargs: Any) -> Any:
    """Call ``fn``; ParameterError passes through, other numerical failures become
    :class:`ComputeError` (:class:`NeedsQueue` when the quick step budget ran out)."""
    try:
        return fn(*args, **kwargs)
    except (ParameterError, ComputeError):
        raise
    except (ArithmeticError, ValueError, RuntimeError, FloatingPointError) as exc:
        if getattr(exc, "reason", None) == "budget" and kwargs.get("max_steps") is not None:
            raise NeedsQueue(str(exc)) from exc
        raise ComputeError(f"{type(exc).__name__}: {exc}") from exc


def json_dict(obj: Any) -> dict[str, Any]:
    """rsfcore.jsonsafe of a dict answer, typed as one."""
    out = jsonsafe(obj)
    assert isinstance(out, dict)
    return out


def dim_params(req: Any) -> Params:
    p: Params = guard(Params, ba=req.ba, kappa=req.kappa, eps=req.eps, vo=req.vo)
    return p
