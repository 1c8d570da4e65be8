"""Time every `rsf` command as a user runs it: a fresh process each time, warm (the
kernels already compiled in the per-user cache) and, with ``--cold``, against an empty
cache (the first run after installing or changing rsfcore).

    python bench/bench_cli.py [--repeat 5] [--cold] [--only classify,critical]
    python bench/bench_cli.py --figures      # also draw each of the paper's 12 figures
    python bench/bench_cli.py --root /path/to/other/checkout   # time another version

Prints per command the best and median wall time [s] and the median and best CPU time
[s] (user + sys of the child) of ``--repeat`` warm runs, with the machine's 1-minute load
average at the start of each command: on a shared machine the wall time grows with the
load while the CPU time hardly does, so both are reported; CPU is the load-independent
figure.  Target (issue 20 item 7): every command warm well under 1.5 s; `rsf fit` of a
10^4-sample record end to end <= 1.5 s (issue 23 item 5).

The children run as an installed package does: Python's bytecode cache on (a
``PYTHONDONTWRITEBYTECODE`` in the environment is dropped; the ``.pyc`` files go to a
temporary ``PYTHONPYCACHEPREFIX``, written by the untimed warm-up run), so the times do
not include compiling the sources.  ``--no-bytecode`` keeps the environment as it is.

Every command of `rsf --help` is timed, each group's subcommands too, except the
server commands (serve, api, worker: they start processes, not answer) and the ones
that write to the deployment (``keys create|revoke``, ``db upgrade|revision``); ``rsf
sweep`` is timed against a closed port (it must fail at once, without retrying a refused
connection: submit, status, download, cancel).  ``--figures`` adds the drawing of each
figure of the paper (``figure-<name>``, PNG at paper quality).
"""

from __future__ import annotations

import argparse
import json
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
    """The 10^4-sample velocity-step record of bench/bench_fit.py (`single-step`: aging
    law, a = 0.01, b = 0.015, Dc = 10 um, k = 1000 /m = 2 k_crit, 1 -> 10 um/s at 20 s,
    noise 1e-4; rsfcore.fit.synthetic_record) for `rsf fit`."""
    import numpy as np

    from rsfcore.fit import synthetic_record

    t = np.linspace(0.0, 60.0, 10_000)
    v = np.where(t < 20.0, 1e-6, 1e-5)
    rec = synthetic_record(
        t, v, mu0=0.6, a=0.01, b=0.015, Dc_m=1e-5, eps=1.0, k_per_m=1000.0, noise=1e-4,
        rtol=1e-13,
    )  # fmt: skip
    path.write_text(rec.to_csv())


REFUSED = ["--url", "http://127.0.0.1:9"]  # nothing listens on port 9 (discard)


def commands(tmp: Path, figures: bool = False) -> dict[str, list[str]]:
    """name -> argv after `rsf`."""
    out = _commands(tmp)
    if figures:
        from rsfapp.requests.figures import FIGURES  # the catalogue the CLI draws from

        out.update({f"figure-{n}": ["figure", n, "--out", str(tmp / f"{n}.png")] for n in FIGURES})
    return out


