"""rsfclient: the Python client of the rsf-stability HTTP API, for lab tools.

    >>> from rsfclient import Client, axis
    >>> with Client() as c:                     # RSF_URL, else http://127.0.0.1:8000
    ...     r = c.critical(a=0.010, b=0.014, Dc_m=20e-6, sigma_Pa=10e6,
    ...                    k_Pa_per_m=4e9, V_star_m_s=1e-6)
    ...     r.kind, r.critical_size, r.si["velocity_jump"]["new_slip_rate_m_s"]
    ...     s = c.sweep(axes=[axis("kappa_ratio", 1, 5, 100), axis("eps", 0, 0.9, 100)],
    ...                 ba=2.0)
    ...     s.wait(progress=True)
    ...     ds = s.to_xarray()                  # needs xarray

One method per question of the API (single queries dimensionless or in SI, batches,
protocols, fits, sweeps, figures), keyword arguments named exactly like the HTTP JSON
fields; an argument left out is not sent, so the server's default applies.  Answers are
typed dataclasses that also read like the JSON (``r["critical_size"]``) and convert to
pandas or xarray where they hold a table or a grid.

A refused connection fails at once (:class:`ConnectionFailed` naming the URL); a 503,
a 429 with ``Retry-After`` or a connection reset is retried; an error answer raises
:class:`ProblemError` carrying the server's problem+json (``status``, ``title``,
``detail``, ``field``, ``valid``).  Needs only httpx; ``rich`` (progress bar), ``pandas``
and ``xarray`` are used when installed.
"""

from ._client import MACHINE_FIELDS, RENDERABLE, Client, axis
from ._errors import ConnectionFailed, NotReady, ProblemError, RsfError, SweepCancelled
from ._fits import Fit
from ._results import (
    AnalyticUResult,
    Answer,
    BatchResult,
    BoundariesResult,
    ClassifyResult,
    CriticalResult,
    FigureData,
    FigureInfo,
    FitResult,
    ItemError,
    Params,
    PointsResult,
    ProtocolResult,
    Start,
    StiffnessResult,
    TrajectoryResult,
)
from ._sweeps import Sweep, SweepPoints, SweepStatus

__all__ = [
    "AnalyticUResult",
    "Answer",
    "BatchResult",
    "BoundariesResult",
    "ClassifyResult",
    "Client",
    "ConnectionFailed",
    "CriticalResult",
    "FigureData",
    "FigureInfo",
    "Fit",
    "FitResult",
    "ItemError",
    "MACHINE_FIELDS",
    "NotReady",
    "Params",
    "PointsResult",
    "ProblemError",
    "ProtocolResult",
    "RENDERABLE",
    "RsfError",
    "Start",
    "StiffnessResult",
    "Sweep",
    "SweepCancelled",
    "SweepPoints",
    "SweepStatus",
    "TrajectoryResult",
    "__version__",
    "axis",
]

__version__ = "0.2.0"
