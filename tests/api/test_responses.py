"""Responses of the app match the response models published in OpenAPI."""

from __future__ import annotations

import pytest
from fastapi.testclient import TestClient

from service.responses import ClassifyResult, CriticalResult, TrajectoryResult


@pytest.mark.parametrize(
    "body",
    [
        {"ba": 2, "kappa": 2, "eps": 0.25, "size": 2.0},
        {"ba": 2, "kappa": 2, "eps": 0.25, "size": 3.0},
        {"ba": 2, "kappa": 1, "eps": 0.3, "vo": 0, "size": 1.0},
    ],
)
def test_classify_and_trajectory_match_models(c: TestClient, body: dict) -> None:
    r = c.post("/v1/classify", json=body)
    assert r.status_code == 200
    ClassifyResult.model_validate(r.json(), strict=False)
    r = c.post("/v1/trajectory", json={**body, "n_points": 5})
    assert r.status_code == 200
    t = TrajectoryResult.model_validate(r.json())
    assert len(t.trajectory["T"]) == 5


@pytest.mark.parametrize("kappa", [0.5, 2.0, 5.0])
def test_critical_matches_model(c: TestClient, kappa: float) -> None:
    r = c.post("/v1/critical", json={"ba": 2, "kappa": kappa, "eps": 0.25})
    assert r.status_code == 200
    m = CriticalResult.model_validate(r.json())
    assert m.kind == {0.5: "zero", 2.0: "finite", 5.0: "infinite"}[kappa]


def test_openapi_documents_the_results(c: TestClient) -> None:
    o = c.get("/openapi.json").json()
    for path, name in (
        ("/v1/classify", "ClassifyResult"),
        ("/v1/trajectory", "TrajectoryResult"),
        ("/v1/critical", "CriticalResult"),
    ):
        schema = o["paths"][path]["post"]["responses"]["200"]["content"]["application/json"][
            "schema"
        ]
        assert schema["$ref"].endswith(name)


#: issue 22 (bench_speed seed 991): a slow outward spiral, kappa = 0.18 kappa_crit at
#: b/a = 1 + 4.3e-11: the outcome is certain, the blow-up millions of steps away
SPIRAL = {
    "ba": 1.0000000000430638,
    "kappa": 7.706221673638276e-12,
    "eps": 0.43432546839273345,
    "vo": 6.843075815542354e-06,
    "perturbation": "load-point-jump",
    "size": -0.017153579760950312,
}


def test_incomplete_answers_say_why_at_every_door(c: TestClient) -> None:
    """classify and trajectory of the spiral: complete false and the same reason over HTTP
    and through rsfclient (the trajectory's adds where its samples end); a complete
    answer's reason is ''."""
    from rsfclient import Client

    cl = c.post("/v1/classify", json=SPIRAL).json()
    tr = c.post("/v1/trajectory", json={**SPIRAL, "n_points": 20}).json()
    ClassifyResult.model_validate(cl)
    TrajectoryResult.model_validate(tr)
    assert cl["complete"] is False and "kappa < kappa_crit" in cl["reason"]
    assert tr["complete"] is False and tr["reason"].startswith(cl["reason"])
    assert f"the samples end at T = {tr['trajectory']['T'][-1]:.6g}" in tr["reason"]
    client = Client("http://testserver", transport=c._transport, retries=0, poll=0.0)
    r = client.trajectory(**SPIRAL, n_points=20)
    assert r.complete is False and r.reason == tr["reason"]
    ok = c.post("/v1/classify", json={"ba": 2, "kappa": 2, "eps": 0.25, "size": 2.0}).json()
    assert ok["complete"] is True and ok["reason"] == ""
