"""POST /v1/classify/points and classify by log_size, in process."""

from __future__ import annotations

import numpy as np
from fastapi.testclient import TestClient

from rsfcore import Params, classify
from rsfcore.critical import critical_perturbation


def test_points_agree_with_single_classify(c: TestClient) -> None:
    """Every outcome equals /v1/classify with the same start, including points 1e-9 from
    the separatrix (the velocity-jump line phi = psi through d_crit)."""
    p = Params(2.0, 2.0, 0.25, 1.0)
    dc = critical_perturbation(p).critical_size
    assert dc is not None
    rng = np.random.default_rng(7)
    phi = list(rng.uniform(-3, 6, 40)) + [dc * (1 - 1e-9), dc * (1 + 1e-9)]
    psi = list(rng.uniform(-3, 6, 40)) + [dc * (1 - 1e-9), dc * (1 + 1e-9)]
    body = {"ba": 2.0, "kappa": 2.0, "eps": 0.25, "vo": 1.0, "phi": phi, "psi": psi}
    r = c.post("/v1/classify/points", json=body)
    assert r.status_code == 200, r.text
    got = r.json()["outcome"]
    assert len(got) == len(phi) and got[-2:] == ["stable", "unstable"]
    for i, (a, b) in enumerate(zip(phi, psi, strict=True)):
        assert got[i] == classify(p, start=(a, b)).outcome, (i, a, b)


def test_points_lengths_must_match(c: TestClient) -> None:
    r = c.post("/v1/classify/points", json={"phi": [0.0, 1.0], "psi": [0.0]})
    assert r.status_code == 422 and r.json()["field"] == "psi"


def test_classify_by_log_size_checks_a_size_beyond_double_range(c: TestClient) -> None:
    """A load-point critical size beyond the double range is reported by its logarithm
    (critical_size null, kind finite), and classify by log_size confirms both sides."""
    body = {"ba": 10.0, "kappa": 9000.0, "eps": 0.0, "vo": 1.0, "perturbation": "load-point-jump"}
    crit = c.post("/v1/critical", json=body).json()
    lg = crit["log_critical_size"]
    # ln(1 + dv) = 997.8 (docs/accuracy.md): dv = e^997.8 is beyond the double range
    assert (
        crit["kind"] == "finite" and crit["critical_size"] is None and lg > 709.8
    )  # ln(max double) = 709.78
    tol = 10 * max(crit["rel_accuracy"], 1e-9)
    below = c.post("/v1/classify", json={**body, "log_size": lg * (1 - tol)}).json()
    above = c.post("/v1/classify", json={**body, "log_size": lg * (1 + tol)}).json()
    assert (below["outcome"], above["outcome"]) == ("stable", "unstable")
    both = c.post("/v1/classify", json={**body, "log_size": lg, "size": 1.0})
    assert both.status_code == 422 and both.json()["field"] == "log_size"
