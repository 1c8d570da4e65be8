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
import math
import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..params import ParameterError

__all__ = [
    "Record",
    "read_record",
    "commanded_velocity",
    "parse_column_map",
    "RECORD_COLUMNS",
    "MAX_SEGMENTS",
    "MIN_SAMPLES",
    "QUANTITIES",
    "KNOWN_HEADERS",
    "UNITS",
    "DECIMALS",
]

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
                f"> t_s[{i - 1}] = {float(t[i - 1])!r} (strictly increasing time)",
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
                f"> x_lp_m[{i - 1}] = {float(x[i - 1])!r} (strictly increasing displacement)",
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


# ---------------------------------------------------------------------------------------
# Lab files as they come: column mapping, units, units row, decimal separator
# ---------------------------------------------------------------------------------------
#: Quantities a record column can hold: name -> (dimension, SI column name).
QUANTITIES: dict[str, tuple[str, str]] = {
    "t": ("time", "t_s"),
    "x_lp": ("length", "x_lp_m"),
    "v_lp": ("velocity", "v_lp_m_s"),
    "mu": ("friction", "mu"),
    "tau": ("stress", "tau_Pa"),
    "sigma_n": ("stress", "sigma_n_Pa"),
}
#: Header names recognised without a mapping (SI units implied): the record format's own
#: names, the protocol output's names (rsfcore.protocols: friction, Vo_m_s, load_point_m),
#: and shear / normal stress in Pa.
KNOWN_HEADERS: dict[str, str] = {
    "t_s": "t",
    "x_lp_m": "x_lp",
    "v_lp_m_s": "v_lp",
    "mu": "mu",
    "friction": "mu",
    "Vo_m_s": "v_lp",
    "load_point_m": "x_lp",
    "tau_Pa": "tau",
    "sigma_n_Pa": "sigma_n",
}
#: Units by dimension: name -> factor to SI.
UNITS: dict[str, dict[str, float]] = {
    "time": {"s": 1.0, "ms": 1e-3, "us": 1e-6, "µs": 1e-6, "min": 60.0, "h": 3600.0},
    "length": {"m": 1.0, "mm": 1e-3, "um": 1e-6, "µm": 1e-6, "micron": 1e-6, "nm": 1e-9},
    "velocity": {
        "m/s": 1.0,
        "mm/s": 1e-3,
        "um/s": 1e-6,
        "µm/s": 1e-6,
        "micron/s": 1e-6,
        "nm/s": 1e-9,
    },
    "stress": {"Pa": 1.0, "kPa": 1e3, "MPa": 1e6, "GPa": 1e9},
    "friction": {"": 1.0, "-": 1.0, "1": 1.0},
}
#: Decimal separators accepted (a decimal comma needs ';' or tab between columns).
DECIMALS: tuple[str, ...] = (".", ",")


def _unit_factor(quantity: str, unit: str, where: str) -> float:
    dim = QUANTITIES[quantity][0]
    u = unit.strip().strip("()[]").strip()
    table = UNITS[dim]
    if u in table:
        return table[u]
    low = {k.lower(): v for k, v in table.items()}
    if u.lower() in low:
        return low[u.lower()]
    raise ParameterError(
        where, unit, f"a {dim} unit: " + ", ".join(repr(k) for k in table if k not in ("",))
    )


def _header_unit(header: str) -> str | None:
    """The unit in a header's trailing brackets: 'Time (s)' -> 's', 'v [um/s]' -> 'um/s'."""
    h = header.strip()
    for op, cl in (("(", ")"), ("[", "]")):
        if h.endswith(cl) and op in h:
            return h[h.rindex(op) + 1 : -1].strip()
    return None


