"""Stiff spring-sliders: rsfcore's DOP853 -> Rosenbrock (RODASP) switch against scipy's stiff
solvers.

Cases (load-point jumps on stiff machines, where DOP853 alone is stability-limited):

    A: b/a = 1 + 1e-6, kappa = 1e6, eps = 0,   v_o = 1, dv = 10   (the issue-13 target)
    B: b/a = 5,        kappa = 4e4, eps = 0.1, v_o = 1, dv = 3
    C: b/a = 2,        kappa = 1e4, eps = 0.3, v_o = 1, dv = 1

Quantity compared: the state (phi, ln theta) at T = 1 (dimensionless time), from the same
hybrid-time system the engine integrates (rsfcore.engine module docstring).  Reference:
rsfcore with its Rosenbrock method (RODASP) alone at rtol 1e-13, cross-checked against
DOP853 alone at rtol 1e-13 (printed).  Delivered error = max(|d phi|, |d ln theta|) against the reference.

For rsfcore (automatic switch, rtol 1e-6 .. 1e-12), DOP853 alone (rtol 1e-10) and scipy's
Radau, BDF and LSODA (analytic Jacobian supplied; rtol 1e-4 .. 1e-12, atol = rtol; the
compiled right-hand side called from Python) it prints wall time, steps and delivered
error, and the speed ratio at equal delivered error (scipy's time interpolated log-log at
the error rsfcore delivers at rtol 1e-10; '-' when a solver never reaches it).

    python bench/bench_stiff.py [--quick]
"""

from __future__ import annotations

import argparse
import math
import time
from collections.abc import Callable

import numpy as np
from scipy.integrate import solve_ivp

from rsfcore import Params, engine, simulate

CASES = {
    "A": (Params(1 + 1e-6, 1e6, 0.0, 1.0), 10.0),
    "B": (Params(5.0, 4e4, 0.1, 1.0), 3.0),
    "C": (Params(2.0, 1e4, 0.3, 1.0), 1.0),
}
T_END = 1.0


def _best(fn: Callable[[], object], reps: int) -> float:
    best = math.inf
    for _ in range(reps):
        t = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t)
    return best


_INTEGRATORS = {"auto": engine.Integrator.AUTO, "explicit": engine.Integrator.EXPLICIT,
                "implicit": engine.Integrator.IMPLICIT}  # fmt: skip


def _rsfcore_state(p: Params, dv: float, rtol: float, integrator: str) -> tuple[np.ndarray, int]:
    """One engine run to T = T_END, the same system, start and tolerances as the scipy runs
    (simulate would add the run to the classification and the rtol/10 accuracy check that
    the scipy runs do not make)."""
    vo = p.vo * (1.0 + dv)
    phi0 = math.log(p.vo)
    # (phi, ln theta, T) like the scipy runs; the run stops at T_END on its dense output
    opts = engine.EngineOptions(
        rtol=rtol, atol=rtol, t_end=T_END, integrator=_INTEGRATORS[integrator]
    )
    res = engine.run(np.array([phi0, -phi0, 0.0]), p.ba, p.kappa, p.eps, vo, opts)
    assert res.status == engine.Status.T_END
    return np.array([res.y_end[0], res.y_end[1]]), res.n_steps


def _scipy_state(p: Params, dv: float, rtol: float, method: str) -> tuple[np.ndarray, int]:
    """The engine's hybrid-time system through solve_ivp, stopped at T = T_END by an event."""
    vo = p.vo * (1.0 + dv)
    c = vo
    lnc = math.log(c)
    ba, kappa, eps = p.ba, p.kappa, p.eps
    f = np.empty(3)
    J = np.empty((3, 2))

    def rhs(tau: float, y: np.ndarray) -> np.ndarray:
        engine._rhs(y, f, ba, kappa, eps, vo, c, lnc)
        return f.copy()

    def jac(tau: float, y: np.ndarray) -> np.ndarray:
        engine._jacobian(y, J, ba, kappa, eps, vo, c, lnc)
        out = np.zeros((3, 3))
        out[:, :2] = J
        return out

    def at_end(tau: float, y: np.ndarray) -> float:
        return y[2] - c * T_END  # the engine's time component is c T

    at_end.terminal = True  # type: ignore[attr-defined]
    # start of the v_o = p.vo (1 + dv) run: steady state at the old v_o
    phi0 = math.log(p.vo)
    lth0 = -phi0
    kw: dict[str, object] = {"jac": jac} if method in ("Radau", "BDF", "LSODA") else {}
    sol = solve_ivp(rhs, (0.0, 1e9), [phi0, lth0, 0.0], method=method, rtol=rtol, atol=rtol,
                    events=at_end, **kw)  # fmt: skip
    y = sol.y_events[0][0] if sol.status == 1 else sol.y[:, -1]
    return np.array([y[0], y[1]]), int(sol.t.size - 1)


