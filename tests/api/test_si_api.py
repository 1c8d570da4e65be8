"""SI inputs and answers over HTTP.

An SI request and the dimensionless request with the same groups (b/a, kappa =
k Dc/(a sigma), v_o = V_load/V_*, size = ln(factor) or V_new/V_load - 1) give the same
answers to 1e-12: the SI path converts with rsfcore.units (a few roundings, ~1e-16
relative in the groups), and the answers' condition numbers with respect to the groups
are O(1-100) at these points, so 1e-12 leaves a margin of >= 100 over what rounding can
produce while still catching any wrong conversion (those are O(1) errors).  The SI
answers are checked against the definitions t = T Dc/V_*, V = V_* e^phi,
tau - tau_* = a sigma psi computed here independently.
"""

from __future__ import annotations

import csv
import io
import math
from typing import Any

import pytest
from fastapi.testclient import TestClient

pytestmark = pytest.mark.timeout(300)

A, B, DC, SIGMA, VS = 0.01, 0.025, 2e-5, 5e7, 1e-6
K = 1.8 * 1.5 * A * SIGMA / DC  # kappa = 1.8 kappa_crit (kappa_crit = 1.5)
VL = 3e-6
PHYS = {
    "a": A,
    "b": B,
    "Dc_m": DC,
    "sigma_Pa": SIGMA,
    "k_Pa_per_m": K,
    "V_star_m_s": VS,
    "V_load_m_s": VL,
}
DIMLESS = {"ba": B / A, "kappa": K * DC / (A * SIGMA), "vo": VL / VS}
TOL = 1e-12


def close(x: Any, y: Any, path: str = "") -> None:
    """Recursive comparison: floats to TOL relative (absolute near 0), rest exact."""
    if isinstance(x, dict):
        assert set(x) == set(y), (path, set(x) ^ set(y))
        for k in x:
            close(x[k], y[k], f"{path}.{k}")
    elif isinstance(x, list):
        assert len(x) == len(y), path
        for i, (a, b) in enumerate(zip(x, y, strict=True)):
            close(a, b, f"{path}[{i}]")
    elif isinstance(x, float) and isinstance(y, float):
        assert math.isclose(x, y, rel_tol=TOL, abs_tol=TOL), (path, x, y)
    else:
        assert x == y, (path, x, y)


def _core(d: dict[str, Any]) -> dict[str, Any]:
    return {
        k: v for k, v in d.items() if k not in ("cached", "cache_key", "si", "n_steps", "n_rhs")
    }


@pytest.mark.parametrize("eps", [0.0, 0.4, 1.0])
@pytest.mark.parametrize("factor", [0.3, 4.0, 60.0])
def test_classify_si_equals_dimensionless(c: TestClient, eps: float, factor: float) -> None:
    si = c.post("/v1/classify", json={"physical": PHYS, "eps": eps, "factor": factor})
    dl = c.post("/v1/classify", json={**DIMLESS, "eps": eps, "size": math.log(factor)})
    assert si.status_code == 200 and dl.status_code == 200, si.text + dl.text
    s, d = si.json(), dl.json()
    close(_core(s), _core(d))
    blk = s["si"]
    for key in ("blowup_time", "return_time", "peak_time"):
        want = None if d[key] is None else d[key] * DC / VS
        if want is None:
            assert blk[key + "_s"] is None
        else:
            assert math.isclose(blk[key + "_s"], want, rel_tol=TOL)
    if d["peak_phi"] is not None:
        assert math.isclose(blk["peak_slip_rate_m_s"], VS * math.exp(d["peak_phi"]), rel_tol=TOL)
    vj = blk["velocity_jump"]
    assert math.isclose(vj["new_slip_rate_m_s"], VL * factor, rel_tol=TOL)
    assert math.isclose(
        vj["shear_stress_jump_Pa"], A * SIGMA * math.log(factor), rel_tol=TOL, abs_tol=1e-9
    )
    assert math.isclose(
        blk["start_shear_stress_change_Pa"],
        A * SIGMA * d["start"]["psi"],
        rel_tol=TOL,
        abs_tol=1e-9,
    )


