"""Request model of a fit (POST /v1/fits, ``rsf fit``): a lab record and the fit options.

The record is CSV or JSON text in the formats of rsfcore.fit.read_record (CSV with header
columns ``t_s`` (or ``x_lp_m``, load-point displacement), ``v_lp_m_s`` (imposed
load-point velocity [m/s]) and ``mu`` (friction); JSON ``{"t_s": [...], "v_lp_m_s": [...],
"mu": [...]}``; the protocol output as written; any headers with ``columns``, a units
row, a decimal comma).  The machine stiffness is ``k_Pa_per_m`` with ``sigma_Pa`` (the
SI spelling of every door), or ``k_friction_per_m`` in friction per metre of load-point
displacement [1/m] (k [Pa/m] = k [1/m] sigma); with neither it is fitted (docs/fitting.md
says why), ``rigid_machine`` assumes an infinitely stiff one.  The cache key of a fit is
the record's content hash (rsfcore.fit.Record.digest) and these options.
"""

from __future__ import annotations

from typing import Literal

from pydantic import ConfigDict, model_validator

from ._base import F
from ._base import Model as _Model
from ._rules import Rule, stated
from .single import field_error

__all__ = ["FitRequest", "FIT_LAWS", "MAX_RECORD_CHARS", "PosteriorOptions"]

#: Laws a record can be fitted with (rsfcore.fit.Law values).
FIT_LAWS: tuple[str, ...] = ("aging", "slip", "nagata", "eps")
#: Largest record text accepted (characters; ~ 3e5 samples of CSV).
MAX_RECORD_CHARS = 20_000_000


