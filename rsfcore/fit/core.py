"""Fit a lab velocity-step record for mu0, a, b, Dc (and eps, machine stiffness), then
answer how close the sample and machine are to instability.

Method: bounded non-linear least squares (rsfcore.fit.lsq: trust-region Gauss-Newton with
Coleman-Li bound scaling, as scipy's "trf") of the friction residuals mu_model - mu_data,
with the compiled forward model
of rsfcore.fit.model (rsfcore.engine's DOP853 for a finite machine stiffness, the exact
closed form for an infinitely stiff one).  Fitted coordinates are (mu0, a, b, ln Dc,
[eps], [ln k], [trend]); the Jacobian, during the iterations and at the solution, is
ForwardModel.jacobian: the friction is linear in mu0, a, b and the trend apart from the
states' dependence on (b/a, ln kappa, ln(V0/Dc), eps), so only those 2-4 directions are
differenced (forward, steps 1e-6; relative error ~1e-5, 1e-4 near kappa_crit, far below
what a standard error needs) and the columns follow by the chain rule: 3 forward runs per
Jacobian for a, b, Dc, k, instead of one per fitted parameter (bench/bench_fit.py: the
fits take 1.3-1.9x fewer runs; results moved by <= 5e-4 standard errors, the optimiser's
tolerance); a trial run that does not complete falls back to forward differences in
every coordinate (steps 1e-6).  Optimiser tolerances ftol = xtol = gtol = 1e-10 (a tighter
1e-14 took 2x the forward runs on a noisy record for changes below 1e-6 of a standard
error; noise-free records are still recovered to ~1e-13).

Start (rsfcore.fit.start): variable projection on the infinitely-stiff closed form (for fixed Dc and eps the
friction is linear in mu0, a, b), scanned over 40 values of Dc (log-spaced over the
record's slip range) and, for laws with eps not fixed, 5 values of eps; the machine
stiffness starts from the loading slope just after the first velocity step,
d mu/dt = k (v_new - v_old), a least-squares line through the first third of the
elastic loading time a/(k |dv|).

Uncertainty: covariance C = s^2 (J^T J)^-1 in the fitted coordinates, with J the
Jacobian at the solution and s^2 = RSS/(n - p) the residual variance (floored at the
forward model's own accuracy, so that noise-free records do not claim zero error);
standard errors of Dc and k by the delta method (sd(Dc) = Dc sd(ln Dc)).  This is the
linearised (Gauss-Newton) uncertainty: tests/core/test_fit.py checks that the true
parameters lie within 2 stated standard errors in >= 90 % of 50 noisy synthetic records.

Identifiability (never a confident wrong answer): the result is ILL_CONDITIONED, and no
stability answer is given, when a fitted parameter has no effect on the model, when the
Jacobian with unit-normalised columns has condition number above ``max_condition``
(1e8), when a, b, Dc or k has a relative standard error above ``max_rel_stderr`` (0.25)
or eps a standard error above 0.25, or when a, b, Dc or k ends on a bound.  The message
names the parameters and what the record lacks.

Law comparison: misfit, AIC = n ln(RSS/n) + 2 (p + 1) and BIC = n ln(RSS/n) + (p + 1) ln n
per law, with RSS floored at n * misfit_floor^2 (misfit_floor = 1e-9 in friction by
default, ~30 times the forward model's error at the default rtol): misfit differences
below what the model resolves do not count, and then the simpler law wins.
"""

from __future__ import annotations

import contextlib
import inspect
import math
import time
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field, replace
from enum import StrEnum
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..jsonsafe import jsonsafe
from ..laws import intermediate_to_nagata
from ..params import ParameterError, check_range
from .lsq import least_squares
from .model import PARAM_NAMES, ForwardModel, Law, ModelSpec, describe
from .record import Record, read_record
from .stability import StabilityAnswer, stability_answer
from .start import StartScans, initial_guess

__all__ = [
    "FitStatus",
    "FitResult",
    "LawComparison",
    "LawScore",
    "fit_record",
    "compare_laws",
    "attach_stability",
    "DEFAULT_BOUNDS",
    "REJECT_DELTA_AIC",
    "STIFFNESS_MISMATCH",
    "TIME_BUDGET_S",
    "STABILITY_STATUSES",
    "plausibility",
]

#: Default bounds of the physical parameters (inclusive).  k in friction per metre [1/m].
DEFAULT_BOUNDS: dict[str, tuple[float, float]] = {
    "mu0": (-10.0, 10.0),
    "a": (1e-7, 1.0),
    "b": (-1.0, 1.0),
    "Dc_m": (1e-10, 1e3),
    "eps": (0.0, 1.0),
    "k_per_m": (1e-6, 1e12),
    "trend_per_m": (-1e4, 1e4),
}
#: A law whose AIC exceeds the best law's by more than this is rejected by the record
#: (Burnham & Anderson 2002: delta AIC > 10, "essentially no support"); its fit is never
#: a plain ``ok`` (FitStatus.REJECTED) and its stability answer carries the warning.
REJECT_DELTA_AIC = 10.0
#: Default wall-time budget of one fit [s]: the optimiser stops there (NOT_CONVERGED).
TIME_BUDGET_S = 20.0
#: Lab plausibility limits (unit slips): Dc above 1 mm, load-point velocities above 1 cm/s,
#: velocity ratios within a record above 1e4, friction outside [0, 3].
PLAUSIBLE_DC_M = 1e-3
PLAUSIBLE_V_M_S = 1e-2
PLAUSIBLE_V_RATIO = 1e4
PLAUSIBLE_MU = (0.0, 3.0)
#: Residual used for samples a trial parameter set cannot reach (runaway or step budget).
_PENALTY = 1.0
#: Finite-difference step in the fitted coordinates (relative for a and b).
_FD_STEP = 1e-6
#: Optimiser tolerances (ftol, xtol, gtol of least_squares).
_TOL = 1e-10
_LOG = ("Dc_m", "k_per_m")
#: least_squares status of a minimisation ended by its ``stop`` (rsfcore.fit.lsq).
_STOPPED = 5
#: A comparison stops a law's fit when its AIC stays above the rejection threshold even if
#: the misfit fell by this many times what the Gauss-Newton model still predicts.  On the
#: test and bench records the decrease still to come was at most 2.1x the prediction
#: after the 2nd iteration (a 5-step record's slip fit; 0.5-1.3x otherwise).
_REJECT_SAFETY = 10.0
#: ... and only when the best law's rms misfit is this many times the misfit floor (so a
#: floor raised by a later law's model accuracy cannot change the verdict).
_REJECT_FLOOR_MARGIN = 1e3


class FitStatus(StrEnum):
    """Outcome of a fit.

    OK: converged and every fitted parameter is determined by the record.
    ILL_CONDITIONED: converged (or not) but some parameter is not determined by the record
        (see FitResult.message and .identified); no stability answer is given.
    SUSPECT: determined, but values implausible for a lab (Dc above a millimetre, slip rates
        above a centimetre per second, a velocity step by more than 1e4, friction outside
        [0, 3]): the message names the likely unit slip; or a stiffness the user gave (or
        a rigid machine) that the record contradicts: refitted with k free, the record
        determines a k differing by more than STIFFNESS_MISMATCH and lowers the AIC by
        more than REJECT_DELTA_AIC; the message names that k and the option to fit it.
        The stability answer carries the warning.
    REJECTED: determined, but the law comparison rejects this law (its AIC is more than
        REJECT_DELTA_AIC above the best law's): the message names the law the record
        supports.  The stability answer carries the warning.
    NOT_CONVERGED: the optimiser stopped on its evaluation or time budget.
    FAILED: the forward model could not reproduce the record at the best parameters found
        (e.g. every trial ran away), or the start ran away.
    """

    OK = "ok"
    SUSPECT = "suspect"
    REJECTED = "rejected"
    ILL_CONDITIONED = "ill_conditioned"
    NOT_CONVERGED = "not_converged"
    FAILED = "failed"


#: Statuses whose fit determines every parameter (a stability answer is given; for
#: SUSPECT and REJECTED it carries the warning).
STABILITY_STATUSES: tuple[FitStatus, ...] = (FitStatus.OK, FitStatus.SUSPECT, FitStatus.REJECTED)