def test_classify_si_new_slip_rate_and_load_point(c: TestClient) -> None:
    a = c.post(
        "/v1/classify", json={"physical": PHYS, "eps": 0.3, "new_slip_rate_m_s": 40 * VL}
    ).json()
    b = c.post("/v1/classify", json={"physical": PHYS, "eps": 0.3, "factor": 40.0}).json()
    close(_core(a), _core(b))
    lp = c.post(
        "/v1/classify",
        json={
            "physical": PHYS,
            "eps": 0.3,
            "perturbation": "load-point-jump",
            "new_load_point_velocity_m_s": 9 * VL,
        },
    )
    dl = c.post(
        "/v1/classify", json={**DIMLESS, "eps": 0.3, "perturbation": "load-point-jump", "size": 8.0}
    )
    close(_core(lp.json()), _core(dl.json()))
    assert math.isclose(
        lp.json()["si"]["load_point_jump"]["new_load_point_velocity_m_s"], 9 * VL, rel_tol=TOL
    )


@pytest.mark.parametrize("pert", ["velocity-jump", "load-point-jump"])
@pytest.mark.parametrize("eps", [0.0, 0.5])
def test_critical_si_equals_dimensionless(c: TestClient, pert: str, eps: float) -> None:
    s = c.post("/v1/critical", json={"physical": PHYS, "eps": eps, "perturbation": pert}).json()
    d = c.post("/v1/critical", json={**DIMLESS, "eps": eps, "perturbation": pert}).json()
    close(_core(s), _core(d))
    assert s["kind"] == "finite"
    if pert == "velocity-jump":
        got = s["si"]["velocity_jump"]["new_slip_rate_m_s"]
        assert math.isclose(got, VL * math.exp(d["critical_size"]), rel_tol=TOL)
    else:
        got = s["si"]["load_point_jump"]["new_load_point_velocity_m_s"]
        assert math.isclose(got, VL * (1 + d["critical_size"]), rel_tol=TOL)


def test_trajectory_si_sampling_and_csv(c: TestClient) -> None:
    body = {"physical": PHYS, "eps": 0.5, "factor": 3.0, "n_points": 41, "sampling": "seconds"}
    r = c.post("/v1/trajectory", json=body)
    assert r.status_code == 200, r.text
    res = r.json()
    assert res["sampling"]["kind"] == "seconds"
    t = res["trajectory"]["t_s"]
    T = res["trajectory"]["T"]
    dt = [b - a for a, b in zip(t, t[1:], strict=False)]
    # evenly spaced: differences agree to rounding of t (~1e-16 relative of t_end)
    assert max(dt) - min(dt) <= 1e-12 * t[-1]
    assert all(math.isclose(ts, Ti * DC / VS, rel_tol=1e-14) for ts, Ti in zip(t, T, strict=True))
    dl = c.post(
        "/v1/trajectory",
        json={**DIMLESS, "eps": 0.5, "size": math.log(3.0), "n_points": 41, "sampling": "T"},
    ).json()
    close({k: v for k, v in res["trajectory"].items() if k in dl["trajectory"]}, dl["trajectory"])
    tau = c.post("/v1/trajectory", json={**body, "sampling": "tau"}).json()
    Tt = tau["trajectory"]["T"]
    dT = [b - a for a, b in zip(Tt, Tt[1:], strict=False)]
    assert max(dT) > 2 * min(dT) and tau["sampling"]["kind"] == "tau"
    csvr = c.post("/v1/trajectory?format=csv", json=body)
    assert csvr.status_code == 200 and csvr.headers["x-sampling"] == "seconds"
    rows = list(csv.DictReader(io.StringIO(csvr.text)))
    assert len(rows) == 41 and [float(x["t_s"]) for x in rows] == t


@pytest.mark.parametrize(
    "body,field",
    [
        ({"physical": PHYS, "ba": 2.0}, "ba"),
        ({"physical": PHYS, "kappa": 2.0}, "kappa"),
        ({"physical": PHYS, "factor": 2.0, "size": 1.0}, "size"),
        ({"factor": 2.0}, "factor"),
        ({"physical": PHYS, "factor": 2.0, "new_slip_rate_m_s": 1e-6}, "new_slip_rate_m_s"),
        ({"physical": {**PHYS, "b": 0.005}}, "physical.b"),
        ({"physical": {**PHYS, "Dc": 1e-5}}, "physical.Dc"),
        ({"physical": {k: v for k, v in PHYS.items() if k != "sigma_Pa"}}, "physical.sigma_Pa"),
        (
            {"physical": PHYS, "perturbation": "load-point-jump", "new_slip_rate_m_s": 1e-5},
            "new_slip_rate_m_s",
        ),
        (
            {
                "physical": {**PHYS, "V_load_m_s": 0.0},
                "perturbation": "load-point-jump",
                "factor": 2.0,
            },
            "physical.V_load_m_s",
        ),
    ],
)
def test_si_errors_name_the_field(c: TestClient, body: dict[str, Any], field: str) -> None:
    r = c.post("/v1/classify", json=body)
    assert r.status_code == 422 and r.json()["field"] == field, r.text


