"""`rsf si`, `rsf protocol` and `rsf fit` as real subprocesses: the answers equal the
HTTP adapter's / rsfcore's for the same inputs, files are written, bad input exits 2
naming the field."""

from __future__ import annotations

import csv
import json
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from rsfcore import protocols
from rsfcore.critical import critical_perturbation
from rsfcore.params import Params
from rsfcore.units import PhysicalInputs

A, B, DC, SIGMA, VS = 0.01, 0.015, 1e-5, 1e8, 1e-6
K = 6e10
MACHINE = [
    "--a",
    str(A),
    "--b",
    str(B),
    "--Dc_m",
    str(DC),
    "--sigma_Pa",
    str(SIGMA),
    "--k_Pa_per_m",
    str(K),
    "--V_star_m_s",
    str(VS),
]
#: The same machine with the older kebab-case options (still accepted).
MACHINE_OLD = [
    "--a",
    str(A),
    "--b",
    str(B),
    "--dc-m",
    str(DC),
    "--sigma-pa",
    str(SIGMA),
    "--k-pa-per-m",
    str(K),
    "--v-star-m-s",
    str(VS),
]


def rsf(*args: str, check: bool = True) -> subprocess.CompletedProcess[str]:
    p = subprocess.run(
        [sys.executable, "-m", "rsfcli.main", *args], capture_output=True, text=True, timeout=300
    )
    if check and p.returncode != 0:
        raise AssertionError(f"rsf {' '.join(args)} failed ({p.returncode}): {p.stderr}")
    return p


def test_si_critical_equals_dimensionless() -> None:
    d = json.loads(rsf("si", "critical", *MACHINE, "--eps", "0.5", "--json").stdout)
    # the same groups computed here: b/a, kappa = k Dc/(a sigma); 1e-12: see
    # tests/api/test_si_api.py (rounding of the groups ~1e-16, condition O(1-100))
    ref = critical_perturbation(Params(B / A, K * DC / (A * SIGMA), 0.5, 1.0), "velocity-jump")
    assert math.isclose(d["critical_size"], ref.critical_size, rel_tol=1e-12)
    assert math.isclose(
        d["si"]["velocity_jump"]["new_slip_rate_m_s"],
        VS * math.exp(ref.critical_size),
        rel_tol=1e-12,
    )


def test_si_classify_and_trajectory_csv(tmp_path: Path) -> None:
    d = json.loads(
        rsf("si", "classify", *MACHINE, "--eps", "0.5", "--factor", "100", "--json").stdout
    )
    assert d["outcome"] == "unstable" and d["si"]["blowup_time_s"] > 0
    out = tmp_path / "tr.csv"
    t = json.loads(
        rsf(
            "si",
            "trajectory",
            *MACHINE,
            "--eps",
            "0.5",
            "--factor",
            "2",
            "--n-points",
            "21",
            "--sampling",
            "seconds",
            "--out",
            str(out),
            "--json",
        ).stdout
    )
    rows = list(csv.DictReader(out.read_text().splitlines()))
    assert len(rows) == 21 and [float(r["t_s"]) for r in rows] == t["trajectory"]["t_s"]
    assert t["sampling"]["kind"] == "seconds"


def test_si_bad_input_names_the_field() -> None:
    p = rsf("si", "critical", *MACHINE[:2], "--b", "0.001", *MACHINE[4:], check=False)
    assert p.returncode == 2 and "physical.b" in p.stderr
    p = rsf("si", "classify", *MACHINE, "--factor", "2", "--size", "1", check=False)
    assert p.returncode == 2 and "size" in p.stderr


def test_protocol_velocity_step_equals_rsfcore(tmp_path: Path) -> None:
    png = tmp_path / "vs.png"
    d = json.loads(
        rsf(
            "protocol",
            "velocity-step",
            *MACHINE,
            "--eps",
            "1",
            "--v1-m-s",
            "1e-6",
            "--v2-m-s",
            "1e-5",
            "--n-points",
            "100",
            "--out",
            str(png),
            "--json",
        ).stdout
    )
    ph = PhysicalInputs(A, B, DC, SIGMA, K, VS).to_physical_params(1.0, 0.6)
    ref = protocols.velocity_step(ph, 1e-6, 1e-5, n_points=100).to_dict()
    assert d["protocol"] == ref["protocol"] and d["max_deviation"] == ref["max_deviation"]
    assert math.isclose(
        d["friction_changes"]["steady_state_delta_f"], (A - B) * math.log(10.0), rel_tol=1e-12
    )
    assert png.read_bytes()[:4] == b"\x89PNG"


def test_protocol_load_history_csv(tmp_path: Path) -> None:
    out = tmp_path / "h.csv"
    rsf(
        "protocol",
        "load-history",
        *MACHINE,
        "--segment",
        "20:1e-6",
        "--segment",
        "5:1e-5",
        "--segment",
        "20:0",
        "--eps",
        "1",  # aging law: this machine stays stable through every segment
        "--n-points-per-segment",
        "20",
        "--out",
        str(out),
    )
    rows = list(csv.DictReader(out.read_text().splitlines()))
    assert rows and {r["segment"] for r in rows} == {"0", "1", "2"}
    p = rsf("protocol", "load-history", *MACHINE, "--segment", "20", check=False)
    assert p.returncode == 2 and "segment[0]" in p.stderr