@dataclass
class FitResult:
    """A fitted record.

    Attributes:
        status: FitStatus; ``ok`` is True only for FitStatus.OK.
        message: one or two sentences (what is not determined and why, if anything).
        law: the evolution law ("aging", "slip", "nagata", "eps").
        params: all model parameters: mu0 (steady-state friction at v_ref_m_s), a, b,
            Dc_m [m], eps, k_per_m [1/m] (inf: infinitely stiff), plus "b_minus_a";
            for law "nagata" also aN, bN, DcN_m, cN (rsfcore.laws.intermediate_to_nagata).
        fitted: names of the fitted parameters (the others were fixed).
        stderr: standard errors of the fitted parameters (same units; linearised).
        correlation: correlation matrix of the fitted parameters (names in ``fitted``).
        covariance: covariance in the fitted coordinates (mu0, a, b, ln Dc, eps, ln k).
        identified: per fitted parameter, whether the record determines it.
        condition_number: of the Jacobian with unit-normalised columns (None = infinite).
        linearity: (min, max) ratio of the misfit increase 2 standard errors away along
            the covariance's principal axes to the quadratic prediction (1 for a linear
            model; None when not checked: noise-free record or singular covariance).
        residuals: mu_model - mu_data at the record's samples; model: mu_model.
        rss, rms: residual sum of squares and root mean square (friction).
        sigma: residual standard deviation sqrt(RSS/(n - p)) used for the covariance
            (floored at model_accuracy).
        model_accuracy: max |mu(rtol) - mu(rtol/100)| at the solution (forward model error).
        n, n_params: samples and fitted parameters.
        aic, bic: information criteria (module docstring), misfit_floor: floor used.
        converged: optimiser reported convergence; optimizer_message, n_fev: its details;
            n_model_evals: forward-model runs in total (Jacobians included).
        stability: StabilityAnswer (None unless status is in STABILITY_STATUSES).
        warnings: why the status is SUSPECT or REJECTED (also in the message), and notes
            (e.g. a start moved because it ran away).
        stiffness_mode: "fitted", "fixed" or "rigid" (infinitely stiff machine).
        stopped_early: a law of a comparison whose fit was stopped once the comparison's
            rejection was certain (compare_laws ``complete``): status REJECTED, parameters
            not polished (the optimiser's iterate), no standard errors, covariance,
            identifiability or stability answer, converged False, model_accuracy NaN;
            rss_lower_bound: the misfit it was certain not to go below.
        sigma_Pa: normal stress [Pa] when given (stiffnesses also in Pa/m).
        used: samples that entered the misfit (time windows / step selection; None: all).
        v_ref_m_s: reference velocity of mu0 and of the stability answer [m/s].
        elapsed_s: wall time of the fit [s].
        record, spec: the inputs (for plots, posterior sampling and re-fits).
    """

    status: FitStatus
    message: str
    law: str
    params: dict[str, float]
    fitted: tuple[str, ...]
    stderr: dict[str, float | None]
    correlation: NDArray[np.float64]
    covariance: NDArray[np.float64]
    identified: dict[str, bool]
    condition_number: float | None
    linearity: tuple[float, float] | None
    residuals: NDArray[np.float64]
    model: NDArray[np.float64]
    rss: float
    rms: float
    sigma: float
    model_accuracy: float
    n: int
    n_params: int
    aic: float
    bic: float
    misfit_floor: float
    converged: bool
    optimizer_message: str
    n_fev: int
    n_model_evals: int
    stability: StabilityAnswer | None
    v_ref_m_s: float
    elapsed_s: float
    record: Record = field(repr=False)
    spec: ModelSpec = field(repr=False)
    warnings: list[str] = field(default_factory=list)
    stiffness_mode: str = "fixed"
    sigma_Pa: float | None = None
    used: NDArray[np.bool_] | None = field(repr=False, default=None)
    stopped_early: bool = False
    rss_lower_bound: float | None = field(repr=False, default=None)
    x_internal: NDArray[np.float64] = field(repr=False, default_factory=lambda: np.empty(0))
    bounds_internal: tuple[NDArray[np.float64], NDArray[np.float64]] = field(
        repr=False, default=(np.empty(0), np.empty(0))
    )

    @property
    def ok(self) -> bool:
        return self.status is FitStatus.OK

    def _step_index(self) -> list[int]:
        """Per sample: the index of its constant-velocity segment (0 before the first step)."""
        idx = np.zeros(self.record.n, dtype=np.int64)
        for j, i0 in enumerate(self.record.segment_starts[1:], start=1):
            idx[int(i0) :] = j
        return idx.tolist()

    def step_residuals(self) -> list[dict[str, Any]]:
        """Per constant-velocity segment: index, start time [s], load-point velocity [m/s],
        samples used, rms of the residuals (friction; None when no sample is used)."""
        rec = self.record
        starts = [int(i) for i in rec.segment_starts] + [rec.n]
        out = []
        for j in range(len(starts) - 1):
            i0, i1 = starts[j], starts[j + 1]
            r = self.residuals[i0:i1]
            if self.used is not None:
                r = r[self.used[i0:i1]]
            r = r[np.isfinite(r)]
            out.append(
                {
                    "index": j,
                    "t_start_s": float(rec.t_s[i0]),
                    "v_lp_m_s": float(rec.v_lp_m_s[i0]),
                    "n": int(r.shape[0]),
                    "rms": float(math.sqrt(float(r @ r) / r.shape[0])) if r.shape[0] else None,
                }
            )
        return out

    def to_dict(self, *, series: bool = True) -> dict[str, Any]:
        """JSON-safe dict (no NaN/inf: infinite or undefined values are null).

        Keys: status, message, law, params, fitted, stderr, correlation {names, matrix},
        identified, condition_number, misfit {rss, rms, sigma, model_accuracy, n, n_params,
        aic, bic, misfit_floor}, converged, optimizer_message, n_fev, stability, v_ref_m_s,
        elapsed_s, spec, record {name, digest, n, n_steps}; with ``series`` also
        t_s, mu, model, residuals, v_lp_m_s (arrays).
        """
        d: dict[str, Any] = {
            "status": self.status.value,
            "ok": self.ok,
            "message": self.message,
            "warnings": list(self.warnings),
            "stiffness_mode": self.stiffness_mode,
            "stopped_early": self.stopped_early,
            "sigma_Pa": self.sigma_Pa,
            "steps": self.step_residuals(),
            "law": self.law,
            "params": dict(self.params),
            "fitted": list(self.fitted),
            "stderr": dict(self.stderr),
            "correlation": {"names": list(self.fitted), "matrix": self.correlation},
            "identified": dict(self.identified),
            "condition_number": self.condition_number,
            "linearity": None if self.linearity is None else list(self.linearity),
            "misfit": {
                "rss": self.rss,
                "rms": self.rms,
                "sigma": self.sigma,
                "model_accuracy": self.model_accuracy,
                "n": self.n,
                "n_params": self.n_params,
                "aic": self.aic,
                "bic": self.bic,
                "misfit_floor": self.misfit_floor,
            },
            "converged": self.converged,
            "optimizer_message": self.optimizer_message,
            "n_fev": self.n_fev,
            "n_model_evals": self.n_model_evals,
            "stability": None if self.stability is None else self.stability.to_dict(),
            "v_ref_m_s": self.v_ref_m_s,
            "elapsed_s": self.elapsed_s,
            "spec": describe(self.spec),
            "record": {
                "name": self.record.name,
                "digest": self.record.digest(),
                "n": self.record.n,
                "n_steps": self.record.n_steps,
            },
        }
        if series:
            d["series"] = {
                "t_s": self.record.t_s,
                "v_lp_m_s": self.record.v_lp_m_s,
                "mu": self.record.mu,
                "model": self.model,
                "residuals": self.residuals,
                "step": self._step_index(),
                "used": None if self.used is None else self.used.tolist(),
            }
        out = jsonsafe(d)
        assert isinstance(out, dict)
        return out


# ---------------------------------------------------------------------------------------
# Coordinates
# ---------------------------------------------------------------------------------------
def _to_x(names: tuple[str, ...], p: Mapping[str, float]) -> NDArray[np.float64]:
    return np.array([math.log(p[n]) if n in _LOG else p[n] for n in names], dtype=np.float64)


def _from_x(names: tuple[str, ...], x: NDArray[np.float64]) -> dict[str, float]:
    return {
        n: (math.exp(float(v)) if n in _LOG else float(v)) for n, v in zip(names, x, strict=True)
    }


