"""A sweep stated in lab units through a real uvicorn and Celery worker: the perturbation
size swept in SI (a slip-rate axis, scattered load-point velocities), each point's outcome
against rsfcore.trajectory.classify at the size converted by hand, and the CSV's SI
column against the critical size computed by rsfcore.critical with hand-converted groups.
"""

from __future__ import annotations

import csv
import io
import math
from pathlib import Path

import pytest

from tests.conftest import Server, Worker
from tests.e2e.test_worker_sweeps import done, exactly_once, submit

pytestmark = pytest.mark.timeout(180)

PH = {
    "a": 0.012,
    "b": 0.031,
    "Dc_m": 2.3e-5,
    "sigma_Pa": 4.7e7,
    "k_Pa_per_m": 6.1e10,
    "V_star_m_s": 1.3e-6,
    "V_load_m_s": 3.7e-6,
}
VL = PH["V_load_m_s"]
# the groups of `eq: characteristic scales`, by hand
BA = PH["b"] / PH["a"]
KAPPA = PH["k_Pa_per_m"] * PH["Dc_m"] / (PH["a"] * PH["sigma_Pa"])
VO = VL / PH["V_star_m_s"]


def test_si_size_sweeps_through_a_worker(tmp_path: Path, procs: list, client_for) -> None:
    from rsfcore.critical import critical_perturbation
    from rsfcore.params import Params
    from rsfcore.trajectory import classify

    procs.append(srv := Server(tmp_path))
    procs.append(Worker(tmp_path))
    c = client_for(srv.url)
    v_new = [0.5 * VL, 4.0 * VL, 1e-3]
    eps = [0.1, 0.5]
    grid = {
        "axes": [{"name": "new_slip_rate_m_s", "values": v_new}, {"name": "eps", "values": eps}],
        "fixed": {"physical": PH},
        "chunk_points": 4,
    }
    lp_v = [2.0 * VL, 0.3 * VL, 30.0 * VL]
    lp_eps = [0.2, 0.0, 0.6]
    scattered = {
        "points": {"new_load_point_velocity_m_s": lp_v, "eps": lp_eps},
        "fixed": {"physical": PH},
        "perturbation": "load-point-jump",
        "chunk_points": 2,
    }
    sid_g, sid_p = submit(c, grid), submit(c, scattered)
    assert done(c, sid_g)["n_failed"] == 0 and done(c, sid_p)["n_failed"] == 0
    exactly_once(tmp_path, sid_g, 6)
    exactly_once(tmp_path, sid_p, 3)

    def rows(sid: str) -> list[dict[str, str]]:
        r = c.get(f"/v1/sweeps/{sid}/data", params={"format": "csv"})
        assert r.status_code == 200
        return list(csv.DictReader(io.StringIO(r.text)))

    cases = [
        (rows(sid_g), "velocity-jump", [(v, e) for v in v_new for e in eps]),
        (rows(sid_p), "load-point-jump", list(zip(lp_v, lp_eps, strict=True))),
    ]
    for table, pert, pts in cases:
        assert len(table) == len(pts)
        for row, (v, e) in zip(table, pts, strict=True):
            p = Params(BA, KAPPA, e, VO)
            size = math.log(v / VL) if pert == "velocity-jump" else v / VL - 1.0
            # the size column: one log or one division off the hand value (4e-16)
            assert float(row["size"]) == pytest.approx(size, rel=4e-16, abs=4e-16)
            # the outcome of a separate integration (sizes are far from critical)
            assert row["outcome"] == classify(p, pert, size).outcome, (pert, v, e)
            ref = critical_perturbation(p, pert, rtol=1e-10)
            if ref.kind == "finite":
                assert float(row["critical_size"]) == pytest.approx(ref.critical_size, rel=1e-12)
                si = (
                    VL * math.exp(ref.critical_size)
                    if pert == "velocity-jump"
                    else VL * (1.0 + ref.critical_size)
                )
                col = (
                    "critical_slip_rate_m_s"
                    if pert == "velocity-jump"
                    else "critical_load_point_velocity_m_s"
                )
                # 1e-11: the critical size agrees to 1e-12 relative; through e^d its
                # relative error becomes |d| 1e-12 (d_crit <= 10 here), through 1 + dv
                # at most (dv/(1 + dv)) 1e-12
                assert float(row[col]) == pytest.approx(si, rel=1e-11)