def _interp_time(rows: list[tuple[float, float]], target: float) -> float:
    """log-log interpolation of time at the delivered error ``target`` (rows: (err, time))."""
    rows = sorted((e, t) for e, t in rows if e > 0 and math.isfinite(e))
    for (e0, t0), (e1, t1) in zip(rows, rows[1:], strict=False):
        if e0 <= target <= e1:
            w = (math.log(target) - math.log(e0)) / (math.log(e1) - math.log(e0))
            return math.exp(math.log(t0) + w * (math.log(t1) - math.log(t0)))
    if rows and rows[0][0] <= target:
        return rows[0][1]
    return math.nan


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="fewer tolerances and repetitions")
    args = ap.parse_args()
    reps = 2 if args.quick else 5
    rs_rtols = [1e-8, 1e-10] if args.quick else [1e-6, 1e-8, 1e-10, 1e-12]
    sp_rtols = [1e-6, 1e-9] if args.quick else [1e-4, 1e-6, 1e-8, 1e-10, 1e-12]
    simulate(Params(2.0, 2.0, 0.25), "load-point-jump", 1.0, times=[1.0])  # numba warm-up

    for name, (p, dv) in CASES.items():
        ref, _ = _rsfcore_state(p, dv, 1e-13, "implicit")
        print(f"\ncase {name}: b/a = {p.ba:.7g}, kappa = {p.kappa:g} (kappa/kappa_crit = "
              f"{p.kappa_ratio:.3g}), eps = {p.eps:g}, dv = {dv:g}; state at T = {T_END:g}")  # fmt: skip
        if p.kappa <= 1e5 or not args.quick:
            t_ex = time.perf_counter()
            ex, n_ex = _rsfcore_state(p, dv, 1e-13, "explicit")
            t_ex = time.perf_counter() - t_ex
            print(f"  reference RODASP rtol 1e-13 vs DOP853 rtol 1e-13 ({n_ex} steps, "
                  f"{t_ex:.2f} s): max difference {np.abs(ex - ref).max():.1e}")  # fmt: skip
        print(f"  {'solver':<22}{'rtol':>8}{'steps':>10}{'time [ms]':>12}{'error':>10}")
        target = math.nan
        results: dict[str, list[tuple[float, float]]] = {}
        for rt in rs_rtols:
            y, n = _rsfcore_state(p, dv, rt, "auto")
            t = _best(lambda p=p, dv=dv, rt=rt: _rsfcore_state(p, dv, rt, "auto"), reps)
            err = float(np.abs(y - ref).max())
            results.setdefault("rsfcore auto", []).append((err, t))
            if rt == 1e-10:
                target = err
            print(f"  {'rsfcore auto':<22}{rt:>8.0e}{n:>10}{t * 1e3:>12.3f}{err:>10.1e}")
        if p.kappa <= 1e5:
            t = time.perf_counter()
            y, n = _rsfcore_state(p, dv, 1e-10, "explicit")
            t = time.perf_counter() - t
            err = float(np.abs(y - ref).max())
            print(f"  {'rsfcore DOP853 only':<22}{1e-10:>8.0e}{n:>10}{t * 1e3:>12.1f}{err:>10.1e}")
        for method in ("Radau", "BDF", "LSODA"):
            for rt in sp_rtols:
                t = time.perf_counter()
                y, n = _scipy_state(p, dv, rt, method)
                t = time.perf_counter() - t
                err = float(np.abs(y - ref).max())
                results.setdefault(method, []).append((err, t))
                print(f"  {'scipy ' + method:<22}{rt:>8.0e}{n:>10}{t * 1e3:>12.1f}{err:>10.1e}")
        t_rs = _interp_time(results["rsfcore auto"], target)
        print(
            f"  at equal delivered error {target:.1e} (rsfcore at rtol 1e-10: {t_rs * 1e3:.3f} ms):"
        )
        for method in ("Radau", "BDF", "LSODA"):
            t_m = _interp_time(results[method], target)
            ratio = "-" if not math.isfinite(t_m) else f"{t_m / t_rs:.0f}x slower"
            print(f"    scipy {method:<6} {ratio}")


if __name__ == "__main__":
    main()