def _fd_steps(
    names: tuple[str, ...],
    x: NDArray[np.float64],
    lb: NDArray[np.float64],
    ub: NDArray[np.float64],
    inv_xlp: float = 1.0,
) -> NDArray[np.float64]:
    """Forward-difference steps: 1e-6 (relative for a, b; for the trend 1e-6 max(|trend|,
    a/x_lp_max), i.e. a friction change ~1e-6 a like the others), pointing away from a
    near bound.  ``inv_xlp`` is 1/(largest load-point displacement) [1/m]."""
    h = np.empty(len(names))
    a = x[names.index("a")]
    for j, n in enumerate(names):
        if n == "a":
            hj = _FD_STEP * abs(x[j])
        elif n == "b":
            hj = _FD_STEP * max(abs(x[j]), a)
        elif n == "trend_per_m":
            hj = _FD_STEP * max(abs(x[j]), a * inv_xlp)
        else:
            hj = _FD_STEP * (max(1.0, abs(x[j])) if n == "mu0" else 1.0)
        if x[j] + hj > ub[j]:
            hj = -hj
        h[j] = hj
    return h


# ---------------------------------------------------------------------------------------
# The fit
# ---------------------------------------------------------------------------------------
def _one_blas_thread() -> contextlib.AbstractContextManager[Any]:
    """Limit BLAS/LAPACK to one thread while fitting (threadpoolctl, when installed).

    The trust-region solver factorises a tall n x p Jacobian each iteration; multi-threaded
    OpenBLAS on a loaded machine made that 50 ms instead of 0.15 ms (measured, 2 cores),
    and a fit is serial anyway.
    """
    try:
        from threadpoolctl import threadpool_limits
    except ImportError:  # pragma: no cover - a dependency; tolerated if absent
        return contextlib.nullcontext()
    return threadpool_limits(limits=1, user_api="blas")


def _law(law: str | Law) -> Law:
    try:
        return Law(law)
    except ValueError:
        raise ParameterError("law", law, "one of " + ", ".join(m.value for m in Law)) from None


def fit_record(
    record: Record | str | Mapping[str, Any],
    law: str | Law = "aging",
    *,
    stiffness: float | None = None,
    fit_stiffness: bool | None = None,
    k_Pa_per_m: float | None = None,
    sigma_Pa: float | None = None,
    trend: bool = False,
    windows: Iterable[tuple[float, float]] | None = None,
    steps: Iterable[int] | None = None,
    nagata_c: float = 2.0,
    initial: Mapping[str, float] | None = None,
    bounds: Mapping[str, tuple[float, float]] | None = None,
    rtol: float = 1e-10,
    max_rel_stderr: float = 0.25,
    max_condition: float = 1e8,
    max_nonlinearity: float = 2.0,
    misfit_floor: float = 1e-9,
    uncertainty_samples: int = 400,
    seed: int = 0,
    max_nfev: int = 200,
    time_budget_s: float = TIME_BUDGET_S,
    stability: bool = True,
) -> FitResult:
    """Fit a velocity-step record for mu0, a, b, Dc [and eps, machine stiffness, trend].

    Args:
        record: a Record, or anything rsfcore.fit.read_record accepts (path, CSV/JSON
            text, mapping of columns t_s | x_lp_m, v_lp_m_s, mu).
        law: "aging" (eps = 1), "slip" (eps = 0), "nagata" (Nagata law with fixed
            ``nagata_c``; eps = b/(b + c a)), or "eps" (eps fitted in [0, 1]).
        stiffness: machine stiffness k in friction per metre of load-point displacement
            [1/m], > 0, or inf (an infinitely stiff machine: V follows the load point).
            With fit_stiffness it is the start value.
        fit_stiffness: fit k.  Default (None): fitted unless a stiffness is given
            (``stiffness`` or ``k_Pa_per_m``); False needs a stiffness.  The loading slope
            after a step determines k; a record that does not resolve it is
            ILL_CONDITIONED with the estimate and the options (docs/fitting.md).
        k_Pa_per_m: the stiffness in Pa/m instead (needs ``sigma_Pa``; k = k_Pa_per_m/sigma).
        sigma_Pa: normal stress [Pa], > 0: converts k_Pa_per_m, and the answer states the
            stiffnesses also in Pa/m.
        trend: fit a linear friction trend in load-point displacement (trend_per_m [1/m]);
            the stability answer uses the trend-free parameters.
        windows: (t_start, t_end) time windows [s, record time]: only samples inside enter
            the misfit (the model still runs through the whole record).
        steps: indices of constant-velocity segments (0 = before the first step, j = after
            the j-th step) whose samples enter the misfit.  With windows: both must hold.
        nagata_c: Nagata's c >= 0 (law "nagata"; Nagata et al. 2012 found c ~ 2).
        initial: start values overriding the automatic ones (keys of PARAM_NAMES).
        bounds: overrides of DEFAULT_BOUNDS, e.g. {"Dc_m": (1e-7, 1e-3)}.
        rtol: forward-model (engine) tolerance, [1e-13, 1e-6].
        max_rel_stderr: largest relative standard error of a, b, Dc, k (absolute for
            eps) for the parameter to count as determined, (0, inf).
        max_condition: largest condition number of the column-normalised Jacobian.
        max_nonlinearity: the misfit 2 standard errors away along each principal axis
            of the covariance must rise between 1/max_nonlinearity and max_nonlinearity
            times the quadratic prediction 4 sigma^2 (else the linearised uncertainties
            are not trusted and the fit is ILL_CONDITIONED), (1, inf).
        misfit_floor: friction misfit below which differences do not count (AIC/BIC).
        uncertainty_samples: covariance samples for the stability uncertainty, [0, 100000].
        seed: random seed of those samples (results are reproducible).
        max_nfev: budget of optimiser iterations' function evaluations.
        time_budget_s: wall-time budget of the optimiser [s], (0, 3600]; a fit that has not
            converged by then is NOT_CONVERGED (message: start or record at fault).
        stability: compute the stability answer (when the fit determines the parameters).

    Returns a FitResult (never raises for a record that fits badly: see ``status``).
    Raises ParameterError for invalid records or options.
    """
    with _one_blas_thread():
        return _fit_record(
            record,
            law,
            stiffness=stiffness,
            fit_stiffness=fit_stiffness,
            k_Pa_per_m=k_Pa_per_m,
            sigma_Pa=sigma_Pa,
            trend=trend,
            windows=windows,
            steps=steps,
            nagata_c=nagata_c,
            initial=initial,
            bounds=bounds,
            rtol=rtol,
            max_rel_stderr=max_rel_stderr,
            max_condition=max_condition,
            max_nonlinearity=max_nonlinearity,
            misfit_floor=misfit_floor,
            uncertainty_samples=uncertainty_samples,
            seed=seed,
            max_nfev=max_nfev,
            time_budget_s=time_budget_s,
            stability=stability,
        )


class _OutOfTime(Exception):
    """The fit's time budget ran out (raised from the residual function)."""


def _stiffness_choice(
    stiffness: float | None,
    fit_stiffness: bool | None,
    k_Pa_per_m: float | None,
    sigma_Pa: float | None,
) -> tuple[float, bool, str, float | None]:
    """(k fixed or start [1/m] (nan: none), fit k?, mode, sigma_Pa) from the options."""
    sig = None if sigma_Pa is None else check_range("sigma_Pa", sigma_Pa, 0.0, 1e12, lo_open=True)
    if k_Pa_per_m is not None:
        if stiffness is not None:
            raise ParameterError(
                "k_Pa_per_m", k_Pa_per_m, "given alone: either k_Pa_per_m or stiffness [1/m]"
            )
        kp = check_range("k_Pa_per_m", k_Pa_per_m, 0.0, None, lo_open=True)
        if sig is None:
            raise ParameterError(
                "sigma_Pa", None, "(0, 1e12] Pa with k_Pa_per_m (k [1/m] = k_Pa_per_m/sigma_Pa)"
            )
        stiffness = kp / sig
    if stiffness is None:
        if fit_stiffness is False:
            raise ParameterError(
                "fit_stiffness",
                False,
                "true or null unless a stiffness is given (stiffness [1/m], k_Pa_per_m with "
                "sigma_Pa, or inf for an infinitely stiff machine)",
            )
        return math.nan, True, "fitted", sig
    if isinstance(stiffness, (int, float)) and math.isinf(stiffness) and stiffness > 0:
        if fit_stiffness:
            raise ParameterError(
                "fit_stiffness", True, "false with stiffness = inf (an infinitely stiff machine)"
            )
        return math.inf, False, "rigid", sig
    k = check_range("stiffness", stiffness, 0.0, None, lo_open=True)
    fit = bool(fit_stiffness)
    return k, fit, "fitted" if fit else "fixed", sig


