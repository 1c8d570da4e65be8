"""The client: one method per question of the API, keyword arguments named exactly like
the HTTP JSON fields, typed answers.

An argument left out (None) is not sent, so the server's default applies: the same
default as at every other door (CLI, HTTP, library).  The machine in SI is given either as
``physical={...}`` or flat, by its fields (``a, b, Dc_m, sigma_Pa, k_Pa_per_m, V_star_m_s,
V_load_m_s``), which the client nests into ``physical``; never together with the
dimensionless ``ba, kappa, vo`` (the server answers 422 naming the field).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from types import TracebackType
from typing import Any, Literal

import httpx

from ._fits import Fit, record_text
from ._http import Http
from ._results import (
    AnalyticUResult,
    BatchResult,
    BoundariesResult,
    ClassifyResult,
    CriticalResult,
    FigureData,
    FigureInfo,
    FitResult,
    PointsResult,
    ProtocolResult,
    StiffnessResult,
    TrajectoryResult,
)
from ._sweeps import Sweep, SweepStatus

__all__ = ["Client", "MACHINE_FIELDS", "RENDERABLE", "axis"]

#: The spring-slider in SI: the fields of ``physical`` (HTTP names, units in the names).
MACHINE_FIELDS = ("a", "b", "Dc_m", "sigma_Pa", "k_Pa_per_m", "V_star_m_s", "V_load_m_s")
#: Questions with an image or table form (:meth:`Client.render`): path and formats.
RENDERABLE: dict[str, tuple[str, tuple[str, ...]]] = {
    "trajectory": ("/v1/trajectory", ("png", "csv")),
    "analytic_u": ("/v1/analytic/u", ("png",)),
    "velocity_step": ("/v1/protocols/velocity-step", ("png", "csv")),
    "slide_hold_slide": ("/v1/protocols/slide-hold-slide", ("png", "csv")),
    "load_history": ("/v1/protocols/load-history", ("png", "csv")),
}

Perturbation = Literal["velocity-jump", "load-point-jump"]
Point = Mapping[str, float] | Sequence[float]


def axis(
    name: str,
    start: float | None = None,
    stop: float | None = None,
    n: int | None = None,
    *,
    values: Sequence[float] | None = None,
    log: bool | None = None,
) -> dict[str, Any]:
    """One sweep axis: ``axis("eps", 0, 0.9, 10)`` or ``axis("vo", values=[0, 1])``
    (``log=True``: geometric spacing)."""
    d: dict[str, Any] = {"name": name}
    if values is not None:
        d["values"] = [float(v) for v in values]
    for k, v in (("start", start), ("stop", stop), ("n", n), ("log", log)):
        if v is not None:
            d[k] = v
    return d


def _point(p: Point) -> dict[str, float]:
    if isinstance(p, Mapping):
        return {"phi": float(p["phi"]), "psi": float(p["psi"])}
    phi, psi = p
    return {"phi": float(phi), "psi": float(psi)}


def _floats(v: Any) -> Any:
    """Sequences (lists, tuples, numpy arrays) as lists of float; other values as is."""
    if isinstance(v, str | bytes | Mapping) or not hasattr(v, "__len__"):
        return v
    return [float(x) for x in v]


def body(fields: Mapping[str, Any], nest_machine: bool = True) -> dict[str, Any]:
    """The JSON body of keyword arguments: None left out; with ``nest_machine`` the flat SI
    machine fields nested into ``physical`` (ValueError if ``physical`` is given as well),
    without it (fits: k_Pa_per_m and sigma_Pa are top-level fields there) sent as given."""
    out = {k: v for k, v in fields.items() if v is not None and k != "self"}
    if not nest_machine:
        return out
    machine = {k: out.pop(k) for k in MACHINE_FIELDS if k in out}
    if machine:
        if "physical" in out:
            raise ValueError(
                "give the machine either as physical={...} or by its fields "
                f"({', '.join(machine)}), not both"
            )
        out["physical"] = machine
    return out


class Client:
    """A client of one rsf-stability API.

    Args:
        base_url: e.g. ``http://127.0.0.1:8000``; default the ``RSF_URL`` environment
            variable, else ``http://127.0.0.1:8000`` (``rsf serve``'s default).
        api_key: sent as ``Authorization: Bearer <key>``; default ``RSF_API_KEY`` (if set).
        timeout: seconds per request.
        retries: times a 503, a 429 with Retry-After, or a connection reset is retried
            (waiting Retry-After, else exponential backoff from ``backoff`` seconds).  A
            refused connection fails at once (:class:`ConnectionFailed`).
        poll: seconds between polls of deferred answers.
        transport: an httpx transport (tests: ``httpx.MockTransport``, an in-process app).

    Every method raises :class:`ProblemError` (status, field, valid) on an error answer.
    """

    def __init__(
        self,
        base_url: str | None = None,
        *,
        api_key: str | None = None,
        timeout: float = 60.0,
        retries: int = 5,
        backoff: float = 0.5,
        poll: float = 0.5,
        transport: httpx.BaseTransport | None = None,
    ) -> None:
        self.http = Http(
            base_url,
            api_key=api_key,
            timeout=timeout,
            retries=retries,
            backoff=backoff,
            transport=transport,
        )
        self.poll = poll

    @property
    def base_url(self) -> str:
        """The API's base URL."""
        return self.http.base_url

    def __repr__(self) -> str:
        return f"Client({self.base_url!r})"

    def close(self) -> None:
        """Close the connection pool."""
        self.http.close()

    def __enter__(self) -> Client:
        return self

    def __exit__(self, *exc: type[BaseException] | BaseException | TracebackType | None) -> None:
        self.close()

    def request(self, method: str, path: str, **kw: Any) -> httpx.Response:
        """Any request (httpx keyword arguments), with the client's retries and errors."""
        return self.http.request(method, path, **kw)

    def _ask(self, path: str, fields: Mapping[str, Any]) -> dict[str, Any]:
        return self.http.answer(path, body(fields), poll=self.poll)

    # -- single queries ----------------------------------------------------------------
    def classify(
        self,
        *,
        ba: float | None = None,
        kappa: float | None = None,
        eps: float | None = None,
        vo: float | None = None,
        physical: Mapping[str, Any] | None = None,
        a: float | None = None,
        b: float | None = None,
        Dc_m: float | None = None,  # noqa: N803
        sigma_Pa: float | None = None,  # noqa: N803
        k_Pa_per_m: float | None = None,  # noqa: N803
        V_star_m_s: float | None = None,  # noqa: N803
        V_load_m_s: float | None = None,  # noqa: N803
        perturbation: Perturbation | None = None,
        size: float | None = None,
        log_size: float | None = None,
        factor: float | None = None,
        new_slip_rate_m_s: float | None = None,
        new_load_point_velocity_m_s: float | None = None,
        start: Point | None = None,
        rtol: float | None = None,
    ) -> ClassifyResult:
        """Certified outcome of one perturbation (POST /v1/classify): dimensionless
        (ba, kappa, eps, vo, size) or in SI (the machine, eps, and the size as ``factor``,
        ``new_slip_rate_m_s`` or ``new_load_point_velocity_m_s``); ``start``: an explicit
        (phi, psi) instead of a perturbation.  A long integration (202) is polled."""
        f = dict(locals())
        f["start"] = None if start is None else _point(start)
        return ClassifyResult.from_json(self._ask("/v1/classify", f))

    def trajectory(
        self,
        *,
        ba: float | None = None,
        kappa: float | None = None,
        eps: float | None = None,
        vo: float | None = None,
        physical: Mapping[str, Any] | None = None,
        a: float | None = None,
        b: float | None = None,
        Dc_m: float | None = None,  # noqa: N803
        sigma_Pa: float | None = None,  # noqa: N803
        k_Pa_per_m: float | None = None,  # noqa: N803
        V_star_m_s: float | None = None,  # noqa: N803
        V_load_m_s: float | None = None,  # noqa: N803
        perturbation: Perturbation | None = None,
        size: float | None = None,
        log_size: float | None = None,
        factor: float | None = None,
        new_slip_rate_m_s: float | None = None,
        new_load_point_velocity_m_s: float | None = None,
        start: Point | None = None,
        rtol: float | None = None,
        n_points: int | None = None,
        t_end: float | None = None,
        t_end_s: float | None = None,
        sampling: Literal["tau", "T", "seconds"] | None = None,
        f_star: float | None = None,
        scales: Mapping[str, float] | None = None,
    ) -> TrajectoryResult:
        """Outcome plus the trajectory at ``n_points`` samples (POST /v1/trajectory);
        arguments as :meth:`classify`, plus t_end (T) or t_end_s [s], sampling ('tau',
        'T', 'seconds'), f_star (SI friction column), scales (SI columns of a
        dimensionless query).  ``.to_pandas()`` / ``.to_xarray()`` give the samples."""
        f = dict(locals())
        f["start"] = None if start is None else _point(start)
        return TrajectoryResult.from_json(self._ask("/v1/trajectory", f))

    def critical(
        self,
        *,
        ba: float | None = None,
        kappa: float | None = None,
        eps: float | None = None,
        vo: float | None = None,
        physical: Mapping[str, Any] | None = None,
        a: float | None = None,
        b: float | None = None,
        Dc_m: float | None = None,  # noqa: N803
        sigma_Pa: float | None = None,  # noqa: N803
        k_Pa_per_m: float | None = None,  # noqa: N803
        V_star_m_s: float | None = None,  # noqa: N803
        V_load_m_s: float | None = None,  # noqa: N803
        perturbation: Perturbation | None = None,
        rtol: float | None = None,
    ) -> CriticalResult:
        """Critical perturbation size (POST /v1/critical): dimensionless or with the
        machine in SI (then also the critical slip rate / load-point velocity in m/s)."""
        return CriticalResult.from_json(self._ask("/v1/critical", dict(locals())))

    def boundaries(
        self,
        *,
        ba: float | None = None,
        kappa: float | None = None,
        eps: float | None = None,
        phi: Sequence[float] | None = None,
        physical: Mapping[str, Any] | None = None,
        a: float | None = None,
        b: float | None = None,
        Dc_m: float | None = None,  # noqa: N803
        sigma_Pa: float | None = None,  # noqa: N803
        k_Pa_per_m: float | None = None,  # noqa: N803
        V_star_m_s: float | None = None,  # noqa: N803
        V_load_m_s: float | None = None,  # noqa: N803
    ) -> BoundariesResult:
        """Stability boundaries (POST /v1/boundaries): kappa_crit, eps_crit, (a/b)_crit,
        the acceleration line at the ``phi`` values; dimensionless or the machine in SI."""
        f = dict(locals())
        f["phi"] = _floats(phi)
        return BoundariesResult.from_json(self._ask("/v1/boundaries", f))

    def analytic_u(
        self,
        *,
        function: Literal["kcrit", "vo0"] | None = None,
        ba: float | None = None,
        eps: float | None = None,
        vo: float | None = None,
        kappa: float | None = None,
        points: Sequence[Point] | None = None,
        grid: Mapping[str, float] | None = None,
    ) -> AnalyticUResult:
        """The analytic Lyapunov function U (POST /v1/analytic/u) at ``points``
        ((phi, psi) pairs) or on a ``grid`` {phi_min, phi_max, n_phi, psi_min, psi_max,
        n_psi}; ``.to_xarray()`` gives U on its (phi, psi) grid."""
        f = dict(locals())
        f["points"] = None if points is None else [_point(p) for p in points]
        return AnalyticUResult.from_json(self._ask("/v1/analytic/u", f))

    def stiffness(
        self,
        *,
        case: Literal["A", "B", "C", "D", "E"] | None = None,
        mode: int | None = None,
        physical: Mapping[str, Any] | None = None,
    ) -> StiffnessResult:
        """Eigen-stiffness k/k_* of continuum case A-E (POST /v1/stiffness) and, with
        ``physical`` {mu, nu, mode_of_slip, sigma_Pa, a, b, Dc_m, h} in SI, the critical
        dimension [m]."""
        return StiffnessResult.from_json(self._ask("/v1/stiffness", dict(locals())))

    def classify_points(
        self,
        *,
        phi: Sequence[float],
        psi: Sequence[float],
        ba: float | None = None,
        kappa: float | None = None,
        eps: float | None = None,
        vo: float | None = None,
        rtol: float | None = None,
    ) -> PointsResult:
        """Outcomes of many start points (phi[i], psi[i]) of one parameter set
        (POST /v1/classify/points)."""
        f = dict(locals())
        f["phi"], f["psi"] = _floats(phi), _floats(psi)
        return PointsResult.from_json(self._ask("/v1/classify/points", f))

    # -- batch ----------------------------------------------------------------------------
    def classify_batch(self, items: Sequence[Mapping[str, Any]]) -> BatchResult:
        """Many classify questions at once (POST /v1/classify/batch): each item holds the
        keyword arguments of :meth:`classify` (flat SI machine fields allowed); the
        answers keep the items' order, an invalid item is an :class:`ItemError`."""
        d = self.http.json("POST", "/v1/classify/batch", json={"items": [body(i) for i in items]})
        return BatchResult.of(d, ClassifyResult)

    def critical_batch(self, items: Sequence[Mapping[str, Any]]) -> BatchResult:
        """Many critical-size questions at once (POST /v1/critical/batch); items as the
        keyword arguments of :meth:`critical`."""
        d = self.http.json("POST", "/v1/critical/batch", json={"items": [body(i) for i in items]})
        return BatchResult.of(d, CriticalResult)

    # -- lab protocols (SI) ----------------------------------------------------------------
    def velocity_step(
        self,
        *,
        V1_m_s: float,  # noqa: N803
        V2_m_s: float,  # noqa: N803
        physical: Mapping[str, Any] | None = None,
        a: float | None = None,
        b: float | None = None,
        Dc_m: float | None = None,  # noqa: N803
        sigma_Pa: float | None = None,  # noqa: N803
        k_Pa_per_m: float | None = None,  # noqa: N803
        V_star_m_s: float | None = None,  # noqa: N803
        V_load_m_s: float | None = None,  # noqa: N803
        eps: float | None = None,
        f_star: float | None = None,
        rtol: float | None = None,
        slip_total_m: float | None = None,
        slip_after_m: float | None = None,
        n_points: int | None = None,
    ) -> ProtocolResult:
        """Load-point velocity step V1 -> V2 from steady state at V1
        (POST /v1/protocols/velocity-step)."""
        return ProtocolResult.from_json(self._ask("/v1/protocols/velocity-step", dict(locals())))

    def slide_hold_slide(
        self,
        *,
        V_m_s: float,  # noqa: N803
        hold_s: float,
        slide_before_s: float,
        slide_after_s: float,
        physical: Mapping[str, Any] | None = None,
        a: float | None = None,
        b: float | None = None,
        Dc_m: float | None = None,  # noqa: N803
        sigma_Pa: float | None = None,  # noqa: N803
        k_Pa_per_m: float | None = None,  # noqa: N803
        V_star_m_s: float | None = None,  # noqa: N803
        V_load_m_s: float | None = None,  # noqa: N803
        eps: float | None = None,
        f_star: float | None = None,
        rtol: float | None = None,
        n_points_per_segment: int | None = None,
    ) -> ProtocolResult:
        """Slide at V, hold, reslide (POST /v1/protocols/slide-hold-slide)."""
        return ProtocolResult.from_json(self._ask("/v1/protocols/slide-hold-slide", dict(locals())))

    def load_history(
        self,
        *,
        segments: Sequence[Mapping[str, float] | Sequence[float]],
        physical: Mapping[str, Any] | None = None,
        a: float | None = None,
        b: float | None = None,
        Dc_m: float | None = None,  # noqa: N803
        sigma_Pa: float | None = None,  # noqa: N803
        k_Pa_per_m: float | None = None,  # noqa: N803
        V_star_m_s: float | None = None,  # noqa: N803
        V_load_m_s: float | None = None,  # noqa: N803
        eps: float | None = None,
        f_star: float | None = None,
        rtol: float | None = None,
        n_points_per_segment: int | None = None,
        start_state: Literal["steady"] | Mapping[str, float] | None = None,
    ) -> ProtocolResult:
        """Any piecewise-constant load-point history (POST /v1/protocols/load-history):
        ``segments`` as {duration_s, V_load_m_s} objects or (duration_s, V_load_m_s)
        pairs; ``start_state`` 'steady' or {V_m_s, theta_s}."""
        f = dict(locals())
        f["segments"] = [
            dict(s)
            if isinstance(s, Mapping)
            else {"duration_s": float(s[0]), "V_load_m_s": float(s[1])}
            for s in segments
        ]
        return ProtocolResult.from_json(self._ask("/v1/protocols/load-history", f))

    # -- fits ------------------------------------------------------------------------------
    def submit_fit(
        self,
        record: Any,
        *,
        law: Literal["aging", "slip", "nagata", "eps"] | None = None,
        compare: bool | None = None,
        k_Pa_per_m: float | None = None,
        sigma_Pa: float | None = None,
        k_friction_per_m: float | None = None,
        stiffness_per_m: float | None = None,
        fit_stiffness: bool | None = None,
        rigid_machine: bool | None = None,
        trend: bool | None = None,
        windows: Sequence[tuple[float, float]] | None = None,
        steps: Sequence[int] | None = None,
        columns: Mapping[str, str] | None = None,
        decimal: Literal[".", ","] | None = None,
        smooth: int | None = None,
        time_budget_s: float | None = None,
        nagata_c: float | None = None,
        rtol: float | None = None,
        uncertainty_samples: int | None = None,
        seed: int | None = None,
        posterior: Mapping[str, int] | None = None,
    ) -> Fit:
        """Submit a lab record for fitting (POST /v1/fits) and return its :class:`Fit`
        handle at once (``.wait()``, ``.result()``).  ``record``: CSV/JSON text, a path,
        a mapping of columns (t_s, v_lp_m_s, mu) or a pandas.DataFrame."""
        f = dict(locals())
        f["record"] = record_text(record)
        r = self.http.request("POST", "/v1/fits", json=body(f, nest_machine=False))
        d = r.json()
        key = str(d["cache_key"])
        return Fit(self.http, key, d if r.status_code == 200 else None)

    def fit(
        self,
        record: Any,
        *,
        law: Literal["aging", "slip", "nagata", "eps"] | None = None,
        compare: bool | None = None,
        k_Pa_per_m: float | None = None,
        sigma_Pa: float | None = None,
        k_friction_per_m: float | None = None,
        stiffness_per_m: float | None = None,
        fit_stiffness: bool | None = None,
        rigid_machine: bool | None = None,
        trend: bool | None = None,
        windows: Sequence[tuple[float, float]] | None = None,
        steps: Sequence[int] | None = None,
        columns: Mapping[str, str] | None = None,
        decimal: Literal[".", ","] | None = None,
        smooth: int | None = None,
        time_budget_s: float | None = None,
        nagata_c: float | None = None,
        rtol: float | None = None,
        uncertainty_samples: int | None = None,
        seed: int | None = None,
        posterior: Mapping[str, int] | None = None,
        timeout: float | None = None,
    ) -> FitResult:
        """Submit a record (as :meth:`submit_fit`) and wait for its result."""
        f = dict(locals())
        del f["self"], f["timeout"]
        return self.submit_fit(**f).wait(timeout=timeout, poll=self.poll)

    def get_fit(self, key: str) -> Fit:
        """The handle of a fit submitted before (by its key)."""
        return Fit(self.http, key)

    # -- sweeps ----------------------------------------------------------------------------
    def sweep(
        self,
        spec: Mapping[str, Any] | None = None,
        *,
        axes: Sequence[Mapping[str, Any]] | None = None,
        points: Mapping[str, Sequence[float]] | None = None,
        x: Mapping[str, Any] | None = None,
        y: Mapping[str, Any] | None = None,
        fixed: Mapping[str, Any] | None = None,
        perturbation: Perturbation | None = None,
        rtol: float | None = None,
        chunk_points: int | None = None,
        ba: float | None = None,
        kappa_ratio: float | None = None,
        kappa: float | None = None,
        eps: float | None = None,
        vo: float | None = None,
        size: float | None = None,
        physical: Mapping[str, Any] | None = None,
        a: float | None = None,
        b: float | None = None,
        Dc_m: float | None = None,  # noqa: N803
        sigma_Pa: float | None = None,  # noqa: N803
        k_Pa_per_m: float | None = None,  # noqa: N803
        V_star_m_s: float | None = None,  # noqa: N803
        V_load_m_s: float | None = None,  # noqa: N803
        factor: float | None = None,
        new_slip_rate_m_s: float | None = None,
        new_load_point_velocity_m_s: float | None = None,
    ) -> Sweep:
        """Submit a sweep (POST /v1/sweeps) and return its :class:`Sweep` handle.

        Give a whole request body as ``spec``, or its parts: ``axes`` (1-5 grid axes,
        see :func:`axis`) or ``points`` (equal-length arrays; numpy arrays are accepted)
        or ``x``/``y``; ``perturbation``, ``rtol``, ``chunk_points``; the values not swept
        in ``fixed`` or by their names (ba, kappa_ratio, ..., the SI machine fields,
        factor, ...), which go into ``fixed`` (the machine into ``fixed.physical``).
        Submitting a finished sweep returns it at once; a cancelled one is resumed.
        """
        given = dict(locals())
        top = {
            "axes": None if axes is None else [dict(ax) for ax in axes],
            "points": None if points is None else {k: _floats(v) for k, v in points.items()},
            "x": x,
            "y": y,
            "perturbation": perturbation,
            "rtol": rtol,
            "chunk_points": chunk_points,
        }
        loose = body(
            {k: v for k, v in given.items() if k not in top and k not in ("spec", "fixed")}
        )
        req: dict[str, Any] = dict(spec or {})
        req.update({k: v for k, v in top.items() if v is not None})
        if fixed is not None or loose:
            merged = {**dict(req.get("fixed") or {}), **dict(fixed or {})}
            clash = sorted(set(merged) & set(loose))
            if clash:
                raise ValueError(f"{clash[0]} given both in fixed and as an argument")
            req["fixed"] = {**merged, **loose}
        st = SweepStatus.from_json(self.http.json("POST", "/v1/sweeps", json=req))
        return Sweep(self.http, st.id, st)

    def get_sweep(self, sweep_id: str) -> Sweep:
        """The handle of an existing sweep (its status is fetched)."""
        return Sweep(self.http, sweep_id)

    def sweeps(self, limit: int = 100, offset: int = 0) -> list[SweepStatus]:
        """Sweeps, newest first (GET /v1/sweeps)."""
        d = self.http.json("GET", "/v1/sweeps", params={"limit": limit, "offset": offset})
        return [SweepStatus.from_json(s) for s in d["sweeps"]]

    # -- figures, images, service -------------------------------------------------------
    def figures(self) -> list[FigureInfo]:
        """The reproducible figures of the paper (GET /v1/figures)."""
        d = self.http.json("GET", "/v1/figures")
        return [
            FigureInfo(f["name"], f["caption"], f["label"], f.get("note", ""), f["url"])
            for f in d["figures"]
        ]

    def figure(
        self,
        name: str,
        format: Literal["png", "svg"] | None = None,  # noqa: A002
        quality: Literal["paper", "draft"] | None = None,
    ) -> bytes:
        """One figure regenerated from rsfcore (GET /v1/figures/{name}): PNG or SVG bytes.
        ``format`` and ``quality`` left out take the server's defaults (png, paper)."""
        if format is not None and format not in ("png", "svg"):
            raise ValueError(f"format: 'png' or 'svg', not {format!r} (data: figure_data)")
        return self.http.request(
            "GET", f"/v1/figures/{name}", params=body({"format": format, "quality": quality})
        ).content

    def figure_data(
        self, name: str, quality: Literal["paper", "draft"] | None = None
    ) -> FigureData:
        """The numbers figure ``name`` plots (GET /v1/figures/{name}?format=json): the same
        JSON as ``rsf figure NAME --json`` and the library's figure adapter.  ``quality``
        left out takes the server's default (paper)."""
        params = body({"format": "json", "quality": quality})
        return FigureData.from_json(self.http.json("GET", f"/v1/figures/{name}", params=params))

    def render(self, question: str, format: str = "png", **fields: Any) -> bytes:  # noqa: A002
        """The image (``png``) or table (``csv``) form of a question in
        :data:`RENDERABLE` (trajectory, analytic_u, velocity_step, slide_hold_slide,
        load_history), with the same keyword arguments as its method."""
        if question not in RENDERABLE:
            raise ValueError(f"question: one of {', '.join(RENDERABLE)}, not {question!r}")
        path, formats = RENDERABLE[question]
        if format not in formats:
            raise ValueError(f"format: one of {', '.join(formats)} for {question}")
        if "start" in fields and fields["start"] is not None:
            fields["start"] = _point(fields["start"])
        r = self.http.request("POST", path, params={"format": format}, json=body(fields))
        return r.content

    def result(self, key: str) -> dict[str, Any]:
        """A deferred answer by its key (GET /v1/results/{key}); 202 means still running."""
        return self.http.json("GET", f"/v1/results/{key}")

    def health(self) -> dict[str, Any]:
        """The deployment's health (GET /health): database, broker, workers."""
        return self.http.json("GET", "/health")

    def metrics(self) -> str:
        """The API process's Prometheus metrics (GET /metrics, text exposition format)."""
        return self.http.request("GET", "/metrics").text

    def cache_stats(self) -> dict[str, Any]:
        """Result-cache statistics (GET /v1/cache/stats)."""
        return self.http.json("GET", "/v1/cache/stats")
