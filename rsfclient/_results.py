"""Typed answers of the API: one frozen dataclass per question.

Each answer carries the fields documented by the API (``/docs``) as typed attributes and
the whole JSON answer as ``raw``; it also reads like that JSON (``r["critical_size"]``,
``r.get("si")``), so fields a newer server adds are never lost.  Answers holding a table
or a grid convert to pandas (``to_pandas()``) or xarray (``to_xarray()``), each imported
only when asked.  Units are the API's: dimensionless times T = V_* t/Dc, phi = ln(V/V_*),
psi = (tau - tau_*)/(a sigma); SI fields carry their unit in their name (``_s``, ``_m_s``,
``_Pa``, ``_m``).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from typing import Any, ClassVar, TypeVar

from ._tables import columns_of, need, to_frame

__all__ = [
    "AnalyticUResult",
    "Answer",
    "BatchResult",
    "BoundariesResult",
    "ClassifyResult",
    "CriticalResult",
    "FigureData",
    "FigureInfo",
    "FitResult",
    "ItemError",
    "Params",
    "PointsResult",
    "ProtocolResult",
    "Start",
    "StiffnessResult",
    "TrajectoryResult",
]

A = TypeVar("A", bound="Answer")


def _nested(cls: type[Any]) -> Callable[[Any], Any]:
    def conv(v: Any) -> Any:
        return (
            None if v is None else cls(**{f.name: v.get(f.name) for f in dataclasses.fields(cls)})
        )

    return conv


@dataclass(frozen=True)
class Params:
    """The dimensionless groups a question was answered with: b/a, kappa = k Dc/(a sigma),
    eps (0 slip law .. 1 aging law), v_o = V_load/V_*."""

    ba: float
    kappa: float
    eps: float
    vo: float


@dataclass(frozen=True)
class Start:
    """A point (phi, psi) of the phase plane."""

    phi: float
    psi: float


@dataclass(frozen=True, kw_only=True)
class Answer:
    """Base of every answer: ``raw`` is the JSON answer; ``cached`` and ``cache_key`` say
    whether it came from the server's result cache and under which key."""

    raw: dict[str, Any] = field(repr=False, compare=False)
    cached: bool | None = None
    cache_key: str | None = field(default=None, repr=False)
    #: Converters of nested fields (field name -> callable on the JSON value).
    _convert: ClassVar[dict[str, Callable[[Any], Any]]] = {}

    @classmethod
    def from_json(cls: type[A], d: dict[str, Any]) -> A:
        """The answer of a JSON object: fields without a default must be present."""
        kw: dict[str, Any] = {}
        for f in dataclasses.fields(cls):
            if f.name == "raw":
                continue
            required = f.default is dataclasses.MISSING and f.default_factory is dataclasses.MISSING
            if f.name not in d and not required:
                continue
            v = d[f.name]
            conv = cls._convert.get(f.name)
            kw[f.name] = v if conv is None else conv(v)
        return cls(raw=d, **kw)

    def __getitem__(self, key: str) -> Any:
        return self.raw[key]

    def __contains__(self, key: object) -> bool:
        return key in self.raw

    def get(self, key: str, default: Any = None) -> Any:
        """A field of the JSON answer, ``default`` if absent."""
        return self.raw.get(key, default)

    def keys(self) -> Iterator[str]:
        """The fields of the JSON answer."""
        return iter(self.raw)

    def to_dict(self) -> dict[str, Any]:
        """A copy of the JSON answer."""
        return dict(self.raw)


_PARAMS = {"params": _nested(Params), "start": _nested(Start)}


@dataclass(frozen=True, kw_only=True)
class ClassifyResult(Answer):
    """Certified outcome of one perturbation (POST /v1/classify).

    outcome 'stable' | 'unstable'; certificate: what decided it; blowup_time (unstable) /
    return_time (stable, v_o > 0), peak_phi, peak_time in T; rel_accuracy of those (a
    tested bound); n_steps, n_rhs; the params and start point used; the perturbation and
    its dimensionless size; ``complete`` and, when it is false, ``reason`` (why: a step
    budget, unchecked times, samples ending before the extent asked); ``si``: the same in
    SI (s, m/s, Pa) when asked in SI.
    """

    outcome: str
    certificate: str
    blowup_time: float | None = None
    return_time: float | None = None
    peak_phi: float | None = None
    peak_time: float | None = None
    rel_accuracy: float
    n_steps: int | None = None
    n_rhs: int | None = None
    params: Params
    start: Start | None = None
    perturbation: str | None = None
    size: float | None = None
    complete: bool | None = None
    reason: str | None = None
    si: dict[str, Any] | None = None
    _convert: ClassVar[dict[str, Callable[[Any], Any]]] = _PARAMS


