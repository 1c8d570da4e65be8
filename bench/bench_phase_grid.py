"""classify_points over a grid of parameter sets: seconds per 10^5 starts (issue 22, item 3).

For every parameter set of a grid over b/a (1.01 .. 1e6), kappa/kappa_crit (1.0001 .. 10)
and eps (0, 0.3), plus the corners where the separatrix was not traced before RODAS4 took
over its stiff part ((b/a, kappa) = (1e4, 1.0001e4), (1e5, 1.1e5), (1e6, 1e6), eps = 0),
and for each rtol, it times one warm call of rsfcore.classify_points on 10^5 random
starts (phi in ln v_o + [-4, 6], ln theta in -ln v_o + [-5, 4], as bench/bench_phase.py)
and one warm call of critical_perturbation (velocity jump) for comparison.  Prints, per
rtol, p50 / p99 / max of the wall time per 10^5 starts and of the CPU time of the
process, the worst sets with their parameters, the number of integrated starts (the
margin) and how the separatrix was traced (steps, RODAS4 steps; "none" = not traced,
every start integrated).  The machine's load average is printed with the figures: on the
shared development machine wall times are up to ~(load / cores) x the CPU times.

    python bench/bench_phase_grid.py [--n 100000] [--rtol 1e-6 1e-8 1e-10 1e-12 1e-13] [--quick]
"""

from __future__ import annotations

import argparse
import os
import time

import numpy as np
from bench_phase import points as starts  # the same random starts as bench/bench_phase.py

from rsfcore import Params, critical_perturbation
from rsfcore.phase import classify_points, trace_separatrix

CORNERS = [(1e4, 1.0001e4, 0.0), (1e5, 1.1e5, 0.0), (1e6, 1e6, 0.0)]


def grid(quick: bool) -> list[tuple[float, float, float]]:
    bas = [1.01, 2.0, 10.0, 1e2, 1e3, 1e4, 1e5, 1e6]
    ratios = [1.0001, 1.1, 2.0, 10.0]
    epss = [0.0, 0.3]
    if quick:
        bas, ratios, epss = [2.0, 1e3, 1e6], [1.1, 2.0], [0.0]
    out = list(CORNERS)
    for ba in bas:
        for r in ratios:
            for eps in epss:
                kappa = r * (ba - 1.0)
                if kappa <= 1e6:  # the valid range of kappa (rsfcore.limits.KAPPA)
                    out.append((ba, kappa, eps))
    return out


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--n", type=int, default=100_000)
    ap.add_argument("--rtol", type=float, nargs="+", default=[1e-6, 1e-8, 1e-10, 1e-12, 1e-13])
    ap.add_argument("--quick", action="store_true", help="a 6-set grid (a smoke run)")
    args = ap.parse_args()
    sets = grid(args.quick)
    scale = 1e5 / args.n
    # warm-up: load every kernel once
    p0 = Params(2.0, 3.0, 0.25)
    classify_points(p0, *starts(p0, 10), rtol=1e-10)
    critical_perturbation(p0, rtol=1e-10)
    print(f"classify_points, {args.n} random starts per set, {len(sets)} parameter sets")
    print(f"load average at start: {os.getloadavg()[0]:.1f} ({os.cpu_count()} cores)")
    for rtol in args.rtol:
        rows = []
        for ba, kappa, eps in sets:
            p = Params(ba, kappa, eps)
            phi, psi = starts(p, args.n)
            t0, c0 = time.perf_counter(), time.process_time()
            r = classify_points(p, phi, psi, rtol=rtol)
            wall = (time.perf_counter() - t0) * scale
            cpu = (time.process_time() - c0) * scale
            t0 = time.perf_counter()
            critical_perturbation(p, rtol=rtol)
            crit = time.perf_counter() - t0
            sep = trace_separatrix(p, rtol)
            how = "none" if sep is None else f"{sep.n_a + sep.n_b} steps/{sep.n_stiff} RODAS4"
            rows.append((wall, cpu, crit, r.n_integrated, how, ba, kappa, eps))
        wall = np.array([w[0] for w in rows])
        cpu = np.array([w[1] for w in rows])
        print(
            f"\nrtol {rtol:g}: s per 1e5 starts  wall p50 {np.median(wall):.4f} "
            f"p99 {np.quantile(wall, 0.99):.4f} max {wall.max():.4f} | CPU p50 "
            f"{np.median(cpu):.4f} p99 {np.quantile(cpu, 0.99):.4f} max {cpu.max():.4f}  "
            f"(load {os.getloadavg()[0]:.1f})"
        )
        print(
            f"  {'b/a':>9s} {'kappa':>11s} {'eps':>4s} {'wall s':>8s} {'CPU s':>8s} "
            f"{'critical':>9s} {'integr.':>7s}  separatrix"
        )
        order = sorted(rows, key=lambda w: -w[0])
        corners = [w for w in rows if (w[5], w[6], w[7]) in CORNERS]
        for w in order[:5] + [c for c in corners if c not in order[:5]]:
            print(
                f"  {w[5]:9.4g} {w[6]:11.6g} {w[7]:4.2g} {w[0]:8.4f} {w[1]:8.4f} "
                f"{w[2] * 1e3:7.2f}ms {w[3]:7d}  {w[4]}"
            )


if __name__ == "__main__":
    main()
