"""Fitting lab velocity-step records (rate-and-state friction) and the stability answer.

Public API (docs/fitting.md):

    read_record(path_or_text, columns=..., decimal=".") -> Record
    fit_record(record, law="aging"|"slip"|"nagata"|"eps", *, stiffness=K_PER_M | inf | None,
               k_Pa_per_m=..., sigma_Pa=..., trend=False, windows=..., steps=...,
               ...) -> FitResult                           (FitResult.to_dict() JSON-safe)
    compare_laws(record, laws=(...), **options) -> LawComparison
    sample_posterior(result, ...) -> Posterior                 (needs the ``fit`` extra: emcee)
"""

from __future__ import annotations

from .core import (
    DEFAULT_BOUNDS,
    REJECT_DELTA_AIC,
    STABILITY_STATUSES,
    STIFFNESS_MISMATCH,
    TIME_BUDGET_S,
    FitResult,
    FitStatus,
    LawComparison,
    LawScore,
    attach_stability,
    compare_laws,
    fit_record,
    plausibility,
)
from .model import (
    LAWS,
    PARAM_NAMES,
    ForwardModel,
    Law,
    ModelSpec,
    Simulation,
    nagata_eps,
    synthetic_record,
)
from .posterior import Posterior, sample_posterior
from .record import (
    MAX_SEGMENTS,
    QUANTITIES,
    RECORD_COLUMNS,
    UNITS,
    Record,
    commanded_velocity,
    parse_column_map,
    read_record,
)
from .stability import REGIMES, CriticalAnswer, Spread, StabilityAnswer, stability_answer

__all__ = [
    "DEFAULT_BOUNDS",
    "REJECT_DELTA_AIC",
    "STIFFNESS_MISMATCH",
    "STABILITY_STATUSES",
    "TIME_BUDGET_S",
    "plausibility",
    "QUANTITIES",
    "UNITS",
    "commanded_velocity",
    "parse_column_map",
    "FitResult",
    "FitStatus",
    "LawComparison",
    "LawScore",
    "attach_stability",
    "compare_laws",
    "fit_record",
    "LAWS",
    "PARAM_NAMES",
    "ForwardModel",
    "Law",
    "ModelSpec",
    "Simulation",
    "nagata_eps",
    "synthetic_record",
    "Posterior",
    "sample_posterior",
    "MAX_SEGMENTS",
    "RECORD_COLUMNS",
    "Record",
    "read_record",
    "REGIMES",
    "CriticalAnswer",
    "Spread",
    "StabilityAnswer",
    "stability_answer",
]