@dataclass(frozen=True, kw_only=True)
class TrajectoryResult(ClassifyResult):
    """Outcome plus the downsampled trajectory (POST /v1/trajectory): ``trajectory`` holds
    columns T, phi, psi, ln_theta, slip, load_point (and the SI columns t_s, V_m_s,
    tau_change_Pa, friction, theta_s, slip_m, load_point_m when asked in SI); ``sampling``
    says how the samples are spaced."""

    trajectory: dict[str, list[float | None]]
    sampling: dict[str, Any] | None = None

    def to_pandas(self) -> Any:
        """The samples as a pandas.DataFrame, one column per quantity."""
        return to_frame(self.trajectory)

    def to_xarray(self) -> Any:
        """The samples as an xarray.Dataset on dimension ``sample`` with coordinate T."""
        xr = need("xarray")
        cols = {
            k: ("sample", [float("nan") if x is None else x for x in v])
            for k, v in self.trajectory.items()
            if k != "T"
        }
        return xr.Dataset(cols, coords={"T": ("sample", self.trajectory["T"])})


@dataclass(frozen=True, kw_only=True)
class CriticalResult(Answer):
    """Critical perturbation size (POST /v1/critical): kind 'zero' | 'finite' |
    'infinite'; critical_size d (velocity jump) or dv (load-point jump), null when
    infinite or beyond the double range; log_critical_size (finite for every finite size);
    rel_accuracy (a tested bound), accuracy_met and reason; method; ``si``: the critical
    slip rate / load-point velocity [m/s] when asked in SI."""

    kind: str
    critical_size: float | None = None
    log_critical_size: float | None = None
    rel_accuracy: float
    accuracy_met: bool | None = None
    reason: str | None = None
    method: str
    perturbation: str
    params: Params
    on_boundary: bool | None = None
    si: dict[str, Any] | None = None
    _convert: ClassVar[dict[str, Callable[[Any], Any]]] = _PARAMS


@dataclass(frozen=True, kw_only=True)
class BoundariesResult(Answer):
    """Stability boundaries (GET|POST /v1/boundaries): kappa_crit = b/a - 1, eps_crit,
    (a/b)_crit, whether acceleration is possible, the largest unstable kappa, and the
    acceleration line psi(phi) at the phis asked; ``si``: k_crit [Pa/m] and
    kappa/kappa_crit when asked in SI.  A boundary that does not exist is an
    ``{"error": ...}`` object."""

    ba: float
    kappa: float
    eps: float
    kappa_crit: float
    eps_crit: Any = None
    ab_crit: Any = None
    acceleration_possible: Any = None
    max_unstable_kappa: Any = None
    acceleration_line: list[dict[str, Any]] = field(default_factory=list)
    si: dict[str, Any] | None = None

    def to_pandas(self) -> Any:
        """The acceleration line as a pandas.DataFrame (phi, psi[, error])."""
        return need("pandas").DataFrame(self.acceleration_line)


@dataclass(frozen=True, kw_only=True)
class AnalyticUResult(Answer):
    """The analytic Lyapunov function U (POST /v1/analytic/u): at points (``U[i]`` at
    (phi[i], psi[i])) or on a grid (``U[i][j]`` at (phi[i], psi[j]), ``shape``)."""

    function: str
    phi: list[float]
    psi: list[float]
    U: Any
    shape: list[int] | None = None

    def to_xarray(self) -> Any:
        """U as an xarray.DataArray: dims (phi, psi) on a grid, (point,) at points."""
        xr = need("xarray")
        if self.shape is not None:
            return xr.DataArray(
                self.U, dims=("phi", "psi"), coords={"phi": self.phi, "psi": self.psi}, name="U"
            )
        return xr.DataArray(
            self.U,
            dims=("point",),
            coords={"phi": ("point", self.phi), "psi": ("point", self.psi)},
            name="U",
        )

    def to_pandas(self) -> Any:
        """phi, psi, U as a pandas.DataFrame (one row per point or grid node)."""
        if self.shape is None:
            return to_frame({"phi": self.phi, "psi": self.psi, "U": self.U})
        return self.to_xarray().to_dataframe().reset_index()


@dataclass(frozen=True, kw_only=True)
class StiffnessResult(Answer):
    """Continuum stiffness (POST /v1/stiffness): eigenvalue k/k_* of case A-E, the k_*
    formula, and with physical parameters the critical dimension [m] and its name
    (lambda_c, L_c or R_c)."""

    case: str
    mode: int
    eigenvalue: float | None = None
    k_star_formula: str | None = None
    critical_dimension_m: float | None = None
    critical_dimension_name: str | None = None


