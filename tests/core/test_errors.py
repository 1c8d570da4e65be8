"""rsfcore.errors: one exception hierarchy; the old import paths name the same classes."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

import rsfcore
from rsfcore import errors, params, protocols, trajectory
from rsfcore._version import NUMERICS_VERSION
from rsfcore.jsonsafe import finite_list, finite_or_none, jsonsafe


def test_hierarchy() -> None:
    assert issubclass(errors.ParameterError, ValueError)
    assert issubclass(errors.UndecidedError, RuntimeError)
    assert issubclass(errors.BudgetExceeded, errors.UndecidedError)
    assert issubclass(errors.IntegrationBudgetError, errors.BudgetExceeded)
    assert errors.BudgetExceeded("x").reason == "budget"


def test_old_import_paths_are_the_same_classes() -> None:
    assert params.ParameterError is errors.ParameterError is rsfcore.ParameterError
    assert trajectory.UndecidedError is errors.UndecidedError is rsfcore.UndecidedError
    assert protocols.IntegrationBudgetError is errors.IntegrationBudgetError
    assert rsfcore.NUMERICS_VERSION == NUMERICS_VERSION == "10"


def test_budget_exhaustion_raises_budget_exceeded() -> None:
    # b/a = 2, kappa = 2.5, eps = 0.25 (x = 0.625 < 1): an explicit start (1, 1) needs far
    # more than 5 steps to certify its return (no closed form and, unlike a named velocity
    # jump, no separatrix side applies): the budget runs out
    with pytest.raises(errors.BudgetExceeded) as e:
        rsfcore.classify(rsfcore.Params(2.0, 2.5, 0.25), start=(1.0, 1.0), max_steps=5)
    assert e.value.reason == "budget"


def test_finite_helpers() -> None:
    assert finite_or_none(None) is None
    assert finite_or_none(math.inf) is None and finite_or_none(-math.inf) is None
    assert finite_or_none(math.nan) is None
    assert finite_or_none(np.float32(2.5)) == 2.5 and type(finite_or_none(np.float64(1.0))) is float
    assert finite_list(np.array([1.0, np.inf, np.nan])) == [1.0, None, None]
    assert finite_list(np.array([[1.0, -np.inf], [np.nan, 2.0]])) == [[1.0, None], [None, 2.0]]
    assert finite_list(3.0) == [3.0]
    assert jsonsafe({"a": np.array([np.inf, 1.0]), "b": np.float64(np.nan)}) == {
        "a": [None, 1.0],
        "b": None,
    }


def _jsonsafe_item_by_item(x: object) -> object:
    """The reference: jsonsafe as it was before sequences of finite floats were copied
    whole (every item converted on its own)."""
    if isinstance(x, dict):
        return {str(k): _jsonsafe_item_by_item(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_jsonsafe_item_by_item(v) for v in x]
    if isinstance(x, np.ndarray):
        return [_jsonsafe_item_by_item(v) for v in x.tolist()]
    if isinstance(x, (float, np.floating)):
        return finite_or_none(x)
    return x


@pytest.mark.parametrize(
    "value",
    [
        [1.0, 2.5, -3.0],
        (1.0, 2.0),
        [],
        [1.0, float("nan")],
        [1.0, float("inf"), -float("inf")],
        [1e308, 1e308],  # a finite sequence whose sum overflows
        [np.float64(1.5), 2.0, np.float64(np.inf)],
        [1.0, 2],
        np.array([1.0, 2.0, 3.0]),
        np.array([1.0, np.nan]),
        np.array([[1.0, 2.0], [3.0, np.inf]]),
        np.array([[1.0, 2.0], [3.0, 4.0]]),
        np.zeros(0),
        {"r": np.linspace(0.0, 1.0, 10_001), "s": [0.5] * 1000 + [float("nan")]},
    ],
)
def test_jsonsafe_fast_paths_agree_with_item_by_item(value: object) -> None:
    out = jsonsafe(value)
    ref = _jsonsafe_item_by_item(value)
    assert out == ref
    assert json.dumps(out, allow_nan=False) == json.dumps(ref, allow_nan=False)