def _used_mask(
    rec: Record, windows: Iterable[tuple[float, float]] | None, steps: Iterable[int] | None
) -> NDArray[np.bool_] | None:
    if windows is None and steps is None:
        return None
    used = np.ones(rec.n, dtype=bool)
    if windows is not None:
        win = np.zeros(rec.n, dtype=bool)
        wl = list(windows)
        if not wl:
            raise ParameterError("windows", wl, "a non-empty list of (t_start_s, t_end_s)")
        for i, w in enumerate(wl):
            try:
                t0, t1 = (float(v) for v in w)
            except (TypeError, ValueError):
                raise ParameterError(f"windows[{i}]", w, "a (t_start_s, t_end_s) pair") from None
            if not t0 < t1:
                raise ParameterError(f"windows[{i}]", [t0, t1], "t_start_s < t_end_s")
            win |= (rec.t_s >= t0) & (rec.t_s <= t1)
        used &= win
    if steps is not None:
        sl = list(steps)
        starts = [int(i) for i in rec.segment_starts] + [rec.n]
        sel = np.zeros(rec.n, dtype=bool)
        if not sl:
            raise ParameterError("steps", sl, "a non-empty list of segment indices")
        for j in sl:
            if isinstance(j, bool) or not isinstance(j, (int, np.integer)):
                raise ParameterError("steps", j, "segment indices (integers)")
            if not 0 <= int(j) < len(starts) - 1:
                raise ParameterError(
                    "steps", int(j), f"[0, {len(starts) - 2}] (the record's {rec.n_steps} steps)"
                )
            sel[starts[int(j)] : starts[int(j) + 1]] = True
        used &= sel
    if int(used.sum()) < MIN_USED:
        raise ParameterError(
            "windows", int(used.sum()), f">= {MIN_USED} samples inside the windows / steps"
        )
    return used


#: Fewest samples the windows / step selection must leave.
MIN_USED = 10


def plausibility(rec: Record, params: Mapping[str, float]) -> list[str]:
    """Lab plausibility of a fit (unit slips): one sentence per implausible value, naming
    the likely slip.  Limits: PLAUSIBLE_DC_M, PLAUSIBLE_V_M_S, PLAUSIBLE_V_RATIO,
    PLAUSIBLE_MU."""
    out = []
    v = rec.v_lp_m_s
    vmax = float(np.max(v))
    pos = v[v > 0]
    vmin = float(np.min(pos))
    if vmax > PLAUSIBLE_V_M_S:
        unit = "um/s" if vmax >= 1.0 else "mm/s"
        out.append(
            f"load-point velocities {_num(vmin)}-{_num(vmax)} m/s (above 1 cm/s): is the "
            f"velocity column in {unit}?"
        )
    if vmax / vmin > PLAUSIBLE_V_RATIO:
        out.append(
            f"velocities from {_num(vmin)} to {_num(vmax)} m/s, a step by a factor "
            f"{_num(vmax / vmin)} (above 1e4): are all velocities in one unit?"
        )
    Dc = params.get("Dc_m", math.nan)
    if Dc > PLAUSIBLE_DC_M:
        out.append(
            f"Dc = {_num(Dc)} m (above a millimetre): is the time column in ms, or the "
            "velocity or displacement in um?"
        )
    mu0 = params.get("mu0", math.nan)
    if not PLAUSIBLE_MU[0] <= mu0 <= PLAUSIBLE_MU[1]:
        out.append(
            f"friction mu0 = {_num(mu0)} (outside [0, 3]): is the friction column a stress? "
            "(give shear and normal stress columns to form mu)"
        )
    return out


#: A given stiffness is contradicted by the record when the fit with k free determines a k
#: differing from it by more than this factor (either way; any finite k for a rigid
#: machine) and lowers the AIC by more than REJECT_DELTA_AIC.  5 %: on a 1201-sample
#: record (noise 1e-4, k = 1000 /m = 2 k_crit) a stiffness given 10 % high biased a by
#: +8.8 % at 3.4x the noise's misfit; the factor keeps forward-model-level differences
#: (an independent solver's record, k recovered to 1e-8) from ever counting.
STIFFNESS_MISMATCH = 1.05


def _stiffness_contradiction(
    mode: str, k_given: float, aic: float, free: FitResult, sigma_Pa: float | None
) -> str:
    """The sentence naming the record's stiffness when it contradicts the given one ("" if
    not): ``free`` is the same fit with k fitted (from the given k or the loading slope)."""
    if free.status not in (FitStatus.OK, FitStatus.SUSPECT) or not free.converged:
        return ""
    k = free.params["k_per_m"]
    d_aic = aic - free.aic
    if not (math.isfinite(k) and d_aic > REJECT_DELTA_AIC):
        return ""
    if mode != "rigid" and 1.0 / STIFFNESS_MISMATCH <= k / k_given <= STIFFNESS_MISMATCH:
        return ""
    se = free.stderr.get("k_per_m")
    est = f"k = {_num(k)}" + (f" +- {_num(se)}" if se is not None else "") + " /m"
    if sigma_Pa:
        est += f" (= {_num(k * sigma_Pa)} Pa/m)"
    given = (
        "an infinitely stiff machine (rigid)"
        if mode == "rigid"
        else f"the given stiffness k = {_num(k_given)} /m"
        + (f" (= {_num(k_given * sigma_Pa)} Pa/m)" if sigma_Pa else "")
    )
    option = (
        "give no stiffness to fit it (rigid_machine false; CLI without --rigid)"
        if mode == "rigid"
        else "fit it (fit_stiffness true; CLI --fit-stiffness), or check the machine's stiffness"
    )
    return (
        f"the record contradicts {given}: fitted with the stiffness free, {est}, the AIC is "
        f"{_num(d_aic)} units lower (beyond {_num(REJECT_DELTA_AIC)}); {option}."
    )


def _num(x: float) -> str:
    """A plain number for messages (4 significant digits, no numpy repr)."""
    return f"{float(x):.4g}"


