"""Posterior sampling of a fit with emcee (the ``fit`` extra: ``pip install rsf-stability[fit]``).

Model: Gaussian residuals with the fit's residual standard deviation sigma (fixed), i.e.
log L = -RSS/(2 sigma^2); priors uniform in the fitted coordinates (mu0, a, b, ln Dc,
eps, ln k) inside the fit's bounds, so log-uniform in Dc and k.  Sampler: emcee's affine-
invariant ensemble (Foreman-Mackey et al. 2013), walkers started in a small ball
(0.1 standard error) around the least-squares solution.  Each log-probability is one run
of the compiled forward model (~0.2-2 ms), so 32 walkers x 2000 steps take ~15-120 s.

The posterior is the honest uncertainty when the misfit is not quadratic (see
FitResult.linearity); for a well-determined fit its standard deviations agree with the
linearised standard errors (tests/core/test_fit.py).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..jsonsafe import jsonsafe
from ..params import ParameterError, check_range
from .core import FitResult, _from_x
from .model import PARAM_NAMES, ForwardModel, Law
from .stability import Spread, StabilityAnswer, stability_answer

__all__ = ["Posterior", "sample_posterior"]


@dataclass
class Posterior:
    """Posterior samples of the fitted parameters (physical units: Dc_m [m], k_per_m [1/m]).

    Attributes:
        names: fitted parameter names (columns of ``samples``).
        samples: (m, p) array after burn-in and thinning.
        median, std: per parameter.
        spread: per parameter Spread (2.5/16/50/84/97.5 percentiles).
        acceptance_fraction: mean over walkers (0.2-0.5 is healthy).
        autocorr_steps: emcee's integrated autocorrelation time per parameter, in steps
            (None where the chain is too short to estimate it reliably).
        n_walkers, n_steps, burn, thin: sampler settings; sigma: residual std used.
        stability: StabilityAnswer with its spreads from the posterior samples (or None).
    """

    names: tuple[str, ...]
    samples: NDArray[np.float64]
    median: dict[str, float]
    std: dict[str, float]
    spread: dict[str, Spread]
    acceptance_fraction: float
    autocorr_steps: dict[str, float | None]
    n_walkers: int
    n_steps: int
    burn: int
    thin: int
    sigma: float
    stability: StabilityAnswer | None

    def to_dict(self, *, samples: bool = False) -> dict[str, Any]:
        d: dict[str, Any] = {
            "names": list(self.names),
            "median": self.median,
            "std": self.std,
            "spread": {k: v.to_dict() for k, v in self.spread.items()},
            "acceptance_fraction": self.acceptance_fraction,
            "autocorr_steps": self.autocorr_steps,
            "n_walkers": self.n_walkers,
            "n_steps": self.n_steps,
            "burn": self.burn,
            "thin": self.thin,
            "sigma": self.sigma,
            "stability": None if self.stability is None else self.stability.to_dict(),
        }
        if samples:
            d["samples"] = self.samples
        out = jsonsafe(d)
        assert isinstance(out, dict)
        return out


def sample_posterior(
    result: FitResult,
    *,
    n_walkers: int = 32,
    n_steps: int = 2000,
    burn: int = 500,
    thin: int = 10,
    seed: int = 0,
    stability: bool = True,
    stability_samples: int = 400,
) -> Posterior:
    """Sample the posterior of a converged fit with emcee.

    Args:
        result: a FitResult with finite residuals and covariance (status OK or
            ILL_CONDITIONED with a finite covariance).
        n_walkers: ensemble size, >= 2 x the number of fitted parameters.
        n_steps: steps per walker (> burn); burn: discarded steps; thin: keep every thin-th.
        seed: random seed (reproducible chains).
        stability: also propagate the posterior to the stability answer, using up to
            ``stability_samples`` posterior draws.

    Raises ImportError (with the install hint) when emcee is missing and ParameterError
    for unusable inputs.
    """
    try:
        import emcee
    except ImportError as e:  # pragma: no cover - depends on the environment
        raise ImportError("posterior sampling needs emcee: pip install 'rsf-stability[fit]'") from e
    names = result.fitted
    p = len(names)
    n_walkers = int(check_range("n_walkers", n_walkers, 2 * p, 10_000))
    n_steps = int(check_range("n_steps", n_steps, 2, 10_000_000))
    burn = int(check_range("burn", burn, 0, n_steps - 1))
    thin = int(check_range("thin", thin, 1, n_steps))
    if not math.isfinite(result.rss) or not np.all(np.isfinite(result.covariance)):
        raise ParameterError(
            "result", result.status.value, "a fit with finite residuals and covariance"
        )
    model = ForwardModel(result.record, result.spec)
    lb, ub = result.bounds_internal
    mu_data = result.record.mu
    sigma = result.sigma
    nagata = result.spec.law is Law.NAGATA

    def log_prob(x: NDArray[np.float64]) -> float:
        if np.any(x < lb) or np.any(x > ub):
            return -math.inf
        q = _from_x(names, x)
        if nagata and not q["b"] > 0.0:
            return -math.inf
        m, n_ok = model.friction(model.full(q))
        if n_ok < mu_data.shape[0]:
            return -math.inf
        r = m - mu_data
        return -0.5 * float(r @ r) / sigma**2

    rng = np.random.default_rng(seed)
    sd = np.sqrt(np.diag(result.covariance))
    x0 = result.x_internal + 0.1 * sd * rng.standard_normal((n_walkers, p))
    x0 = np.clip(x0, lb + 1e-12 * (ub - lb), ub - 1e-12 * (ub - lb))
    sampler = emcee.EnsembleSampler(n_walkers, p, log_prob)
    sampler.random_state = np.random.RandomState(seed).get_state()  # emcee's own generator
    sampler.run_mcmc(x0, n_steps, progress=False)
    chain = sampler.get_chain(discard=burn, thin=thin, flat=True)
    phys = np.array(
        [
            [
                math.exp(v) if nm in ("Dc_m", "k_per_m") else v
                for nm, v in zip(names, row, strict=True)
            ]
            for row in chain
        ]
    )
    try:
        tau = sampler.get_autocorr_time(discard=burn, quiet=True)
        autocorr = {
            nm: (float(t) if math.isfinite(t) else None) for nm, t in zip(names, tau, strict=True)
        }
    except Exception:  # noqa: BLE001 - emcee raises its own AutocorrError on short chains
        autocorr = {nm: None for nm in names}
    spread = {
        nm: s
        for nm, s in ((nm, Spread.of(phys[:, j])) for j, nm in enumerate(names))
        if s is not None
    }
    stab = None
    if stability and result.ok:
        idx = rng.choice(chain.shape[0], size=min(stability_samples, chain.shape[0]), replace=False)
        draws = []
        for row in chain[idx]:
            q = _from_x(names, row)
            draws.append(model.full(q))
        full = {k: result.params[k] for k in PARAM_NAMES}
        stab = stability_answer(
            full, draws, v_ref_m_s=result.v_ref_m_s, stiffness_fitted=result.spec.fit_stiffness
        )
    return Posterior(
        names=names,
        samples=phys,
        median={nm: float(np.median(phys[:, j])) for j, nm in enumerate(names)},
        std={nm: float(np.std(phys[:, j], ddof=1)) for j, nm in enumerate(names)},
        spread=spread,
        acceptance_fraction=float(np.mean(sampler.acceptance_fraction)),
        autocorr_steps=autocorr,
        n_walkers=n_walkers,
        n_steps=n_steps,
        burn=burn,
        thin=thin,
        sigma=sigma,
        stability=stab,
    )
