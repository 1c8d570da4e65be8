"""Time every `rsf` command as a user runs it: a fresh process each time, warm (the
kernels already compiled in the per-user cache) and, with ``--cold``, against an empty
cache (the first run after installing or changing rsfcore).

    python bench/bench_cli.py [--repeat 3] [--cold] [--only classify,critical]

Prints per command the best and median wall time [s] of ``--repeat`` warm runs and the
CPU time (user + sys of the child) of the best run, with the machine's load average
before and after: on a shared machine the wall time grows with the load while the CPU
time does not, so both are reported.  Target (issue 20): every command warm well under
1.5 s.  Server commands (serve, api, worker) and ``rsf sweep`` against a running service
are not answers of the CLI itself and are not timed here; ``rsf sweep status`` is timed
against a closed port (it must fail at once, without retrying a refused connection).
"""

from __future__ import annotations

import argparse
import os
import resource
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
LAB = [
    "--a", "0.010", "--b", "0.014", "--Dc_m", "20e-6", "--sigma_Pa", "10e6",
    "--k_Pa_per_m", "4e9", "--V_star_m_s", "1e-6",
]  # fmt: skip


def _record(path: Path) -> None:
    """A synthetic velocity-step record (rsfcore.fit.synthetic_record) for `rsf fit`."""
    import numpy as np

    from rsfcore.fit.model import synthetic_record

    t = np.linspace(0.0, 60.0, 601)
    v = np.where(t < 20, 1e-6, np.where(t < 40, 1e-5, 1e-6))
    rec = synthetic_record(t, v, k_per_m=2000.0, mu0=0.6, a=0.01, b=0.015, Dc_m=1e-5, eps=1.0)
    path.write_text(rec.to_csv())


def commands(tmp: Path) -> dict[str, list[str]]:
    """name -> argv after `rsf`."""
    return {
        "help": ["--help"],
        "classify": ["classify"],
        "trajectory": ["trajectory", "--n_points", "50"],
        "critical": ["critical"],
        "critical-load-point": ["critical", "--perturbation", "load-point-jump"],
        "diagram": [
            "diagram",
            "--x",
            "kappa_ratio",
            "1",
            "5",
            "20",
            "--y",
            "eps",
            "0",
            "0.99",
            "20",
            "--out",
            str(tmp / "d.npz"),
        ],  # fmt: skip
        "stiffness": [
            "stiffness",
            "--case",
            "B",
            "--mu",
            "3e10",
            "--sigma_Pa",
            "1e8",
            "--a",
            "0.01",
            "--b",
            "0.015",
            "--Dc_m",
            "1e-5",
        ],  # fmt: skip
        "si-classify": ["si", "classify", *LAB, "--factor", "10"],
        "si-critical": ["si", "critical", *LAB],
        "si-trajectory": ["si", "trajectory", *LAB, "--factor", "10", "--n_points", "50"],
        "protocol-velocity-step": [
            "protocol",
            "velocity-step",
            *LAB,
            "--V1_m_s",
            "1e-6",
            "--V2_m_s",
            "1e-5",
        ],  # fmt: skip
        "protocol-slide-hold-slide": [
            "protocol",
            "slide-hold-slide",
            *LAB,
            "--V_m_s",
            "1e-6",
            "--hold_s",
            "100",
            "--slide_before_s",
            "50",
            "--slide_after_s",
            "100",
        ],  # fmt: skip
        "protocol-load-history": [
            "protocol",
            "load-history",
            *LAB,
            "--segment",
            "100:1e-6",
            "--segment",
            "100:1e-5",
        ],  # fmt: skip
        "fit": [
            "fit",
            str(tmp / "record.csv"),
            "--law",
            "aging",
            "--no-compare",
            "--stiffness",
            "2000",
            "--uncertainty-samples",
            "0",
        ],  # fmt: skip
        "figure-list": ["figure", "--list"],
        "keys-list": ["keys", "list"],
        "sweep-status-refused": ["sweep", "status", "abc", "--url", "http://127.0.0.1:9"],
    }


def _run(argv: list[str], env: dict[str, str]) -> tuple[float, float, int]:
    """(wall [s], child CPU user + sys [s], exit status) of one `rsf` process."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    p = subprocess.run(
        [sys.executable, "-m", "rsfcli.main", *argv],
        env=env,
        cwd=env["BENCH_CWD"],
        capture_output=True,
        text=True,
        timeout=900,
    )
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return wall, cpu, p.returncode


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--cold", action="store_true", help="also time each command once cold")
    ap.add_argument("--only", default="", help="comma-separated command names")
    args = ap.parse_args()
    tmp = Path(tempfile.mkdtemp(prefix="rsf-bench-cli-"))
    try:
        _record(tmp / "record.csv")
        env = dict(os.environ, PYTHONPATH=str(ROOT), RSF_DATA_DIR=str(tmp / "data"))
        env["BENCH_CWD"] = str(tmp)
        cmds = commands(tmp)
        if args.only:
            cmds = {k: v for k, v in cmds.items() if k in args.only.split(",")}
        print(f"load average before: {os.getloadavg()}; {os.cpu_count()} CPUs")
        print(f"{'command':<28} {'best s':>7} {'median s':>8} {'cpu s':>6} {'cold s':>7} rc")
        for name, argv in cmds.items():
            cold = ""
            if args.cold:
                cenv = {k: v for k, v in env.items() if k != "NUMBA_CACHE_DIR"}
                cenv["RSF_CACHE_DIR"] = str(tmp / f"cold-{name}")
                cold = f"{_run(argv, cenv)[0]:7.2f}"
            _run(argv, env)  # makes sure this command's kernels are compiled (warm)
            runs = [_run(argv, env) for _ in range(args.repeat)]
            best = min(runs, key=lambda r: r[0])
            med = statistics.median(r[0] for r in runs)
            print(
                f"{name:<28} {best[0]:7.2f} {med:8.2f} {best[1]:6.2f} {cold:>7} {best[2]}",
                flush=True,
            )
        print(f"load average after: {os.getloadavg()}")
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