def parse_column_map(columns: Mapping[str, str] | Sequence[str] | None) -> dict[str, str]:
    """``{"t": "Time (s)", "v_lp": "LP Velocity:um/s"}`` or ``["t=Time (s)", ...]`` ->
    {quantity: "header[:unit]"}.  Quantities: t, x_lp, v_lp, mu, tau, sigma_n (also their
    SI column names t_s, x_lp_m, ...).  Raises ParameterError naming ``columns``."""
    if columns is None:
        return {}
    items: list[tuple[str, str]] = []
    if isinstance(columns, Mapping):
        items = [(str(k), str(v)) for k, v in columns.items()]
    else:
        for i, c in enumerate(columns):
            if "=" not in str(c):
                raise ParameterError(
                    f"columns[{i}]", str(c), "QUANTITY=HEADER[:UNIT], e.g. v_lp=LP Velocity:um/s"
                )
            k, v = str(c).split("=", 1)
            items.append((k.strip(), v))
    out: dict[str, str] = {}
    si_names = {v[1]: k for k, v in QUANTITIES.items()}
    for k, v in items:
        q = k if k in QUANTITIES else si_names.get(k)
        if q is None:
            raise ParameterError(
                f"columns.{k}", v, "a quantity: " + ", ".join(QUANTITIES) + " (or t_s, x_lp_m, ...)"
            )
        if q in out:
            raise ParameterError(f"columns.{k}", v, "each quantity once")
        if not v.strip():
            raise ParameterError(f"columns.{k}", v, "a column header")
        out[q] = v
    return out


def _split_spec(q: str, spec: str) -> tuple[str, str | None]:
    """'LP Velocity:um/s' -> ('LP Velocity', 'um/s'); the unit part only when it is a unit."""
    if ":" in spec:
        head, unit = spec.rsplit(":", 1)
        dim = QUANTITIES[q][0]
        if unit.strip() in UNITS[dim] or unit.strip().lower() in {u.lower() for u in UNITS[dim]}:
            return head.strip(), unit.strip()
    return spec.strip(), None


@dataclass(frozen=True)
class _Column:
    quantity: str
    source: str  # header or key as written
    factor: float  # to SI


def _select_columns(
    headers: Sequence[str], mapping: Mapping[str, str], units: Mapping[str, str]
) -> dict[str, tuple[int, _Column]]:
    """Which header holds which quantity (mapping first, then KNOWN_HEADERS), with units
    from the mapping, else the units row / ``units``, else the header's brackets, else SI."""
    hs = [h.strip().strip('"') for h in headers]
    chosen: dict[str, tuple[int, _Column]] = {}
    for q, spec in mapping.items():
        head, unit = _split_spec(q, spec)
        if head not in hs:
            raise ParameterError(
                f"columns.{q}", head, "a column header of the record: " + ", ".join(hs)
            )
        j = hs.index(head)
        u = unit if unit is not None else units.get(head) or _header_unit(head)
        f = _unit_factor(q, u, f"columns.{q}") if u is not None else 1.0
        chosen[q] = (j, _Column(q, head, f))
    for j, h in enumerate(hs):
        kq = KNOWN_HEADERS.get(h)
        if kq is None or kq in chosen:
            continue
        if any(c.source == h for _, c in chosen.values()):
            continue
        dup = [jj for jj, hh in enumerate(hs) if hh == h]
        if len(dup) > 1:
            raise ParameterError(f"record.{h}", "duplicate column", "each column once")
        # a units row may restate the SI unit; another unit there is a contradiction
        u = units.get(h)
        f = _unit_factor(kq, u, f"record.{h} unit") if u else 1.0
        if u and f != 1.0:
            raise ParameterError(
                f"record.{h} unit", u, f"the unit its name states ({h}), or map the column"
            )
        # the protocol output names two columns for x_lp (load_point_m) and time; a record
        # with both x_lp_m and load_point_m keeps the record format's own name
        chosen[kq] = (j, _Column(kq, h, 1.0))
    return chosen


def _number(cell: str, decimal: str) -> float:
    c = cell.strip().strip('"')
    if decimal == ",":
        c = c.replace(".", "").replace(",", ".") if c.count(",") == 1 else c
    return float(c)


def _line_note(lines: Sequence[int] | None, name: str, field: str) -> str:
    """' (line 17 of run.csv; data rows counted from 0)' for a field like record.mu[14]."""
    if lines is None or "[" not in field:
        return ""
    try:
        i = int(field[field.rindex("[") + 1 : field.rindex("]")])
    except ValueError:
        return ""
    if not 0 <= i < len(lines):
        return ""
    return f" (line {lines[i]} of {name or 'the text'}; data rows counted from 0)"