def test_trajectory_seconds_needs_physical(c: TestClient) -> None:
    r = c.post("/v1/trajectory", json={"sampling": "seconds"})
    assert r.status_code == 422 and r.json()["field"] == "sampling"


def test_si_request_dump_validates_again() -> None:
    """Queued work (worker.tasks.compute_single) and cache keys use the request's JSON
    dump: an SI request's dump must validate to the same request (no unused ba, kappa,
    vo alongside physical)."""
    from rsfapp.requests import ClassifyRequest, CriticalRequest, TrajectoryRequest

    for model in (ClassifyRequest, TrajectoryRequest, CriticalRequest):
        r = model.model_validate({"physical": PHYS, "eps": 0.3})
        d = r.model_dump(mode="json")
        assert not {"ba", "kappa", "vo"} & set(d)
        assert model.model_validate(d) == r
    d = ClassifyRequest.model_validate({"ba": 3.0}).model_dump(mode="json")
    assert d["ba"] == 3.0 and d["physical"] is None


def test_boundaries_si_equals_dimensionless(c: TestClient) -> None:
    s = c.post("/v1/boundaries", json={"physical": PHYS, "eps": 0.3, "phi": [0.5, 2.0]})
    d = c.post(
        "/v1/boundaries",
        json={"ba": DIMLESS["ba"], "kappa": DIMLESS["kappa"], "eps": 0.3, "phi": [0.5, 2.0]},
    )
    assert s.status_code == 200 and d.status_code == 200, s.text + d.text
    sj, dj = s.json(), d.json()
    assert math.isclose(
        sj["si"]["kappa_ratio"], DIMLESS["kappa"] / (DIMLESS["ba"] - 1), rel_tol=TOL
    )
    assert math.isclose(sj["si"]["k_crit_Pa_per_m"], SIGMA * (B - A) / DC, rel_tol=TOL)
    close(
        {k: v for k, v in sj.items() if k not in ("si", "cached", "cache_key")},
        {k: v for k, v in dj.items() if k not in ("cached", "cache_key")},
    )
    bad = c.post("/v1/boundaries", json={"physical": PHYS, "kappa": 1.0})
    assert bad.status_code == 422 and bad.json()["field"] == "kappa"


@pytest.mark.parametrize("pert", ["velocity-jump", "load-point-jump"])
def test_critical_si_beyond_double_range_is_answered(c: TestClient, pert: str) -> None:
    """b/a = 1.4, eps = 0, kappa = 4100 through ``physical``: the critical jump is about
    e^10250, beyond the double range.  It is answered 200 with its kind and logarithm,
    exactly the dimensionless answer's, and the SI logarithms follow from their
    definitions (log10 factor = l/ln 10, log10 V_new = log10 V_before + l/ln 10); the values
    that overflow are null.  Before, this was 422 on a field 'd' the request never had."""
    a, sigma, dc, vs = 0.01, 1e7, 1e-5, 1e-6
    phys = {
        "a": a,
        "b": 1.4 * a,
        "Dc_m": dc,
        "sigma_Pa": sigma,
        "k_Pa_per_m": 4100 * a * sigma / dc,
        "V_star_m_s": vs,
    }
    r = c.post("/v1/critical", json={"physical": phys, "eps": 0.0, "perturbation": pert})
    assert r.status_code == 200, r.text
    d = r.json()
    p = d["params"]
    dim = c.post(
        "/v1/critical",
        json={"ba": p["ba"], "kappa": p["kappa"], "eps": 0.0, "vo": 1.0, "perturbation": pert},
    ).json()
    assert d["kind"] == dim["kind"] == "finite"
    assert d["log_critical_size"] == dim["log_critical_size"]
    lg = d["log_critical_size"]
    assert lg > 1e4
    key = "velocity_jump" if pert == "velocity-jump" else "load_point_jump"
    j = d["si"][key]
    new = "new_slip_rate_m_s" if pert == "velocity-jump" else "new_load_point_velocity_m_s"
    assert j["factor"] is None and j[new] is None
    assert math.isclose(j["log10_factor"], lg / math.log(10.0), rel_tol=1e-15)
    assert math.isclose(j[f"log10_{new}"], math.log10(vs) + lg / math.log(10.0), rel_tol=1e-15)
