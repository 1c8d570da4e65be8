"""The public surface of rsfcore (docs/core-api.md) is pinned here.

Changing it is a decision: update docs/core-api.md, this list and rsfcore/__init__.py
together.
"""

from __future__ import annotations

import importlib
import re
import types
from pathlib import Path

import rsfcore

EXPECTED = [
    "NUMERICS_VERSION",
    "BudgetExceeded",
    "IntegrationBudgetError",
    "ParameterError",
    "UndecidedError",
    "DEFAULT_RTOL",
    "Limit",
    "Params",
    "PhysicalParams",
    "RTOL_RANGE",
    "Perturbation",
    "Trajectory",
    "TrajectoryResult",
    "classify",
    "simulate",
    "start_point",
    "PointsResult",
    "classify_points",
    "CriticalResult",
    "KINDS",
    "PERTURBATIONS",
    "bisect_critical",
    "critical_perturbation",
    "AXIS_NAMES",
    "DiagramResult",
    "stability_diagram",
    "ab_crit",
    "acceleration_line",
    "acceleration_possible",
    "boundaries_summary",
    "eps_crit",
    "kappa_crit",
    "max_unstable_kappa",
    "U_kcrit",
    "U_vo0",
    "ProtocolResult",
    "SlideHoldSlideResult",
    "VelocityStepResult",
    "load_history",
    "slide_hold_slide",
    "steady_state_friction",
    "velocity_step",
    "critical_dimension",
    "eigen_mode",
    "eigen_stiffness",
    "kappa_of_fault",
    "stiffness_of_fault",
    "stiffness_summary",
    "EngineResult",
    "analytic",
    "boundaries",
    "critical",
    "diagram",
    "engine",
    "errors",
    "laws",
    "limits",
    "ode",
    "params",
    "phase",
    "protocols",
    "separatrix",
    "stiffness",
    "trajectory",
]

DOC = Path(__file__).resolve().parents[2] / "docs" / "core-api.md"


def test_all_is_pinned() -> None:
    assert rsfcore.__all__ == EXPECTED
    assert len(set(rsfcore.__all__)) == len(rsfcore.__all__)


def test_every_name_resolves() -> None:
    for name in rsfcore.__all__:
        assert hasattr(rsfcore, name), name


def test_public_names_are_the_modules_own() -> None:
    """Re-exported objects are the very objects of their defining module (no copies)."""
    for name in rsfcore.__all__:
        obj = getattr(rsfcore, name)
        if isinstance(obj, types.ModuleType):
            assert obj is importlib.import_module(f"rsfcore.{name}")
            continue
        home = getattr(obj, "__module__", None)
        if home and home.startswith("rsfcore.") and not isinstance(obj, (str, tuple, float)):
            assert getattr(importlib.import_module(home), name, obj) is obj, name


def test_every_module_declares_all() -> None:
    root = Path(rsfcore.__file__).parent
    for f in sorted(root.rglob("*.py")):
        rel = f.relative_to(root.parent).with_suffix("")
        mod = importlib.import_module(".".join(rel.parts).removesuffix(".__init__"))
        assert isinstance(getattr(mod, "__all__", None), list), mod.__name__
        for name in mod.__all__:
            assert hasattr(mod, name), (mod.__name__, name)


def test_doc_mentions_every_exported_name() -> None:
    """docs/core-api.md documents each name of rsfcore.__all__ (as `name` in backticks)."""
    text = DOC.read_text()
    missing = [
        n for n in rsfcore.__all__ if not re.search(rf"`(rsfcore\.)?{re.escape(n)}[`(.\s]", text)
    ]
    assert not missing, missing