def _build(
    cols: dict[str, NDArray[np.float64]],
    name: str,
    lines: Sequence[int] | None = None,
    *,
    smooth: int | None = None,
) -> Record:
    """Record from SI quantity columns (t, x_lp, v_lp, mu | tau + sigma_n)."""
    try:
        if "mu" not in cols:
            if "tau" in cols and "sigma_n" in cols:
                sig = cols["sigma_n"]
                bad = np.flatnonzero(~(sig > 0.0))
                if bad.size:
                    i = int(bad[0])
                    raise ParameterError(
                        f"record.sigma_n[{i}]", float(sig[i]), "> 0 (normal stress forming mu)"
                    )
                cols["mu"] = cols["tau"] / sig
            else:
                raise ParameterError(
                    "record.mu",
                    None,
                    "a friction column (mu, or shear stress tau with normal stress sigma_n)",
                )
        if "v_lp" not in cols:
            if "t" in cols and "x_lp" in cols:
                cols["v_lp"] = commanded_velocity(cols["t"], cols["x_lp"], smooth=smooth)
            else:
                raise ParameterError(
                    "record.v_lp_m_s",
                    None,
                    "a load-point velocity column, or time with a measured load-point "
                    "displacement (x_lp_m) to derive it from",
                )
        si = {QUANTITIES[q][1]: v for q, v in cols.items() if q in ("t", "x_lp", "v_lp", "mu")}
        return Record.from_columns(si, name=name)
    except ParameterError as exc:
        note = _line_note(lines, name, exc.field)
        if not note:
            raise
        raise ParameterError(exc.field, exc.value, str(exc.valid) + note) from None


