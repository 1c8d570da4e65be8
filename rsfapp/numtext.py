"""Numbers of whole arrays as text, at C speed: the CSV fields and JSON arrays of sweep
downloads (:mod:`rsfapp.sweepdata`).

Python's ``repr`` of each float costs ~0.3-2 us a number, which made a CSV download of a
10^8-point sweep take hours.  orjson writes a numpy array's floats with the same shortest
round-trip digits as ``repr`` (both are Ryu-style shortest representations) in ~20 ns a
number; it differs from ``repr`` only in notation: its exponents carry no ``+`` and no
leading zero (``1e16``, ``1e-7`` against ``1e+16``, ``1e-07``), and 1e-5 <= |x| < 1e-4 is
written positionally (``0.000015`` against ``1.5e-05``).  :func:`float_texts` rewrites the
exponents with two regular expressions over the whole text and formats that one decade,
NaN and infinities one by one, so every field is exactly ``repr(float(x))``
(tests/app/test_numtext.py checks this against ``repr`` over the whole double range).
"""

from __future__ import annotations

import re
from typing import Any

import numpy as np
import orjson
from numpy.typing import NDArray

__all__ = ["float_texts", "int_texts", "json_floats", "json_ints"]

_SIGN = re.compile(r"e(\d)")  # 1e16 -> 1e+16
_PAD = re.compile(r"e([+-])(\d)(?!\d)")  # 1e-7 -> 1e-07, 1e+9 -> 1e+09


def _repr_exponents(text: str) -> str:
    if "e" not in text:
        return text
    return _PAD.sub(r"e\g<1>0\2", _SIGN.sub(r"e+\1", text))


def _floats(x: NDArray[Any]) -> NDArray[np.float64]:
    return np.ascontiguousarray(x, dtype=np.float64)


def json_floats(x: NDArray[Any]) -> str:
    """A JSON array of the floats of ``x``, each as ``repr`` writes it, ``null`` where
    not finite (NaN, +-inf)."""
    a = _floats(x)
    text = _repr_exponents(orjson.dumps(a, option=orjson.OPT_SERIALIZE_NUMPY).decode())
    odd = np.flatnonzero(np.isfinite(a) & (np.abs(a) >= 1e-5) & (np.abs(a) < 1e-4))
    if odd.size == 0:
        return text
    items = text[1:-1].split(",")
    for i in odd.tolist():
        items[i] = repr(float(a[i]))
    return "[" + ",".join(items) + "]"


def float_texts(x: NDArray[Any], nan: str = "") -> list[str]:
    """``repr(float(v))`` of every element of ``x`` (``inf``, ``-inf`` kept), ``nan``
    where NaN."""
    a = _floats(x)
    if a.size == 0:
        return []
    text = _repr_exponents(orjson.dumps(a, option=orjson.OPT_SERIALIZE_NUMPY).decode())
    items = text[1:-1].split(",")
    mag = np.abs(a)
    odd = np.flatnonzero(~np.isfinite(a) | ((mag >= 1e-5) & (mag < 1e-4)))
    for i in odd.tolist():
        v = float(a[i])
        items[i] = nan if v != v else repr(v)
    return items


def json_ints(x: NDArray[Any]) -> str:
    """A JSON array of the integers (or 0/1 of the booleans) of ``x``."""
    a = np.ascontiguousarray(x)
    if a.dtype == np.bool_:
        a = a.view(np.uint8)
    return orjson.dumps(a, option=orjson.OPT_SERIALIZE_NUMPY).decode()


def int_texts(x: NDArray[Any]) -> list[str]:
    """``str(int(v))`` of every element of ``x`` (booleans as 0/1)."""
    if np.size(x) == 0:
        return []
    return json_ints(x)[1:-1].split(",")
