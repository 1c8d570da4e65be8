"""rsfclient and `rsf sweep` against a real uvicorn + Celery worker."""

from __future__ import annotations

import json
import math
import subprocess
import sys
from pathlib import Path

import pytest

from tests.conftest import ROOT, Server, Worker, service_env

pytestmark = pytest.mark.timeout(180)


def test_client_and_cli(tmp_path: Path, procs: list) -> None:
    import xarray as xr

    from rsfclient import Client, ProblemError
    from rsfcore import critical
    from rsfcore.params import Params

    procs.append(srv := Server(tmp_path))
    procs.append(Worker(tmp_path))
    with Client(srv.url) as c:
        one = c.critical(ba=2.0, kappa=3.0, eps=0.2)
        ref = critical.critical_perturbation(Params(2.0, 3.0, 0.2, 1.0))
        assert one["critical_size"] == ref.critical_size
        assert (
            c.classify(ba=2.0, kappa=3.0, eps=0.2, size=2 * ref.critical_size)["outcome"]
            == "unstable"
        )
        with pytest.raises(ProblemError) as e:
            c.sweep(axes=[{"name": "eps", "start": 0, "stop": 2, "n": 3}])
        assert e.value.status == 422 and e.value.field == "axes[0].stop"
        s = c.sweep(
            axes=[
                {"name": "kappa_ratio", "start": 1.0, "stop": 4.0, "n": 5},
                {"name": "eps", "values": [0.0, 0.5]},
            ],
            fixed={"ba": 3.0},
        )
        st = s.wait(progress=True, poll=0.1, timeout=60)
        assert st["n_done"] == 10
        ds = s.to_xarray()
        assert ds["critical_size"].dims == ("kappa_ratio", "eps")
        k = ds["kappa_ratio"].values[3]
        want = critical.critical_perturbation(Params(3.0, k * 2.0, 0.0, 1.0)).critical_size
        assert float(ds["critical_size"].sel(kappa_ratio=k, eps=0.0)) == want
        # eps kappa/kappa_crit = 1.6 >= 1: no runaway, critical size infinite
        assert math.isinf(float(ds["critical_size"].sel(kappa_ratio=k, eps=0.5)))

    # the CLI: submit --wait, status, download -o f.nc
    spec = tmp_path / "spec.json"
    spec.write_text(
        json.dumps(
            {
                "axes": [
                    {"name": "vo", "values": [0.0, 1.0]},
                    {"name": "eps", "values": [0.1, 0.3, 0.6]},
                ],
                "fixed": {"ba": 2.0, "kappa_ratio": 2.0},
            }
        )
    )
    env = service_env(tmp_path, RSF_URL=srv.url)

    def rsf(*args: str) -> subprocess.CompletedProcess[str]:
        return subprocess.run(
            [sys.executable, "-m", "rsfcli.main", "sweep", *args],
            env=env,
            cwd=ROOT,
            capture_output=True,
            text=True,
            timeout=120,
        )

    r = rsf("submit", str(spec), "--wait")
    assert r.returncode == 0, r.stderr
    sid = r.stdout.strip()
    assert len(sid) == 32 and "done: 6 points, 0 failed" in r.stderr
    r = rsf("status", sid)
    assert r.returncode == 0 and "done  6/6 points" in r.stdout, r.stdout + r.stderr
    out = tmp_path / "f.nc"
    r = rsf("download", sid, "-o", str(out))
    assert r.returncode == 0, r.stderr
    ds = xr.open_dataset(out)
    assert ds["vo"].values.tolist() == [0.0, 1.0] and ds["eps"].values.tolist() == [0.1, 0.3, 0.6]
    assert not any(math.isnan(v) for v in ds["critical_size"].values.ravel())  # all computed
    r = rsf("status", "0" * 32)
    assert r.returncode == 2 and "404" in r.stderr
