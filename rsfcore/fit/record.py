"""Lab velocity-step records: the documented CSV / JSON formats and their validation.

A record is a friction time series under an imposed (commanded) load-point velocity:

    t_s        time [s], strictly increasing                   (or x_lp_m, see below)
    v_lp_m_s   imposed load-point velocity [m/s], >= 0, piecewise constant
    mu         measured friction coefficient (-)

Convention (documented in docs/fitting.md): the value ``v_lp_m_s[i]`` is the load-point
velocity on the interval [t_i, t_{i+1}); a velocity step therefore happens at the first
sample that carries the new velocity.  The record starts in steady sliding at
``v_lp_m_s[0]`` (> 0).  Instead of time a record may give the load-point displacement
``x_lp_m`` [m] (strictly increasing; every velocity > 0): then t_0 = 0 and
t_i = t_{i-1} + (x_i - x_{i-1})/v_{i-1}.

CSV: one header line naming the columns (any order, extra columns ignored), then one
row per sample; separators ``,`` ``;`` tab or spaces; lines starting with ``#`` are
comments.  JSON: an object with the same column names as arrays,
``{"t_s": [...], "v_lp_m_s": [...], "mu": [...]}``, optionally ``"name"``.

Validation errors are rsfcore.params.ParameterError naming the column and row, e.g.
``record.mu[17]``.
"""

from __future__ import annotations

import csv
import hashlib
import io
import json
import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..params import ParameterError

__all__ = ["Record", "read_record", "RECORD_COLUMNS", "MAX_SEGMENTS", "MIN_SAMPLES"]

#: Recognised column names: time or displacement, imposed velocity, friction.
RECORD_COLUMNS: tuple[str, ...] = ("t_s", "x_lp_m", "v_lp_m_s", "mu")
#: A record must be piecewise constant in v_lp: at most this many constant segments.
MAX_SEGMENTS = 2000
#: Fewest samples accepted (enough for 6 parameters and a residual variance).
MIN_SAMPLES = 10


def _as_array(name: str, values: Any) -> NDArray[np.float64]:
    try:
        arr = np.asarray(values, dtype=np.float64)
    except (TypeError, ValueError):
        raise ParameterError(
            f"record.{name}", "<non-numeric>", "a list of finite numbers"
        ) from None
    if arr.ndim != 1:
        raise ParameterError(
            f"record.{name}", f"<array of shape {arr.shape}>", "a one-dimensional list of numbers"
        )
    bad = np.flatnonzero(~np.isfinite(arr))
    if bad.size:
        i = int(bad[0])
        raise ParameterError(f"record.{name}[{i}]", float(arr[i]), "a finite number")
    return np.ascontiguousarray(arr)


