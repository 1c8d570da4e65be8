"""The OpenAPI document states the cross-field rules (issue 25, item 5).

* every request model whose validity ties fields together lists its rules
  (``x-cross-field-rules``) and shows them in its description;
* each rule the schema states as a constraint agrees with the server: a request that
  breaks only that rule is invalid under the published schema (validated here with
  jsonschema, independently of the code that writes the schema) and answered 422 naming
  the field; the same request without the breach is valid and answered 2xx.

Rules JSON Schema cannot state (b > a, phi and psi of equal length, ...) are text only;
tests/e2e/schemathesis.toml accepts their 422 for the operations that have them, and
tests/e2e/test_service_fuzz.py runs schemathesis with a fixed seed against a real server.
"""

from __future__ import annotations

from typing import Any

import pytest
from fastapi.testclient import TestClient
from jsonschema import Draft202012Validator

#: Request models whose fields are tied together (a model validator, or rsfapp.grid).
WITH_RULES = [
    "ClassifyRequest",
    "TrajectoryRequest",
    "CriticalRequest",
    "BoundariesSIRequest",
    "AnalyticRequest",
    "GridSpec",
    "ClassifyPointsRequest",
    "StiffnessRequest",
    "FitRequest",
    "PosteriorOptions",
    "VelocityStepRequest",
    "SlideHoldSlideRequest",
    "LoadHistoryRequest",
    "SweepRequest",
    "SweepAxis",
    "SweepFixed",
]

BASE = {"ba": 2.0, "kappa": 2.0, "eps": 0.25}
PHYS = {
    "a": 0.01,
    "b": 0.015,
    "Dc_m": 1e-5,
    "sigma_Pa": 1e8,
    "k_Pa_per_m": 1e9,
    "V_star_m_s": 1e-6,
    "V_load_m_s": 1e-6,
}
AXIS_X = {"name": "kappa_ratio", "start": 0.5, "stop": 2.0, "n": 3}
AXIS_Y = {"name": "eps", "start": 0.1, "stop": 0.9, "n": 2}

#: (path, schema, body that breaks one rule, field named by the 422, the body made valid)
CASES: list[tuple[str, str, dict[str, Any], str, dict[str, Any]]] = [
    ("/v1/classify", "ClassifyRequest", {**BASE, "size": 1e5}, "size", {**BASE, "size": 2.7}),
    (
        "/v1/classify",
        "ClassifyRequest",
        {**BASE, "size": -2.0, "perturbation": "load-point-jump"},
        "size",
        {
            **BASE,
            "size": -2.0,
            "perturbation": "load-point-jump",
            "start": {"phi": 0.5, "psi": 0.5},
        },
    ),
    ("/v1/classify", "ClassifyRequest", {"physical": PHYS, "ba": 2.0}, "ba", {"physical": PHYS}),
    ("/v1/classify", "ClassifyRequest", {**BASE, "log_size": 1.0, "size": 1.0}, "log_size", BASE),
    (
        "/v1/trajectory",
        "TrajectoryRequest",
        {**BASE, "sampling": "seconds", "n_points": 10},
        "sampling",
        {**BASE, "sampling": "T", "n_points": 10},
    ),
    (
        "/v1/trajectory",
        "TrajectoryRequest",
        {**BASE, "t_end_s": 10.0, "n_points": 10},
        "t_end_s",
        {"physical": PHYS, "t_end_s": 10.0, "n_points": 10},
    ),
    (
        "/v1/trajectory",
        "TrajectoryRequest",
        {"physical": PHYS, "t_end": 5.0, "t_end_s": 10.0, "n_points": 10},
        "t_end_s",
        {"physical": PHYS, "t_end": 5.0, "n_points": 10},
    ),
    ("/v1/critical", "CriticalRequest", {"physical": PHYS, "vo": 1.0}, "vo", {"physical": PHYS}),
    (
        "/v1/sweeps",
        "SweepRequest",
        {"x": {**AXIS_X, "values": [1.0]}, "y": AXIS_Y},
        "x.values",
        {"x": AXIS_X, "y": AXIS_Y},
    ),
    (
        "/v1/sweeps",
        "SweepRequest",
        {"x": {"name": "kappa_ratio", "n": 3}, "y": AXIS_Y},
        "x.start",
        {"x": {"name": "kappa_ratio", "values": [1.0, 2.0]}, "y": AXIS_Y},
    ),
    (
        "/v1/sweeps",
        "SweepRequest",
        {"x": AXIS_X, "y": AXIS_Y, "points": {"eps": [0.1]}},
        "x",
        {"points": {"eps": [0.1], "kappa_ratio": [2.0]}},
    ),
    ("/v1/sweeps", "SweepRequest", {"x": AXIS_X}, "y", {"axes": [AXIS_X]}),
    (
        "/v1/sweeps",
        "SweepRequest",
        {"x": {**AXIS_X, "name": "ba", "start": 0.0}, "y": AXIS_Y},
        "x.start",
        {"x": {**AXIS_X, "name": "ba", "start": 1.5}, "y": AXIS_Y},
    ),
    (
        "/v1/sweeps",
        "SweepRequest",
        {"x": {**AXIS_X, "log": True, "start": 0.0}, "y": AXIS_Y},
        "x.start",
        {"x": {**AXIS_X, "log": True}, "y": AXIS_Y},
    ),
]


@pytest.fixture(scope="module")
def doc(c: TestClient) -> dict[str, Any]:
    r = c.get("/openapi.json")
    assert r.status_code == 200
    return dict(r.json())


def _validator(doc: dict[str, Any], name: str) -> Draft202012Validator:
    return Draft202012Validator(
        {"$ref": f"#/components/schemas/{name}", "components": doc["components"]}
    )


@pytest.mark.parametrize("name", WITH_RULES)
def test_models_list_their_rules(doc: dict[str, Any], name: str) -> None:
    schema = doc["components"]["schemas"][name]
    rules = schema.get("x-cross-field-rules")
    assert rules and all(isinstance(r, str) and len(r) > 10 for r in rules), name
    assert "Cross-field rules:" in schema["description"]
    for r in rules:
        assert f"- {r}" in schema["description"]


@pytest.mark.parametrize(("path", "schema", "bad", "field", "good"), CASES)
def test_stated_constraints_agree_with_the_server(
    c: TestClient,
    doc: dict[str, Any],
    path: str,
    schema: str,
    bad: dict[str, Any],
    field: str,
    good: dict[str, Any],
) -> None:
    v = _validator(doc, schema)
    assert not v.is_valid(bad), f"the schema should refuse {bad}"
    r = c.post(path, json=bad)
    assert r.status_code == 422, r.text
    assert r.json()["field"].startswith(field), r.json()
    errors = list(v.iter_errors(good))
    assert not errors, [e.message for e in errors]
    r = c.post(path, json=good)
    assert 200 <= r.status_code < 300, r.text
