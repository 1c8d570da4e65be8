"""Batch queries over HTTP: every answered item equals the single endpoint's answer for
the same item (bit for bit: the same compiled decision runs), invalid items get their own
error entry naming index and field, the others are answered."""

from __future__ import annotations

from typing import Any

import pytest
from fastapi.testclient import TestClient

pytestmark = pytest.mark.timeout(300)

PHYS = {
    "a": 0.01,
    "b": 0.015,
    "Dc_m": 1e-5,
    "sigma_Pa": 1e8,
    "k_Pa_per_m": 6e10,
    "V_star_m_s": 1e-6,
}


def _strip(d: dict[str, Any]) -> dict[str, Any]:
    return {k: v for k, v in d.items() if k not in ("cached", "cache_key", "index")}


CRITICAL_ITEMS: list[dict[str, Any]] = [
    {"ba": 3.0, "kappa": 2.5, "eps": 0.3},  # separatrix
    {"ba": 3.0, "kappa": 4.0, "eps": 0.3, "perturbation": "load-point-jump"},
    {"ba": 2.0, "kappa": 0.5, "eps": 0.5},  # zero (kappa < kappa_crit)
    {"ba": 2.0, "kappa": 1.0, "eps": 0.2},  # closed form at kappa_crit
    {"ba": 2.0, "kappa": 5.0, "eps": 0.5},  # infinite (eps kappa >= kc)
    {"ba": 2.0, "kappa": 2.0, "eps": 0.1, "vo": 0.0},  # v_o = 0 closed form
    {"ba": 0.5},  # invalid: ba
    {"ba": 2.0, "kappa": 1.5, "eps": 0.1, "vo": 3.0, "rtol": 1e-8},
    {"physical": PHYS, "eps": 0.25},  # SI
    {"physical": {**PHYS, "b": 0.001}},  # invalid: physical.b
    {"physical": PHYS, "ba": 2.0},  # invalid: both
    {"vo": 0.0, "perturbation": "load-point-jump"},  # invalid: vo
    {"ba": 2.0, "kappa": 1.5, "eps": 0.1, "bogus": 1},  # invalid: extra field
    # the columnar fast path of plain items must agree with the request model on each of:
    {"ba": True, "kappa": 2.5},  # invalid: a boolean is not a number
    {"ba": "3", "kappa": 2.5, "eps": 0.3},  # a numeric string (the model reads it)
    {"ba": 3, "kappa": 2, "eps": 0},  # integers
    {"perturbation": "bogus"},  # invalid: perturbation
    {"rtol": 1e-20},  # invalid: rtol
    {"ba": 2.0, "kappa": 1e3, "eps": 0.0, "perturbation": "load-point-jump"},  # dv > 1e308
    {"ba": 10**400},  # invalid: an integer beyond double range
    {"ba": 2.0, "kappa": 3.0, "eps": 0.1, "vo": 0.0, "perturbation": "load-point-jump"},
    {"perturbation": ["velocity-jump"]},  # invalid: a list is not a perturbation name
    {"ba": [2.0]},  # invalid: a list is not a number
]
BAD = {
    6: "ba",
    9: "physical.b",
    10: "ba",
    11: "vo",
    12: "bogus",
    13: "ba",
    16: "perturbation",
    17: "rtol",
    19: "ba",
    20: "vo",
    21: "perturbation",
    22: "ba",
}


def test_critical_batch_equals_single(c: TestClient) -> None:
    r = c.post("/v1/critical/batch", json={"items": CRITICAL_ITEMS})
    assert r.status_code == 200, r.text
    body = r.json()
    res = body["results"]
    assert len(res) == len(CRITICAL_ITEMS) and body["n_failed"] == len(BAD)
    assert body["n_ok"] == len(CRITICAL_ITEMS) - len(BAD)
    for i, (item, got) in enumerate(zip(CRITICAL_ITEMS, res, strict=True)):
        assert got["index"] == i
        single = c.post("/v1/critical", json=item)
        if i in BAD:
            assert "error" in got and got["error"]["field"] == BAD[i], got
            assert single.status_code == 422 and single.json()["field"] == BAD[i]
        else:
            assert single.status_code == 200, single.text
            assert _strip(got) == _strip(single.json()), i  # exact equality
    kinds = {res[i]["kind"] for i in range(len(res)) if i not in BAD}
    assert kinds == {"zero", "finite", "infinite"}
    assert res[8]["si"]["velocity_jump"]["new_slip_rate_m_s"] > 0


def test_classify_batch_equals_single(c: TestClient) -> None:
    items = [{"ba": 3.0, "kappa": 2.5, "eps": 0.3, "size": s} for s in (0.5, 2.5, 4.0)]
    items += [
        {"kappa": -1},
        {"physical": PHYS, "eps": 0.3, "factor": 20.0},
        {"physical": PHYS, "new_load_point_velocity_m_s": 1e-5},
    ]
    r = c.post("/v1/classify/batch", json={"items": items})
    assert r.status_code == 200, r.text
    res = r.json()["results"]
    assert res[3]["error"]["field"] == "kappa" and res[3]["index"] == 3
    assert res[5]["error"]["field"] == "new_load_point_velocity_m_s"
    for i in (0, 1, 2, 4):
        single = c.post("/v1/classify", json=items[i]).json()
        assert _strip(res[i]) == _strip(single), i
    assert {res[i]["outcome"] for i in (0, 1, 2)} == {"stable", "unstable"}


def test_batch_limits(c: TestClient, monkeypatch: pytest.MonkeyPatch) -> None:
    assert c.post("/v1/critical/batch", json={"items": []}).status_code == 422
    assert c.post("/v1/critical/batch", json={"items": [1]}).json()["field"].startswith("items")
    monkeypatch.setenv("RSF_BATCH_MAX_ITEMS", "3")
    r = c.post("/v1/critical/batch", json={"items": [{}] * 4})
    assert r.status_code == 422 and r.json()["field"] == "items"
    assert c.post("/v1/critical/batch", json={"items": [{}] * 3}).status_code == 200
