"""Benchmark: fitting 10^4-sample lab records, the library and `rsf fit` against the
do-it-yourself route, in the same run.

Records (10^4 samples each; aging law, a = 0.01, b = 0.015, Dc = 10 um, mu0 = 0.6,
machine k = 1000 /m = 2 k_crit; Gaussian noise 1e-4 in friction; computed by
rsfcore.fit.synthetic_record at rtol 1e-13):

* ``single-step``: 1 um/s for 20 s, 10 um/s for 40 s;
* ``multi-step+trend``: 1, 10, 3, 30, 1, 10 um/s (5 steps over 200 s) with a linear
  friction trend of 20 /m in load-point displacement (slip hardening), fitted with the
  trend term;
* ``slide-hold-slide``: 1 um/s for 20 s, hold 30 s, 1 um/s for 50 s.

Routes (stiffness fitted in every route, as the library does by default):

* library: ``rsfcore.fit.fit_record(record, "aging")`` (the default options: covariance,
  identifiability and linearity checks, stability answer with 400 covariance samples);
  best of 3 after a warm-up, wall and CPU time;
* library comparison: ``rsfcore.fit.compare_laws(record)`` of the four laws (aging,
  slip, nagata, eps) with every law fitted completely (the library's default), and with
  ``complete=()`` as the CLI and HTTP fits run it (laws stop once their rejection is
  certain; the best law is always complete); best of 3, wall and CPU time, and the
  status per law;
* CLI: ``rsf fit FILE --law aging --no-compare [--trend] --json`` as a subprocess
  (python -m rsfcli.main), warm (second run; kernels cached), wall and CPU time end to
  end; and the DEFAULT ``rsf fit FILE [--trend] --json`` (all four laws compared, the
  aging law reported as best), timed the same way;
* do-it-yourself: an rsfmodel-style forward model written here (the textbook SI
  equations, mu = mu0 + a ln(V/V0) + b ln(V0 theta/Dc) [+ trend x_lp],
  d mu/dt = k (v_lp - V), d theta/dt = 1 - V theta/Dc, integrated by
  scipy.integrate.solve_ivp LSODA at rtol 1e-8, segment by segment, t_eval at the
  samples) and scipy.optimize.least_squares (trf, 2-point Jacobian, x_scale set to the
  parameters' magnitudes, default tolerances) on (mu0, a, b, Dc, k [, trend]) from a
  reasonable lab start: mu0 = first friction sample, a = 0.005, b = 0.01, Dc = 20 um,
  k = 3000 /m [, trend 0].

Printed per case and route: time per fit, status, and each parameter's error relative to
the truth and in units of the library's stated standard error.  Targets (issue 23):
library <= 0.2 s, CLI <= 1.5 s warm.  Also the machine load (os.getloadavg): on a shared
machine the wall times scale with it; CPU times less so.

    python bench/bench_fit.py            # all routes
    python bench/bench_fit.py --no-diy   # skip the (slow) do-it-yourself route
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("MKL_NUM_THREADS", "1")
os.environ.setdefault("NUMBA_NUM_THREADS", "1")

import json  # noqa: E402
import math  # noqa: E402
import resource  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
from dataclasses import dataclass  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402
from numpy.typing import NDArray  # noqa: E402
from scipy.integrate import solve_ivp  # noqa: E402
from scipy.optimize import least_squares  # noqa: E402

from rsfcore.fit import Record, compare_laws, fit_record, synthetic_record  # noqa: E402

N = 10_000
NOISE = 1e-4
TRUE = {"mu0": 0.6, "a": 0.01, "b": 0.015, "Dc_m": 1e-5, "eps": 1.0, "k_per_m": 1000.0}
NAMES = ("mu0", "a", "b", "Dc_m", "k_per_m")


@dataclass(frozen=True)
class Case:
    name: str
    record: Record
    trend: float  # true trend [1/m] (fitted when nonzero)


def cases() -> list[Case]:
    out = []
    t = np.linspace(0.0, 60.0, N)
    v = np.where(t < 20.0, 1e-6, 1e-5)
    out.append(Case("single-step", synthetic_record(t, v, **TRUE, noise=NOISE, rtol=1e-13), 0.0))
    t = np.linspace(0.0, 200.0, N)
    v = np.full(N, 1e-6)
    for t0, t1, vv in ((30, 60, 1e-5), (60, 90, 3e-6), (90, 120, 3e-5), (120, 150, 1e-6)):
        v[(t >= t0) & (t < t1)] = vv
    v[t >= 150] = 1e-5
    rec = synthetic_record(t, v, **TRUE, trend_per_m=20.0, noise=NOISE, rtol=1e-13, seed=2)
    out.append(Case("multi-step+trend", rec, 20.0))
    t = np.linspace(0.0, 100.0, N)
    v = np.where((t >= 20.0) & (t < 50.0), 0.0, 1e-6)
    out.append(
        Case(
            "slide-hold-slide", synthetic_record(t, v, **TRUE, noise=NOISE, rtol=1e-13, seed=3), 0.0
        )
    )
    return out


# --------------------------------------------------------------------------- DIY route
class DiyModel:
    """rsfmodel-style forward model: textbook SI equations by solve_ivp (LSODA)."""

    def __init__(self, rec: Record, rtol: float = 1e-8) -> None:
        self.t, self.v, self.rtol = rec.t_s, rec.v_lp_m_s, rtol
        self.x = rec.load_point_m
        self.starts = [int(i) for i in rec.segment_starts] + [rec.n]
        self.runs = 0

    def friction(
        self, mu0: float, a: float, b: float, Dc: float, k: float, c: float
    ) -> NDArray[np.float64]:
        self.runs += 1
        V0 = float(self.v[0])

        def rhs(_t: float, y: NDArray[np.float64], vlp: float) -> list[float]:
            mu, th = y
            arg = (mu - mu0 - b * math.log(max(V0 * th / Dc, 1e-300))) / a
            V = V0 * math.exp(min(arg, 700.0))
            return [k * (vlp - V), 1.0 - V * th / Dc]

        y = np.array([mu0, Dc / V0])
        out = np.full(self.t.shape[0], np.nan)
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
                method="LSODA",
                t_eval=te,
                rtol=self.rtol,
                atol=[1e-12, 1e-12 * Dc / V0],
                args=(float(self.v[i0]),),
            )
            if not sol.success:
                return out
            out[i0:i1] = sol.y[0, : i1 - i0]
            y = sol.y[:, -1]
        return out + c * self.x


def diy_fit(case: Case) -> tuple[float, dict[str, float], str, int]:
    rec = case.record
    model = DiyModel(rec)
    with_trend = case.trend != 0.0

    def resid(p: NDArray[np.float64]) -> NDArray[np.float64]:
        c = p[5] if with_trend else 0.0
        r = model.friction(p[0], p[1], p[2], p[3], p[4], c) - rec.mu
        r[~np.isfinite(r)] = 1.0
        return r

    x0 = [float(rec.mu[0]), 0.005, 0.01, 2e-5, 3000.0] + ([0.0] if with_trend else [])
    lo = [-10.0, 1e-6, -1.0, 1e-9, 1.0] + ([-1e4] if with_trend else [])
    hi = [10.0, 1.0, 1.0, 1e-1, 1e9] + ([1e4] if with_trend else [])
    scale = [1.0, 0.01, 0.01, 1e-5, 1e3] + ([10.0] if with_trend else [])
    t0 = time.process_time()
    sol = least_squares(resid, x0, bounds=(lo, hi), x_scale=scale, method="trf")
    dt = time.process_time() - t0
    est = dict(zip(NAMES, (float(v) for v in sol.x[:5]), strict=True))
    if with_trend:
        est["trend_per_m"] = float(sol.x[5])
    return dt, est, str(sol.message), model.runs


# --------------------------------------------------------------------------- routes
def library_fit(case: Case) -> tuple[float, float, object]:
    kw = {"trend": case.trend != 0.0}
    fit_record(case.record, "aging", **kw)  # warm-up
    best_wall, best_cpu, res = math.inf, math.inf, None
    for _ in range(3):
        w0, c0 = time.perf_counter(), time.process_time()
        res = fit_record(case.record, "aging", **kw)
        best_wall = min(best_wall, time.perf_counter() - w0)
        best_cpu = min(best_cpu, time.process_time() - c0)
    return best_wall, best_cpu, res


def library_compare(case: Case, complete: tuple[str, ...] | None) -> tuple[float, float, object]:
    kw = {"trend": case.trend != 0.0, "complete": complete}
    compare_laws(case.record, **kw)  # warm-up
    best_wall, best_cpu, res = math.inf, math.inf, None
    for _ in range(3):
        w0, c0 = time.perf_counter(), time.process_time()
        res = compare_laws(case.record, **kw)
        best_wall = min(best_wall, time.perf_counter() - w0)
        best_cpu = min(best_cpu, time.process_time() - c0)
    return best_wall, best_cpu, res


def _children_cpu() -> float:
    ru = resource.getrusage(resource.RUSAGE_CHILDREN)
    return ru.ru_utime + ru.ru_stime


def cli_fit(path: Path, case: Case, compare: bool) -> tuple[float, float, dict]:
    args = [sys.executable, "-m", "rsfcli.main", "fit", str(path), "--json"]
    if not compare:
        args += ["--law", "aging", "--no-compare"]
    if case.trend:
        args.append("--trend")
    times = []
    out: dict = {}
    cpu = 0.0
    for _ in range(2):  # the first warms the kernel cache and the OS file cache
        t0, c0 = time.perf_counter(), _children_cpu()
        p = subprocess.run(args, capture_output=True, text=True, check=True)
        times.append(time.perf_counter() - t0)
        cpu = _children_cpu() - c0
        out = json.loads(p.stdout)
    return times[-1], cpu, out


def errors(est: dict[str, float], truth: dict[str, float], se: dict[str, float | None]) -> str:
    parts = []
    for n, v in truth.items():
        rel = est[n] / v - 1.0
        s = se.get(n)
        z = f" ({(est[n] - v) / s:+.1f} se)" if s else ""
        parts.append(f"{n} {rel:+.1e}{z}")
    return "  ".join(parts)


def main() -> None:
    diy = "--no-diy" not in sys.argv
    print(
        f"10^4-sample records, aging law, k = {TRUE['k_per_m']:g} /m (2 k_crit), noise {NOISE:g}; "
        f"load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} CPUs"
    )
    with tempfile.TemporaryDirectory() as tmp:
        for case in cases():
            truth = {n: TRUE[n] for n in NAMES}
            if case.trend:
                truth["trend_per_m"] = case.trend
            wall, cpu, res = library_fit(case)
            assert res is not None
            se = res.stderr  # type: ignore[attr-defined]
            print(f"\n[{case.name}] {case.record.n} samples, {case.record.n_steps} steps")
            print(
                f"  library  {wall:6.3f} s wall ({cpu:.3f} s CPU), status "
                f"{res.status.value}, {res.n_model_evals} forward runs"  # type: ignore[attr-defined]
            )
            print(f"           errors: {errors(res.params, truth, se)}")  # type: ignore[attr-defined]
            for label, complete in (("complete", None), ("CLI-style", ())):
                w, c, cmp = library_compare(case, complete)
                laws = ", ".join(
                    f"{k} {f.status.value}{' (stopped)' if f.stopped_early else ''}"
                    for k, f in cmp.fits.items()  # type: ignore[attr-defined]
                )
                print(
                    f"  compare  {w:6.3f} s wall ({c:.3f} s CPU), 4 laws, {label}: best "
                    f"{cmp.best}; {laws}"  # type: ignore[attr-defined]
                )
            path = Path(tmp) / f"{case.name}.csv"
            path.write_text(case.record.to_csv())
            t_cli, c_cli, d = cli_fit(path, case, compare=False)
            same = all(d["params"][n] == res.params[n] for n in truth)  # type: ignore[attr-defined]
            print(
                f"  rsf fit  {t_cli:6.3f} s wall ({c_cli:.3f} s CPU) warm, end to end "
                f"(--law aging --no-compare); status {d['status']}; parameters equal to the "
                f"library's: {same}"
            )
            t_cmp, c_cmp, d2 = cli_fit(path, case, compare=True)
            same2 = all(d2["params"][n] == res.params[n] for n in truth)  # type: ignore[attr-defined]
            print(
                f"  rsf fit  {t_cmp:6.3f} s wall ({c_cmp:.3f} s CPU) warm, end to end, DEFAULT "
                f"(4 laws compared; best {d2['law_comparison']['best']}, status {d2['status']}; "
                f"parameters equal to the library's: {same2})"
            )
            if diy:
                t_diy, est, msg, runs = diy_fit(case)
                print(
                    f"  DIY      {t_diy:6.3f} s CPU ({runs} forward runs; {msg}) "
                    f"x{t_diy / cpu:.0f} the library's CPU time"
                )
                print(f"           errors: {errors(est, truth, se)}")


if __name__ == "__main__":
    main()