def test_fit_json(tmp_path: Path) -> None:
    from rsfcore.fit import synthetic_record

    t = np.linspace(0.0, 60.0, 601)
    v = np.where(t < 20, 1e-6, np.where(t < 40, 1e-5, 1e-6))
    rec = synthetic_record(t, v, mu0=0.6, a=0.01, b=0.015, Dc_m=1e-5, eps=0.0, k_per_m=2000.0)
    f = tmp_path / "rec.csv"
    f.write_text(rec.to_csv())
    d = json.loads(
        rsf(
            "fit",
            str(f),
            "--law",
            "slip",
            "--stiffness",
            "2000",
            "--json",
            "--uncertainty-samples",
            "50",
        ).stdout
    )
    assert {"params", "stderr", "stability", "law_comparison"} <= set(d)
    for k, val in {"mu0": 0.6, "a": 0.01, "b": 0.015, "Dc_m": 1e-5}.items():
        assert d["params"][k] == pytest.approx(val, rel=1e-6)
    assert d["law_comparison"]["best"] == "slip" and "series" not in d
    p = rsf("fit", str(tmp_path / "missing.csv"), check=False)
    assert p.returncode == 2 and "file" in p.stderr


def test_si_defaults_and_old_option_names() -> None:
    """`rsf si critical` without --eps uses the one eps default of every door (0.25, the
    request model's: the same as POST /v1/critical without eps), says so in its text
    output, and the older kebab-case options give the identical answer."""
    from rsfapp import adapter
    from rsfapp.requests import CriticalRequest

    phys = {"a": A, "b": B, "Dc_m": DC, "sigma_Pa": SIGMA, "k_Pa_per_m": K, "V_star_m_s": VS}
    ref = adapter.critical(CriticalRequest(physical=phys))
    new = json.loads(rsf("si", "critical", *MACHINE, "--json").stdout)
    old = json.loads(rsf("si", "critical", *MACHINE_OLD, "--json").stdout)
    assert new == old == ref and ref["params"]["eps"] == 0.25 and ref["rtol"] == 1e-10
    text = rsf("si", "critical", *MACHINE).stdout
    assert "eps 0.25" in text and "rtol 1e-10" in text and "Dc_m 1e-05" in text


@pytest.mark.parametrize("suffix", [".csv", ".json"])
def test_protocol_output_fits_as_written(tmp_path: Path, suffix: str) -> None:
    """`rsf protocol velocity-step --out F` then `rsf fit F`: the file as written is a fit
    record; the fit (stiffness fitted, the default) recovers a, b, Dc and k (1/m and, with
    --sigma-pa, Pa/m) to 1e-6 relative (both at rtol 1e-10: measured ~1e-10)."""
    out = tmp_path / f"vs{suffix}"
    rsf(
        "protocol",
        "velocity-step",
        *MACHINE,
        "--eps",
        "1",
        "--v1-m-s",
        "1e-6",
        "--v2-m-s",
        "1e-5",
        "--slip-total-m",
        "3e-4",
        "--n-points",
        "1500",
        "--out",
        str(out),
    )
    d = json.loads(
        rsf(
            "fit",
            str(out),
            "--law",
            "aging",
            "--no-compare",
            "--sigma-pa",
            str(SIGMA),
            "--uncertainty-samples",
            "0",
            "--json",
        ).stdout
    )
    assert d["status"] == "ok", d["message"]
    want = {"a": A, "b": B, "Dc_m": DC, "k_per_m": K / SIGMA, "k_Pa_per_m": K}
    for k, val in want.items():
        assert d["params"][k] == pytest.approx(val, rel=1e-6), k
    assert d["stability"]["critical_stiffness_Pa_per_m"] == pytest.approx(
        (B - A) / DC * SIGMA, rel=1e-6
    )


def test_lab_file_cli_equals_library_and_errors_name_the_line(tmp_path: Path) -> None:
    """A lab export (own headers, um/s, a units row, decimal comma) read with --column and
    --decimal: `rsf fit --json` equals the adapter's answer for the same request (what
    POST /v1/fits computes) in every parameter, bit for bit; a bad cell exits 2 naming the
    column and the file's line."""
    from rsfapp import adapter
    from rsfapp.requests.fits import FitRequest
    from rsfcore.fit import synthetic_record

    t = np.linspace(0.0, 60.0, 601)
    v = np.where(t < 20, 1e-6, np.where(t < 40, 1e-5, 1e-6))
    rec = synthetic_record(t, v, mu0=0.6, a=A, b=B, Dc_m=DC, eps=1.0, k_per_m=1000.0)
    rows = [
        f"{x!r};{y * 1e6!r};{m!r}".replace(".", ",")
        for x, y, m in zip(rec.t_s.tolist(), rec.v_lp_m_s.tolist(), rec.mu.tolist(), strict=True)
    ]
    f = tmp_path / "lab.csv"
    f.write_text("\n".join(["Time (s);LP Velocity;Friction", "s;um/s;-", *rows]) + "\n")
    cols = ["--column", "t=Time (s)", "--column", "v_lp=LP Velocity", "--column", "mu=Friction"]
    args = ["--law", "aging", "--no-compare", "--uncertainty-samples", "20"]
    d = json.loads(rsf("fit", str(f), *cols, "--decimal", ",", *args, "--json").stdout)
    req = FitRequest(
        record=f.read_text(),
        columns={"t": "Time (s)", "v_lp": "LP Velocity", "mu": "Friction"},
        decimal=",",
        law="aging",
        compare=False,
        uncertainty_samples=20,
    )
    ref = adapter.fit(req)
    assert d["params"] == ref["params"] and d["stderr"] == ref["stderr"]
    assert d["status"] == "ok" and d["params"]["b"] == pytest.approx(B, rel=1e-6)
    lines = f.read_text().splitlines()
    lines[9] = lines[9].rsplit(";", 1)[0] + ";n/a"  # line 10 of the file, data row 7
    f.write_text("\n".join(lines) + "\n")
    p = rsf("fit", str(f), *cols, "--decimal", ",", *args, check=False)
    assert p.returncode == 2 and "record.Friction[7]" in p.stderr and "line 10" in p.stderr
