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
        return Path(env)
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


def perturbation_of(case: dict[str, Any]) -> str:
    text = case["quantity"] + " " + str(case["inputs"].get("perturbation", ""))
    return "load-point-jump" if "load" in text else "velocity-jump"