@dataclass(frozen=True)
class Record:
    """A validated lab record (SI units).

    Attributes:
        t_s: time [s], strictly increasing, shape (n,), n >= 10.
        v_lp_m_s: imposed load-point velocity [m/s] on [t_i, t_{i+1}), >= 0, v[0] > 0.
        mu: friction (-).
        x_lp_m: load-point displacement [m] when the record was given that way, else None.
        name: free text (file name).
    """

    t_s: NDArray[np.float64]
    v_lp_m_s: NDArray[np.float64]
    mu: NDArray[np.float64]
    x_lp_m: NDArray[np.float64] | None = None
    name: str = ""
    segment_starts: NDArray[np.int64] = field(init=False, repr=False)

    def __post_init__(self) -> None:
        t = _as_array("t_s", self.t_s)
        v = _as_array("v_lp_m_s", self.v_lp_m_s)
        mu = _as_array("mu", self.mu)
        n = t.shape[0]
        if v.shape[0] != n or mu.shape[0] != n:
            raise ParameterError(
                "record",
                {"t_s": n, "v_lp_m_s": v.shape[0], "mu": mu.shape[0]},
                "columns of equal length",
            )
        if n < MIN_SAMPLES:
            raise ParameterError("record", f"{n} samples", f">= {MIN_SAMPLES} samples")
        dt = np.diff(t)
        bad = np.flatnonzero(~(dt > 0.0))
        if bad.size:
            i = int(bad[0]) + 1
            raise ParameterError(
                f"record.t_s[{i}]",
                float(t[i]),
                f"> t_s[{i - 1}] = {t[i - 1]!r} (strictly increasing time)",
            )
        neg = np.flatnonzero(v < 0.0)
        if neg.size:
            i = int(neg[0])
            raise ParameterError(
                f"record.v_lp_m_s[{i}]", float(v[i]), ">= 0 (imposed load-point velocity)"
            )
        if not v[0] > 0.0:
            raise ParameterError(
                "record.v_lp_m_s[0]", float(v[0]), "> 0 (the record starts in steady sliding)"
            )
        if np.max(v) / v[0] > 1e300 or np.min(v[v > 0]) / v[0] < 1e-300:
            raise ParameterError(
                "record.v_lp_m_s", float(np.max(v)), "within a factor 1e300 of v_lp_m_s[0]"
            )
        starts = np.concatenate(([0], np.flatnonzero(v[1:] != v[:-1]) + 1)).astype(np.int64)
        if starts.shape[0] > MAX_SEGMENTS:
            raise ParameterError(
                "record.v_lp_m_s",
                f"{starts.shape[0]} constant segments",
                f"piecewise constant with <= {MAX_SEGMENTS} segments: give the commanded "
                "velocity, not a measured one",
            )
        object.__setattr__(self, "t_s", t)
        object.__setattr__(self, "v_lp_m_s", v)
        object.__setattr__(self, "mu", mu)
        if self.x_lp_m is not None:
            object.__setattr__(self, "x_lp_m", _as_array("x_lp_m", self.x_lp_m))
        object.__setattr__(self, "segment_starts", starts)

    # -- constructors -----------------------------------------------------------------
    @classmethod
    def from_displacement(
        cls, x_lp_m: Sequence[float], v_lp_m_s: Sequence[float], mu: Sequence[float], name: str = ""
    ) -> Record:
        """Record given against load-point displacement x [m] (strictly increasing, all v > 0).

        t_0 = 0, t_i = t_{i-1} + (x_i - x_{i-1})/v_{i-1} (v_{i-1} is the velocity on the interval).
        """
        x = _as_array("x_lp_m", x_lp_m)
        v = _as_array("v_lp_m_s", v_lp_m_s)
        if v.shape[0] != x.shape[0]:
            raise ParameterError(
                "record", {"x_lp_m": x.shape[0], "v_lp_m_s": v.shape[0]}, "columns of equal length"
            )
        nz = np.flatnonzero(~(v > 0.0))
        if nz.size:
            i = int(nz[0])
            raise ParameterError(
                f"record.v_lp_m_s[{i}]",
                float(v[i]),
                "> 0 when the record is given against displacement x_lp_m "
                "(a hold has no displacement axis)",
            )
        dx = np.diff(x)
        bad = np.flatnonzero(~(dx > 0.0))
        if bad.size:
            i = int(bad[0]) + 1
            raise ParameterError(
                f"record.x_lp_m[{i}]",
                float(x[i]),
                f"> x_lp_m[{i - 1}] = {x[i - 1]!r} (strictly increasing displacement)",
            )
        t = np.concatenate(([0.0], np.cumsum(dx / v[:-1])))
        return cls(t_s=t, v_lp_m_s=v, mu=_as_array("mu", mu), x_lp_m=x, name=name)

    @classmethod
    def from_columns(cls, cols: Mapping[str, Any], name: str = "") -> Record:
        """From a mapping of column name -> values (t_s or x_lp_m, v_lp_m_s, mu)."""
        for need in ("v_lp_m_s", "mu"):
            if need not in cols:
                raise ParameterError(
                    f"record.{need}",
                    None,
                    "a required column (" + ", ".join(RECORD_COLUMNS) + "; t_s or x_lp_m)",
                )
        if "t_s" in cols:
            return cls(
                t_s=cols["t_s"],
                v_lp_m_s=cols["v_lp_m_s"],
                mu=cols["mu"],
                x_lp_m=cols.get("x_lp_m"),
                name=name,
            )
        if "x_lp_m" in cols:
            return cls.from_displacement(cols["x_lp_m"], cols["v_lp_m_s"], cols["mu"], name=name)
        raise ParameterError(
            "record.t_s", None, "a required column (or x_lp_m, load-point displacement [m])"
        )

    # -- derived ------------------------------------------------------------------------
    @property
    def n(self) -> int:
        return int(self.t_s.shape[0])

    @property
    def v_ref_m_s(self) -> float:
        """The initial load-point velocity v_lp_m_s[0] [m/s] (reference velocity of mu0)."""
        return float(self.v_lp_m_s[0])

    @property
    def n_steps(self) -> int:
        """Number of velocity changes in the record."""
        return int(self.segment_starts.shape[0] - 1)

    @property
    def load_point_m(self) -> NDArray[np.float64]:
        """Load-point displacement since t_0 [m] (sum of v dt over the intervals)."""
        if self.x_lp_m is not None:
            return self.x_lp_m - self.x_lp_m[0]
        return np.concatenate(([0.0], np.cumsum(np.diff(self.t_s) * self.v_lp_m_s[:-1])))

    def digest(self) -> str:
        """SHA-256 of the three columns (float64 bytes): a cache key for the record."""
        h = hashlib.sha256()
        for a in (self.t_s, self.v_lp_m_s, self.mu):
            h.update(np.ascontiguousarray(a, dtype="<f8").tobytes())
        return h.hexdigest()

    def to_dict(self) -> dict[str, Any]:
        """JSON-safe columns (the JSON record format)."""
        d: dict[str, Any] = {
            "name": self.name,
            "t_s": self.t_s.tolist(),
            "v_lp_m_s": self.v_lp_m_s.tolist(),
            "mu": self.mu.tolist(),
        }
        if self.x_lp_m is not None:
            d["x_lp_m"] = self.x_lp_m.tolist()
        return d

    def to_csv(self) -> str:
        """The record in the documented CSV format."""
        cols = ["t_s", "v_lp_m_s", "mu"] + (["x_lp_m"] if self.x_lp_m is not None else [])
        arrs = [self.t_s, self.v_lp_m_s, self.mu] + (
            [self.x_lp_m] if self.x_lp_m is not None else []
        )
        lines = [",".join(cols)]
        for row in zip(*(a.tolist() for a in arrs), strict=True):
            lines.append(",".join(repr(float(x)) for x in row))
        return "\n".join(lines) + "\n"


