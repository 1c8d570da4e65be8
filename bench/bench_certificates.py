"""Certificate stress run: are classify's outcomes and accuracies always true? (issue 22)

Own sampling and seeds (independent of bench/bench_stress.py), over the whole valid range:

* b/a - 1 log-uniform in [1e-12, 1e6] (half of the points in the corner b/a - 1 < 1e-6);
* kappa/kappa_crit: 30 % log-uniform in [1e-3, 1e3], 30 % near 1 (1 + 10^U(-12, 0)),
  40 % placed near x = eps kappa/kappa_crit = 1 (x = 1 - 10^U(-12, -1), the issue-22
  corner), kappa clipped to 1e6;
* eps: 10 % 0, 10 % 1, 30 % uniform, the rest from the x placement;
* v_o: 10 % exactly 0, else 10^U(-300, 300) on a quarter of the points, 10^U(-40, 40)
  on the rest;
* rtol of every query log-uniform in [1e-13, 1e-3]; both perturbations;
* on 6 % of the points kappa is replaced by 0 or 10^U(-300, -15) (TINY_KAPPA_SHARE).

Where the critical size is "zero" or "infinite", classify at two positive sizes (d in
10^U(-3, 1), dv in 10^U(-3, 2)) must give the kind's side (unstable, stable), each
against its rtol 1e-13 run as below.

Per (point, perturbation) with a finite critical size s_c (rel_accuracy a_c): classify at
s_c (1 -/+ f), f in {0.1, 1e-2, 1e-3} where f > 4 a_c (through log_size), each at its own
rtol, and the same starts at rtol 1e-13 (the reference).  Checks:

1. contradiction: an outcome that contradicts the critical size (stable above, unstable
   below) outside its stated error;
2. monotone: the outcomes along the sizes are stable ... stable, unstable ... unstable;
3. wrong: a complete outcome that differs from the rtol 1e-13 run (and, where they
   disagree, from the critical size's side: the referee);
4. bound: every time and peak within its rel_accuracy of the reference (plus the
   reference's own claim);
   The trajectory (simulate, 16 samples) at s_c (1 -/+ 1e-2) and the query's rtol: the
   same outcome as classify (else trajectory_differs), no NaN, fields within its claim;
5. exceptions other than ParameterError and UndecidedError(reason="not_certified")
   (an uncertified answer that says so is counted apart).

Timing: p50 / p99 / max per rtol decade and the slowest queries with their parameters.

    python bench/bench_certificates.py [--n 800] [--seed 2211] [--json out.json]
        [--checkpoint run.jsonl] [--summary-only] [--points 3,17]
"""

from __future__ import annotations

import argparse
import json
import math
import time
from typing import Any

import numpy as np

import rsfcore as rc
from rsfcore.errors import ParameterError, UndecidedError

VJ, LJ = "velocity-jump", "load-point-jump"
FRACTIONS = (0.1, 1e-2, 1e-3)
#: at s_c (1 -/+ this) the trajectory (simulate with 16 samples) is asked too
TRAJECTORY_FRACTION = 1e-2
#: share of points whose kappa is replaced by 0 (a fifth) or 10^U(-300, -15) (kind "zero"
#: for a velocity jump: classify at two sizes must say unstable)
TINY_KAPPA_SHARE = 0.06
REF_RTOL = 1e-13


def sample_point(rng: np.random.Generator) -> rc.Params:
    kc = 10.0 ** rng.uniform(-12, -6) if rng.random() < 0.5 else 10.0 ** rng.uniform(-6, 6)
    ba = min(1.0 + kc, 1e6)
    kc = ba - 1.0
    u = rng.random()
    if u < 0.3:
        r = 10.0 ** rng.uniform(-3, 3)
        eps = float(rng.choice([0.0, 1.0, rng.uniform()]))
    elif u < 0.6:
        r = 1.0 + 10.0 ** rng.uniform(-12, 0)
        eps = float(rng.choice([0.0, 1.0, rng.uniform()]))
    else:
        x = 1.0 - 10.0 ** rng.uniform(-12, -1)
        r = 1.0 + 10.0 ** rng.uniform(-3, 1)
        eps = x / r
    kappa = min(r * kc, 1e6)
    v = rng.random()
    if v < 0.1:
        vo = 0.0
    elif v < 0.325:
        vo = 10.0 ** rng.uniform(-300, 300)
    else:
        vo = 10.0 ** rng.uniform(-40, 40)
    return rc.Params(ba, kappa, eps, vo)


