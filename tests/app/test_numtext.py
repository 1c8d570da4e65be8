"""rsfapp.numtext: array numbers as text equal ``repr``/``str`` of each number exactly."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from rsfapp.numtext import float_texts, int_texts, json_floats, json_ints

_EDGES = [
    0.0, -0.0, 0.1, 1.0, 100.0, 1e15, 1e16, 1.5e16, 9999999999999998.0, 1e22, 1e-4,
    1.2e-4, 9.99e-5, 1e-5, 1.5e-5, 9.9999e-6, 1e-7, 1.7976931348623157e308, 5e-324,
    2.2250738585072014e-308, 123456789.0, 2.0**60, -1e-5, -3.5e-300, 0.00012,
]  # fmt: skip


def _sample() -> np.ndarray:
    rng = np.random.default_rng(7)
    x = np.exp(rng.uniform(-740, 709, 100_000)) * rng.choice([-1.0, 1.0], 100_000)
    decade = rng.uniform(1e-6, 1e-3, 20_000)  # around the notation switch at 1e-4 / 1e-5
    return np.concatenate([np.array(_EDGES), x, decade, rng.random(10_000) * 10])


def test_float_texts_are_repr_everywhere() -> None:
    a = _sample()
    assert float_texts(a) == [repr(v) for v in a.tolist()]
    special = np.array([math.nan, math.inf, -math.inf, 1.5e-5, 2.0])
    assert float_texts(special, nan="") == ["", "inf", "-inf", "1.5e-05", "2.0"]
    assert float_texts(special, nan="NA")[0] == "NA"
    assert float_texts(np.array([], dtype=np.float64)) == []
    assert float_texts(np.array([1, 2], dtype=np.int8)) == ["1.0", "2.0"]


def test_json_floats_are_repr_and_null() -> None:
    a = _sample()
    want = "[" + ",".join(repr(v) for v in a.tolist()) + "]"
    assert json_floats(a) == want
    s = json_floats(np.array([math.nan, math.inf, 1e-5, 0.5]))
    assert s == "[null,null,1e-05,0.5]" and json.loads(s) == [None, None, 1e-5, 0.5]


@pytest.mark.parametrize("dtype", [np.int8, np.int64, np.bool_])
def test_ints(dtype: type) -> None:
    a = (
        np.array([0, 1, 1, 0, 1], dtype=dtype)
        if dtype is np.bool_
        else np.arange(-3, 120, 7, dtype=dtype)
    )
    want = [str(int(v)) for v in a.tolist()]
    assert int_texts(a) == want
    assert json.loads(json_ints(a)) == [int(v) for v in want]
    assert int_texts(np.array([], dtype=dtype)) == []
