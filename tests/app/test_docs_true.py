"""The README documents every setting the code reads (and no setting that does not exist)."""

from __future__ import annotations

import re
from pathlib import Path

from rsfapp.config import Settings

README = Path(__file__).resolve().parents[2] / "README.md"


def test_readme_lists_every_setting() -> None:
    text = README.read_text()
    documented = set(re.findall(r"`(RSF_[A-Z0-9_]+)`", text))
    expected = {f"RSF_{name.upper()}" for name in Settings.model_fields}
    missing = expected - documented
    assert not missing, f"settings missing from README: {sorted(missing)}"
    # variables the README names that are neither settings nor client/test variables
    # RSF_CACHE_DIR: the compiled-kernel cache, read by rsfcore itself (rsfcore/_cache.py)
    others = {"RSF_API_KEY", "RSF_URL", "RSF_REFERENCE", "RSF_CACHE_DIR"}
    unknown = documented - expected - others
    assert not unknown, f"README names settings that do not exist: {sorted(unknown)}"