def _fit_record(
    record: Record | str | Mapping[str, Any],
    law: str | Law,
    *,
    stiffness: float | None,
    fit_stiffness: bool | None,
    k_Pa_per_m: float | None,
    sigma_Pa: float | None,
    trend: bool,
    windows: Iterable[tuple[float, float]] | None,
    steps: Iterable[int] | None,
    nagata_c: float,
    initial: Mapping[str, float] | None,
    bounds: Mapping[str, tuple[float, float]] | None,
    rtol: float,
    max_rel_stderr: float,
    max_condition: float,
    max_nonlinearity: float,
    misfit_floor: float,
    uncertainty_samples: int,
    seed: int,
    max_nfev: int,
    time_budget_s: float,
    stability: bool,
    scans: StartScans | None = None,
    reject_above: tuple[float, float] | None = None,
) -> FitResult:
    t_start = time.perf_counter()
    rec = read_record(record)
    lw = _law(law)
    rtol = check_range("rtol", rtol, 1e-13, 1e-6)
    nagata_c = check_range("nagata_c", nagata_c, 0.0, 1e6)
    max_rel_stderr = check_range("max_rel_stderr", max_rel_stderr, 0.0, None, lo_open=True)
    max_condition = check_range("max_condition", max_condition, 1.0, None)
    max_nonlinearity = check_range("max_nonlinearity", max_nonlinearity, 1.0, None, lo_open=True)
    misfit_floor = check_range("misfit_floor", misfit_floor, 0.0, None)
    uncertainty_samples = int(check_range("uncertainty_samples", uncertainty_samples, 0, 100_000))
    max_nfev = int(check_range("max_nfev", max_nfev, 1, 100_000))
    time_budget_s = check_range("time_budget_s", time_budget_s, 0.0, 3600.0, lo_open=True)
    k_given, fit_k, mode, sig = _stiffness_choice(stiffness, fit_stiffness, k_Pa_per_m, sigma_Pa)
    windows = None if windows is None else list(windows)  # used twice (stiffness check)
    steps = None if steps is None else list(steps)
    used = _used_mask(rec, windows, steps)
    bnd = dict(DEFAULT_BOUNDS)
    if lw is Law.NAGATA:
        bnd["b"] = (1e-7, 1.0)
    if bounds:
        for key, val in bounds.items():
            if key not in PARAM_NAMES:
                raise ParameterError(f"bounds.{key}", val, "a key of " + ", ".join(PARAM_NAMES))
            try:
                lo, hi = (float(v) for v in val)
            except (TypeError, ValueError):
                raise ParameterError(f"bounds.{key}", val, "a (lower, upper) pair") from None
            if not lo < hi or (key in _LOG and not lo > 0.0):
                raise ParameterError(
                    f"bounds.{key}",
                    val,
                    "lower < upper" + (" and lower > 0" if key in _LOG else ""),
                )
            bnd[key] = (lo, hi)
    spec = ModelSpec(
        law=lw,
        fit_stiffness=fit_k,
        stiffness_per_m=k_given if not math.isnan(k_given) else math.inf,
        nagata_c=nagata_c,
        rtol=rtol,
        trend=bool(trend),
    )
    model = ForwardModel(rec, spec)
    names = spec.fitted
    warnings: list[str] = []

    # -- start ---------------------------------------------------------------------------
    p0 = initial_guess(rec, spec, bnd, used, scans)
    if spec.fit_stiffness and math.isfinite(k_given):
        p0["k_per_m"] = k_given
    user_start = bool(initial) or (spec.fit_stiffness and math.isfinite(k_given))
    if initial:
        for key, v0 in initial.items():
            if key not in PARAM_NAMES:
                raise ParameterError(f"initial.{key}", v0, "a key of " + ", ".join(PARAM_NAMES))
            p0[key] = check_range(f"initial.{key}", v0, None, None)
    lb = _to_x(names, {n: bnd[n][0] for n in names})
    ub = _to_x(names, {n: bnd[n][1] for n in names})
    span = ub - lb

    def start_x(p: Mapping[str, float]) -> NDArray[np.float64]:
        x = _to_x(names, {n: min(max(p[n], bnd[n][0]), bnd[n][1]) for n in names})
        return np.clip(x, lb + 1e-9 * span, ub - 1e-9 * span)

    x0 = start_x(p0)

    mu_data = rec.mu
    inv_xlp = 1.0 / max(float(np.max(np.abs(rec.load_point_m))), 1e-300)
    cache: dict[bytes, NDArray[np.float64]] = {}
    # (phi, ln theta) of complete runs by x, for the Jacobian at an evaluated point
    states: dict[bytes, tuple[NDArray[np.float64], NDArray[np.float64]]] = {}
    deadline = t_start + time_budget_s
    best: list[Any] = [math.inf, x0.copy()]

    def resid(x: NDArray[np.float64]) -> NDArray[np.float64]:
        key = x.tobytes()
        if key in cache:
            return cache[key]
        if time.perf_counter() > deadline:
            raise _OutOfTime
        p = model.full(_from_x(names, x))
        phi, lth, n_ok = model.states(*model.engine_params(p))
        m = p["mu0"] + p["a"] * phi + p["b"] * lth
        if p["trend_per_m"] != 0.0:
            m = m + p["trend_per_m"] * model.x_lp
        r = m - mu_data
        if len(states) > 8:
            states.clear()
        if n_ok == rec.n:
            states[key] = (phi, lth)
        if n_ok < rec.n:
            r[n_ok:] = _PENALTY
        bad = ~np.isfinite(r)
        if bad.any():
            r[bad] = _PENALTY
        if used is not None:
            r = r[used]
        if len(cache) > 64:
            cache.clear()
        cache[key] = r
        ss = float(r @ r)
        if ss < best[0]:
            best[0], best[1] = ss, x.copy()
        return r

    def runs_away(x: NDArray[np.float64]) -> bool:
        p = model.full(_from_x(names, x))
        if math.isinf(p["k_per_m"]):
            return False
        return model.friction(p)[1] < rec.n

    # A start that runs away (k at or below the critical stiffness of the start's a, b,
    # Dc) leaves the optimiser nothing to descend: move it to a stable machine (k fitted:
    # k = 10 k_crit; k fixed: b closer to a), and say so; if that fails too, stop at once.
    start_message = ""
    if runs_away(x0):
        p_bad = model.full(_from_x(names, x0))
        kc0 = (p_bad["b"] - p_bad["a"]) / p_bad["Dc_m"]
        described = (
            f"The start (a = {_num(p_bad['a'])}, b = {_num(p_bad['b'])}, Dc = "
            f"{_num(p_bad['Dc_m'])} m, k = {_num(p_bad['k_per_m'])} /m"
            + (f", k/k_crit = {_num(p_bad['k_per_m'] / kc0)}" if kc0 > 0 else "")
            + ") runs away"
        )
        p1 = dict(p0)
        if spec.fit_stiffness:
            p1["k_per_m"] = max(p_bad["k_per_m"], 10.0 * max(kc0, p_bad["a"] / p_bad["Dc_m"]))
        else:
            p1["b"] = min(p_bad["b"], p_bad["a"] + 0.5 * p_bad["k_per_m"] * p_bad["Dc_m"])
        x1 = start_x(p1)
        if not runs_away(x1):
            warnings.append(
                described
                + ("" if not user_start else " (the start given)")
                + f"; the fit started from a stable machine instead (k = "
                f"{_num(model.full(_from_x(names, x1))['k_per_m'])} /m, b = "
                f"{_num(model.full(_from_x(names, x1))['b'])})."
            )
            x0 = x1
        else:
            start_message = (
                described + ": the start is at fault, not necessarily the record. Give a start "
                "(initial) with the stiffness above the critical stiffness (b - a)/Dc, or "
                "fix the stiffness to the machine's measured value."
            )

    def jac(x: NDArray[np.float64]) -> NDArray[np.float64]:
        r0 = resid(x)
        base = states.get(x.tobytes())
        if base is not None and bool(np.all(np.isfinite(r0))):
            if time.perf_counter() > deadline:
                raise _OutOfTime
            Jm = model.jacobian(model.full(_from_x(names, x)), names, base)
            if Jm is not None and bool(np.all(np.isfinite(Jm))):
                return Jm if used is None else Jm[used]
        # a run that does not complete (penalised samples): differences in every coordinate
        h = _fd_steps(names, x, lb, ub, inv_xlp)
        J = np.empty((r0.shape[0], len(names)))
        for j in range(len(names)):
            xp = x.copy()
            xp[j] += h[j]
            J[:, j] = (resid(xp) - r0) / h[j]
        return J

    # A comparison's law that cannot come within REJECT_DELTA_AIC of the best law found so
    # far: stopped once that is certain (compare_laws, ``complete``).  reject_above is
    # (AIC threshold, misfit floor); certain when even the Gauss-Newton model's lowest
    # misfit, its predicted decrease taken _REJECT_SAFETY times, is above the threshold.
    stop_lower: list[float] = []

    def stop(rss_k: float, rss_lin: float, k: int) -> bool:
        if reject_above is None or k < 2:
            return False
        threshold, floor = reject_above
        nu = int(mu_data.shape[0] if used is None else int(used.sum()))
        low = max(rss_k - _REJECT_SAFETY * (rss_k - rss_lin), nu * floor**2)
        if not low > 0.0:
            return False
        if nu * math.log(low / nu) + 2.0 * (len(names) + 1) > threshold:
            stop_lower.append(low)
            return True
        return False

    out_of_time = False
    nfev = 0
    opt_message = ""
    opt_status = 0
    if start_message:
        x = x0
        opt_message = "the start runs away"
    else:
        try:
            sol = least_squares(
                resid,
                x0,
                jac=jac,
                bounds=(lb, ub),
                ftol=_TOL,
                xtol=_TOL,
                gtol=_TOL,
                max_nfev=max_nfev,
                stop=stop if reject_above is not None else None,
            )
            x, nfev, opt_message, opt_status = (
                sol.x,
                int(sol.nfev),
                str(sol.message),
                int(sol.status),
            )
        except _OutOfTime:
            out_of_time = True
            x = np.asarray(best[1])
            opt_message = f"time budget of {_num(time_budget_s)} s reached"
    # The budget bounds the optimisation; the Jacobian at the solution below is p + 1 more
    # forward runs (bounded), and an optimisation that ended just before the deadline must
    # not turn it into an escaping _OutOfTime.  resid reads `deadline` when called.
    deadline = math.inf
    stopped = opt_status == _STOPPED
    if stopped:
        opt_message = "stopped once the law comparison's rejection was certain"
    p_hat = model.full(_from_x(names, x))
    mu_model, n_ok = model.friction(p_hat)
    complete = n_ok == rec.n
    r = mu_model - mu_data
    if not complete:
        r[n_ok:] = np.nan
    ru = r if used is None else r[used]

    # -- accuracy of the forward model at the solution ------------------------------------
    if stopped:
        model_acc = math.nan  # not polished: no accuracy claim (and no share in the floor)
    elif math.isinf(p_hat["k_per_m"]):
        model_acc = 1e-15 * float(np.max(np.abs(mu_data)))
    else:
        tight = ForwardModel(
            rec,
            ModelSpec(
                lw,
                spec.fit_stiffness,
                spec.stiffness_per_m,
                spec.nagata_c,
                max(1e-14, rtol * 1e-2),
                spec.trend,
            ),
        )
        mu_t, n_t = tight.friction(p_hat)
        model_acc = (
            float(np.max(np.abs(mu_t[: min(n_t, n_ok)] - mu_model[: min(n_t, n_ok)])))
            if min(n_t, n_ok)
            else math.inf
        )

    # -- statistics --------------------------------------------------------------------
    n, p = int(ru.shape[0]), len(names)
    rss = float(np.sum(ru[np.isfinite(ru)] ** 2)) if complete else math.inf
    rms = math.sqrt(rss / n) if complete else math.inf
    sigma = math.sqrt(rss / max(1, n - p)) if complete else math.inf
    sigma_eff = sigma if stopped else max(sigma, model_acc)
    floor_rss = n * misfit_floor**2
    rss_eff = max(rss, floor_rss)
    aic = n * math.log(rss_eff / n) + 2.0 * (p + 1) if complete else math.inf
    bic = n * math.log(rss_eff / n) + (p + 1) * math.log(n) if complete else math.inf

    cov = np.full((p, p), np.nan)
    corr = np.full((p, p), np.nan)
    stderr: dict[str, float | None] = {nm: None for nm in names}
    identified = {nm: False for nm in names}
    cond: float | None = None
    linearity: tuple[float, float] | None = None
    problems: list[str] = []
    if complete and not out_of_time and not start_message and not stopped:
        J = jac(x)
        norms = np.sqrt(np.sum(J**2, axis=0))
        dead = [names[j] for j in range(p) if not norms[j] > 1e-300]
        if dead:
            cond = None
            problems.append(
                f"{', '.join(dead)} {'has' if len(dead) == 1 else 'have'} no effect on the "
                "model for this record"
            )
        else:
            Jn = J / norms
            _, S, Vt = np.linalg.svd(Jn, full_matrices=False)
            cond = float(S[0] / S[-1]) if S[-1] > 0 else None
            if S[-1] > 0:
                cov_n = (Vt.T / S**2) @ Vt
                cov = sigma_eff**2 * cov_n / np.outer(norms, norms)
                sd = np.sqrt(np.diag(cov))
                corr = cov / np.outer(sd, sd)
                for j, nm in enumerate(names):
                    stderr[nm] = float(sd[j]) * (p_hat[nm] if nm in _LOG else 1.0)
            if cond is None or cond > max_condition:
                weak = [names[j] for j in range(p) if abs(Vt[-1, j]) > 0.3]
                problems.append(
                    f"{', '.join(weak)} cannot be separated (Jacobian condition number "
                    f"{'inf' if cond is None else f'{cond:.3g}'} > {max_condition:.3g})"
                )
                dead = weak
        for j, nm in enumerate(names):
            ok = nm not in dead and stderr[nm] is not None
            if ok and nm != "mu0":
                se = stderr[nm]
                assert se is not None
                if nm == "eps":
                    rel = se
                elif nm == "b":
                    rel = se / max(abs(p_hat["b"]), p_hat["a"])
                else:
                    rel = se / abs(p_hat[nm])
                if not rel <= max_rel_stderr:
                    ok = False
                    what = "standard error" if nm == "eps" else "relative standard error"
                    problems.append(
                        f"{nm} is not constrained ({what} {rel:.3g} > {max_rel_stderr:.3g})"
                    )
            if nm in ("a", "b", "Dc_m", "k_per_m"):
                tol = 1e-6 * (ub[j] - lb[j])
                if x[j] <= lb[j] + tol or x[j] >= ub[j] - tol:
                    ok = False
                    side = "lower" if x[j] <= lb[j] + tol else "upper"
                    problems.append(
                        f"{nm} ended on its {side} bound {bnd[nm][0 if side == 'lower' else 1]:g}"
                    )
            identified[nm] = ok
        # Is the misfit quadratic out to 2 standard errors?  Along each principal axis of
        # the covariance the increase of RSS at +-2 sd must be 4 sigma^2 for a linear
        # model; the ratio measures how far the linearised uncertainty can be trusted.
        if np.all(np.isfinite(cov)) and sigma > 2.0 * model_acc:
            ratio_lo, ratio_hi, culprits = _linearity(resid, names, x, cov, rss, sigma, lb, ub)
            linearity = (ratio_lo, ratio_hi)
            if ratio_lo < 1.0 / max_nonlinearity or ratio_hi > max_nonlinearity:
                problems.append(
                    f"{', '.join(culprits)} {'is' if len(culprits) == 1 else 'are'} not "
                    "determined within the linear approximation (the misfit rises "
                    f"{ratio_lo:.3g} to {ratio_hi:.3g} times the quadratic prediction "
                    "2 standard errors away; allowed "
                    f"1/{max_nonlinearity:g} to {max_nonlinearity:g})"
                )
                for nm in culprits:
                    identified[nm] = False

    converged = 0 < opt_status < _STOPPED
    if stopped and complete:
        status = FitStatus.REJECTED
        message = (
            f"Stopped after {nfev} evaluations, once the law comparison's rejection was "
            "certain: parameters not polished, no standard errors."
        )
    elif start_message:
        status = FitStatus.FAILED
        message = start_message
    elif out_of_time:
        status = FitStatus.NOT_CONVERGED
        message = (
            f"The fit stopped at its time budget of {_num(time_budget_s)} s after "
            f"{model.n_evals} forward runs without converging"
            + (
                " (the best parameters found do not reproduce the whole record: trial slip "
                "ran away; the record may show stick-slip)"
                if not complete
                else ""
            )
            + ". "
            + (
                "The start was moved because it ran away: give a better start (initial) or "
                "fix the stiffness."
                if warnings
                else "Give start values (initial), fix the law or the stiffness, or select "
                "the steps to fit (windows, steps); time_budget_s raises the budget."
            )
        )
    elif not complete:
        status = FitStatus.FAILED
        message = (
            "The forward model could not reproduce the record at the best parameters found "
            "(trial slip ran away or exceeded the step budget); the record may show stick-slip."
        )
    elif problems:
        status = FitStatus.ILL_CONDITIONED
        message = (
            "The record does not determine all parameters: "
            + "; ".join(problems)
            + ". "
            + _advice(rec, names, problems, mode, p_hat, sig)
        )
        slips = plausibility(rec, p_hat)
        if slips:
            warnings.extend(slips)
            message += " Also implausible for a lab: " + " ".join(slips)
    elif not converged:
        status = FitStatus.NOT_CONVERGED
        message = (
            f"The optimiser stopped after {nfev} evaluations without converging ({opt_message})."
        )
    else:
        status = FitStatus.OK
        message = f"Converged: rms misfit {rms:.3g} over {n} samples with {p} fitted parameters."
        slips = plausibility(rec, p_hat)
        if slips:
            status = FitStatus.SUSPECT
            warnings.extend(slips)
            message = "Suspect (values implausible for a lab): " + " ".join(slips) + " " + message

    # A stiffness the user gave (or a rigid machine) that the record contradicts: refit
    # with k free from this solution; a clearly different k that the record determines
    # and prefers by more than REJECT_DELTA_AIC makes the fit SUSPECT (never a plain ok).
    if (
        mode != "fitted"
        and complete
        and converged
        and not out_of_time
        and not start_message
        and status in (FitStatus.OK, FitStatus.SUSPECT, FitStatus.ILL_CONDITIONED)
    ):
        start = {nm: p_hat[nm] for nm in names}
        free = _fit_record(
            rec,
            lw,
            stiffness=None if mode == "rigid" else k_given,
            fit_stiffness=True,
            k_Pa_per_m=None,
            sigma_Pa=sig,
            trend=trend,
            windows=windows,
            steps=steps,
            nagata_c=nagata_c,
            initial=start,
            bounds=bounds,
            rtol=rtol,
            max_rel_stderr=max_rel_stderr,
            max_condition=max_condition,
            max_nonlinearity=max_nonlinearity,
            misfit_floor=misfit_floor,
            uncertainty_samples=0,
            seed=seed,
            max_nfev=max_nfev,
            time_budget_s=max(1e-3, t_start + time_budget_s - time.perf_counter()),
            stability=False,
            scans=scans,
        )
        why = _stiffness_contradiction(mode, k_given, aic, free, sig)
        if why:
            warnings.append(why)
            if status is FitStatus.OK:
                status = FitStatus.SUSPECT
                message = "Suspect (the machine stiffness is contradicted by the record): " + why
                message += f" Converged: rms misfit {rms:.3g} over {n} samples with {p} fitted"
                message += " parameters."
            else:
                message = why[0].upper() + why[1:] + " " + message

    params = dict(p_hat)
    params["b_minus_a"] = p_hat["b"] - p_hat["a"]
    if lw is Law.NAGATA and p_hat["eps"] > 0 and p_hat["b"] > 0:
        nag = intermediate_to_nagata(p_hat["a"], p_hat["b"], p_hat["Dc_m"], p_hat["eps"])
        params.update({"aN": nag["aN"], "bN": nag["bN"], "DcN_m": nag["DcN"], "cN": nag["cN"]})
    if sig is not None:
        params["k_Pa_per_m"] = p_hat["k_per_m"] * sig

    res = FitResult(
        status=status,
        message=message,
        law=lw.value,
        params=params,
        fitted=names,
        stderr=stderr,
        correlation=corr,
        covariance=cov,
        identified=identified,
        condition_number=cond,
        linearity=linearity,
        residuals=r,
        model=mu_model,
        rss=rss,
        rms=rms,
        sigma=sigma_eff,
        model_accuracy=model_acc,
        n=n,
        n_params=p,
        aic=aic,
        bic=bic,
        misfit_floor=misfit_floor,
        converged=converged,
        optimizer_message=opt_message,
        n_fev=nfev,
        n_model_evals=model.n_evals,
        stability=None,
        v_ref_m_s=rec.v_ref_m_s,
        elapsed_s=time.perf_counter() - t_start,
        record=rec,
        spec=spec,
        warnings=warnings,
        stiffness_mode=mode,
        sigma_Pa=sig,
        used=used,
        stopped_early=stopped,
        rss_lower_bound=stop_lower[-1] if stopped and stop_lower else None,
        x_internal=x,
        bounds_internal=(lb, ub),
    )
    if status in STABILITY_STATUSES and stability:
        attach_stability(res, uncertainty_samples=uncertainty_samples, seed=seed)
    res.elapsed_s = time.perf_counter() - t_start
    return res