def rtol_draw(rng: np.random.Generator) -> float:
    return float(10.0 ** rng.uniform(-13, -3))


def timed(fn: Any, *a: Any, **k: Any) -> tuple[Any, float, str]:
    t0 = time.perf_counter()
    try:
        out = fn(*a, **k)
        err = ""
    except UndecidedError as e:
        out, err = None, f"UndecidedError:{e.reason}"
    except ParameterError as e:
        out, err = None, f"ParameterError:{e.field}"
    except Exception as e:  # noqa: BLE001 - counted as a defect
        out, err = None, f"{type(e).__name__}:{e}"[:200]
    return out, time.perf_counter() - t0, err


def close(a: float | None, b: float | None, acc: float, acc_ref: float, peak: bool) -> bool:
    if a is None or b is None or not (math.isfinite(a) and math.isfinite(b)):
        return True
    scale = max(abs(b), 1.0) if peak else abs(b)
    if scale <= 1e-290:
        return True
    return abs(a - b) <= (acc + acc_ref) * scale * (1.0 + 1e-9) + 4e-16 * scale


def bound_ratio(a: float | None, b: float | None, acc: float, acc_ref: float, peak: bool) -> float:
    """|a - b| over the claimed error (acc + acc_ref) on the scale `close` uses; 0 where
    `close` does not compare (a value missing, not finite, or a scale below 1e-290)."""
    if a is None or b is None or not (math.isfinite(a) and math.isfinite(b)):
        return 0.0
    scale = max(abs(b), 1.0) if peak else abs(b)
    if scale <= 1e-290:
        return 0.0
    return abs(a - b) / scale / max(acc + acc_ref, 1e-300)


def run_point(seed: int, i: int) -> list[dict[str, Any]]:
    """All queries of parameter point i (its own generator: a run can be resumed)."""
    rng = np.random.default_rng([seed, i])
    p = sample_point(rng)
    # a second generator for what sample_point does not draw (the main stream is unchanged)
    rng2 = np.random.default_rng([seed, i, 1])
    if rng2.random() < TINY_KAPPA_SHARE:  # kappa = 0 or 10^U(-300, -15)
        p = p.with_(kappa=0.0 if rng2.random() < 0.2 else 10.0 ** rng2.uniform(-300, -15))
    recs: list[dict[str, Any]] = []
    for pert in (VJ, LJ):
        if pert == LJ and p.vo == 0.0:
            continue
        rt_c = rtol_draw(rng)
        crit, dt, err = timed(rc.critical_perturbation, p, pert, rtol=rt_c)
        base = {"i": i, "pert": pert, "p": p.as_dict()}
        recs.append({**base, "q": "critical", "rtol": rt_c, "dt": dt, "err": err})
        if not err and crit.kind in ("zero", "infinite"):
            # every positive size is on one side: classify at sizes drawn across decades
            side = "unstable" if crit.kind == "zero" else "stable"
            for _ in range(2):
                sz = 10.0 ** rng2.uniform(-3, 1) if pert == VJ else 10.0 ** rng2.uniform(-3, 2)
                lg = sz if pert == VJ else math.log1p(sz)
                recs.append(_classify_row(p, pert, base, 0.0, lg, rtol_draw(rng2), side))
            continue
        if err or crit.kind != "finite" or crit.log_critical_size is None:
            continue
        lc = crit.log_critical_size
        recs[-1].update(lc=lc, acc=crit.rel_accuracy, size=crit.critical_size)
        if pert == VJ and not lc > 0.0:
            continue
        ac = crit.rel_accuracy
        # sizes as log sizes: d for a velocity jump, ln(1 + dv) for a load-point jump
        for f in sorted([-f for f in FRACTIONS] + list(FRACTIONS)):
            if abs(f) <= 4.0 * ac:
                continue
            if pert == VJ:
                lg = lc * (1.0 + f)
            else:
                dvc = crit.critical_size
                if dvc is not None and math.isfinite(dvc) and lc < 700.0:
                    lg = math.log1p(dvc * (1.0 + f))
                else:
                    lg = lc + math.log1p(f)  # dv (1 + f) for dv >> 1
            side = "stable" if f < 0 else "unstable"
            recs.append(_classify_row(p, pert, base, f, lg, rtol_draw(rng), side))
    return recs


