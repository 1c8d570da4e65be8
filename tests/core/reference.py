"""The independently verified reference values vendored in tests/data/reference.json.

Provenance (how each value was obtained, its digits and ``trusted_rel_tol``):
tests/data/README.md.  The file is part of the repository, so nothing here skips.
"""

from __future__ import annotations

import json
from functools import cache
from pathlib import Path
from typing import Any

import pytest

__all__ = [
    "REFERENCE_PATH",
    "perturbation_of",
    "reference_case",
    "reference_cases",
    "reference_by_id",
]

REFERENCE_PATH = Path(__file__).resolve().parents[1] / "data" / "reference.json"


@cache
def _load() -> tuple[dict[str, Any], ...]:
    return tuple(json.loads(REFERENCE_PATH.read_text())["cases"])


def reference_cases() -> list[dict[str, Any]]:
    """All reference cases (fresh dicts: callers may modify them)."""
    return [json.loads(json.dumps(c)) for c in _load()]


def reference_by_id() -> dict[str, dict[str, Any]]:
    """All reference cases keyed by id."""
    return {c["id"]: c for c in reference_cases()}


def reference_case(case_id: str) -> dict[str, Any]:
    """One reference case by id (fails the test if the id is missing)."""
    for c in reference_cases():
        if c["id"] == case_id:
            return c
    pytest.fail(f"reference case {case_id} missing from {REFERENCE_PATH}")


def perturbation_of(case: dict[str, Any]) -> str:
    text = case["quantity"] + " " + str(case["inputs"].get("perturbation", ""))
    return "load-point-jump" if "load" in text else "velocity-jump"
