"""Benchmark: the 100 x 100 stability diagram against scipy-based bisection.

Grid: kappa/kappa_crit in linspace(1, 5, 100) x eps in linspace(0, 0.99, 100), b/a = 2,
v_o = 1, velocity jump (issue 4 target: <= 0.1 s on one core after warm-up, <= 1e-9
relative error on the finite points).

The comparison is bisection on trajectories integrated by scipy's solve_ivp (DOP853,
rtol = atol = 1e-10) on the same equations as rsfcore.engine (hybrid time d tau =
D (1 + e^phi) dT, variables phi and ln theta), with terminal events L > L* (runaway) and
phi crossing 0 downward (return), bisected on [0, L*] to 1e-10 relative.  Its time per
point is measured on a random sample of finite grid points and extrapolated to all finite
points (zero/infinite points cost nothing for either method).

Run: python bench/bench_diagram.py [--sample 10]   (< 2 minutes)
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path

import numpy as np
from scipy.integrate import solve_ivp

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from rsfcore.diagram import stability_diagram  # noqa: E402
from rsfcore.laws import L_star  # noqa: E402

BA = 2.0
XR = np.linspace(1.0, 5.0, 100)
YE = np.linspace(0.0, 0.99, 100)


def _G(L: float, eps: float) -> float:
    x = eps * L
    if abs(x) < 1e-4:
        return -L * (1.0 - x * (0.5 - x * (1.0 / 6.0 - x / 24.0)))
    return math.expm1(-min(x, 700.0)) / eps if x > -700.0 else math.expm1(700.0) / eps


def scipy_outcome(ba: float, kappa: float, eps: float, d: float, Ls: float) -> bool:
    """True if a velocity jump d runs away (scipy DOP853, hybrid time, events)."""

    def rhs(_tau, y):
        phi, lth = y
        e = math.exp(-abs(phi))
        ap = 1.0 / (1.0 + e) if phi >= 0 else e / (1.0 + e)
        om = 1.0 - ap
        g = _G(phi + lth, eps)
        z = ba * g * ap
        inv = 1.0 / math.sqrt(1.0 + z * z)
        return [(kappa * (om - ap) - z) * inv, g * ap * inv]

    def runaway(_tau, y):
        return y[0] + y[1] - Ls

    runaway.terminal = True
    runaway.direction = 1

    def returned(_tau, y):
        return y[0]

    returned.terminal = True
    returned.direction = -1

    y0 = [d, 0.0]
    tau_end = 1e6
    sol = solve_ivp(
        rhs, (0.0, tau_end), y0, method="DOP853", rtol=1e-10, atol=1e-10, events=(runaway, returned)
    )
    if sol.t_events[0].size:
        return True
    if sol.t_events[1].size:
        return False
    raise RuntimeError(
        f"scipy: undecided at ba={ba}, kappa={kappa}, eps={eps}, d={d}: {sol.message}"
    )


def scipy_bisection(ba: float, kappa: float, eps: float, rtol: float = 1e-10) -> float:
    Ls = float(L_star(kappa, ba - 1.0, eps))
    lo, hi = 0.0, Ls
    while hi - lo > rtol * hi:
        mid = 0.5 * (lo + hi)
        if scipy_outcome(ba, kappa, eps, mid, Ls):
            hi = mid
        else:
            lo = mid
    return 0.5 * (lo + hi)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sample", type=int, default=10, help="points for the scipy bisection sample")
    ap.add_argument("--repeat", type=int, default=7)
    args = ap.parse_args()

    t0 = time.perf_counter()
    stability_diagram("kappa_ratio", XR, "eps", YE)  # warm-up (compile or load the numba cache)
    print(f"warm-up (numba compile/cache load): {time.perf_counter() - t0:.2f} s")
    times = []
    for _ in range(args.repeat):
        t = time.perf_counter()
        d = stability_diagram("kappa_ratio", XR, "eps", YE)
        times.append(time.perf_counter() - t)
    t_grid = min(times)
    fin = d.kind == 1
    n_fin = int(fin.sum())
    print(
        f"grid 100 x 100: {t_grid * 1e3:.1f} ms (best of {args.repeat}; median {np.median(times) * 1e3:.1f} ms); "
        f"finite {n_fin}, infinite {int((d.kind == 2).sum())}, zero {int((d.kind == 0).sum())}, "
        f"on boundary {int(d.on_boundary.sum())}, fallbacks {d.n_fallback}"
    )

    tight = stability_diagram("kappa_ratio", XR, "eps", YE, rtol=1e-13)
    err = np.abs(d.critical_size[fin] / tight.critical_size[fin] - 1.0)
    print(
        f"max relative error on finite points vs rtol=1e-13 run: {err.max():.2e} "
        f"(reported rel_accuracy max {d.rel_accuracy[fin].max():.1e})"
    )

    rng = np.random.default_rng(0)
    idx = np.argwhere(fin)
    pick = idx[rng.choice(len(idx), args.sample, replace=False)]
    t_sc = 0.0
    dev = 0.0
    for i, j in pick:
        kappa = XR[i] * (BA - 1.0)
        t = time.perf_counter()
        v = scipy_bisection(BA, kappa, YE[j])
        t_sc += time.perf_counter() - t
        dev = max(dev, abs(v / d.critical_size[i, j] - 1.0))
    per_point = t_sc / args.sample
    t_scipy = per_point * n_fin
    print(
        f"scipy solve_ivp(DOP853) bisection: {per_point:.3f} s/point on {args.sample} points "
        f"(max deviation from the grid {dev:.1e}); extrapolated to {n_fin} finite points: {t_scipy:.0f} s"
    )
    print(f"ratio scipy-bisection / rsfcore grid: {t_scipy / t_grid:.3g}x")
    print(
        f"target <= 0.1 s: {'met' if t_grid <= 0.1 else 'NOT met'}; target <= 1e-9: {'met' if err.max() <= 1e-9 else 'NOT met'}"
    )


if __name__ == "__main__":
    main()