def commanded_velocity(
    t_s: NDArray[np.float64], x_lp_m: NDArray[np.float64], *, smooth: int | None = None
) -> NDArray[np.float64]:
    """Piecewise-constant load-point velocity [m/s] from a measured (noisy) load-point
    displacement x(t) of a displacement-controlled record.

    Method: interval velocities dx/dt are median-filtered over ``smooth`` samples (odd;
    default max(5, n/200)); a new segment starts where the filtered velocity leaves the
    current segment's by more than 10 % of the larger (or 3 standard deviations of the
    interval velocities' noise, estimated from their median absolute deviation; segments
    shorter than half the filter width are merged); each segment's velocity
    is the least-squares slope of x(t) over its samples (0 when below 3 standard errors:
    a hold), and each step time is moved (within one filter width) to the sample that
    minimises the misfit of the broken line x(t).  Noise-free piecewise-linear x(t) gives
    the commanded velocities exactly; tested with noise in tests/core/test_fit.py.
    """
    t = np.asarray(t_s, dtype=np.float64)
    x = np.asarray(x_lp_m, dtype=np.float64)
    n = t.shape[0]
    if n < MIN_SAMPLES or x.shape[0] != n:
        raise ParameterError("record.x_lp_m", f"{x.shape[0]} samples", f">= {MIN_SAMPLES}, as t_s")
    dt = np.diff(t)
    if not np.all(dt > 0):
        i = int(np.flatnonzero(~(dt > 0))[0]) + 1
        raise ParameterError(f"record.t_s[{i}]", float(t[i]), "strictly increasing time")
    vr = np.diff(x) / dt
    w = smooth if smooth is not None else max(5, (n // 200) | 1)
    w = max(1, int(w) | 1)
    h = w // 2
    pad = np.concatenate((np.full(h, vr[0]), vr, np.full(h, vr[-1])))
    vs = np.median(np.lib.stride_tricks.sliding_window_view(pad, w), axis=1)
    sd_raw = 1.4826 * float(np.median(np.abs(vr - vs)))
    m_int = vs.shape[0]
    starts = [0]
    ref = vs[min(h, m_int - 1)]
    for i in range(1, m_int):
        if abs(vs[i] - ref) > max(0.1 * max(abs(vs[i]), abs(ref)), 3.0 * sd_raw):
            starts.append(i)
            ref = vs[min(i + h, m_int - 1)]
    # a segment shorter than half the filter width is the filter's edge, not a step
    starts = [s0 for k, s0 in enumerate(starts) if k == 0 or s0 - starts[k - 1] > h] or [0]
    # interval i joins sample i..i+1; the velocity of interval i is v[i] (record convention)
    bounds = starts + [n - 1]

    def slope(i0: int, i1: int) -> tuple[float, float]:
        tt, xx = t[i0 : i1 + 1], x[i0 : i1 + 1]
        if tt.shape[0] < 3:
            return float((xx[-1] - xx[0]) / (tt[-1] - tt[0])), 0.0
        A = np.column_stack((np.ones_like(tt), tt - tt.mean()))
        coef, res, *_ = np.linalg.lstsq(A, xx, rcond=None)
        s2 = float(res[0]) / (tt.shape[0] - 2) if res.size else 0.0
        se = math.sqrt(s2 / float(np.sum((tt - tt.mean()) ** 2)))
        return float(coef[1]), se

    vel = []
    for j in range(len(bounds) - 1):
        i0, i1 = bounds[j], bounds[j + 1]
        m = min(h, max(0, (i1 - i0) // 4))
        s, se = slope(i0 + m, i1 - m) if i1 - m > i0 + m else slope(i0, i1)
        vel.append(0.0 if (s <= 0.0 or s < 3.0 * se) else s)
    # refine each step time: the broken line through x with the two segment velocities
    for j in range(1, len(bounds) - 1):
        b0 = bounds[j]
        lo, hi = max(bounds[j - 1] + 1, b0 - w), min(bounds[j + 1] - 1, b0 + w)
        best, best_b = math.inf, b0
        for b in range(lo, hi + 1):
            ii = np.arange(max(0, b - 2 * w), min(n, b + 2 * w + 1))
            model = np.where(ii <= b, vel[j - 1] * (t[ii] - t[b]), vel[j] * (t[ii] - t[b]))
            r = x[ii] - model
            r = r - r.mean()
            ss = float(r @ r)
            if ss < best:
                best, best_b = ss, b
        bounds[j] = best_b
    v = np.empty(n)
    for j in range(len(bounds) - 1):
        v[bounds[j] : bounds[j + 1]] = vel[j]
    v[-1] = vel[-1]
    return v


def _parse_csv(
    text: str,
    name: str,
    mapping: Mapping[str, str],
    decimal: str,
    smooth: int | None,
) -> Record:
    numbered = [
        (k + 1, ln)
        for k, ln in enumerate(text.splitlines())
        if ln.strip() and not ln.lstrip().startswith("#")
    ]
    if not numbered:
        raise ParameterError(
            "record", name or "<text>", "a CSV header line and rows, or a JSON object"
        )
    head = numbered[0][1]
    if "\t" in head:
        delim = "\t"
    elif ";" in head:
        delim = ";"
    elif "," in head and decimal != ",":
        delim = ","
    elif "," in head:
        raise ParameterError(
            "decimal", decimal, "'.' when columns are separated by commas (or separate by ';')"
        )
    else:
        delim = " "
    body = [ln for _, ln in numbered]
    if delim == " ":
        rows = [ln.split() for ln in body]
    else:
        rows = [
            [c.strip() for c in r]
            for r in csv.reader(io.StringIO("\n".join(body)), delimiter=delim)
        ]
    header = [h.strip().strip('"') for h in rows[0]]
    data_rows, data_lines = rows[1:], [ln for ln, _ in numbered[1:]]
    units: dict[str, str] = {}
    if data_rows:
        first = data_rows[0]
        numeric = 0
        for c in first:
            try:
                _number(c, decimal)
                numeric += 1
            except ValueError:
                pass
        if numeric == 0 and any(c.strip() for c in first):
            units = {
                header[j]: first[j].strip().strip("()[]")
                for j in range(min(len(header), len(first)))
            }
            data_rows, data_lines = data_rows[1:], data_lines[1:]
    chosen = _select_columns(header, mapping, units)
    qs = set(chosen)
    if not (("mu" in qs or {"tau", "sigma_n"} <= qs) and ("t" in qs or "x_lp" in qs)) or not (
        "v_lp" in qs or {"t", "x_lp"} <= qs
    ):
        raise ParameterError(
            "record.header",
            ",".join(header),
            "a header naming t_s (or x_lp_m), v_lp_m_s and mu (extra columns are ignored), "
            "or a column mapping such as t=Time (s), v_lp=LP Velocity:um/s, mu=Friction",
        )
    cols: dict[str, list[float]] = {q: [] for q in chosen}
    for r, (row, line) in enumerate(zip(data_rows, data_lines, strict=True)):
        for q, (j, col) in chosen.items():
            cell = row[j] if j < len(row) else None
            try:
                if cell is None:
                    raise ValueError
                val = _number(cell, decimal)
            except ValueError:
                hint = (
                    "; is the decimal separator ','? (choose decimal=',')"
                    if cell is not None and "," in cell and decimal == "."
                    else ""
                )
                raise ParameterError(
                    f"record.{col.source}[{r}]",
                    cell,
                    f"a finite number (line {line} of {name or 'the text'}; data rows counted "
                    f"from 0){hint}",
                ) from None
            cols[q].append(val * col.factor)
    arrays = {q: np.asarray(v, dtype=np.float64) for q, v in cols.items()}
    return _build(arrays, name, data_lines, smooth=smooth)


def _from_mapping(
    obj: Mapping[str, Any], name: str, mapping: Mapping[str, str], smooth: int | None
) -> Record:
    """Columns from a mapping (JSON object): the record format, the protocol output (also
    its nested ``protocol`` object), or any keys with a column mapping; ``units``
    {key: unit} optional."""
    if "protocol" in obj and isinstance(obj["protocol"], Mapping) and "t_s" in obj["protocol"]:
        obj = obj["protocol"]
    units_raw = obj.get("units")
    units_obj: Mapping[str, Any] = units_raw if isinstance(units_raw, Mapping) else {}
    keys = [k for k, v in obj.items() if isinstance(v, (list, tuple, np.ndarray))]
    chosen = _select_columns(keys, mapping, {str(k): str(v) for k, v in units_obj.items()})
    cols: dict[str, NDArray[np.float64]] = {}
    for q, (j, col) in chosen.items():
        cols[q] = _as_array(col.source, obj[keys[j]]) * col.factor
    return _build(cols, name, smooth=smooth)


def _parse_json(text: str, name: str, mapping: Mapping[str, str], smooth: int | None) -> Record:
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
    return _from_mapping(obj, str(obj.get("name", name) or name), mapping, smooth)


def read_record(
    source: str | os.PathLike[str] | Mapping[str, Any] | Record,
    *,
    columns: Mapping[str, str] | Sequence[str] | None = None,
    decimal: str = ".",
    smooth: int | None = None,
) -> Record:
    """Read a lab record from a path, from CSV or JSON text, or from a mapping of columns.

    Text containing a newline or starting with ``{`` is parsed directly; any other string
    or PathLike is a file path (``.json`` files, or content starting with ``{``, are
    JSON; everything else CSV).  See the module docstring for the formats.

    Args:
        columns: column mapping {quantity: "header[:unit]"} or ["quantity=header[:unit]"]
            (quantities t, x_lp, v_lp, mu, tau, sigma_n); units otherwise from a units row
            under the header, a bracketed suffix of the header ("Time (s)"), else SI.
        decimal: "." or "," (a decimal comma needs ';' or tab between columns).
        smooth: median-filter width [samples] when the velocity is derived from a
            measured load-point displacement (commanded_velocity), default max(5, n/200).
    """
    if isinstance(source, Record):
        return source
    mapping = parse_column_map(columns)
    if decimal not in DECIMALS:
        raise ParameterError("decimal", decimal, "'.' or ','")
    if smooth is not None:
        smooth = int(smooth)
        if not 1 <= smooth <= 100_001:
            raise ParameterError("smooth", smooth, "[1, 100001] samples")
    if isinstance(source, Mapping):
        return _from_mapping(source, str(source.get("name", "")), mapping, smooth)
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
        return _parse_json(text, name, mapping, smooth)
    return _parse_csv(text, name, mapping, decimal, smooth)
