"""Request model of a fit (POST /v1/fits, ``rsf fit``): a lab record and the fit options.

The record is CSV or JSON text in the formats of rsfcore.fit.read_record (CSV with header
columns ``t_s`` (or ``x_lp_m``, load-point displacement), ``v_lp_m_s`` (imposed
load-point velocity [m/s]) and ``mu`` (friction); JSON ``{"t_s": [...], "v_lp_m_s": [...],
"mu": [...]}``).  Machine stiffness is in friction per metre of load-point displacement
[1/m] (the lab convention; k [Pa/m] = k [1/m] sigma).  The cache key of a fit is the
record's content hash (rsfcore.fit.Record.digest) and these options.
"""

from __future__ import annotations

from typing import Literal

from pydantic import model_validator

from ._base import F
from ._base import Model as _Model
from .single import field_error

__all__ = ["FitRequest", "FIT_LAWS", "MAX_RECORD_CHARS", "PosteriorOptions"]

#: Laws a record can be fitted with (rsfcore.fit.Law values).
FIT_LAWS: tuple[str, ...] = ("aging", "slip", "nagata", "eps")
#: Largest record text accepted (characters; ~ 3e5 samples of CSV).
MAX_RECORD_CHARS = 20_000_000


class PosteriorOptions(_Model):
    """MCMC (emcee) settings of a posterior sample (rsfcore.fit.sample_posterior)."""

    n_walkers: int = F(
        32, "[4, 256]", "Ensemble size (>= 2 x fitted parameters).", name="n_walkers", ge=4, le=256
    )
    n_steps: int = F(2000, "[10, 100000]", "Steps per walker.", name="n_steps", ge=10, le=100_000)
    burn: int = F(500, "[0, 99999], < n_steps", "Discarded steps.", name="burn", ge=0, le=99_999)
    thin: int = F(10, "[1, 1000]", "Keep every thin-th step.", name="thin", ge=1, le=1000)

    @model_validator(mode="after")
    def _burn(self) -> PosteriorOptions:
        if self.burn >= self.n_steps:
            raise field_error(type(self).__name__, "burn", "burn must be < n_steps", self.burn)
        return self


class FitRequest(_Model):
    """Fit mu0, a, b, Dc (and eps, machine stiffness) to a velocity-step record, compare
    the evolution laws, and answer how close sample and machine are to instability."""

    record: str = F(
        ...,
        "CSV or JSON text, 1..2e7 characters",
        "The lab record: CSV with header t_s (or x_lp_m), v_lp_m_s, mu; or JSON columns.",
        name="record",
        min_length=1,
        max_length=MAX_RECORD_CHARS,
    )
    law: Literal["aging", "slip", "nagata", "eps"] | None = F(
        None,
        "null, 'aging', 'slip', 'nagata' or 'eps'",
        "Evolution law of the reported fit; null = the best law of the comparison (lowest AIC).",
        name="law",
    )
    compare: bool = F(
        True,
        "true or false",
        "Also fit the other laws and report the "
        "comparison (misfit, AIC, BIC, Akaike weight per law).",
        name="compare",
    )
    stiffness_per_m: float | None = F(
        None,
        "null or (0, 1e12] 1/m",
        "Machine stiffness in "
        "friction per metre of load-point displacement [1/m] "
        "(null: infinitely stiff, unless fit_stiffness).",
        name="stiffness_per_m",
        gt=0,
        le=1e12,
    )
    fit_stiffness: bool = F(
        False,
        "true or false",
        "Fit the machine stiffness too (stiffness_per_m, if given, is the start value).",
        name="fit_stiffness",
    )
    nagata_c: float = F(
        2.0, "[0, 1e6]", "Nagata's c for law 'nagata' (-).", name="nagata_c", ge=0, le=1e6
    )
    rtol: float = F(1e-10, "[1e-13, 1e-6]", "Forward-model tolerance (-).", ge=1e-13, le=1e-6)
    uncertainty_samples: int = F(
        400,
        "[0, 100000]",
        "Covariance samples for the uncertainty of the stability answer.",
        name="uncertainty_samples",
        ge=0,
        le=100_000,
    )
    seed: int = F(0, "[0, 2^31)", "Random seed of those samples.", name="seed", ge=0, lt=2**31)
    posterior: PosteriorOptions | None = F(
        None,
        "null or {n_walkers, n_steps, burn, thin}",
        "Also sample the posterior with emcee (MCMC) and propagate it to the stability answer.",
        name="posterior",
    )

    @model_validator(mode="after")
    def _law_needed(self) -> FitRequest:
        if not self.compare and self.law is None:
            raise field_error(type(self).__name__, "law", "give a law when compare is false", None)
        return self

    def options(self) -> dict[str, object]:
        """Everything but the record (with the record's digest: the cache key)."""
        return self.model_dump(mode="json", exclude={"record"})
