"""Work-precision benchmark of the compiled core against scipy's solve_ivp on the same equations.

Case: b/a = 2, kappa = 2, eps = 0.25, v_o = 1, velocity jumps d = 2.0 (stable), 2.7 (stable,
near-critical) and 2.75 (unstable).  For rtol = 1e-6 .. 1e-12 it prints, for rsfcore and
for scipy DOP853 and LSODA (Python right-hand side of the same hybrid-time system, with the
same stop events), the wall time per classification and the delivered relative error of the
decisive time (return time or blow-up time) against an rsfcore run at rtol = 1e-13 (the tightest valid), and the
speed ratio at equal delivered error (scipy's time interpolated log-log at rsfcore's error).
Full trajectories (1000 samples) are timed too.  JIT compile time is measured separately,
cold (empty cache directory) and warm (cache on disk), in subprocesses.

    python bench/bench_core.py [--quick]
"""

from __future__ import annotations

import argparse
import math
import os
import subprocess
import sys
import tempfile
import time

import numpy as np

RTOLS = [1e-6, 1e-8, 1e-10, 1e-12]
SIZES = [2.0, 2.7, 2.75]
BA, KAPPA, EPS, VO = 2.0, 2.0, 0.25, 1.0


def _best_time(fn, min_time: float = 0.2, max_reps: int = 2000) -> float:
    fn()
    n, t0 = 0, time.perf_counter()
    best = math.inf
    while n < max_reps and time.perf_counter() - t0 < min_time:
        t = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t)
        n += 1
    return best


def _scipy_classify(d: float, rtol: float, method: str) -> float:
    """Return (or blow-up) time T from solve_ivp on the hybrid-time system of rsfcore.engine."""
    from scipy.integrate import solve_ivp

    ba, kappa, eps = BA, KAPPA, EPS

    def rhs(tau: float, y: np.ndarray) -> list[float]:
        phi, lth = y[0], y[1]
        z = phi
        e = math.exp(-abs(z))
        inv = 1 / (1 + e)
        ap, om = (inv, e * inv) if z >= 0 else (e * inv, inv)
        L = phi + lth
        x = -eps * L
        g = math.expm1(min(x, 600.0)) / eps
        zz = ba * g * ap
        invd = 1 / math.hypot(1, zz)
        return [(kappa * (om - ap) - zz) * invd, g * ap * invd, om * invd]

    def ev_return(tau: float, y: np.ndarray) -> float:
        return y[0] if tau > 0 else 1.0

    ev_return.terminal = True  # type: ignore[attr-defined]
    ev_return.direction = -1  # type: ignore[attr-defined]

    def ev_blow(tau: float, y: np.ndarray) -> float:
        return y[0] - 40.0

    ev_blow.terminal = True  # type: ignore[attr-defined]
    ev_blow.direction = 1  # type: ignore[attr-defined]

    sol = solve_ivp(
        rhs,
        (0, 1e4),
        [d, 0.0, 0.0],
        method=method,
        rtol=rtol,
        atol=rtol,
        events=[ev_return, ev_blow],
    )
    if sol.t_events[0].size:
        return float(sol.y_events[0][0][2])
    return float(sol.y_events[1][0][2]) + math.exp(-40.0) / 1.0  # tail below 1e-17 relative


def _decisive(r) -> float:  # noqa: ANN001
    return r.return_time if r.outcome == "stable" else r.blowup_time


def _compile_times() -> tuple[float, float]:
    code = "import time; t=time.perf_counter(); from rsfcore import Params, classify; classify(Params(2,2,0.25,1),'velocity-jump',2.0); print(time.perf_counter()-t)"
    with tempfile.TemporaryDirectory() as tmp:
        env = dict(os.environ, NUMBA_CACHE_DIR=tmp)
        cold = float(subprocess.check_output([sys.executable, "-c", code], env=env).split()[-1])
        warm = float(subprocess.check_output([sys.executable, "-c", code], env=env).split()[-1])
    return cold, warm


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--quick", action="store_true", help="fewer rtols, skip LSODA")
    args = ap.parse_args()
    from rsfcore import Params, classify, simulate

    rtols = [1e-6, 1e-10] if args.quick else RTOLS
    methods = ["DOP853"] if args.quick else ["DOP853", "LSODA"]
    p = Params(BA, KAPPA, EPS, VO)

    cold, warm = _compile_times()
    print(
        f"JIT compile: cold {cold:.2f} s (empty cache), warm start {warm:.2f} s (cache on disk)\n"
    )

    print(
        "Classification (wall time per call, best of repeats; error = delivered relative error of the return/blow-up time)"
    )
    hdr = f"{'d':>5} {'rtol':>7} | {'rsfcore us':>10} {'err':>8} {'steps':>5} | " + " | ".join(
        f"{m + ' us':>11} {'err':>8} {'ratio@err':>9}" for m in methods
    )
    print(hdr)
    print("-" * len(hdr))
    worst_ratio: dict[str, float] = {m: math.inf for m in methods}
    t_1e10: list[float] = []
    for d in SIZES:
        ref = _decisive(classify(p, "velocity-jump", d, rtol=1e-13))
        curves: dict[str, list[tuple[float, float]]] = {m: [] for m in methods}
        for m in methods:
            for rt in sorted(set(RTOLS + [1e-13]), reverse=True):
                if m == "LSODA" and rt < 1e-12:
                    continue
                t = _best_time(lambda: _scipy_classify(d, rt, m), min_time=0.3, max_reps=20)
                err = abs(_scipy_classify(d, rt, m) - ref) / ref
                curves[m].append((max(err, 1e-16), t))
        for rt in rtols:
            r = classify(p, "velocity-jump", d, rtol=rt)
            t = _best_time(lambda: classify(p, "velocity-jump", d, rtol=rt))
            if rt == 1e-10:
                t_1e10.append(t)
            err = abs(_decisive(r) - ref) / ref
            cells = []
            for m in methods:
                st = _best_time(lambda: _scipy_classify(d, rt, m), min_time=0.3, max_reps=20)
                serr = abs(_scipy_classify(d, rt, m) - ref) / ref
                # scipy's time at rsfcore's delivered error (log-log interpolation on its curve)
                pts = sorted(curves[m])
                le = math.log(max(err, 1e-16))
                xs = [math.log(e) for e, _ in pts]
                ys = [math.log(tt) for _, tt in pts]
                t_eq = math.exp(float(np.interp(le, xs, ys))) if le >= xs[0] else math.exp(ys[0])
                ratio = t_eq / t
                worst_ratio[m] = min(worst_ratio[m], ratio)
                cells.append(f"{st * 1e6:11.0f} {serr:8.1e} {ratio:9.0f}")
            print(
                f"{d:5.2f} {rt:7.0e} | {t * 1e6:10.1f} {err:8.1e} {r.n_steps:5d} | "
                + " | ".join(cells)
            )
    print()
    for m in methods:
        print(f"speed-up vs scipy {m} at equal delivered error: at least {worst_ratio[m]:.0f}x")
    print(f"classification at rtol 1e-10: {max(t_1e10) * 1e6:.1f} us worst of d = {SIZES}")

    print("\nFull trajectories, 1000 samples (dense output), rsfcore:")
    for d in SIZES:
        for rt in rtols:
            t = _best_time(
                lambda: simulate(p, "velocity-jump", d, rtol=rt, n_points=1000),
                min_time=0.2,
                max_reps=200,
            )
            print(f"  d={d:4.2f} rtol={rt:7.0e}: {t * 1e6:8.1f} us")


if __name__ == "__main__":
    main()
