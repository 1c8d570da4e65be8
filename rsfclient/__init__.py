"""rsfclient: a small Python client of the rsf-stability HTTP API, for lab tools.

    >>> from rsfclient import Client
    >>> with Client("http://127.0.0.1:8000") as c:
    ...     c.critical(ba=2.0, kappa=3.0, eps=0.2)["critical_size"]
    ...     s = c.sweep(axes=[{"name": "kappa_ratio", "start": 1, "stop": 5, "n": 100},
    ...                       {"name": "eps", "start": 0, "stop": 0.9, "n": 100}])
    ...     s.wait(progress=True)
    ...     ds = s.to_xarray()          # needs xarray

Transient failures (HTTP 502/503/504, connection errors, timeouts) are retried with
exponential backoff, honouring ``Retry-After``; an error answer raises
:class:`ProblemError` carrying the server's problem+json (``status``, ``title``,
``detail``, ``field``, ``valid``).  Needs only httpx; ``rich`` (progress bar) and
``xarray`` are used when installed.
"""

from ._client import Client, Sweep
from ._errors import ConnectionFailed, ProblemError, RsfError, SweepCancelled

__all__ = [
    "Client",
    "ConnectionFailed",
    "ProblemError",
    "RsfError",
    "Sweep",
    "SweepCancelled",
    "__version__",
]

__version__ = "0.1.0"