def _classify_row(
    p: rc.Params, pert: str, base: dict[str, Any], f: float, lg: float, rt: float, side: str
) -> dict[str, Any]:
    """classify at (rt, REF_RTOL) and, at |f| = TRAJECTORY_FRACTION, simulate at rt."""
    row: dict[str, Any] = {**base, "q": "classify", "f": f, "lg": lg, "rtol": rt, "side": side}
    runs: list[tuple[str, Any, dict[str, Any]]] = [
        ("", rc.classify, {"rtol": rt}),
        ("ref_", rc.classify, {"rtol": REF_RTOL}),
    ]
    if abs(f) == TRAJECTORY_FRACTION:  # the trajectory's fields, at the same rtol
        runs.append(("traj_", rc.simulate, {"rtol": rt, "n_points": 16}))
    for tag, fn, kw in runs:
        res, dt, err = timed(fn, p, pert, log_size=lg, **kw)
        row[tag + "dt"] = dt
        row[tag + "err"] = err
        if res is not None:
            for k in FIELDS:
                v = getattr(res, k)
                row[tag + k] = v if not isinstance(v, float) or math.isfinite(v) else None
            if res.trajectory is not None:
                tr = res.trajectory
                row[tag + "nan"] = bool(np.isnan(tr.phi).any() or np.isnan(tr.T).any())
    return row


FIELDS = (
    "outcome",
    "certificate",
    "complete",
    "rel_accuracy",
    "blowup_time",
    "return_time",
    "peak_time",
    "peak_phi",
    "n_steps",
)