class PosteriorOptions(_Model):
    """MCMC (emcee) settings of a posterior sample (rsfcore.fit.sample_posterior)."""

    model_config = ConfigDict(json_schema_extra=stated(Rule("burn < n_steps")))

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

    model_config = ConfigDict(
        json_schema_extra=stated(
            Rule(
                "law is given when compare is false",
                {
                    "anyOf": [
                        {"properties": {"compare": {"const": True}}},
                        {"required": ["law"], "properties": {"law": {"type": "string"}}},
                    ]
                },
            ),
            Rule(
                "record is a readable lab record: CSV or JSON text (or a mapping of columns) "
                "with the columns the fit needs"
            ),
        )
    )

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
        "comparison (misfit, AIC, BIC, Akaike weight per law). A law other than the "
        "requested or best one stops once its rejection is certain (stopped_early: "
        "parameters not polished, no standard errors).",
        name="compare",
    )
    k_Pa_per_m: float | None = F(
        None,
        "null or (0, 1e21] Pa/m, with sigma_Pa",
        "Machine stiffness [Pa/m] (needs sigma_Pa; k [1/m] = k_Pa_per_m/sigma_Pa).",
        name="k_Pa_per_m",
        gt=0,
        le=1e21,
    )
    sigma_Pa: float | None = F(
        None,
        "null or (0, 1e12] Pa",
        "Normal stress [Pa]: converts k_Pa_per_m, and the answer gives the stiffness and "
        "the critical stiffness also in Pa/m.",
        name="sigma_Pa",
        gt=0,
        le=1e12,
    )
    k_friction_per_m: float | None = F(
        None,
        "null or (0, 1e12] 1/m",
        "Machine stiffness in friction per metre of load-point displacement [1/m] "
        "(the lab convention; k [Pa/m]/sigma).",
        name="k_friction_per_m",
        gt=0,
        le=1e12,
    )
    stiffness_per_m: float | None = F(
        None,
        "null or (0, 1e12] 1/m",
        "Deprecated name of k_friction_per_m (friction per metre [1/m]).",
        name="stiffness_per_m",
        gt=0,
        le=1e12,
    )
    fit_stiffness: bool | None = F(
        None,
        "null, true or false",
        "Fit the machine stiffness (a given stiffness is the start value); null: fitted "
        "unless a stiffness is given or rigid_machine; false needs a stiffness.",
        name="fit_stiffness",
    )
    rigid_machine: bool = F(
        False,
        "true or false",
        "Assume an infinitely stiff machine (V follows the load point; no stiffness given).",
        name="rigid_machine",
    )
    trend: bool = F(
        False,
        "true or false",
        "Fit a linear friction trend in load-point displacement (trend_per_m [1/m]); the "
        "stability answer uses the trend-free parameters.",
        name="trend",
    )
    windows: list[tuple[float, float]] | None = F(
        None,
        "null or 1..1000 pairs [t_start_s, t_end_s], t_start_s < t_end_s",
        "Time windows [s, record time]: only samples inside enter the misfit.",
        name="windows",
        min_length=1,
        max_length=1000,
    )
    steps: list[int] | None = F(
        None,
        "null or 1..2000 segment indices (0 = before the first step)",
        "Constant-velocity segments whose samples enter the misfit.",
        name="steps",
        min_length=1,
        max_length=2000,
    )
    columns: dict[str, str] | None = F(
        None,
        "null or {quantity: 'header[:unit]'}, quantities t, x_lp, v_lp, mu, tau, sigma_n",
        "Column mapping of the record, e.g. {'t': 'Time (s)', 'v_lp': 'LP Velocity:um/s', "
        "'mu': 'Friction'}; units: s ms min h; m mm um nm; m/s mm/s um/s nm/s; Pa kPa MPa GPa.",
        name="columns",
    )
    decimal: Literal[".", ","] = F(
        ".", "'.' or ','", "Decimal separator of the CSV record.", name="decimal"
    )
    smooth: int | None = F(
        None,
        "null or [1, 100001] samples",
        "Median-filter width when the load-point velocity is derived from a measured "
        "load-point displacement (default max(5, n/200)).",
        name="smooth",
        ge=1,
        le=100_001,
    )
    time_budget_s: float = F(
        20.0,
        "(0, 600] s",
        "Wall-time budget of each law's fit: a fit not converged by then is not_converged.",
        name="time_budget_s",
        gt=0,
        le=600,
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
        name = type(self).__name__
        if not self.compare and self.law is None:
            raise field_error(name, "law", "give a law when compare is false", None)
        given = [
            f for f in ("k_Pa_per_m", "k_friction_per_m", "stiffness_per_m") if getattr(self, f)
        ]
        if len(given) > 1:
            raise field_error(
                name, given[1], f"give one stiffness, not {' and '.join(given)}", None
            )
        if self.k_Pa_per_m is not None and self.sigma_Pa is None:
            raise field_error(name, "sigma_Pa", "give sigma_Pa with k_Pa_per_m", None)
        if self.rigid_machine and (given or self.fit_stiffness):
            raise field_error(
                name, "rigid_machine", "a rigid machine has no stiffness to give or fit", True
            )
        if self.fit_stiffness is False and not given and not self.rigid_machine:
            raise field_error(
                name,
                "fit_stiffness",
                "fit_stiffness false needs a stiffness (k_Pa_per_m with sigma_Pa, or "
                "k_friction_per_m) or rigid_machine true",
                False,
            )
        for i, w in enumerate(self.windows or []):
            if not w[0] < w[1]:
                raise field_error(name, "windows", f"windows[{i}]: t_start_s < t_end_s", list(w))
        return self

    def stiffness_options(self) -> dict[str, object]:
        """The stiffness as rsfcore.fit.fit_record takes it (stiffness [1/m] or inf,
        fit_stiffness, k_Pa_per_m, sigma_Pa)."""
        k = self.k_friction_per_m if self.k_friction_per_m is not None else self.stiffness_per_m
        return {
            "stiffness": float("inf") if self.rigid_machine else k,
            "fit_stiffness": self.fit_stiffness,
            "k_Pa_per_m": self.k_Pa_per_m,
            "sigma_Pa": self.sigma_Pa,
        }

    def options(self) -> dict[str, object]:
        """Everything but the record (with the record's digest: the cache key)."""
        return self.model_dump(mode="json", exclude={"record"})