@dataclass(frozen=True, kw_only=True)
class PointsResult(Answer):
    """Outcomes of many start points of one parameter set (POST /v1/classify/points):
    ``outcome[i]`` and ``method[i]`` for (phi[i], psi[i]) of the request."""

    outcome: list[str]
    method: list[str]
    n_points: int
    n_integrated: int | None = None
    params: Params
    rtol: float | None = None
    _convert: ClassVar[dict[str, Callable[[Any], Any]]] = _PARAMS

    def to_pandas(self) -> Any:
        """outcome and method per point as a pandas.DataFrame."""
        return to_frame({"outcome": self.outcome, "method": self.method})


@dataclass(frozen=True)
class ItemError:
    """A batch item that could not be answered: its index, the field at fault, why, and
    the field's valid range."""

    index: int
    field: str | None
    message: str
    valid: str | None


@dataclass(frozen=True, kw_only=True)
class BatchResult(Answer):
    """Answers of a batch (POST /v1/classify/batch, /v1/critical/batch), in the items'
    order: a :class:`ClassifyResult` / :class:`CriticalResult`, or an :class:`ItemError`."""

    results: list[Any]
    n_items: int
    n_ok: int
    n_failed: int

    @classmethod
    def of(cls, d: dict[str, Any], item: type[Answer]) -> BatchResult:
        """The batch answer ``d`` whose answered items are ``item``s."""
        res: list[Any] = []
        for r in d["results"]:
            if "error" in r:
                e = r["error"]
                res.append(
                    ItemError(r["index"], e.get("field"), e.get("message", ""), e.get("valid"))
                )
            else:
                res.append(item.from_json(r))
        return cls(raw=d, results=res, n_items=d["n_items"], n_ok=d["n_ok"], n_failed=d["n_failed"])

    def to_pandas(self) -> Any:
        """One row per item: index, the scalar fields of its answer (params flattened as
        params.ba, ...), and ``error`` (null for answered items)."""
        rows = []
        for i, r in enumerate(self.results):
            if isinstance(r, ItemError):
                rows.append({"index": i, "error": r.message, "error_field": r.field})
                continue
            row: dict[str, Any] = {"index": i, "error": None}
            for k, v in r.raw.items():
                if isinstance(v, dict) and k == "params":
                    row.update({f"params.{p}": x for p, x in v.items()})
                elif v is None or isinstance(v, str | int | float | bool):
                    row[k] = v
            rows.append(row)
        return need("pandas").DataFrame(rows)


@dataclass(frozen=True, kw_only=True)
class ProtocolResult(Answer):
    """A lab protocol (POST /v1/protocols/...): ``kind`` (velocity-step, slide-hold-slide,
    load-history), the sampled history (``series``: t_s, V_m_s, friction, ... as columns),
    the per-segment peaks and friction changes, and the runaway check."""

    kind: str
    friction_changes: dict[str, Any] | None = None
    segments: list[dict[str, Any]] | None = None
    runaway: dict[str, Any] | None = None

    @property
    def series(self) -> dict[str, list[Any]]:
        """The sampled history as columns (all equal length)."""
        inner = self.raw.get("protocol")
        src = inner if isinstance(inner, dict) else self.raw
        return columns_of(src, "t_s")

    def to_pandas(self) -> Any:
        """The sampled history as a pandas.DataFrame."""
        return to_frame(self.series)


@dataclass(frozen=True, kw_only=True)
class FitResult(Answer):
    """A fitted lab record (GET /v1/fits/{key}): status and message, the reported law,
    params (mu0, a, b, Dc_m, ...) with stderr, misfit, the stability answer in SI with
    its spread, the law comparison; ``series`` (t_s, v_lp_m_s, mu, model, residuals)."""

    status: str
    ok: bool | None = None
    message: str | None = None
    law: str | None = None
    params: dict[str, Any] = field(default_factory=dict)
    stderr: dict[str, Any] = field(default_factory=dict)
    misfit: dict[str, Any] | None = None
    stability: dict[str, Any] | None = None
    law_comparison: dict[str, Any] | None = None

    @property
    def series(self) -> dict[str, list[Any]]:
        """Data, model and residuals as columns."""
        s = self.raw.get("series")
        return columns_of(s if isinstance(s, dict) else self.raw, "t_s")

    def to_pandas(self) -> Any:
        """Data, model and residuals as a pandas.DataFrame."""
        return to_frame(self.series)


@dataclass(frozen=True, kw_only=True)
class FigureData(Answer):
    """The numbers a figure of the paper plots (GET /v1/figures/{name}?format=json): its
    catalogue entry (``name``, ``label``, ``caption``, ``note``), the ``quality`` they were
    computed at, and the figure's arrays (every curve at most 400 points) in ``raw``, as
    nested JSON lists (``d["panels"][0]["curves"]``)."""

    name: str
    label: str
    caption: str
    note: str = ""
    quality: str


@dataclass(frozen=True)
class FigureInfo:
    """One reproducible figure of the paper (GET /v1/figures)."""

    name: str
    caption: str
    label: str
    note: str
    url: str