def _parse_csv(text: str, name: str) -> Record:
    lines = [ln for ln in text.splitlines() if ln.strip() and not ln.lstrip().startswith("#")]
    if not lines:
        raise ParameterError(
            "record", name or "<text>", "a CSV header line and rows, or a JSON object"
        )
    head = lines[0]
    if "," in head:
        delim = ","
    elif ";" in head:
        delim = ";"
    elif "\t" in head:
        delim = "\t"
    else:
        delim = " "
    if delim == " ":
        rows = [ln.split() for ln in lines]
    else:
        rows = [
            [c.strip() for c in r]
            for r in csv.reader(io.StringIO("\n".join(lines)), delimiter=delim)
        ]
    header = [h.strip().strip('"') for h in rows[0]]
    idx: dict[str, int] = {}
    for j, h in enumerate(header):
        if h in RECORD_COLUMNS:
            if h in idx:
                raise ParameterError(f"record.{h}", "duplicate column", "each column once")
            idx[h] = j
    if "mu" not in idx or "v_lp_m_s" not in idx or not ("t_s" in idx or "x_lp_m" in idx):
        raise ParameterError(
            "record.header",
            ",".join(header),
            "a header naming t_s (or x_lp_m), v_lp_m_s and mu (extra columns are ignored)",
        )
    cols: dict[str, list[float]] = {k: [] for k in idx}
    for r, row in enumerate(rows[1:]):
        for k, j in idx.items():
            try:
                val = float(row[j])
            except (IndexError, ValueError):
                raise ParameterError(
                    f"record.{k}[{r}]", row[j] if j < len(row) else None, "a finite number"
                ) from None
            cols[k].append(val)
    return Record.from_columns(cols, name=name)


def _parse_json(text: str, name: str) -> Record:
    try:
        obj = json.loads(text)
    except json.JSONDecodeError as e:
        raise ParameterError(
            "record", f"invalid JSON ({e.msg} at line {e.lineno})", "a JSON object of columns"
        ) from None
    if not isinstance(obj, dict):
        raise ParameterError(
            "record", type(obj).__name__, "a JSON object with arrays t_s (or x_lp_m), v_lp_m_s, mu"
        )
    return Record.from_columns(obj, name=str(obj.get("name", name)))


def read_record(source: str | os.PathLike[str] | Mapping[str, Any] | Record) -> Record:
    """Read a lab record from a path, from CSV or JSON text, or from a mapping of columns.

    Text containing a newline or starting with ``{`` is parsed directly; any other string
    or PathLike is a file path (``.json`` files, or content starting with ``{``, are
    JSON; everything else CSV).  See the module docstring for the formats.
    """
    if isinstance(source, Record):
        return source
    if isinstance(source, Mapping):
        return Record.from_columns(source, name=str(source.get("name", "")))
    name = ""
    if isinstance(source, os.PathLike) or (
        isinstance(source, str) and "\n" not in source and not source.lstrip().startswith("{")
    ):
        path = Path(source)
        if not path.is_file():
            raise ParameterError(
                "record", str(source), "an existing file, CSV/JSON text, or a mapping of columns"
            )
        text = path.read_text(encoding="utf-8-sig")
        name = path.name
    elif isinstance(source, str):
        text = source
    else:
        raise ParameterError(
            "record", type(source).__name__, "a path, CSV/JSON text, or a mapping of columns"
        )
    if text.lstrip().startswith("{"):
        return _parse_json(text, name)
    return _parse_csv(text, name)
