"""Stability consequences of a fit: how close the fitted sample and machine are to instability.

From the fitted (a, b, Dc, eps) and machine stiffness k [1/m] (friction per metre of
load-point displacement) at the reference sliding velocity v_ref:

* kappa = k Dc/a, kappa_crit = b/a - 1 (`eq: dimensionless critical stiffness`), their
  ratio (= k/k_crit with k_crit = (b - a)/Dc [1/m], `eq: critical stiffness`);
* the critical velocity jump (factor V/v_ref and new slip rate [m/s]) and the critical
  load-point jump (new load-point velocity [m/s]) of rsfcore.critical.critical_perturbation,
  converted by rsfcore.units;
* their uncertainty, propagated by sampling the fit's covariance (a multivariate normal in
  the fitted coordinates mu0, a, b, ln Dc, eps, ln k; eps clipped to [0, 1]): the
  probability of each kind (zero / finite / infinite) and percentiles of the finite sizes.
  Sampled critical sizes use rtol 1e-6, far below any fitted spread.

Regimes: "velocity-strengthening" (b <= a: steady sliding is stable for any stiffness and
perturbation), "rigid-machine" (k = inf: V follows the load point, no instability),
"linearly-unstable" (kappa < kappa_crit: every perturbation grows, stick-slip expected),
"finite-critical" (at least one finite critical size), "unconditionally-stable" (no
perturbation of either kind runs away: eps kappa >= kappa_crit), "outside-range" (b/a or
kappa beyond the core's validated range).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..critical import critical_perturbation
from ..params import BA_MAX, KAPPA_MAX, Params
from ..units import CriticalSI, PhysicalInputs, critical_si, kappa_from_lab_stiffness

__all__ = ["Spread", "CriticalAnswer", "StabilityAnswer", "stability_answer", "REGIMES"]

REGIMES: tuple[str, ...] = (
    "velocity-strengthening",
    "rigid-machine",
    "linearly-unstable",
    "finite-critical",
    "unconditionally-stable",
    "outside-range",
)
_PERTS = ("velocity-jump", "load-point-jump")
_SAMPLE_RTOL = 1e-6


def _f(x: float | None) -> float | None:
    if x is None:
        return None
    x = float(x)
    return x if math.isfinite(x) else None


@dataclass(frozen=True)
class Spread:
    """Percentiles of a sampled quantity (None where not finite)."""

    median: float | None
    p2_5: float | None
    p16: float | None
    p84: float | None
    p97_5: float | None
    n: int

    @classmethod
    def of(cls, x: NDArray[np.float64]) -> Spread | None:
        x = np.asarray(x, dtype=np.float64)
        if x.size == 0:
            return None
        q = [_f(v) for v in np.percentile(x, [50.0, 2.5, 16.0, 84.0, 97.5])]
        return cls(median=q[0], p2_5=q[1], p16=q[2], p84=q[3], p97_5=q[4], n=int(x.size))

    def to_dict(self) -> dict[str, Any]:
        return {
            "median": self.median,
            "p2_5": self.p2_5,
            "p16": self.p16,
            "p84": self.p84,
            "p97_5": self.p97_5,
            "n": self.n,
        }


@dataclass(frozen=True)
class CriticalAnswer:
    """Critical perturbation of one kind at the fitted point, with its sampled uncertainty.

    Attributes:
        perturbation: "velocity-jump" | "load-point-jump".
        kind: "zero" | "finite" | "infinite" at the fitted point (None: outside range).
        estimate: the rsfcore.units.CriticalSI answer at the fitted point (SI values:
            velocity_jump.new_slip_rate_m_s or load_point_jump.new_load_point_velocity_m_s).
        kind_probability: fraction of covariance samples of each kind.
        size: percentiles of the finite critical sizes (d_crit or dv_crit) over samples.
        critical_m_s: percentiles of the critical new slip rate (velocity jump) or new
            load-point velocity (load-point jump) [m/s] over the finite samples.
    """

    perturbation: str
    kind: str | None
    estimate: CriticalSI | None
    kind_probability: dict[str, float]
    size: Spread | None
    critical_m_s: Spread | None

    def to_dict(self) -> dict[str, Any]:
        return {
            "perturbation": self.perturbation,
            "kind": self.kind,
            "estimate": None if self.estimate is None else self.estimate.to_dict(),
            "kind_probability": dict(self.kind_probability),
            "size": None if self.size is None else self.size.to_dict(),
            "critical_m_s": None if self.critical_m_s is None else self.critical_m_s.to_dict(),
        }


@dataclass(frozen=True)
class StabilityAnswer:
    """How close the fitted sample and machine are to instability (SI, with uncertainty).

    Attributes:
        regime: one of REGIMES (module docstring), at the fitted point.
        v_ref_m_s: steady sliding velocity the perturbations start from [m/s].
        stiffness_per_m: machine stiffness k [1/m] (None: infinitely stiff).
        stiffness_fitted: whether k was fitted.
        critical_stiffness_per_m: k_crit = (b - a)/Dc [1/m] (None when b <= a).
        kappa, kappa_crit, kappa_ratio: k Dc/a, b/a - 1 and their ratio (None if infinite).
        kappa_ratio_spread, critical_stiffness_spread: sampled percentiles.
        prob_linearly_unstable: fraction of samples with kappa < kappa_crit.
        velocity_jump, load_point_jump: CriticalAnswer.
        n_samples: covariance samples used (0: no uncertainty propagated).
        message: one-sentence summary (led by the warning when there is one).
        sigma_Pa: normal stress [Pa] when known; then stiffness_Pa_per_m and
            critical_stiffness_Pa_per_m = k sigma and k_crit sigma (`eq: critical stiffness`
            in Pa/m), else None.
        warning: why this answer must not be taken at face value (the fit is SUSPECT or
            its law REJECTED), else None.
    """

    regime: str
    v_ref_m_s: float
    stiffness_per_m: float | None
    stiffness_fitted: bool
    critical_stiffness_per_m: float | None
    kappa: float | None
    kappa_crit: float
    kappa_ratio: float | None
    kappa_ratio_spread: Spread | None
    critical_stiffness_spread: Spread | None
    prob_linearly_unstable: float | None
    velocity_jump: CriticalAnswer
    load_point_jump: CriticalAnswer
    n_samples: int
    message: str
    sigma_Pa: float | None = None
    warning: str | None = None

    @property
    def stiffness_Pa_per_m(self) -> float | None:
        if self.sigma_Pa is None or self.stiffness_per_m is None:
            return None
        return self.stiffness_per_m * self.sigma_Pa

    @property
    def critical_stiffness_Pa_per_m(self) -> float | None:
        if self.sigma_Pa is None or self.critical_stiffness_per_m is None:
            return None
        return self.critical_stiffness_per_m * self.sigma_Pa

    def to_dict(self) -> dict[str, Any]:
        return {
            "regime": self.regime,
            "v_ref_m_s": self.v_ref_m_s,
            "stiffness_per_m": _f(self.stiffness_per_m),
            "stiffness_fitted": self.stiffness_fitted,
            "critical_stiffness_per_m": _f(self.critical_stiffness_per_m),
            "kappa": _f(self.kappa),
            "kappa_crit": _f(self.kappa_crit),
            "kappa_ratio": _f(self.kappa_ratio),
            "kappa_ratio_spread": None
            if self.kappa_ratio_spread is None
            else self.kappa_ratio_spread.to_dict(),
            "critical_stiffness_spread": None
            if self.critical_stiffness_spread is None
            else self.critical_stiffness_spread.to_dict(),
            "prob_linearly_unstable": self.prob_linearly_unstable,
            "velocity_jump": self.velocity_jump.to_dict(),
            "load_point_jump": self.load_point_jump.to_dict(),
            "n_samples": self.n_samples,
            "message": self.message,
            "sigma_Pa": self.sigma_Pa,
            "stiffness_Pa_per_m": _f(self.stiffness_Pa_per_m),
            "critical_stiffness_Pa_per_m": _f(self.critical_stiffness_Pa_per_m),
            "warning": self.warning,
        }


def _kind_no_core(a: float, b: float, Dc: float, eps: float, k: float) -> tuple[str | None, str]:
    """(kind, regime) decided without the core: b <= a, k = inf, or beyond the core's range.

    Returns ("", "") when the point is inside the core's range (the core decides, so that
    boundary cases are treated exactly as rsfcore.critical treats them).
    """
    if not b > a:
        return "infinite", "velocity-strengthening"
    if math.isinf(k):
        return "infinite", "rigid-machine"
    ba = b / a
    kappa = kappa_from_lab_stiffness(k, Dc, a)
    if ba <= BA_MAX and kappa <= KAPPA_MAX:
        return "", ""
    kc = ba - 1.0
    if kappa < kc:
        return "zero", "linearly-unstable"
    if eps * kappa >= kc:
        return "infinite", "unconditionally-stable"
    return None, "outside-range"


def _point(
    p: dict[str, float], pert: str, v_ref: float, rtol: float
) -> tuple[str | None, float | None, CriticalSI | None]:
    a, b, Dc, eps, k = p["a"], p["b"], p["Dc_m"], p["eps"], p["k_per_m"]
    kind, _ = _kind_no_core(a, b, Dc, eps, k)
    if kind != "":
        size = 0.0 if kind == "zero" else None
        return kind, size, None
    phys = PhysicalInputs(
        a=a, b=b, Dc_m=Dc, sigma_Pa=1.0, k_Pa_per_m=k, V_star_m_s=v_ref, V_load_m_s=v_ref
    )
    c = critical_si(phys, eps, pert, rtol=rtol)  # type: ignore[arg-type]
    return c.kind, c.critical_size, c


#: Relative margin inside which a sample's kind is left to the core (rounding boundary).
_SHORTCUT_MARGIN = 1e-9


def _sample_kind_size(p: dict[str, float], pert: str) -> tuple[str | None, float | None]:
    a, b, Dc, eps, k = p["a"], p["b"], p["Dc_m"], p["eps"], p["k_per_m"]
    kind, _ = _kind_no_core(a, b, Dc, eps, k)
    if kind != "":
        return kind, (0.0 if kind == "zero" else None)
    # the core's own closed-form kinds (rsfcore.critical methods M_ZERO_LINEAR and
    # M_INF_NO_RUNAWAY), decided here without its per-call set-up when clear of the
    # boundary: kappa < kappa_crit is zero, eps kappa >= kappa_crit infinite
    kc = b / a - 1.0
    kappa = kappa_from_lab_stiffness(k, Dc, a)
    if kappa < kc * (1.0 - _SHORTCUT_MARGIN):
        return "zero", 0.0
    if eps * kappa > kc * (1.0 + _SHORTCUT_MARGIN):
        return "infinite", None
    c = critical_perturbation(
        Params(ba=b / a, kappa=kappa_from_lab_stiffness(k, Dc, a), eps=eps, vo=1.0),
        pert,
        rtol=_SAMPLE_RTOL,
    )
    return c.kind, c.critical_size


def stability_answer(
    params: dict[str, float],
    samples: list[dict[str, float]],
    *,
    v_ref_m_s: float,
    stiffness_fitted: bool,
    rtol: float = 1e-10,
    sigma_Pa: float | None = None,
    warning: str | None = None,
) -> StabilityAnswer:
    """Stability consequences at the fitted ``params`` (keys of rsfcore.fit.PARAM_NAMES) and
    their spread over ``samples`` (parameter dicts drawn from the fit's covariance)."""
    a, b, Dc, eps, k = params["a"], params["b"], params["Dc_m"], params["eps"], params["k_per_m"]
    kc = b / a - 1.0
    kappa = kappa_from_lab_stiffness(k, Dc, a) if math.isfinite(k) else math.inf
    kind0, regime = _kind_no_core(a, b, Dc, eps, k)
    answers: dict[str, CriticalAnswer] = {}
    for pert in _PERTS:
        kind, size, est = _point(params, pert, v_ref_m_s, rtol)
        counts = {"zero": 0, "finite": 0, "infinite": 0, "outside-range": 0}
        sizes: list[float] = []
        for s in samples:
            sk, ss = _sample_kind_size(s, pert)
            counts[sk if sk is not None else "outside-range"] += 1
            if sk == "finite" and ss is not None:
                sizes.append(ss)
        ns = max(1, len(samples))
        prob = {key: val / ns for key, val in counts.items()} if samples else {}
        arr = np.asarray(sizes, dtype=np.float64)
        if pert == "velocity-jump":
            with np.errstate(over="ignore"):
                crit = v_ref_m_s * np.exp(np.minimum(arr, 700.0))
        else:
            crit = v_ref_m_s * (1.0 + arr)
        answers[pert] = CriticalAnswer(
            perturbation=pert,
            kind=kind,
            estimate=est,
            kind_probability=prob,
            size=Spread.of(arr) if arr.size else None,
            critical_m_s=Spread.of(crit) if arr.size else None,
        )
    if kind0 == "":
        if kappa < kc:
            regime = "linearly-unstable"
        elif any(ans.kind == "finite" for ans in answers.values()):
            regime = "finite-critical"
        else:
            regime = "unconditionally-stable"
    ratios = []
    kcrits = []
    n_lin = 0
    for s in samples:
        if s["b"] > s["a"] and math.isfinite(s["k_per_m"]):
            kap = kappa_from_lab_stiffness(s["k_per_m"], s["Dc_m"], s["a"])
            kcs = s["b"] / s["a"] - 1.0
            ratios.append(kap / kcs)
            n_lin += kap < kcs
        if math.isfinite(s["Dc_m"]):
            kcrits.append((s["b"] - s["a"]) / s["Dc_m"])
    kratio = kappa / kc if (kc > 0.0 and math.isfinite(kappa)) else None
    msg = _message(regime, kratio, answers, v_ref_m_s)
    if warning:
        msg = f"{warning} {msg}"
    return StabilityAnswer(
        regime=regime,
        v_ref_m_s=v_ref_m_s,
        stiffness_per_m=k if math.isfinite(k) else None,
        stiffness_fitted=stiffness_fitted,
        critical_stiffness_per_m=(b - a) / Dc if b > a else None,
        kappa=kappa if math.isfinite(kappa) else None,
        kappa_crit=kc,
        kappa_ratio=kratio,
        kappa_ratio_spread=Spread.of(np.asarray(ratios)) if ratios else None,
        critical_stiffness_spread=Spread.of(np.asarray(kcrits)) if kcrits else None,
        prob_linearly_unstable=(n_lin / len(samples)) if samples else None,
        velocity_jump=answers["velocity-jump"],
        load_point_jump=answers["load-point-jump"],
        n_samples=len(samples),
        message=msg,
        sigma_Pa=sigma_Pa,
        warning=warning,
    )


def _message(
    regime: str, kratio: float | None, answers: dict[str, CriticalAnswer], v_ref: float
) -> str:
    if regime == "velocity-strengthening":
        return (
            "b <= a (velocity strengthening): steady sliding is stable for any machine "
            "stiffness and perturbation."
        )
    if regime == "rigid-machine":
        return "Infinitely stiff machine: the slider follows the load point; no instability."
    if regime == "linearly-unstable":
        return (
            f"k/k_crit = {kratio:.4g} < 1: steady sliding is linearly unstable "
            "(stick-slip expected)."
        )
    if regime == "outside-range":
        return "b/a or kappa beyond the core's validated range (1e6): no critical sizes computed."
    parts = [f"k/k_crit = {kratio:.4g}"]
    vj = answers["velocity-jump"].estimate
    if vj is not None and vj.velocity_jump is not None and vj.velocity_jump.factor is not None:
        parts.append(
            f"a slip-rate jump by a factor above {vj.velocity_jump.factor:.4g} "
            f"from {v_ref:.3g} m/s runs away"
        )
    lj = answers["load-point-jump"].estimate
    if (
        lj is not None
        and lj.load_point_jump is not None
        and lj.load_point_jump.new_load_point_velocity_m_s is not None
    ):
        parts.append(
            "a load-point velocity step to above "
            f"{lj.load_point_jump.new_load_point_velocity_m_s:.4g} m/s runs away"
        )
    if len(parts) == 1:
        parts.append("no perturbation of either kind runs away")
    return "; ".join(parts) + "."
