"""The one adapter between the application (every door: service, worker, CLI) and
:mod:`rsfcore`, one module per question beside :mod:`rsfapp.requests`:

================  ==========================================================
module            questions
================  ==========================================================
``single``        classify, trajectory, critical, analytic U, boundaries,
                  stiffness, classify at many start points
``batch``         classify and critical batches
``protocols``     lab protocols (velocity step, slide-hold-slide, load history)
``fits``          fits of lab records
``figures``       the data of the paper's figures (rsfplots draws them)
``_si``           SI inputs and the ``si`` blocks of single answers
``_common``       error convention, quick step budget, JSON-safe answers
================  ==========================================================

Each function takes a validated request model (:mod:`rsfapp.requests`), calls rsfcore and
returns a JSON-safe dict.  rsfcore's ``ParameterError`` passes through unchanged (the API
reports it as 422 problem+json naming the field); a numerical failure (e.g.
``UndecidedError``) becomes :class:`ComputeError` (422 "could not be computed" over HTTP,
recorded per point by sweeps); a single query that runs out of the quick step budget
raises :class:`NeedsQueue`.  Nothing here does I/O or knows about HTTP.  Sweep chunks are
computed by :func:`rsfapp.sweepdata.compute_chunk` (rsfcore.batch).
"""

from typing import TYPE_CHECKING

from rsfapp.lazy import lazy_getattr

from ._common import QUICK_STEPS, ComputeError, NeedsQueue, guard, numerics_version

if TYPE_CHECKING:  # imported on first use (a CLI command loads only its question's module)
    from ._si import resolve_params, resolve_size, si_inputs
    from .batch import classify_batch, critical_batch, item_error, validate_items
    from .figures import figure, figure_arrays, figure_list
    from .fits import FIT_COLUMNS, fit, fit_key_request, fit_record_of, fit_table
    from .protocols import (
        PROTOCOL_COLUMNS,
        protocol_load_history,
        protocol_slide_hold_slide,
        protocol_table,
        protocol_velocity_step,
    )
    from .single import (
        SAMPLING_NOTE,
        analytic_u,
        boundaries,
        classify,
        classify_points,
        critical,
        stiffness,
        trajectory,
    )

#: Where each name lives (PEP 562: imported on first access, so that importing one
#: question's module does not load every rsfcore module and scipy).
_WHERE: dict[str, str] = {
    **dict.fromkeys(("resolve_params", "resolve_size", "si_inputs"), "_si"),
    **dict.fromkeys(("classify_batch", "critical_batch", "item_error", "validate_items"), "batch"),
    **dict.fromkeys(
        ("FIT_COLUMNS", "fit", "fit_key_request", "fit_record_of", "fit_table"), "fits"
    ),
    **dict.fromkeys(("figure", "figure_arrays", "figure_list"), "figures"),
    **dict.fromkeys(
        (
            "PROTOCOL_COLUMNS",
            "protocol_load_history",
            "protocol_slide_hold_slide",
            "protocol_table",
            "protocol_velocity_step",
        ),
        "protocols",
    ),
    **dict.fromkeys(
        (
            "SAMPLING_NOTE",
            "analytic_u",
            "boundaries",
            "classify",
            "classify_points",
            "critical",
            "stiffness",
            "trajectory",
        ),
        "single",
    ),
}
_MODULES = frozenset(("single", "batch", "protocols", "fits", "sweeps", "figures"))


__getattr__ = lazy_getattr(__name__, _MODULES, _WHERE, globals())


__all__ = [
    "ComputeError",
    "NeedsQueue",
    "QUICK_STEPS",
    "SAMPLING_NOTE",
    "numerics_version",
    "classify",
    "classify_points",
    "trajectory",
    "critical",
    "resolve_params",
    "resolve_size",
    "si_inputs",
    "classify_batch",
    "critical_batch",
    "item_error",
    "validate_items",
    "protocol_velocity_step",
    "protocol_slide_hold_slide",
    "protocol_load_history",
    "protocol_table",
    "PROTOCOL_COLUMNS",
    "fit",
    "fit_key_request",
    "fit_record_of",
    "fit_table",
    "FIT_COLUMNS",
    "figure",
    "figure_arrays",
    "figure_list",
    "analytic_u",
    "boundaries",
    "stiffness",
    "guard",
]