def _commands(tmp: Path) -> dict[str, list[str]]:
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
        # stiffness fitted (the default), with checks and the stability answer
        "fit-10k": ["fit", str(tmp / "record.csv"), "--law", "aging", "--no-compare"],
        "fit-10k-json": [
            "fit",
            str(tmp / "record.csv"),
            "--law",
            "aging",
            "--no-compare",
            "--json",
        ],  # fmt: skip
        # the default: four laws fitted and compared (bench/bench_fit.py times the fit)
        "fit-10k-compare": ["fit", str(tmp / "record.csv")],
        "boundaries": ["boundaries", "--ba", "2", "--kappa", "2", "--phi", "0", "--phi", "1"],
        "analytic-u": [
            "analytic-u",
            "--function",
            "vo0",
            "--ba",
            "2",
            "--kappa",
            "0.5",
            "--eps",
            "0.3",
            "--points",
            '[{"phi": 0.0, "psi": 1.0}, {"phi": 1.0, "psi": 0.5}]',
        ],  # fmt: skip
        "classify-points": [
            "classify-points",
            "--ba",
            "2",
            "--kappa",
            "2",
            "--phi",
            "0",
            "--phi",
            "3",
            "--psi",
            "0",
            "--psi",
            "3",
        ],  # fmt: skip
        "critical-batch": ["critical-batch", str(tmp / "critical-batch.json")],
        "classify-batch": ["classify-batch", str(tmp / "classify-batch.json")],
        "figure-list": ["figure", "--list"],
        "figure-list-json": ["figure", "--list", "--json"],
        "figure-draw": ["figure", "velocity-step", "--out", str(tmp / "f.png")],
        "figure-draw-svg": ["figure", "velocity-step", "--out", str(tmp / "f.svg")],
        "figure-json": ["figure", "velocity-step", "--json"],
        "db-current": ["db", "current"],
        "db-history": ["db", "history"],
        "keys-list": ["keys", "list"],
        "sweep-submit-refused": ["sweep", "submit", str(tmp / "sweep.json"), *REFUSED],
        "sweep-status-refused": ["sweep", "status", "abc", *REFUSED],
        "sweep-download-refused": [
            "sweep",
            "download",
            "abc",
            "-o",
            str(tmp / "s.nc"),
            *REFUSED,
        ],  # fmt: skip
        "sweep-cancel-refused": ["sweep", "cancel", "abc", *REFUSED],
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
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--cold", action="store_true", help="also time each command once cold")
    ap.add_argument("--only", default="", help="comma-separated command names")
    ap.add_argument("--figures", action="store_true", help="also draw each of the 12 figures")
    ap.add_argument("--root", type=Path, default=ROOT, help="checkout whose rsf is timed")
    ap.add_argument(
        "--no-bytecode", action="store_true", help="leave PYTHONDONTWRITEBYTECODE as it is"
    )
    args = ap.parse_args()
    tmp = Path(tempfile.mkdtemp(prefix="rsf-bench-cli-"))
    try:
        _record(tmp / "record.csv")
        (tmp / "critical-batch.json").write_text(
            json.dumps({"items": [{"ba": 2.0, "kappa": 2.0}, {"ba": 3.0, "kappa": 4.0}]})
        )
        (tmp / "classify-batch.json").write_text(
            json.dumps({"items": [{"ba": 2.0, "kappa": 2.0, "size": 3.0}]})
        )
        (tmp / "sweep.json").write_text(
            json.dumps(
                {
                    "x": {"name": "kappa_ratio", "start": 1, "stop": 5, "n": 4},
                    "y": {"name": "eps", "start": 0, "stop": 0.99, "n": 4},
                }
            )
        )
        root = args.root.resolve()
        env = dict(os.environ, PYTHONPATH=str(root), RSF_DATA_DIR=str(tmp / "data"))
        if not args.no_bytecode:
            env.pop("PYTHONDONTWRITEBYTECODE", None)
            env["PYTHONPYCACHEPREFIX"] = str(tmp / "pyc")
        env["BENCH_CWD"] = str(tmp)
        cmds = commands(tmp, figures=args.figures or "figure-" in args.only)
        if args.only:
            cmds = {k: v for k, v in cmds.items() if k in args.only.split(",")}
        print(f"rsf of {root}; {os.cpu_count()} CPUs; load average {os.getloadavg()}")
        print(f"bytecode cache: {'as in the environment' if args.no_bytecode else 'on'}")
        print(
            f"{'command':<26} {'wall best':>9} {'median':>7} {'CPU med':>8} {'best':>6} "
            f"{'load':>5} {'cold s':>7} rc"
        )
        for name, argv in cmds.items():
            cold = ""
            if args.cold:
                cenv = {k: v for k, v in env.items() if k != "NUMBA_CACHE_DIR"}
                cenv["RSF_CACHE_DIR"] = str(tmp / f"cold-{name}")
                cold = f"{_run(argv, cenv)[0]:7.2f}"
            load = os.getloadavg()[0]
            _run(argv, env)  # this command's kernels compiled (warm) and its .pyc written
            runs = [_run(argv, env) for _ in range(args.repeat)]
            walls = [r[0] for r in runs]
            cpus = [r[1] for r in runs]
            print(
                f"{name:<26} {min(walls):9.2f} {statistics.median(walls):7.2f} "
                f"{statistics.median(cpus):8.2f} {min(cpus):6.2f} {load:5.1f} {cold:>7} "
                f"{max(r[2] for r in runs)}",
                flush=True,
            )
        print(f"load average after: {os.getloadavg()}")
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