def attach_stability(
    res: FitResult, *, uncertainty_samples: int = 400, seed: int = 0
) -> StabilityAnswer | None:
    """Compute (or recompute) ``res.stability`` from the fit's parameters and covariance.

    For the statuses in STABILITY_STATUSES (an ill-conditioned, unconverged or failed fit
    gets no stability answer: None; nor does a fit stopped early by a comparison).
    SUSPECT and REJECTED fits get it with their warning
    (``StabilityAnswer.warning``, also leading its message).  The trend (trend_per_m)
    does not enter: stability uses a, b, Dc, eps and k.
    """
    if res.status not in STABILITY_STATUSES or res.stopped_early:
        res.stability = None
        return None
    model = ForwardModel(res.record, res.spec)
    samples = _draw(res.fitted, res.x_internal, res.covariance, model, uncertainty_samples, seed)
    full = {k: res.params[k] for k in PARAM_NAMES}
    warning = None
    if res.status is not FitStatus.OK:
        warning = f"{res.status.value.upper()}: " + " ".join(res.warnings)
    res.stability = stability_answer(
        full,
        samples,
        v_ref_m_s=res.v_ref_m_s,
        stiffness_fitted=res.spec.fit_stiffness,
        sigma_Pa=res.sigma_Pa,
        warning=warning,
    )
    return res.stability


