"""Fitting lab velocity-step records (rate-and-state friction) and the stability answer.

Public API (docs/fitting.md):

    read_record(path_or_text) -> Record
    fit_record(record, law="aging"|"slip"|"nagata"|"eps", *, stiffness=K_PER_M | None,
               fit_stiffness=False, ...) -> FitResult          (FitResult.to_dict() JSON-safe)
    compare_laws(record, laws=(...), **options) -> LawComparison
    sample_posterior(result, ...) -> Posterior                 (needs the ``fit`` extra: emcee)
"""

from __future__ import annotations

from .core import (
    DEFAULT_BOUNDS,
    FitResult,
    FitStatus,
    LawComparison,
    LawScore,
    attach_stability,
    compare_laws,
    fit_record,
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
from .record import MAX_SEGMENTS, RECORD_COLUMNS, Record, read_record
from .stability import REGIMES, CriticalAnswer, Spread, StabilityAnswer, stability_answer

__all__ = [
    "DEFAULT_BOUNDS",
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
