"""Benchmark: fitting a 10^4-sample velocity-step record, compiled forward model vs scipy solve_ivp.

Record: a = 0.01, b = 0.015, Dc = 10 um, mu0 = 0.6, aging law, machine stiffness
k = 800 /m (kappa = 0.8, kappa/kappa_crit = 1.6); load point 1 um/s for 200 s, 10 um/s for
30 s, 1 um/s for 300 s; 10^4 samples; noise-free and with Gaussian noise 1e-4.

Fit: the 4 parameters mu0, a, b, Dc (law and stiffness fixed).  Both forward models are
driven by the same optimiser set-up (scipy.optimize.least_squares, trust-region
reflective, coordinates (mu0, a, b, ln Dc), start values from rsfcore's variable-projection
start, forward-difference Jacobian with the same steps and tolerances):

* rsfcore: rsfcore.fit.ForwardModel (compiled DOP853 engine, rtol 1e-10);
* scipy: solve_ivp (DOP853, rtol 1e-10, Python right-hand side) of the textbook SI
  equations mu = mu0 + a ln(V/V0) + b ln(V0 theta/Dc), d mu/dt = k (v_lp - V),
  d theta/dt = 1 - V theta/Dc, segment by segment, sampled with t_eval.

It prints the wall time of each fit after warm-up (best of 3 for rsfcore, 1 run for
scipy), their ratio, the number of forward-model runs, the relative parameter errors
against the truth, and the friction error of each forward model against an rsfcore run
at rtol 1e-13.  Also the full rsfcore.fit.fit_record (with uncertainty, identifiability
and linearity checks and the stability answer).  BLAS and numba are limited to one
thread ("one core").

    python bench/bench_fit.py
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("MKL_NUM_THREADS", "1")
os.environ.setdefault("NUMBA_NUM_THREADS", "1")

import math  # noqa: E402
import time  # noqa: E402
from collections.abc import Callable  # noqa: E402

import numpy as np  # noqa: E402
from numpy.typing import NDArray  # noqa: E402
from scipy.integrate import solve_ivp  # noqa: E402
from scipy.optimize import least_squares  # noqa: E402

from rsfcore.fit import ForwardModel, Law, ModelSpec, Record, fit_record, synthetic_record  # noqa: E402
from rsfcore.fit.core import DEFAULT_BOUNDS, _initial_guess  # noqa: E402

N = 10_000
TRUE = {"mu0": 0.6, "a": 0.01, "b": 0.015, "Dc_m": 1e-5, "eps": 1.0, "k_per_m": 800.0}
NAMES = ("mu0", "a", "b", "Dc_m")


def design() -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    t = np.linspace(0.0, 530.0, N)
    v = np.where(t < 200.0, 1e-6, np.where(t < 230.0, 1e-5, 1e-6))
    return t, v


class ScipyModel:
    """Textbook SI spring-slider (aging law) by solve_ivp DOP853 (Python right-hand side)."""

    def __init__(self, rec: Record, k: float, rtol: float = 1e-10) -> None:
        self.t, self.v, self.k, self.rtol = rec.t_s, rec.v_lp_m_s, k, rtol
        self.starts = [int(i) for i in rec.segment_starts] + [rec.n]
        self.n_evals = 0

    def friction(self, p: dict[str, float]) -> NDArray[np.float64]:
        self.n_evals += 1
        mu0, a, b, Dc, k = p["mu0"], p["a"], p["b"], p["Dc_m"], self.k
        V0 = float(self.v[0])

        def rhs(_t: float, y: NDArray[np.float64], vlp: float) -> list[float]:
            mu, th = y
            arg = (mu - mu0 - b * math.log(V0 * th / Dc)) / a
            V = V0 * math.exp(min(arg, 700.0))
            return [k * (vlp - V), 1.0 - V * th / Dc]

        y = np.array([mu0, Dc / V0])
        out = np.full(self.t.shape[0], np.nan)
        atol = np.array([1e-14, 1e-14 * Dc / V0])
        t = self.t
        for j in range(len(self.starts) - 1):
            i0, i1 = self.starts[j], self.starts[j + 1]
            t_end = t[i1] if i1 < t.shape[0] else t[-1]
            te = t[i0:i1]
            if te[-1] != t_end:
                te = np.append(te, t_end)
            sol = solve_ivp(
                rhs,
                (t[i0], t_end),
                y,
                method="DOP853",
                t_eval=te,
                rtol=self.rtol,
                atol=atol,
                args=(float(self.v[i0]),),
            )
            if not sol.success:
                return out
            out[i0:i1] = sol.y[0, : i1 - i0]
            y = sol.y[:, -1]
        return out


def drive(
    friction: Callable[[dict[str, float]], NDArray[np.float64]],
    rec: Record,
    x0: NDArray[np.float64],
    lb: NDArray[np.float64],
    ub: NDArray[np.float64],
) -> tuple[NDArray[np.float64], int]:
    """Same least-squares set-up as rsfcore.fit (coordinates, steps, tolerances)."""

    def unpack(x: NDArray[np.float64]) -> dict[str, float]:
        return {
            "mu0": x[0],
            "a": x[1],
            "b": x[2],
            "Dc_m": math.exp(x[3]),
            "eps": 1.0,
            "k_per_m": TRUE["k_per_m"],
        }

    def resid(x: NDArray[np.float64]) -> NDArray[np.float64]:
        r = friction(unpack(x)) - rec.mu
        r[~np.isfinite(r)] = 1.0
        return r

    def jac(x: NDArray[np.float64]) -> NDArray[np.float64]:
        r0 = resid(x)
        h = np.array([1e-6 * max(1.0, abs(x[0])), 1e-6 * x[1], 1e-6 * max(abs(x[2]), x[1]), 1e-6])
        J = np.empty((r0.shape[0], 4))
        for j in range(4):
            xp = x.copy()
            xp[j] += h[j]
            J[:, j] = (resid(xp) - r0) / h[j]
        return J

    sol = least_squares(
        resid,
        x0,
        jac=jac,
        bounds=(lb, ub),
        method="trf",
        x_scale="jac",
        ftol=1e-14,
        xtol=1e-14,
        gtol=1e-14,
        max_nfev=200,
    )
    return sol.x, int(sol.nfev)


def errors(x: NDArray[np.float64]) -> str:
    est = {"mu0": x[0], "a": x[1], "b": x[2], "Dc_m": math.exp(x[3])}
    return "  ".join(f"{n} {est[n] / TRUE[n] - 1.0:+.1e}" for n in NAMES)


def main() -> None:
    t, v = design()
    spec = ModelSpec(Law.AGING, False, TRUE["k_per_m"], rtol=1e-10)
    ref = synthetic_record(t, v, **TRUE, rtol=1e-13)
    print(
        f"record: {N} samples, 2 velocity steps, aging law, k = {TRUE['k_per_m']:g} /m; "
        "4-parameter fit (mu0, a, b, Dc)"
    )
    # forward-model accuracy against the rtol 1e-13 reference
    mu_r, _ = ForwardModel(ref, spec).friction(TRUE)
    sm = ScipyModel(ref, TRUE["k_per_m"])
    t0 = time.perf_counter()
    mu_s = sm.friction(TRUE)
    t_one_scipy = time.perf_counter() - t0
    t0 = time.perf_counter()
    for _ in range(10):
        ForwardModel(ref, spec).friction(TRUE)
    t_one_rsf = (time.perf_counter() - t0) / 10
    print(
        f"one forward run: rsfcore {t_one_rsf * 1e3:.2f} ms, scipy {t_one_scipy * 1e3:.1f} ms "
        f"(x{t_one_scipy / t_one_rsf:.0f}); max |friction error| vs rtol 1e-13: "
        f"rsfcore {np.max(np.abs(mu_r - ref.mu)):.1e}, scipy {np.max(np.abs(mu_s - ref.mu)):.1e}"
    )

    for label, noise in (("noise-free", 0.0), ("noise 1e-4", 1e-4)):
        rec = synthetic_record(t, v, **TRUE, noise=noise, seed=1, rtol=1e-13)
        p0 = _initial_guess(rec, spec, DEFAULT_BOUNDS)
        x0 = np.array([p0["mu0"], p0["a"], p0["b"], math.log(p0["Dc_m"])])
        lb = np.array(
            [
                DEFAULT_BOUNDS["mu0"][0],
                DEFAULT_BOUNDS["a"][0],
                DEFAULT_BOUNDS["b"][0],
                math.log(DEFAULT_BOUNDS["Dc_m"][0]),
            ]
        )
        ub = np.array(
            [
                DEFAULT_BOUNDS["mu0"][1],
                DEFAULT_BOUNDS["a"][1],
                DEFAULT_BOUNDS["b"][1],
                math.log(DEFAULT_BOUNDS["Dc_m"][1]),
            ]
        )
        model = ForwardModel(rec, spec)

        def rsf(p: dict[str, float], m: ForwardModel = model) -> NDArray[np.float64]:
            return m.friction(p)[0]

        drive(rsf, rec, x0, lb, ub)  # warm-up
        best = math.inf
        for _ in range(3):
            model.n_evals = 0
            t0 = time.perf_counter()
            x_r, nfev_r = drive(rsf, rec, x0, lb, ub)
            best = min(best, time.perf_counter() - t0)
        runs_r = model.n_evals
        smod = ScipyModel(rec, TRUE["k_per_m"])
        t0 = time.perf_counter()
        x_s, nfev_s = drive(smod.friction, rec, x0, lb, ub)
        t_s = time.perf_counter() - t0
        print(f"\n[{label}] same least-squares driver:")
        print(
            f"  rsfcore forward model: {best:7.3f} s  ({runs_r} forward runs, "
            f"{nfev_r} evaluations)  errors: {errors(x_r)}"
        )
        print(
            f"  scipy solve_ivp      : {t_s:7.3f} s  ({smod.n_evals} forward runs, "
            f"{nfev_s} evaluations)  errors: {errors(x_s)}"
        )
        print(f"  ratio scipy/rsfcore  : {t_s / best:.0f}x")
        fit_record(rec, "aging", stiffness=TRUE["k_per_m"])  # warm-up of the stability path
        t0 = time.perf_counter()
        res = fit_record(rec, "aging", stiffness=TRUE["k_per_m"])
        t_full = time.perf_counter() - t0
        rel = "  ".join(
            f"{n} {res.params[n] / TRUE[n] - 1:+.1e} (se {res.stderr[n] / TRUE[n]:.1e})"
            for n in NAMES
        )
        print(
            "  rsfcore.fit.fit_record (fit + covariance + identifiability + linearity + "
            "stability, "
            f"{res.n_model_evals} forward runs): {t_full:.3f} s, status {res.status.value}"
        )
        print(f"    relative errors (and relative standard errors): {rel}")


if __name__ == "__main__":
    main()
