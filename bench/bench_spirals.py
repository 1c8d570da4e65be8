"""Slow outward spirals: are a trajectory's reported times within their claims? (issue 22)

bench/bench_certificates.py asks trajectories only around finite critical sizes (kappa >
kappa_crit).  Here every point has kappa < kappa_crit with v_o > 0, where the outcome
(unstable, linear instability) is certain before integrating and the trajectory runs on
through the spiral to its blow-up: b/a - 1 log-uniform in [1e-12, 10], kappa/kappa_crit in
10^U(-3, 0), eps 0, 1 or uniform, v_o in 10^U(-12, 12), both perturbations (d in
+-10^U(-3, 1), dv in 10^U(-3, 2) or in (-0.99, 0)), rtol log-uniform in [1e-13, 1e-3].

Per query: rsfcore.simulate with 50 samples; where it reports a blow-up time, that time
against one run at rtol 1e-13 (its own error taken as 5/0.9 x its distance to a run at
1e-12, plus 3e-13; runs without the check runs, with REF_BUDGET steps).
Counts the times checked, the times not reported (None, complete false: not checked
within the budget, see rsfcore.trajectory.TRAJECTORY_CHECK_RATIO) and the violations
(error above the claim plus the reference's own error).

    python bench/bench_spirals.py [--n 150] [--seed 31]
"""

from __future__ import annotations

import argparse
import time

import numpy as np

import rsfcore
from rsfcore import Params
from rsfcore import trajectory as tr
from rsfcore.errors import ParameterError, UndecidedError

__all__ = ["main"]

VJ, LJ = "velocity-jump", "load-point-jump"


#: step budget of a reference run (the trajectory's own, DECIDED_OUTCOME_BUDGET, stops short
#: of the blow-up it is to time)
REF_BUDGET = 500_000


def _one_run(p: Params, pert: str, size: float, rtol: float) -> rsfcore.TrajectoryResult:
    """One run without check runs, with the step budget of a reference (REF_BUDGET)."""
    return tr._simulate(p, pert, size, rtol=rtol, n_points=2, decided_budget=REF_BUDGET)


def _point(rng: np.random.Generator) -> tuple[Params, str, float, float]:
    ba = 1.0 + 10.0 ** rng.uniform(-12.0, 1.0)
    kappa = (ba - 1.0) * 10.0 ** rng.uniform(-3.0, -1e-3)
    eps = float(rng.choice([0.0, 1.0, rng.uniform()]))
    vo = 10.0 ** rng.uniform(-12.0, 12.0)
    if rng.uniform() < 0.6:
        pert = VJ
        size = 10.0 ** rng.uniform(-3.0, 1.0) * (1.0 if rng.uniform() < 0.8 else -1.0)
    else:
        pert = LJ
        size = 10.0 ** rng.uniform(-3.0, 2.0) if rng.uniform() < 0.8 else -rng.uniform(0.0, 0.99)
    return Params(ba, kappa, eps, vo), pert, float(size), 10.0 ** rng.uniform(-13.0, -3.0)


def main() -> None:
    ap = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    ap.add_argument("--n", type=int, default=150, help="queries")
    ap.add_argument("--seed", type=int, default=31)
    a = ap.parse_args()
    rng = np.random.default_rng(a.seed)
    viol = checked = unreported = errors = 0
    worst = 0.0
    t0 = time.perf_counter()
    for _ in range(a.n):
        p, pert, size, rtol = _point(rng)
        try:
            r = rsfcore.simulate(p, pert, size, rtol=rtol, n_points=50)
        except (ParameterError, UndecidedError):
            errors += 1
            continue
        if r.blowup_time is None:
            unreported += 1
            continue
        try:
            ref, ref10 = _one_run(p, pert, size, 1e-13), _one_run(p, pert, size, 1e-12)
        except (ParameterError, UndecidedError):
            continue
        if ref.blowup_time is None or ref10.blowup_time is None or not ref.complete:
            continue
        b = ref.blowup_time
        ref_err = 5.0 * abs(b - ref10.blowup_time) / abs(b) / 0.9 + 3e-13
        ratio = abs(r.blowup_time - b) / abs(b) / (r.rel_accuracy + ref_err)
        checked += 1
        worst = max(worst, ratio)
        if ratio > 1.0:
            viol += 1
            print(
                f"  VIOLATION {ratio:.3g}x: {p} {pert} size={size!r} rtol={rtol:.3g}"
                f" blowup_time={r.blowup_time!r} reference={b!r} claim={r.rel_accuracy:.3g}",
                flush=True,
            )
    print(
        f"seed {a.seed}: {a.n} queries in {time.perf_counter() - t0:.0f} s; blow-up times"
        f" checked {checked}, not reported {unreported}, errors {errors};"
        f" violations {viol}; worst error/claim {worst:.3g}"
    )


if __name__ == "__main__":
    main()
