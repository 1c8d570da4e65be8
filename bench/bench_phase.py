"""Phase-plane classification of 1e5 start points: rsfcore.classify_points against a loop of
rsfcore.classify (the obvious alternative), in the same run.

Cases (rtol 1e-10): a separatrix case (b/a = 2, kappa = 1.5, eps = 0.3), a small-b/a one
(b/a = 1.25, kappa = 0.5, eps = 0), one far from v_o = 1 (b/a = 10, kappa = 20, eps = 0.4,
v_o = 1e-3) and kappa = kappa_crit (U sign).  Points: uniform random over phi in
ln v_o + [-4, 6], ln theta in -ln v_o + [-5, 4].  For each case it prints the warm-up
(first call, compilation from cache included), the best of 5 warm calls for 1e5 points,
the separatrix tracing alone, how many points were integrated (the margin), and the time
of classify() per point on 1000 points, extrapolated to 1e5.  Agreement with classify is
checked on those 1000 points.

    python bench/bench_phase.py [--n 100000]
"""

from __future__ import annotations

import argparse
import math
import time

import numpy as np

from rsfcore import Params, classify
from rsfcore.phase import PointMethod, classify_points, trace_separatrix

RTOL = 1e-10
CASES = [
    Params(2.0, 1.5, 0.3),
    Params(1.25, 0.5, 0.0),
    Params(10.0, 20.0, 0.4, 1e-3),
    Params(2.0, 1.0, 0.3),
]


def points(p: Params, n: int, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    lnvo = math.log(p.vo)
    phi = lnvo + rng.uniform(-4.0, 6.0, n)
    lth = -lnvo + rng.uniform(-5.0, 4.0, n)
    return phi, phi + p.ba * lth


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--n", type=int, default=100_000)
    ap.add_argument("--n-loop", type=int, default=1000)
    args = ap.parse_args()
    print(f"classify_points vs a loop of classify, rtol {RTOL:g}, {args.n} random points")
    print(
        f"{'case':48s} {'first':>8s} {'warm':>8s} {'trace':>8s} {'integr.':>7s} "
        f"{'loop/pt':>9s} {'loop 1e5':>9s} {'speed-up':>9s} agree"
    )
    for p in CASES:
        phi, psi = points(p, args.n)
        t0 = time.perf_counter()
        classify_points(p, phi[:10], psi[:10], rtol=RTOL)
        first = time.perf_counter() - t0
        best = math.inf
        for _ in range(5):
            t0 = time.perf_counter()
            r = classify_points(p, phi, psi, rtol=RTOL)
            best = min(best, time.perf_counter() - t0)
        t0 = time.perf_counter()
        sep = trace_separatrix(p, RTOL)
        trace = time.perf_counter() - t0 if sep is not None else 0.0
        n_int = int(np.count_nonzero(r.method == PointMethod.INTEGRATED))
        m = args.n_loop
        t0 = time.perf_counter()
        ref = [
            classify(p, start=(float(a), float(b)), rtol=RTOL).outcome == "unstable"
            for a, b in zip(phi[:m], psi[:m], strict=True)
        ]
        per = (time.perf_counter() - t0) / m
        agree = bool(np.array_equal(np.array(ref), r.unstable[:m]))
        print(
            f"{str(p):48s} {first * 1e3:7.1f}ms {best * 1e3:7.1f}ms {trace * 1e3:7.2f}ms "
            f"{n_int:7d} {per * 1e6:8.1f}us {per * args.n:8.2f}s {per * args.n / best:8.0f}x "
            f"{agree}"
        )


if __name__ == "__main__":
    main()
