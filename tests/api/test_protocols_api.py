"""Lab protocols over HTTP: answers equal rsfcore.protocols' (same inputs through
rsfcore.units), friction changes consistent with the steady-state law, CSV and PNG."""

from __future__ import annotations

import csv
import io
import math

import pytest
from fastapi.testclient import TestClient

from rsfcore import limits, protocols
from rsfcore.units import PhysicalInputs

pytestmark = pytest.mark.timeout(300)

PHYS = {
    "a": 0.01,
    "b": 0.015,
    "Dc_m": 1e-5,
    "sigma_Pa": 1e7,
    "k_Pa_per_m": 1e11,
    "V_star_m_s": 1e-6,
}


def _machine(eps: float = limits.EPS.default, f_star: float = limits.F_STAR.default):
    """The machine of PHYS; eps and f_star default to the one default of every door."""
    return PhysicalInputs.from_dict(PHYS).to_physical_params(eps, f_star)


def _strip(d: dict) -> dict:
    return {
        k: v for k, v in d.items() if k not in ("cached", "cache_key", "friction_changes", "kind")
    }


def test_velocity_step_equals_rsfcore(c: TestClient) -> None:
    body = {"physical": PHYS, "eps": 0.5, "V1_m_s": 1e-6, "V2_m_s": 1e-5, "n_points": 300}
    r = c.post("/v1/protocols/velocity-step", json=body)
    assert r.status_code == 200, r.text
    got = r.json()
    ref = protocols.velocity_step(_machine(0.5), 1e-6, 1e-5, n_points=300)
    assert _strip(got) == ref.to_dict()  # the same computation: exactly equal
    fc = got["friction_changes"]
    # steady state: (a - b) ln(V2/V1) (`eq: steady state`), independent closed form;
    # two roundings of f_ss ~ 0.6 -> 1e-15 absolute
    assert fc["steady_state_delta_f"] == pytest.approx((0.01 - 0.015) * math.log(10.0), abs=1e-15)
    assert fc["steady_state_delta_tau_Pa"] == pytest.approx(
        fc["steady_state_delta_f"] * 1e7, rel=1e-15
    )
    # the peak exceeds every sample and the direct effect is below a ln(V2/V1)
    pk = ref.protocol.segments[0].peak_friction
    assert fc["peak_friction"] == pk and pk >= max(got["protocol"]["friction"])
    assert 0 < fc["peak_delta_f"] < 0.01 * math.log(10.0)
    assert c.post("/v1/protocols/velocity-step", json=body).headers["x-cache"] == "hit"


def test_slide_hold_slide_and_csv_png(c: TestClient) -> None:
    body = {
        "physical": PHYS,
        "V_m_s": 1e-6,
        "hold_s": 100.0,
        "slide_before_s": 50.0,
        "slide_after_s": 100.0,
        "n_points_per_segment": 50,
    }
    got = c.post("/v1/protocols/slide-hold-slide", json=body).json()
    ref = protocols.slide_hold_slide(
        _machine(), 1e-6, 100.0, slide_before_s=50.0, slide_after_s=100.0, n_points_per_segment=50
    )
    assert _strip(got) == ref.to_dict()
    assert got["friction_changes"]["healing_delta_f"] == ref.healing_delta_f > 0
    r = c.post("/v1/protocols/slide-hold-slide?format=csv", json=body)
    assert r.status_code == 200 and r.headers["content-type"].startswith("text/csv")
    rows = list(csv.DictReader(io.StringIO(r.text)))
    assert len(rows) == len(ref.protocol.t_s)
    assert [float(x["friction"]) for x in rows] == ref.protocol.friction.tolist()
    p = c.post("/v1/protocols/slide-hold-slide?format=png", json=body)
    assert p.status_code == 200 and p.content[:8] == b"\x89PNG\r\n\x1a\n"


def test_load_history_steps(c: TestClient) -> None:
    segs = [
        {"duration_s": 50.0, "V_load_m_s": 1e-6},
        {"duration_s": 5.0, "V_load_m_s": 1e-5},
        {"duration_s": 50.0, "V_load_m_s": 1e-6},
    ]
    got = c.post(
        "/v1/protocols/load-history", json={"physical": PHYS, "eps": 0.0, "segments": segs}
    ).json()
    ref = protocols.load_history(_machine(0.0), [(50.0, 1e-6), (5.0, 1e-5), (50.0, 1e-6)])
    assert _strip(got) == ref.to_dict()
    ch = got["friction_changes"]["segments"]
    assert ch[0]["steady_state_delta_f"] is None
    assert ch[1]["steady_state_delta_f"] == -ch[2]["steady_state_delta_f"]


@pytest.mark.parametrize(
    "body,field",
    [
        ({"physical": PHYS, "V1_m_s": 0, "V2_m_s": 1e-5}, "V1_m_s"),
        ({"physical": {**PHYS, "k_Pa_per_m": 0.0}, "V1_m_s": 1e-6, "V2_m_s": 1e-5}, "k"),
        ({"physical": {**PHYS, "b": 0.001}, "V1_m_s": 1e-6, "V2_m_s": 1e-5}, "physical.b"),
        ({"V1_m_s": 1e-6, "V2_m_s": 1e-5}, "physical"),
    ],
)
def test_protocol_errors_name_the_field(c: TestClient, body: dict, field: str) -> None:
    r = c.post("/v1/protocols/velocity-step", json=body)
    assert r.status_code == 422 and r.json()["field"] == field, r.text


def test_load_history_sample_limit(c: TestClient) -> None:
    segs = [{"duration_s": 1.0, "V_load_m_s": 1e-6}] * 3
    r = c.post(
        "/v1/protocols/load-history",
        json={"physical": PHYS, "segments": segs, "n_points_per_segment": 100_000},
    )
    assert r.status_code == 422 and r.json()["field"] == "n_points_per_segment"