def _linearity(
    resid: Any,
    names: tuple[str, ...],
    x: NDArray[np.float64],
    cov: NDArray[np.float64],
    rss: float,
    sigma: float,
    lb: NDArray[np.float64],
    ub: NDArray[np.float64],
) -> tuple[float, float, list[str]]:
    """(min, max) over principal axes and both signs of [RSS(x +- 2 sd axis) - RSS]/(4 sigma^2),
    and the names of the parameters the worst axis moves by more than one standard error.
    Moves that would leave the bounds are skipped."""
    w, U = np.linalg.eigh(0.5 * (cov + cov.T))
    sd = np.sqrt(np.maximum(np.diag(cov), 1e-300))
    lo, hi = math.inf, -math.inf
    worst, worst_dev = 0, -1.0
    for j in range(w.shape[0]):
        d = 2.0 * math.sqrt(max(w[j], 0.0)) * U[:, j]
        for sgn in (1.0, -1.0):
            xs = x + sgn * d
            if np.any(xs < lb) or np.any(xs > ub):
                continue
            r = resid(xs)
            rho = (float(r @ r) - rss) / (4.0 * sigma**2)
            lo, hi = min(lo, rho), max(hi, rho)
            dev = abs(math.log(rho)) if rho > 0 else math.inf
            if dev > worst_dev:
                worst, worst_dev = j, dev
    d = 2.0 * math.sqrt(max(w[worst], 0.0)) * U[:, worst]
    culprits = [names[i] for i in range(len(names)) if abs(d[i]) / sd[i] > 1.0] or list(names)
    if not math.isfinite(lo):
        lo = hi = 1.0
    return lo, hi, culprits


def _draw(
    names: tuple[str, ...],
    x: NDArray[np.float64],
    cov: NDArray[np.float64],
    model: ForwardModel,
    n: int,
    seed: int,
) -> list[dict[str, float]]:
    """n parameter sets from N(x, cov) in the fitted coordinates; eps clipped to [0, 1]."""
    if n <= 0 or not np.all(np.isfinite(cov)):
        return []
    rng = np.random.default_rng(seed)
    # symmetric square root (cov may be semi-definite to rounding)
    w, U = np.linalg.eigh(0.5 * (cov + cov.T))
    L = U * np.sqrt(np.maximum(w, 0.0))
    xs = x + rng.standard_normal((n, len(names))) @ L.T
    out = []
    for xi in xs:
        q = _from_x(names, xi)
        if "eps" in q:
            q["eps"] = min(1.0, max(0.0, q["eps"]))
        if not q["a"] > 0.0:
            continue
        if model.spec.law is Law.NAGATA and not q["b"] > 0.0:
            continue
        out.append(model.full(q))
    return out


def _advice(
    rec: Record,
    names: tuple[str, ...],
    problems: list[str],
    mode: str = "fixed",
    p_hat: Mapping[str, float] | None = None,
    sigma_Pa: float | None = None,
) -> str:
    txt = " ".join(problems)
    if rec.n_steps == 0:
        return (
            "The record has no velocity step: a, b and Dc need at least one step in "
            "load-point velocity."
        )
    advice = []
    if "Dc_m" in txt:
        advice.append(
            "Dc needs the friction transient after a velocity step to be resolved: a step "
            "followed by load-point displacement of several Dc, sampled densely during the "
            "evolution."
        )
    if "k_per_m" in txt:
        est = ""
        if p_hat is not None and math.isfinite(p_hat.get("k_per_m", math.inf)):
            k = p_hat["k_per_m"]
            est = f" (best estimate k = {_num(k)} /m" + (
                f" = {_num(k * sigma_Pa)} Pa/m)" if sigma_Pa else ")"
            )
        lead = (
            "No stiffness was given, so it was fitted, and the record does not resolve it"
            if mode == "fitted"
            else "The machine stiffness is not resolved"
        )
        advice.append(
            f"{lead}{est}: it shows only in the elastic loading right after a step "
            "(duration ~ a/(k dv)). Sample that loading densely, or give the machine's "
            "stiffness (k_Pa_per_m with sigma_Pa, or stiffness [1/m]; CLI --k-pa-per-m "
            "--sigma-pa or --stiffness), or stiffness=inf (CLI --rigid) for a machine much "
            "stiffer than the sample."
        )
    if "eps" in txt:
        advice.append("eps needs steps up and down with evolution over several Dc; or fix the law.")
    if not advice:
        advice.append("Add steps or longer records, or fix some parameters (law, stiffness).")
    return " ".join(advice)


# ---------------------------------------------------------------------------------------
# Law comparison
# ---------------------------------------------------------------------------------------
@dataclass(frozen=True)
class LawScore:
    """One law's entry in a comparison (misfit and information criteria)."""

    law: str
    status: str
    rms: float
    n_params: int
    aic: float
    bic: float
    delta_aic: float
    delta_bic: float
    akaike_weight: float

    def to_dict(self) -> dict[str, Any]:
        out = jsonsafe(self.__dict__)
        assert isinstance(out, dict)
        return out


