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
