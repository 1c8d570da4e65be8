"""Access to the independently verified reference values in ../shared/reference/values.json."""
from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any

import pytest

_CANDIDATES = [
    Path(__file__).resolve().parents[2] / "shared" / "reference" / "values.json",
    Path(__file__).resolve().parents[1] / "shared" / "reference" / "values.json",
]


def reference_path() -> Path | None:
    env = os.environ.get("RSF_REFERENCE")
    if env:
        p = Path(env)
        return p / "values.json" if p.is_dir() else p
    for p in _CANDIDATES:
        if p.exists():
            return p
    return None


def reference_cases() -> list[dict[str, Any]]:
    """All reference cases; skips the calling test when the file is not reachable."""
    p = reference_path()
    if p is None or not p.exists():
        pytest.skip("reference values not found (set RSF_REFERENCE to shared/reference/values.json)")
    return json.loads(p.read_text())["cases"]


def reference_case(case_id: str) -> dict[str, Any]:
    """One reference case by id (fails the test if the id is missing)."""
    for c in reference_cases():
        if c["id"] == case_id:
            return c
    pytest.fail(f"reference case {case_id} missing")


def perturbation_of(case: dict[str, Any]) -> str:
    text = case["quantity"] + " " + str(case["inputs"].get("perturbation", ""))
    return "load-point-jump" if "load" in text else "velocity-jump"