def summarise(rows: list[dict[str, Any]], wall: float, label: str) -> dict[str, Any]:
    """Counts per category, worst ratio, timing (from the checkpoint records)."""
    counts = dict(
        queries=0,
        contradiction=0,
        non_monotone=0,
        wrong_complete=0,
        wrong_vs_ref_only=0,
        bound_violations=0,
        trajectory_differs=0,
        not_certified=0,
        other_exceptions=0,
        parameter_errors=0,
    )
    examples: dict[str, list[str]] = {k: [] for k in counts}
    worst_ratio = 0.0
    times: list[tuple[float, float, str]] = []

    def note(kind: str, text: str) -> None:
        counts[kind] += 1
        if len(examples[kind]) < 40:
            examples[kind].append(text)

    series: dict[tuple[int, str], list[str | None]] = {}
    for row in rows:
        pd = row["p"]
        if row["q"] == "critical":
            counts["queries"] += 1
            desc = f"critical {row['pert']} {pd} rtol={row['rtol']:.3g}"
            times.append((row["dt"], row["rtol"], desc))
            err = row["err"]
            if err:
                note(
                    "parameter_errors" if err.startswith("Param") else "other_exceptions",
                    f"{desc}: {err}",
                )
            continue
        counts["queries"] += 2
        f, rt = row["f"], row["rtol"]
        desc = f"classify {row['pert']} {pd} log_size={row['lg']!r} (f={f:g}) rtol={rt:.3g}"
        times.append((row["dt"], rt, desc))
        times.append((row["ref_dt"], REF_RTOL, desc + " [reference]"))
        key = (row["i"], row["pert"])
        for tag in ("", "ref_"):
            err = row[tag + "err"]
            if not err:
                continue
            d = desc + (" [reference]" if tag else "")
            if err == "UndecidedError:not_certified":
                note("not_certified", d)
            elif err.startswith("ParameterError"):
                note("parameter_errors", d + " " + err)
            else:
                note("other_exceptions", d + " " + err)
        if row["err"]:
            series.setdefault(key, []).append(None)
            continue
        out = row["outcome"]
        series.setdefault(key, []).append(out)
        side = row.get("side") or ("stable" if f < 0 else "unstable")
        if out != side:
            note("contradiction", f"{desc}: {out} ({row['certificate']})")
        has_ref = not row["ref_err"]
        if has_ref and row["complete"] and out != row["ref_outcome"]:
            if out != side:
                note("wrong_complete", f"{desc}: {out} vs ref {row['ref_outcome']}")
            else:
                note(
                    "wrong_vs_ref_only",
                    f"{desc}: ref {row['ref_outcome']} ({row['ref_certificate']})",
                )
        tags = [""]
        if "traj_dt" in row:
            counts["queries"] += 1
            times.append((row["traj_dt"], rt, desc + " [trajectory]"))
            terr = row["traj_err"]
            if terr == "UndecidedError:not_certified":
                note("not_certified", desc + " [trajectory]")
            elif terr or row.get("traj_nan"):
                note("other_exceptions", f"{desc} [trajectory] {terr or 'NaN in samples'}")
            elif row["traj_outcome"] != out:
                note("trajectory_differs", f"{desc}: {row['traj_outcome']} vs classify {out}")
            else:
                tags.append("traj_")
        for tag in tags:
            if not (has_ref and row[tag + "complete"] and row["ref_complete"]):
                continue
            if row[tag + "outcome"] != row["ref_outcome"]:
                continue
            for name in ("blowup_time", "return_time", "peak_time", "peak_phi"):
                va, vb = row[tag + name], row["ref_" + name]
                acc, acc_ref = row[tag + "rel_accuracy"], row["ref_rel_accuracy"]
                ratio = bound_ratio(va, vb, acc, acc_ref, name == "peak_phi")
                worst_ratio = max(worst_ratio, ratio)
                if not close(va, vb, acc, acc_ref, name == "peak_phi"):
                    note(
                        "bound_violations",
                        f"{desc}{' [trajectory]' if tag else ''}: {name} {va!r} vs {vb!r},"
                        f" claim {acc:.2g} + ref {acc_ref:.2g} ({ratio:.3g}x)",
                    )
    for key, outs in series.items():
        seen_unstable = False
        for o in outs:
            if o is None:
                continue
            if o == "unstable":
                seen_unstable = True
            elif seen_unstable:
                note("non_monotone", f"{key}: {outs}")
                break
    arr = np.array([t for t, _, _ in times])
    print(f"queries {counts['queries']} in {wall:.1f} s ({label})")
    for k, v in counts.items():
        if k != "queries":
            print(f"  {k:20s} {v}")
            for ex in examples[k][:12]:
                print(f"      {ex}")
    print(
        f"  worst bound ratio over every compared field (delivered/claimed incl. the reference's claim) {worst_ratio:.3g}"
    )
    print("time per query [ms]: p50 / p99 / max, by rtol decade")
    for lo in range(-13, -2):
        sel = np.array([lo <= math.log10(r) < lo + 1 for _, r, _ in times])
        if sel.any():
            x = arr[sel] * 1e3
            print(
                f"  rtol 1e{lo:+d}: n {sel.sum():6d}  {np.median(x):7.2f} "
                f"{np.percentile(x, 99):8.2f} {x.max():9.2f}  over 10 ms: {(x > 10).sum()}"
            )
    print(
        f"  all: {np.median(arr) * 1e3:.2f} / {np.percentile(arr, 99) * 1e3:.2f} /"
        f" {arr.max() * 1e3:.1f} ms; over 10 ms: {(arr > 0.01).sum()}"
    )
    print("slowest 12:")
    for t, _, d in sorted(times, key=lambda z: -z[0])[:12]:
        print(f"  {t * 1e3:9.1f} ms  {d}")
    return {"counts": counts, "examples": examples, "worst_ratio": worst_ratio}


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--n", type=int, default=800, help="parameter points")
    ap.add_argument("--seed", type=int, default=2211)
    ap.add_argument("--json", default="", help="write the summary here")
    ap.add_argument(
        "--checkpoint",
        default="",
        help="JSON-lines file of per-query records, appended point by point; a rerun"
        " skips the points already in it (resume), --summary-only just reads it",
    )
    ap.add_argument("--summary-only", action="store_true")
    ap.add_argument(
        "--points", default="", help="comma-separated point indices to run (a failing subset)"
    )
    a = ap.parse_args()
    rows: list[dict[str, Any]] = []
    done: set[int] = set()
    if a.checkpoint:
        try:
            with open(a.checkpoint) as fh:
                for line in fh:
                    rec = json.loads(line)
                    rows.extend(rec["rows"])
                    done.add(rec["i"])
        except FileNotFoundError:
            pass
    t_start = time.perf_counter()
    idx = [int(s) for s in a.points.split(",")] if a.points else list(range(a.n))
    if not a.summary_only:
        for i in idx:
            if i in done:
                continue
            recs = run_point(a.seed, i)
            rows.extend(recs)
            if a.checkpoint:
                with open(a.checkpoint, "a") as fh:
                    fh.write(json.dumps({"i": i, "rows": recs}) + "\n")
    wall = time.perf_counter() - t_start
    if not rows:
        where = f"in {a.checkpoint}" if a.checkpoint else "(no --checkpoint given)"
        raise SystemExit(f"no query records {where}: nothing to summarise")
    out = summarise(rows, wall, f"seed {a.seed}, n {a.n}, {len(idx)} points, this run's wall")
    if a.json:
        with open(a.json, "w") as fh:
            json.dump(out, fh, indent=1)


if __name__ == "__main__":
    main()
