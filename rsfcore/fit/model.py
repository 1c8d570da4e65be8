"""Forward model of a lab record: the spring-slider under a piecewise-constant imposed
load-point velocity, for the aging-to-slip law family, in SI units.

Physics (textbook form, lab stiffness convention):

    mu = mu0 + a ln(V/V0) + b ln(V0 theta/Dc)              `eq: rate and state friction`
    d theta/dt = G(L) V theta/Dc,  L = ln(V theta/Dc),      `eq: intermediate state evolution law`
    G(L) = expm1(-eps L)/eps  (eps = 1 aging: 1 - V theta/Dc; eps -> 0 slip: -L V theta/Dc)
    d mu/dt = k (v_lp - V)                                  `eq: equation of motion2`

with V0 = v_lp[0] (the record starts in steady state at V0: V = V0, theta = Dc/V0,
mu = mu0) and k the machine stiffness in friction per metre of load-point displacement
[1/m] (k [Pa/m] / sigma).  In the groups of `eq: characteristic scales` with V_* = V0 and
f_* = mu0 this is exactly the system integrated by rsfcore.engine.run with
b/a, kappa = k Dc/a, v_o = v_lp/V0, T = V0 t/Dc, psi = (mu - mu0)/a, so the record is
simulated segment by segment by the compiled DOP853 engine, sampled at the record's
times on its 7th-order dense output.

Infinitely stiff machine (k = inf): V = v_lp at all times, and with V constant on a
segment the law has the closed form (w = e^(eps L)):  w(t) = 1 + (w0 - 1) e^(-V t/Dc),
i.e. L = log1p(expm1(eps L0) e^(-V t/Dc))/eps, and L = L0 e^(-V t/Dc) at eps = 0.

Nagata law (Nagata et al. 2012) with fixed c: by rsfcore.laws.nagata_to_intermediate it
is the intermediate law with eps = b/(b + c a) (a, b, Dc the intermediate-law values).

Accuracy (tests/core/test_fit.py, bench/bench_fit.py): at the default rtol = 1e-10 the
friction is within 3e-11 of an rtol = 1e-13 run for a velocity step with a = 0.01.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from enum import StrEnum
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..engine import EngineOptions, Status, run
from ..params import ParameterError
from .record import Record

__all__ = [
    "Law",
    "LAWS",
    "PARAM_NAMES",
    "ModelSpec",
    "ForwardModel",
    "Simulation",
    "nagata_eps",
    "synthetic_record",
    "describe",
]


class Law(StrEnum):
    """Evolution law of a fit: aging (eps = 1), slip (eps = 0), Nagata (fixed c), or eps free."""

    AGING = "aging"
    SLIP = "slip"
    NAGATA = "nagata"
    EPS = "eps"


LAWS: tuple[str, ...] = tuple(m.value for m in Law)

#: All model parameters, in order; the fitted ones are a subset.  ``trend_per_m`` is the
#: optional linear friction trend in load-point displacement [1/m] (0 unless fitted).
PARAM_NAMES: tuple[str, ...] = ("mu0", "a", "b", "Dc_m", "eps", "k_per_m", "trend_per_m")

#: Blow-up threshold on ln(V/V0) for a trial parameter set that runs away.
_PHI_STOP = 40.0
#: Step budget per segment (a trial set deep in stick-slip must not hang a fit).
_MAX_STEPS = 400_000
_EMPTY = np.empty(0)


def nagata_eps(a: float, b: float, c: float) -> float:
    """eps = b/(b + c a) of the Nagata law with stress-rate coefficient c >= 0 (a, b > 0).

    From rsfcore.laws.nagata_to_intermediate: eps = 1 - aN c/((1 + c) bN) with
    aN = a (1 + c), bN = b/eps, solved for eps.
    """
    return b / (b + c * a)


@dataclass(frozen=True)
class ModelSpec:
    """What is fitted and what is fixed.

    Attributes:
        law: Law.
        fit_stiffness: fit k_per_m (else fixed at ``stiffness_per_m``).
        stiffness_per_m: fixed machine stiffness [1/m], > 0 or inf (infinitely stiff).
        nagata_c: Nagata's c (>= 0) for law "nagata".
        rtol: engine tolerance.
        trend: fit a linear friction trend in load-point displacement, mu += trend_per_m x_lp
            (slip hardening > 0 or weakening < 0; the usual detrending term of the field).
    """

    law: Law
    fit_stiffness: bool
    stiffness_per_m: float
    nagata_c: float = 2.0
    rtol: float = 1e-10
    trend: bool = False

    @property
    def fitted(self) -> tuple[str, ...]:
        names = ["mu0", "a", "b", "Dc_m"]
        if self.law is Law.EPS:
            names.append("eps")
        if self.fit_stiffness:
            names.append("k_per_m")
        if self.trend:
            names.append("trend_per_m")
        return tuple(names)

    @property
    def log_params(self) -> tuple[str, ...]:
        """Parameters fitted through their logarithm (positive, scale-free)."""
        return ("Dc_m", "k_per_m")


@dataclass
class Simulation:
    """Forward-model output at the record's samples (SI).

    Attributes:
        mu: friction (-); V_m_s: slip rate [m/s]; theta_s: state [s]; complete: False when
        the trial parameters ran away or exhausted the step budget before the record's end
        (the missing samples are then NaN here); n_steps: engine steps.
    """

    mu: NDArray[np.float64]
    V_m_s: NDArray[np.float64]
    theta_s: NDArray[np.float64]
    complete: bool
    n_steps: int


class ForwardModel:
    """The record's forward model for a ModelSpec; parameters are dicts keyed by PARAM_NAMES."""

    def __init__(self, record: Record, spec: ModelSpec) -> None:
        self.record = record
        self.spec = spec
        self.V0 = record.v_ref_m_s
        self.t = record.t_s - record.t_s[0]
        self.starts = [int(i) for i in record.segment_starts]
        self.ends = self.starts[1:] + [record.n]
        self.v_seg = [float(record.v_lp_m_s[i]) for i in self.starts]
        self.x_lp = record.load_point_m
        if not spec.fit_stiffness and math.isinf(spec.stiffness_per_m) and min(self.v_seg) <= 0.0:
            i = int(np.flatnonzero(record.v_lp_m_s <= 0.0)[0])
            raise ParameterError(
                f"record.v_lp_m_s[{i}]",
                0.0,
                "> 0 with an infinitely stiff machine (a hold needs a finite stiffness)",
            )
        self.n_evals = 0

    # -- parameters -----------------------------------------------------------------
    def full(self, fitted: dict[str, float]) -> dict[str, float]:
        """All six parameters from the fitted ones plus the fixed choices of the spec."""
        p = dict(fitted)
        law = self.spec.law
        if law is Law.AGING:
            p["eps"] = 1.0
        elif law is Law.SLIP:
            p["eps"] = 0.0
        elif law is Law.NAGATA:
            p["eps"] = nagata_eps(p["a"], p["b"], self.spec.nagata_c) if p["b"] > 0.0 else 1.0
        if not self.spec.fit_stiffness:
            p["k_per_m"] = self.spec.stiffness_per_m
        if not self.spec.trend:
            p["trend_per_m"] = 0.0
        return p

    def _trend(self, p: dict[str, float]) -> NDArray[np.float64] | float:
        c = p.get("trend_per_m", 0.0)
        return c * self.x_lp if c != 0.0 else 0.0

    # -- evaluation -------------------------------------------------------------------
    def engine_params(self, p: dict[str, float]) -> tuple[float, float, float, float]:
        """(b/a, kappa = k Dc/a, eps, s = V0/Dc [1/s]): all the dimensionless states depend on.

        phi = ln(V/V0) and ln(V0 theta/Dc) at the samples are functions of these four
        (T = s t); the friction is mu0 + a phi + b ln(V0 theta/Dc) + trend x_lp.
        kappa is inf for an infinitely stiff machine."""
        a = p["a"]
        return p["b"] / a, p["k_per_m"] * p["Dc_m"] / a, p["eps"], self.V0 / p["Dc_m"]

    def states(
        self, ba: float, kappa: float, eps: float, scale: float
    ) -> tuple[NDArray[np.float64], NDArray[np.float64], int]:
        """(phi, ln(V0 theta/Dc), index of the first missing sample (n when complete)) at
        the samples for the engine parameters of :meth:`engine_params` (one forward run)."""
        self.n_evals += 1
        if math.isinf(kappa):
            phi, lth = self._stiff(eps, scale)
            return phi, lth, self.record.n
        phi, lth, n_ok, _ = self._engine(ba, kappa, eps, scale)
        return phi, lth, n_ok

    def friction(self, p: dict[str, float]) -> tuple[NDArray[np.float64], int]:
        """Model friction at the record's samples and the index of the first missing sample
        (n when complete).  ``p`` holds all six parameters."""
        phi, lth, n_ok = self.states(*self.engine_params(p))
        return p["mu0"] + p["a"] * phi + p["b"] * lth + self._trend(p), n_ok

    def jacobian(
        self,
        p: dict[str, float],
        names: tuple[str, ...],
        base: tuple[NDArray[np.float64], NDArray[np.float64]],
        step: float = 1e-6,
    ) -> NDArray[np.float64] | None:
        """d mu/d x at the samples (n, len(names)) in the fitted coordinates (mu0, a, b,
        ln Dc, eps, ln k, trend_per_m), or None when a perturbed run does not complete.

        The friction mu0 + a phi(q) + b lth(q) + trend x_lp is linear in mu0, a, b and the
        trend apart from the states' dependence on q = (b/a, ln kappa, ln s, eps)
        (:meth:`engine_params`), so the states are differenced along those directions
        only (forward differences, steps ``step`` max(|b/a|, 1), ``step``, ``step`` and
        -``step`` for eps near 1; 2 or 3 runs, 1 for an infinitely stiff machine and
        one more when eps varies) and the columns follow by the chain rule.  ``base`` is
        (phi, lth) at ``p`` (from :meth:`states`).  Against forward differences in every
        fitted coordinate (one run per parameter) the columns agree to the difference
        quotients' own error (~1e-6 relative; tests/core/test_fit.py).
        """
        a, b = p["a"], p["b"]
        ba, kappa, eps, scale = self.engine_params(p)
        phi0, lth0 = base
        law = self.spec.law
        eps_varies = "eps" in names or law is Law.NAGATA
        rigid = math.isinf(kappa)
        # q directions: 0 = b/a, 1 = ln kappa, 2 = ln s, 3 = eps
        dirs = [] if rigid else [0, 1]
        dirs.append(2)
        if eps_varies:
            dirs.append(3)
        dphi: dict[int, NDArray[np.float64]] = {}
        dlth: dict[int, NDArray[np.float64]] = {}
        n = self.record.n
        for d in dirs:
            q = [ba, kappa, eps, scale]
            if d == 0:
                h = step * max(abs(ba), 1.0)
                q[0] = ba + h
            elif d == 1:
                h = step
                q[1] = kappa * math.exp(h)
            elif d == 2:
                h = step
                q[3] = scale * math.exp(h)
            else:
                h = step if eps + step <= 1.0 else -step
                q[2] = eps + h
            phi, lth, n_ok = self.states(q[0], q[1], q[2], q[3])
            if n_ok < n:
                return None
            dphi[d] = (phi - phi0) / h
            dlth[d] = (lth - lth0) / h
        # dq/dx per fitted coordinate: {direction: derivative}
        deps_da = deps_db = 0.0
        if law is Law.NAGATA:
            c = self.spec.nagata_c
            den = (b + c * a) ** 2
            deps_da, deps_db = -b * c / den, c * a / den
        J = np.empty((n, len(names)))
        for j, nm in enumerate(names):
            if nm == "mu0":
                J[:, j] = 1.0
                continue
            if nm == "trend_per_m":
                J[:, j] = self.x_lp
                continue
            chain: dict[int, float] = {}
            direct: NDArray[np.float64] | None = None
            if nm == "a":
                chain = {0: -ba / a, 1: -1.0 / a, 3: deps_da}
                direct = phi0
            elif nm == "b":
                chain = {0: 1.0 / a, 3: deps_db}
                direct = lth0
            elif nm == "Dc_m":
                chain = {1: 1.0, 2: -1.0}
            elif nm == "k_per_m":
                chain = {1: 1.0}
            elif nm == "eps":
                chain = {3: 1.0}
            col = np.zeros(n) if direct is None else direct.copy()
            for d, w in chain.items():
                if w != 0.0 and d in dphi:
                    col += w * (a * dphi[d] + b * dlth[d])
            J[:, j] = col
        return J

    def simulate(self, p: dict[str, float]) -> Simulation:
        """Friction, slip rate and state at the samples (for plots and checks)."""
        ba, kappa, eps, scale = self.engine_params(p)
        if math.isinf(kappa):
            phi, lth = self._stiff(eps, scale)
            n_ok, steps = self.record.n, 0
        else:
            phi, lth, n_ok, steps = self._engine(ba, kappa, eps, scale)
        mu = p["mu0"] + p["a"] * phi + p["b"] * lth + self._trend(p)
        with np.errstate(over="ignore", under="ignore"):
            V = self.V0 * np.exp(np.minimum(phi, 700.0))
            th = p["Dc_m"] / self.V0 * np.exp(np.clip(lth, -740.0, 700.0))
        if n_ok < self.record.n:
            mu[n_ok:] = np.nan
            V[n_ok:] = np.nan
            th[n_ok:] = np.nan
        return Simulation(mu=mu, V_m_s=V, theta_s=th, complete=n_ok == self.record.n, n_steps=steps)

    def _stiff(self, eps: float, scale: float) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Closed form for k = inf: phi = ln(v_lp/V0), L from the exact solution per segment
        (scale = V0/Dc [1/s])."""
        n = self.record.n
        phi = np.empty(n)
        lth = np.empty(n)
        L0 = 0.0
        t = self.t
        for j, (i0, i1) in enumerate(zip(self.starts, self.ends, strict=True)):
            v = self.v_seg[j]
            ph = math.log(v / self.V0)
            if j > 0:
                L0 += ph - math.log(self.v_seg[j - 1] / self.V0)  # theta continuous across the step
            rate = (v / self.V0) * scale  # v/Dc
            x = (t[i0:i1] - t[i0]) * rate
            t_end = t[i1] if i1 < n else t[-1]
            x_end = (t_end - t[i0]) * rate
            if eps == 0.0:
                L = L0 * np.exp(-x)
                L_end = L0 * math.exp(-x_end)
            else:
                w0m1 = math.expm1(min(eps * L0, 700.0))
                L = np.log1p(w0m1 * np.exp(-x)) / eps
                L_end = math.log1p(w0m1 * math.exp(-x_end)) / eps
            phi[i0:i1] = ph
            lth[i0:i1] = L - ph
            L0 = L_end
        return phi, lth

    def _engine(
        self, ba: float, kappa: float, eps: float, scale: float
    ) -> tuple[NDArray[np.float64], NDArray[np.float64], int, int]:
        """Segment by segment with rsfcore.engine.run (3-component state phi, ln theta, T;
        T = scale t)."""
        n = self.record.n
        phi = np.zeros(n)
        lth = np.zeros(n)
        y = np.array([0.0, 0.0, 0.0])
        rtol = self.spec.rtol
        steps = 0
        for j, (i0, i1) in enumerate(zip(self.starts, self.ends, strict=True)):
            sT = self.t[i0:i1] * scale
            T_end = (self.t[i1] if i1 < n else self.t[-1]) * scale
            out = np.empty((i1 - i0, 5))
            opts = EngineOptions(
                rtol=rtol, atol=rtol, t_end=T_end, phi_stop=_PHI_STOP, max_steps=_MAX_STEPS
            )
            res = run(y, ba, kappa, eps, self.v_seg[j] / self.V0, opts, _EMPTY, sT, out)
            nf = res.n_filled
            steps += res.n_steps + res.n_rejected
            phi[i0 : i0 + nf] = out[:nf, 0]
            lth[i0 : i0 + nf] = out[:nf, 1]
            if res.status is not Status.T_END or nf != i1 - i0:
                return phi, lth, i0 + nf, steps
            y = np.asarray(res.y_end).copy()
        return phi, lth, n, steps


def describe(spec: ModelSpec) -> dict[str, Any]:
    """JSON-safe description of a spec."""
    return {
        "law": spec.law.value,
        "fit_stiffness": spec.fit_stiffness,
        "stiffness_per_m": spec.stiffness_per_m if math.isfinite(spec.stiffness_per_m) else None,
        "nagata_c": spec.nagata_c,
        "rtol": spec.rtol,
        "trend": spec.trend,
    }


def synthetic_record(
    t_s: NDArray[np.float64],
    v_lp_m_s: NDArray[np.float64],
    *,
    mu0: float,
    a: float,
    b: float,
    Dc_m: float,
    eps: float,
    k_per_m: float = math.inf,
    trend_per_m: float = 0.0,
    noise: float = 0.0,
    seed: int = 0,
    rtol: float = 1e-10,
    name: str = "synthetic",
) -> Record:
    """A record computed by this forward model, plus optional Gaussian noise of std ``noise``
    and a linear friction trend ``trend_per_m`` [1/m] in load-point displacement.

    For tests, demos and benchmarks.  Raises RuntimeError if the parameters run away
    before the record's end (no record of unstable slip is produced).
    """
    proto = Record(t_s=t_s, v_lp_m_s=v_lp_m_s, mu=np.zeros(len(t_s)), name=name)
    model = ForwardModel(
        proto, ModelSpec(law=Law.EPS, fit_stiffness=False, stiffness_per_m=k_per_m, rtol=rtol)
    )
    mu, n_ok = model.friction(
        {
            "mu0": mu0,
            "a": a,
            "b": b,
            "Dc_m": Dc_m,
            "eps": eps,
            "k_per_m": k_per_m,
            "trend_per_m": trend_per_m,
        }
    )
    if n_ok < proto.n:
        raise RuntimeError(
            f"the parameters run away at t = {proto.t_s[n_ok]:g} s: no stable record"
        )
    if noise > 0.0:
        mu = mu + np.random.default_rng(seed).normal(0.0, noise, mu.shape[0])
    return Record(t_s=proto.t_s, v_lp_m_s=proto.v_lp_m_s, mu=mu, name=name)
