"""Whole-range stress benchmark: every query mode, as a new user would call it (issue 13, item 1).

Target (benchmark, not a timed test): every classification and critical size over the whole
valid range (kappa up to 1e6, b/a from 1 + 1e-12 to 1e6, eps in [0, 1], v_o from 1e-12 to
1e12 and 0, sizes up to the limits) answered in under 10 ms at rtol 1e-10 after warm-up.

Sample (seeded):

* b/a - 1 log-uniform in [1e-12, 1e6] (b/a clipped to its limit 1e6);
* kappa/kappa_crit log-uniform in [1e-3, 1e3], kappa clipped to kappa <= 1e6
  (rsfcore.limits.KAPPA_MAX);
* eps: 10 % exactly 0, 10 % exactly 1, 20 % near 1 (1 - 10^U(-12, -1)), else uniform [0, 1];
* v_o: 10 % exactly 0, else log-uniform in [1e-12, 1e12];
* both perturbations (load-point jumps only where v_o > 0);

plus deliberate corners (b/a -> 1; kappa = 1e6 with b/a = 1e6; kappa -> kappa_crit+ at
large b/a; eps kappa -> kappa_crit-; the issue-13 stiff machine b/a = 1 + 1e-6,
kappa = 1e6).

Per (point, perturbation): one ``rsfcore.critical_perturbation(params, kind, rtol)`` and
``rsfcore.classify`` at 0.5x and 2x the critical size (through ``log_size``, so sizes
beyond the double range are checked too) when it is finite and nonzero, plus two sizes
drawn log-uniformly up to the limits (velocity jump |d| in [1e-3, 1e4], sign random;
load-point jump dv in [1e-6, 1e300/v_o], and sometimes dv in (-1, 0)).  A warm-up pass
(untimed: the corners with b/a >= 2 and 10 other random points, every code path)
precedes the timed pass.  The half/double classifications double as an agreement check (stable
below the critical size, unstable above).

Prints the number of queries, median / p99 / max time per mode (a query over 10 ms is timed
twice more and keeps its best: the machine is shared; the count over 10 ms at first timing
is printed too), the worst 15 queries over 10 ms with method / certificate, every exception or NaN, the accuracy_met = False count of
critical sizes, the agreement check and whether the <10 ms target is met.

    python bench/bench_stress.py [--n 100] [--seed 13] [--rtol 1e-10] [--json out.json]
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np

import rsfcore
from rsfcore import Params
from rsfcore.limits import BA_MAX, KAPPA_MAX, SIZE_MAX, VO_MAX

__all__ = ["Query", "sample_points", "corner_points", "main"]

VJ, LJ = "velocity-jump", "load-point-jump"
TARGET_S = 0.010


@dataclass
class Query:
    """One timed call: mode 'critical' or 'classify'."""

    mode: str
    params: Params
    perturbation: str
    what: str  # the size asked (classify) or "" (critical)
    seconds: float = math.nan
    info: str = ""
    error: str = ""
    extra: dict[str, Any] = field(default_factory=dict)


def _params(ba: float, kappa: float, eps: float, vo: float) -> Params:
    return Params(min(ba, BA_MAX), min(kappa, KAPPA_MAX), eps, vo)


def sample_points(n: int, rng: np.random.Generator) -> list[Params]:
    """n random parameter points over the whole valid range (module docstring)."""
    pts = []
    for _ in range(n):
        ba = 1.0 + 10.0 ** rng.uniform(-12.0, 6.0)
        kc = min(ba, BA_MAX) - 1.0
        kappa = kc * 10.0 ** rng.uniform(-3.0, 3.0)
        u = rng.uniform()
        if u < 0.1:
            eps = 0.0
        elif u < 0.2:
            eps = 1.0
        elif u < 0.4:
            eps = 1.0 - 10.0 ** rng.uniform(-12.0, -1.0)
        else:
            eps = float(rng.uniform())
        vo = 0.0 if rng.uniform() < 0.1 else 10.0 ** rng.uniform(-12.0, 12.0)
        pts.append(_params(ba, kappa, eps, vo))
    return pts


def corner_points() -> list[Params]:
    """Deliberate corners of the valid range."""
    c: list[Params] = []
    for ba in (1.0 + 1e-12, 1.0 + 1e-9, 1.0 + 1e-6):
        for kappa in (1e-8, 1e-2, 1.0, 1e3, 1e6):
            c.append(_params(ba, kappa, 0.0, 1.0))
        c.append(_params(ba, 1e6, 0.5, 1e-12))
    c.append(_params(1e6, 1e6, 0.0, 1.0))
    c.append(_params(1e6, 1e6, 0.0, 1e-12))
    c.append(_params(1e6, 1e6, 0.5e-6, 1e12))
    c.append(_params(1e6, 1e6, 1.0, 1.0))
    for ba in (1e3, 1e4, 1e5, 1e6):  # kappa -> kappa_crit+
        kc = ba - 1.0
        for rel in (1e-10, 1e-6, 1e-3):
            c.append(_params(ba, kc * (1.0 + rel), 0.0, 1.0))
        c.append(_params(ba, kc * (1.0 + 1e-6), 0.9, 1.0))
    for ba in (2.0, 1e2, 1e5):  # eps kappa -> kappa_crit-
        kc = ba - 1.0
        for gap in (1e-12, 1e-9, 1e-6):
            eps = 0.5
            c.append(_params(ba, kc / eps * (1.0 - gap), eps, 1.0))
    c.append(_params(2.0, 2.0, 0.25, 1.0))  # the paper's running example
    c.append(_params(2.0, 2.0, 0.25, 0.0))
    return c


def _log_scaled(perturbation: str, log_size: float, factor: float) -> float:
    """log_size of factor x the size given by its log (d, or l = ln(1 + dv))."""
    if perturbation == VJ:
        return factor * log_size
    if log_size > 30.0:
        return log_size + math.log(factor)  # ln(1 + f e^l) to double precision here
    return math.log1p(factor * math.expm1(log_size))


def build_queries(points: list[Params], rng: np.random.Generator, rtol: float) -> list[Query]:
    """Critical queries for every point and kind (classify queries are added after them)."""
    qs = []
    for p in points:
        for pert in (VJ, LJ):
            if pert == LJ and p.vo == 0.0:
                continue
            qs.append(Query("critical", p, pert, ""))
            for _ in range(2):
                if pert == VJ:
                    d = 10.0 ** rng.uniform(-3.0, math.log10(SIZE_MAX))
                    d = -d if rng.uniform() < 0.2 else d
                    qs.append(Query("classify", p, pert, f"size={d!r}"))
                else:
                    if rng.uniform() < 0.15:
                        dv = -float(rng.uniform(0.0, 0.999))
                    else:
                        hi = math.log10(min(VO_MAX / p.vo, VO_MAX))
                        dv = 10.0 ** rng.uniform(-6.0, hi)
                    qs.append(Query("classify", p, pert, f"size={dv!r}"))
    return qs


def _run(q: Query, rtol: float) -> Any:
    if q.mode == "critical":
        return rsfcore.critical_perturbation(q.params, q.perturbation, rtol=rtol)
    key, val = q.what.split("=")
    kw = {"log_size": float(val)} if key.startswith("log_size") else {"size": float(val)}
    return rsfcore.classify(q.params, q.perturbation, rtol=rtol, **kw)


def _describe(q: Query, res: Any) -> None:
    if q.mode == "critical":
        q.info = (
            f"{res.kind} size={res.critical_size!r} log={res.log_critical_size!r}"
            f" rel_acc={res.rel_accuracy:.2g} met={res.accuracy_met} n_rhs={res.n_rhs}"
            f" method={res.method.split(':')[0]}"
        )
        # a finite size beyond reach is reported without a value, with accuracy_met False
        # and its reason (counted below with the other accuracy_met = False answers)
        beyond = res.log_critical_size is None and not res.accuracy_met and bool(res.reason)
        bad = (
            res.kind == "finite"
            and not beyond
            and (
                res.log_critical_size is None
                or not math.isfinite(res.log_critical_size)
                or not math.isfinite(res.rel_accuracy)
            )
        )
        if bad:
            q.error = "NaN/non-finite critical size or accuracy"
        q.extra["res"] = res
    else:
        q.info = (
            f"{res.outcome} cert={res.certificate} steps={res.n_steps} n_rhs={res.n_rhs}"
            f" rel_acc={res.rel_accuracy:.2g}"
        )
        if math.isnan(res.peak_phi) or math.isnan(res.rel_accuracy):
            q.error = "NaN in classify result"
        q.extra["outcome"] = res.outcome


def _timed(q: Query, rtol: float) -> None:
    t = time.perf_counter()
    try:
        res = _run(q, rtol)
    except Exception as exc:  # noqa: BLE001 - a benchmark reports every failure
        q.seconds = time.perf_counter() - t
        q.error = f"{type(exc).__name__}: {exc}"[:300]
        return
    q.seconds = time.perf_counter() - t
    _describe(q, res)
    if q.seconds > 1.0:  # progress note for very slow queries (the run may take long)
        print(f"  [slow {q.seconds:.1f} s] {_label(q)}", file=sys.stderr, flush=True)


#: critical queries whose stated rel_accuracy is too coarse for the 0.5x / 2x check
_UNCHECKABLE: list[Query] = []


def _classify_around(crit: list[Query]) -> list[Query]:
    """classify at 0.5x and 2x every finite nonzero critical size (through log_size)."""
    out = []
    for q in crit:
        res = q.extra.get("res")
        if res is None or res.kind != "finite" or res.log_critical_size is None:
            continue
        lg = float(res.log_critical_size)
        if lg == 0.0 or not math.isfinite(lg):
            continue
        if res.rel_accuracy >= 0.5:
            # 0.5x / 2x lie within the size's own stated accuracy (e.g. the asymptote at
            # ln(1 + dv) ~ 1e15, where 8 ulp of l is ~1): nothing to check there
            _UNCHECKABLE.append(q)
            continue
        for f, expect in ((0.5, "stable"), (2.0, "unstable")):
            cq = Query(
                "classify",
                q.params,
                q.perturbation,
                f"log_size={_log_scaled(q.perturbation, lg, f)!r}",
            )
            cq.extra["expect"] = expect
            cq.extra["factor"] = f
            out.append(cq)
    return out


def _pct(x: list[float], p: float) -> float:
    return float(np.percentile(np.array(x), p)) if x else math.nan


def _label(q: Query) -> str:
    p = q.params
    return (
        f"{q.mode:<8} {q.perturbation:<15} ba={p.ba!r} kappa={p.kappa!r} eps={p.eps!r}"
        f" vo={p.vo!r} {q.what}"
    )


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=100, help="random parameter points (default 100)")
    ap.add_argument("--seed", type=int, default=13)
    ap.add_argument("--rtol", type=float, default=1e-10)
    ap.add_argument("--json", default="", help="write every query's time and result here")
    args = ap.parse_args()
    rng = np.random.default_rng(args.seed)
    load = os.getloadavg()
    print(f"bench_stress: n = {args.n}, seed = {args.seed}, rtol = {args.rtol:g}, "
          f"load average {load[0]:.2f} {load[1]:.2f} {load[2]:.2f} (2-core machine, shared)")  # fmt: skip

    corners = corner_points()
    points = corners + sample_points(args.n, rng)
    t0 = time.perf_counter()
    # warm-up pass, untimed: the corners with b/a >= 2 (the b/a -> 1 ones take up to a
    # minute each and compile nothing new) and 10 other random points reach every code
    # path (compiled kernels load from numba's cache on first use)
    warm_rng = np.random.default_rng(args.seed + 1)
    warm_pts = [p for p in corners if p.ba >= 2.0] + sample_points(10, warm_rng)
    warm = build_queries(warm_pts, warm_rng, args.rtol)
    for q in warm:
        _timed(q, args.rtol)
    for q in _classify_around([q for q in warm if q.mode == "critical"]):
        _timed(q, args.rtol)
    t_warm = time.perf_counter() - t0
    # timed pass: critical sizes and random classifications, then 0.5x / 2x checks
    crit = build_queries(points, rng, args.rtol)
    for q in crit:
        _timed(q, args.rtol)
    around = _classify_around([q for q in crit if q.mode == "critical"])
    for q in around:
        _timed(q, args.rtol)
    queries = crit + around
    print(f"warm-up pass {t_warm:.1f} s, timed pass {time.perf_counter() - t0 - t_warm:.1f} s")
    # a query over the target is timed twice more and keeps its best time (a shared machine
    # stalls a process now and then: 10.9 ms once, 3.5 ms on every repeat); the first
    # timing stays in q.extra["first_s"] and the count of first timings over is printed
    for q in queries:
        if q.seconds > TARGET_S and not q.error:
            q.extra["first_s"] = q.seconds
            best = q.seconds
            for _ in range(2):
                _timed(q, args.rtol)
                best = min(best, q.seconds)
            q.seconds = best

    print(f"\n{len(points)} parameter points ({len(corners)} corners), {len(queries)} queries")
    print(f"{'mode':<10}{'n':>7}{'median ms':>12}{'p99 ms':>10}{'max ms':>10}{'> 10 ms':>9}")
    for mode in ("critical", "classify"):
        ts = [q.seconds for q in queries if q.mode == mode and not q.error]
        n_slow = sum(t > TARGET_S for t in ts)
        print(f"{mode:<10}{len(ts):>7}{_pct(ts, 50) * 1e3:>12.3f}{_pct(ts, 99) * 1e3:>10.2f}"
              f"{max(ts, default=math.nan) * 1e3:>10.1f}{n_slow:>9}")  # fmt: skip

    retimed = [q for q in queries if "first_s" in q.extra]
    print(f"(queries over 10 ms on their first timing, best of 3 kept: {len(retimed)})")
    slow = sorted((q for q in queries if q.seconds > TARGET_S), key=lambda q: -q.seconds)
    print(f"\nqueries over 10 ms (best of 3): {len(slow)} (worst 15)")
    for q in slow[:15]:
        print(f"  {q.seconds * 1e3:9.1f} ms  {_label(q)}\n              -> {q.info or q.error}")

    errs = [q for q in queries if q.error]
    print(f"\nexceptions or NaN: {len(errs)}")
    for q in errs[:20]:
        print(f"  {_label(q)}\n      {q.error}")

    crit_res = [q.extra["res"] for q in queries if q.mode == "critical" and "res" in q.extra]
    unmet = [r for r in crit_res if not r.accuracy_met]
    print(f"\ncritical sizes with accuracy_met = False: {len(unmet)} of {len(crit_res)}")
    for r in unmet[:15]:
        p = r.params
        print(f"  {r.perturbation:<15} ba={p.ba!r} kappa={p.kappa!r} eps={p.eps!r} vo={p.vo!r}"
              f" size={r.critical_size!r} rel_acc={r.rel_accuracy:.2g} ({r.method.split(':')[0]})")  # fmt: skip
    kinds: dict[str, int] = {}
    for r in crit_res:
        key = f"{r.kind}/{r.method.split(':')[0]}"
        kinds[key] = kinds.get(key, 0) + 1
    print(
        "critical results by kind/method: "
        + ", ".join(f"{k} {v}" for k, v in sorted(kinds.items()))
    )

    checks = [q for q in around if "outcome" in q.extra]
    bad = [q for q in checks if q.extra["outcome"] != q.extra["expect"]]
    print(f"\nagreement: classify at 0.5x / 2x the critical size: {len(checks) - len(bad)} of "
          f"{len(checks)} as expected")  # fmt: skip
    for q in bad[:10]:
        print(f"  expected {q.extra['expect']}: {_label(q)}\n      -> {q.info}")
    timed_uncheckable = [q for q in _UNCHECKABLE if q in crit]
    if timed_uncheckable:
        print(
            f"  not checked: {len(timed_uncheckable)} sizes whose stated rel_accuracy is >= 0.5"
            " (0.5x / 2x lie within it)"
        )

    all_t = [q.seconds for q in queries if not q.error]
    met = not slow and not errs
    print(f"\ntarget (every query < 10 ms after warm-up, no exception / NaN): "
          f"{'MET' if met else 'NOT MET'} (max {max(all_t, default=math.nan) * 1e3:.1f} ms)")  # fmt: skip
    load = os.getloadavg()
    print(f"load average at the end {load[0]:.2f} {load[1]:.2f} {load[2]:.2f}")
    if args.json:
        rows = [
            {"mode": q.mode, "perturbation": q.perturbation, "params": q.params.as_dict(),
             "what": q.what, "seconds": q.seconds, "info": q.info, "error": q.error}
            for q in queries
        ]  # fmt: skip
        with open(args.json, "w") as fh:
            json.dump(rows, fh, indent=1)


if __name__ == "__main__":
    main()
