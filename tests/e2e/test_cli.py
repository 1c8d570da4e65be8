"""The `rsf` command line, run as a real subprocess (what a lab script would do)."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from rsfcore import Params, classify
from rsfcore.critical import critical_perturbation


def rsf(*args: str, check: bool = True) -> subprocess.CompletedProcess[str]:
    p = subprocess.run(
        [sys.executable, "-m", "rsfcli.main", *args], capture_output=True, text=True, timeout=300
    )
    if check and p.returncode != 0:
        raise AssertionError(f"rsf {' '.join(args)} failed ({p.returncode}): {p.stderr}")
    return p


def test_help_lists_every_command() -> None:
    out = rsf("--help").stdout
    for cmd in ("classify", "trajectory", "critical", "diagram", "stiffness", "figure", "serve"):
        assert cmd in out
    for cmd in ("classify", "trajectory", "critical", "diagram", "stiffness", "figure", "serve"):
        assert "Usage" in rsf(cmd, "--help").stdout


COMMON = ["--ba", "2", "--kappa", "2", "--eps", "0.25", "--vo", "1"]


def test_classify_json_matches_library() -> None:
    d = json.loads(
        rsf(
            "classify",
            *COMMON,
            "--perturbation",
            "velocity-jump",
            "--size",
            "2.75",
            "--rtol",
            "1e-10",
            "--json",
        ).stdout
    )
    for key in (
        "outcome",
        "certificate",
        "blowup_time",
        "return_time",
        "peak_phi",
        "peak_time",
        "rel_accuracy",
    ):
        assert key in d
    lib = classify(Params(2, 2, 0.25, 1), "velocity-jump", 2.75)
    assert d["outcome"] == "unstable" == lib.outcome
    assert d["blowup_time"] == pytest.approx(lib.blowup_time, rel=1e-14)
    assert d["peak_phi"] is None and d["return_time"] is None


def test_trajectory_json_and_csv(tmp_path: Path) -> None:
    out = tmp_path / "t.csv"
    d = json.loads(
        rsf(
            "trajectory", *COMMON, "--size", "2.0", "--n-points", "25", "--out", str(out), "--json"
        ).stdout
    )
    assert d["outcome"] == "stable" and len(d["trajectory"]["T"]) == 25
    rows = out.read_text().strip().splitlines()
    assert rows[0].startswith("T,phi,psi") and len(rows) == 26


def test_critical_json_matches_library() -> None:
    d = json.loads(rsf("critical", *COMMON, "--perturbation", "load-point-jump", "--json").stdout)
    for key in ("kind", "critical_size", "rel_accuracy", "method"):
        assert key in d
    assert d["kind"] == "finite"
    assert d["critical_size"] == pytest.approx(
        critical_perturbation(Params(2, 2, 0.25, 1), "load-point-jump").critical_size, rel=1e-14
    )
    inf = json.loads(rsf("critical", "--ba", "2", "--kappa", "5", "--eps", "0.25", "--json").stdout)
    assert inf["kind"] == "infinite" and inf["critical_size"] is None


def test_diagram_npz_layout(tmp_path: Path) -> None:
    out = tmp_path / "d.npz"
    rsf(
        "diagram",
        "--x",
        "kappa_ratio",
        "1",
        "5",
        "9",
        "--y",
        "eps",
        "0",
        "0.99",
        "7",
        "--ba",
        "2",
        "--out",
        str(out),
    )
    z = np.load(out)
    assert z["x"].shape == (9,) and z["y"].shape == (7,) and z["critical_size"].shape == (9, 7)
    # critical_size[i, j] at x[i], y[j]
    i, j = 4, 3
    ref = critical_perturbation(Params.from_ratio(2.0, float(z["x"][i]), float(z["y"][j])))
    if ref.kind == "infinite":
        assert np.isinf(z["critical_size"][i, j])
    else:
        assert z["critical_size"][i, j] == pytest.approx(ref.critical_size, rel=1e-9)


def test_stiffness_json() -> None:
    d = json.loads(rsf("stiffness", "--case", "E", "--json").stdout)
    assert d["eigenvalue"] == pytest.approx(1.0030595164694487, rel=1e-12)
    d = json.loads(
        rsf(
            "stiffness",
            "--case",
            "A",
            "--mu",
            "3e10",
            "--nu",
            "0.25",
            "--sigma",
            "1e8",
            "--a",
            "0.01",
            "--b",
            "0.015",
            "--dc",
            "1e-5",
            "--json",
        ).stdout
    )
    mu_p = 3e10 / (2 * 0.75)
    assert d["critical_dimension_m"] == pytest.approx(
        2 * np.pi * mu_p * 1e-5 / (1e8 * 0.015) / (1 - 0.01 / 0.015), rel=1e-12
    )


def test_bad_input_exits_2_naming_the_field() -> None:
    p = rsf("classify", "--eps", "1.5", check=False)
    assert p.returncode == 2 and "eps" in p.stderr and "valid range" in p.stderr
    p = rsf("critical", "--ba", "0.5", check=False)
    assert p.returncode == 2 and "ba" in p.stderr


def test_figure_list() -> None:
    out = rsf("figure", "--list").stdout
    assert "trajectories-kcrit" in out and "velocity-step" in out


def test_dimensionless_commands_are_the_adapters_answers() -> None:
    """`rsf classify|critical --json` print exactly rsfapp.adapter's answer to the request
    model built from the options (the HTTP endpoint's answer, without cached/cache_key);
    an option not given is the model's default (eps 0.25 at every door), and the text
    output echoes every parameter used."""
    from rsfapp import adapter
    from rsfapp.requests import ClassifyRequest, CriticalRequest

    d = json.loads(rsf("classify", "--size", "2.7", "--json").stdout)
    assert d == adapter.classify(ClassifyRequest(size=2.7), max_steps=None)
    assert d["params"] == {"ba": 2.0, "kappa": 2.0, "eps": 0.25, "vo": 1.0} and d["rtol"] == 1e-10
    c = json.loads(rsf("critical", "--ba", "1.4", "--kappa", "4100", "--eps", "0", "--json").stdout)
    assert c == adapter.critical(CriticalRequest(ba=1.4, kappa=4100, eps=0))
    text = rsf("critical").stdout
    assert "ba 2  kappa 2  eps 0.25  vo 1" in text and "rtol 1e-10" in text


@pytest.mark.parametrize("command", [["status", "abc"], ["download", "abc", "-o", "x.nc"]])
def test_sweep_commands_fail_at_once_on_a_refused_connection(
    command: list[str], tmp_path: Path
) -> None:
    """`rsf sweep ...` against a port where nothing listens: exit 2 with a message that
    names the URL and says how to start or name a service (the client does not retry a
    refused connection: only 503, 429 with Retry-After and resets are retried)."""
    from tests.conftest import free_port

    url = f"http://127.0.0.1:{free_port()}"
    if command[0] == "download":
        command = [*command[:-1], str(tmp_path / "x.nc")]
    p = rsf("sweep", *command, "--url", url, check=False)
    assert p.returncode == 2, p.stderr
    assert url in p.stderr and "cannot connect" in p.stderr and "rsf serve" in p.stderr


def test_incomplete_answer_says_why() -> None:
    """An answer with complete false prints its reason (a slow outward spiral whose blow-up
    is beyond the step budget: issue 22); the JSON carries it too."""
    args = ["--ba", "1.0000000000430638", "--kappa", "7.706221673638276e-12", "--eps",
            "0.43432546839273345", "--vo", "6.843075815542354e-06", "--perturbation",
            "load-point-jump", "--size", "-0.017153579760950312"]  # fmt: skip
    out = rsf("classify", *args).stdout
    assert "incomplete    the outcome is certain before integrating (kappa < kappa_crit" in out
    d = json.loads(rsf("trajectory", *args, "--n-points", "5", "--json").stdout)
    assert d["complete"] is False and "the samples end at T" in d["reason"]