@dataclass
class LawComparison:
    """Fits of one record under several laws.

    Attributes:
        best: the law with the lowest AIC among converged fits (None if none converged).
        scores: LawScore per law (AIC/BIC recomputed with one common misfit floor).
        fits: FitResult per law.
        misfit_floor: the common floor (friction).
    """

    best: str | None
    scores: list[LawScore]
    fits: dict[str, FitResult]
    misfit_floor: float

    def to_dict(self, *, series: bool = False) -> dict[str, Any]:
        return {
            "best": self.best,
            "misfit_floor": self.misfit_floor,
            "scores": [s.to_dict() for s in self.scores],
            "fits": {k: v.to_dict(series=series) for k, v in self.fits.items()},
        }


#: fit_record's keyword options and their defaults (compare_laws passes them on).
_FIT_OPTIONS: dict[str, Any] = {
    k: v.default
    for k, v in inspect.signature(fit_record).parameters.items()
    if v.kind is inspect.Parameter.KEYWORD_ONLY
}


def _usable(f: FitResult) -> bool:
    """A comparison's fit that competes for best: converged, complete, determined or not."""
    return (
        f.status in (FitStatus.OK, FitStatus.SUSPECT, FitStatus.ILL_CONDITIONED)
        and f.converged
        and math.isfinite(f.rss)
    )


def _criteria(f: FitResult, floor: float) -> tuple[float, float]:
    """(AIC, BIC) of a fit with the misfit floored at ``floor`` (inf without a misfit)."""
    if not math.isfinite(f.rss):
        return math.inf, math.inf
    rss_eff = max(f.rss, f.n * floor**2)
    k = f.n_params + 1
    return f.n * math.log(rss_eff / f.n) + 2.0 * k, f.n * math.log(rss_eff / f.n) + k * math.log(
        f.n
    )


def _floor(fits: Iterable[FitResult], misfit_floor: float) -> float:
    """The common misfit floor: max(misfit_floor, 10 x the largest model accuracy)."""
    return max(
        [misfit_floor] + [10.0 * f.model_accuracy for f in fits if math.isfinite(f.model_accuracy)]
    )


def _reject_threshold(fits: Iterable[FitResult], misfit_floor: float) -> tuple[float, float] | None:
    """(AIC above which a law is rejected, floor) from the fits so far; None when no fit
    competes yet or the best one's misfit is within _REJECT_FLOOR_MARGIN of the floor."""
    done = list(fits)
    floor = _floor(done, misfit_floor)
    usable = [f for f in done if _usable(f)]
    if not usable:
        return None
    best = min(usable, key=lambda f: _criteria(f, floor)[0])
    if not best.rms >= _REJECT_FLOOR_MARGIN * floor:
        return None
    return _criteria(best, floor)[0] + REJECT_DELTA_AIC, floor


def compare_laws(
    record: Record | str | Mapping[str, Any],
    laws: Iterable[str | Law] = ("aging", "slip", "nagata", "eps"),
    *,
    complete: Iterable[str | Law] | None = None,
    **options: Any,
) -> LawComparison:
    """Fit ``record`` with each law (same options as :func:`fit_record`) and rank them by AIC.

    The common misfit floor is max(misfit_floor, 10 x the largest forward-model accuracy of
    the fits), so that misfit differences the model cannot resolve do not decide; then the
    law with fewer parameters wins.  Stability answers are computed only for the best law.

    Shared work: the start scan (rsfcore.fit.start) is computed once for all laws, and
    BLAS is limited to one thread once.  Each law starts from its own start values, as
    fit_record would (a warm start of the eps law from the aging solution took 3x fewer
    forward runs but ended noise-free records' eps fits at a better minimum, turning
    their ``ill_conditioned`` into ``ok``: verdicts that must not change).

    complete: the laws fitted to convergence whatever their score (default None: every
    law).  The others are stopped as soon as their rejection is certain: after at least
    2 iterations, when their AIC would stay more than REJECT_DELTA_AIC above the best
    (completely fitted) law's so far even if the misfit fell by _REJECT_SAFETY (10) times
    what the Gauss-Newton model at the iterate still predicts (measured: the decrease
    still to come was at most 2.1x that prediction), on records whose best misfit is
    above 1000x the misfit floor.  Such a fit is REJECTED with ``stopped_early`` (its
    parameters are the optimiser's iterate, not polished; no standard errors, no stability
    answer; its score's AIC is that of the iterate, an upper bound).  The best law is
    never stopped (it is never rejected), so every reported best fit is complete; the
    CLI and HTTP fits pass the requested law (if any) here so that it is complete too.
    """
    rec = read_record(record)
    lws = [_law(x) for x in laws]
    if not lws:
        raise ParameterError(
            "laws", list(laws), "a non-empty list of " + ", ".join(m.value for m in Law)
        )
    keep = None if complete is None else {_law(x) for x in complete}
    want_stab = options.pop("stability", True)
    unknown = sorted(set(options) - set(_FIT_OPTIONS))
    if unknown:
        raise TypeError(f"compare_laws() got an unexpected keyword argument {unknown[0]!r}")
    kw = {**_FIT_OPTIONS, **options, "stability": False}
    misfit_floor = float(kw["misfit_floor"])
    scans = StartScans()  # the start grid, shared by the laws
    fits: dict[str, FitResult] = {}
    with _one_blas_thread():
        for lw in lws:
            reject = None
            if keep is not None and lw not in keep:
                reject = _reject_threshold(fits.values(), misfit_floor)
            fits[lw.value] = _fit_record(rec, lw, scans=scans, reject_above=reject, **kw)
    floor = _floor(fits.values(), misfit_floor)
    rows = [(name, f, *_criteria(f, floor)) for name, f in fits.items()]
    usable = [r for r in rows if _usable(r[1])]
    best = min(usable, key=lambda r: (r[2], r[1].n_params))[0] if usable else None
    amin = min((r[2] for r in usable), default=math.inf)
    bmin = min((r[3] for r in usable), default=math.inf)
    wsum = sum(math.exp(-0.5 * (r[2] - amin)) for r in usable) if usable else 0.0
    if best is not None:
        for name, f, aic, _ in rows:
            d_aic = aic - amin
            if f.stopped_early:
                low = f.rss_lower_bound if f.rss_lower_bound is not None else f.rss
                d_low = _criteria(replace(f, rss=low), floor)[0] - amin
                why = (
                    f"the {name} law is rejected by the record: its AIC is at least "
                    f"{_num(d_low)} units above the {best} law's (rejected beyond "
                    f"{_num(REJECT_DELTA_AIC)}); the record supports the {best} law."
                )
                f.warnings.append(why)
                f.message = "Rejected: " + why + " " + f.message
            elif (
                name != best
                and f.status in (FitStatus.OK, FitStatus.SUSPECT)
                and (d_aic > REJECT_DELTA_AIC)
            ):
                why = (
                    f"the {name} law is rejected by the record: its AIC is {_num(d_aic)} units "
                    f"above the {best} law's (rejected beyond {_num(REJECT_DELTA_AIC)}); the "
                    f"record supports the {best} law."
                )
                f.status = FitStatus.REJECTED
                f.warnings.append(why)
                f.message = "Rejected: " + why + " " + f.message
                if f.stability is not None:
                    attach_stability(
                        f,
                        uncertainty_samples=options.get("uncertainty_samples", 400),
                        seed=options.get("seed", 0),
                    )
    scores = []
    for name, f, aic, bic in rows:
        use = any(r[0] == name for r in usable)
        scored = use or f.stopped_early
        scores.append(
            LawScore(
                law=name,
                status=f.status.value,
                rms=f.rms,
                n_params=f.n_params,
                aic=aic,
                bic=bic,
                delta_aic=aic - amin if scored else math.inf,
                delta_bic=bic - bmin if scored else math.inf,
                akaike_weight=math.exp(-0.5 * (aic - amin)) / wsum if use and wsum > 0 else 0.0,
            )
        )
    if best is not None and want_stab and fits[best].status in STABILITY_STATUSES:
        attach_stability(
            fits[best],
            uncertainty_samples=options.get("uncertainty_samples", 400),
            seed=options.get("seed", 0),
        )
    return LawComparison(best=best, scores=scores, fits=fits, misfit_floor=floor)
