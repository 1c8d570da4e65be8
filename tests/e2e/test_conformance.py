"""One question, one answer, through every door.

:data:`TABLE` is one table of questions (dimensionless and SI, both perturbation kinds,
every protocol, batches, a fit, sweeps, with and without the optional fields), each
written once as the HTTP JSON body.  Every row is answered through each door:

* ``library``: the request model (``rsfapp.requests``) and its adapter (``rsfapp.adapter``),
  in this process, as the service computes it (for a sweep: each point asked as a single
  critical question);
* ``cli``: ``rsf ... --json`` in a subprocess, its options spelled as the JSON fields
  (``Dc_m`` -> ``--dc-m``);
* ``http``: httpx against a real uvicorn server with a real Celery worker;
* ``client``: :class:`rsfclient.Client`, its keyword arguments the JSON fields.

A figure of the paper is a question too (its body the query of ``GET /v1/figures/{name}``):
the numbers it plots are compared like every answer, and its PNG and SVG images, drawn by
rsfplots from those numbers, byte for byte (:func:`test_figure_images_agree`); the list of
figures is compared in :func:`test_figure_list_agrees`.

The answers must agree bit for bit in every number and in every echoed parameter (only
``cached`` / ``cache_key``, wall-clock times and the ids of stored work are left out; see
:data:`VOLATILE`).  A failure lists every cell (row x door x JSON path) that disagrees with
the library.

The table must stay complete: a route, a request field, a CLI command or a client method
that no row asks (and that is not listed, with its reason, in :data:`NOT_QUESTIONS`) fails
the coverage tests below, so a new field or door cannot be added without its row.
"""

from __future__ import annotations

import json
import math
import subprocess
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import httpx
import pytest

from tests.conftest import ROOT, Redis, Server, Worker, service_env

pytestmark = pytest.mark.timeout(1800)

DOORS = ("library", "cli", "http", "client")
#: The lab machine of issue 20: a = 0.010, b = 0.014, Dc = 20 um, sigma = 10 MPa,
#: k = 2 k_crit (k_crit = (b - a) sigma/Dc = 2e9 Pa/m), V_* = 1 um/s.
M = {
    "a": 0.010,
    "b": 0.014,
    "Dc_m": 20e-6,
    "sigma_Pa": 10e6,
    "k_Pa_per_m": 4e9,
    "V_star_m_s": 1e-6,
}
ML = {**M, "V_load_m_s": 3e-6}
#: A continuum fault (stiffness question; its own SI set).
FAULT = {"mu": 3e10, "nu": 0.25, "mode_of_slip": "II", "sigma_Pa": 1e8, "a": 0.01, "b": 0.015}


def _fit_record() -> str:
    """A noise-free velocity-step record (aging law, a = 0.01, b = 0.015, Dc = 10 um,
    k = 2000 /m: 4x critical), 121 samples, as CSV."""
    import numpy as np

    from rsfcore.fit import synthetic_record

    t = np.linspace(0.0, 60.0, 121)
    v = np.where(t < 20, 1e-6, np.where(t < 40, 1e-5, 1e-6))
    rec = synthetic_record(t, v, mu0=0.6, a=0.01, b=0.015, Dc_m=1e-5, eps=1.0, k_per_m=2000.0)
    return str(rec.to_csv())


@dataclass(frozen=True)
class Row:
    """One question of the table: ``question`` names the kind, ``body`` is its HTTP JSON."""

    name: str
    question: str
    body: dict[str, Any]


RECORD = "@record"  # replaced by _fit_record() when the table is used

TABLE: list[Row] = [
    # -- classify: defaults, both kinds, SI sizes in each spelling, start, log_size
    Row("classify-defaults", "classify", {}),
    Row("classify-vj", "classify", {"ba": 2.0, "kappa": 2.0, "eps": 0.25, "size": 2.7}),
    Row(
        "classify-lpj-all",
        "classify",
        {
            "ba": 2.0,
            "kappa": 2.0,
            "eps": 0.25,
            "vo": 1.0,
            "perturbation": "load-point-jump",
            "size": 10.0,
            "rtol": 1e-9,
        },
    ),
    Row("classify-si-factor", "classify", {"physical": M, "factor": 3.0}),
    Row(
        "classify-si-new-slip-rate",
        "classify",
        {"physical": ML, "eps": 0.25, "new_slip_rate_m_s": 2e-5},
    ),
    Row(
        "classify-si-lpj",
        "classify",
        {
            "physical": M,
            "eps": 1.0,
            "perturbation": "load-point-jump",
            "new_load_point_velocity_m_s": 5e-6,
        },
    ),
    Row(
        "classify-start",
        "classify",
        {"ba": 2.0, "kappa": 2.0, "eps": 0.25, "start": {"phi": 1.0, "psi": 2.0}},
    ),
    Row("classify-log-size", "classify", {"ba": 2.0, "kappa": 2.0, "eps": 0.25, "log_size": 2.0}),
    # -- trajectory
    Row("trajectory-defaults", "trajectory", {"n_points": 20}),
    Row(
        "trajectory-T",
        "trajectory",
        {
            "ba": 2.0,
            "kappa": 2.0,
            "eps": 0.25,
            "size": 2.7,
            "n_points": 20,
            "sampling": "T",
            "t_end": 0.1,
        },
    ),
    Row(
        "trajectory-si-seconds",
        "trajectory",
        {
            "physical": M,
            "eps": 0.25,
            "factor": 3.0,
            "n_points": 20,
            "sampling": "seconds",
            "t_end_s": 1.0,
            "f_star": 0.55,
        },
    ),
    Row(
        "trajectory-scales",
        "trajectory",
        {
            "ba": 2.0,
            "kappa": 2.0,
            "eps": 0.25,
            "size": 1.0,
            "n_points": 10,
            "scales": {"a": 0.01, "Dc": 2e-5, "sigma": 1e7, "V_star": 1e-6, "f_star": 0.6},
        },
    ),
    Row(
        "trajectory-lpj-all",
        "trajectory",
        {
            "ba": 2.0,
            "kappa": 2.0,
            "eps": 0.25,
            "vo": 0.5,
            "perturbation": "load-point-jump",
            "size": 4.0,
            "rtol": 1e-9,
            "n_points": 15,
        },
    ),
    Row(
        "trajectory-start",
        "trajectory",
        {"ba": 2.0, "kappa": 2.0, "eps": 0.25, "start": {"phi": 1.0, "psi": 2.0}, "n_points": 10},
    ),
    Row(
        "trajectory-log-size",
        "trajectory",
        {"ba": 2.0, "kappa": 2.0, "eps": 0.25, "log_size": 1.0, "n_points": 10},
    ),
    Row(
        "trajectory-si-new-slip-rate",
        "trajectory",
        {"physical": ML, "new_slip_rate_m_s": 2e-5, "n_points": 10},
    ),
    Row(
        "trajectory-si-lpj",
        "trajectory",
        {
            "physical": M,
            "perturbation": "load-point-jump",
            "new_load_point_velocity_m_s": 5e-6,
            "n_points": 10,
        },
    ),
    # -- critical
    Row("critical-defaults", "critical", {}),
    Row(
        "critical-lpj",
        "critical",
        {
            "ba": 2.0,
            "kappa": 2.0,
            "eps": 0.25,
            "vo": 1.0,
            "perturbation": "load-point-jump",
            "rtol": 1e-9,
        },
    ),
    Row("critical-si", "critical", {"physical": M}),
    Row(
        "critical-si-lpj",
        "critical",
        {"physical": ML, "eps": 0.5, "perturbation": "load-point-jump"},
    ),
    # -- boundaries, analytic U, stiffness, many start points
    Row("boundaries", "boundaries", {"ba": 2.0, "kappa": 2.0, "eps": 0.25, "phi": [0.0, 1.0]}),
    Row("boundaries-si", "boundaries", {"physical": M, "eps": 0.25}),
    Row(
        "analytic-u-grid",
        "analytic_u",
        {
            "function": "kcrit",
            "ba": 2.0,
            "eps": 0.25,
            "vo": 1.0,
            "grid": {
                "phi_min": -1.0,
                "phi_max": 1.0,
                "n_phi": 3,
                "psi_min": 0.0,
                "psi_max": 2.0,
                "n_psi": 2,
            },
        },
    ),
    Row(
        "analytic-u-points",
        "analytic_u",
        {
            "function": "vo0",
            "ba": 2.0,
            "kappa": 0.5,
            "eps": 0.3,
            "points": [{"phi": 0.0, "psi": 1.0}, {"phi": 1.0, "psi": 0.5}],
        },
    ),
    Row("stiffness-A", "stiffness", {"case": "A"}),
    Row(
        "stiffness-D",
        "stiffness",
        {"case": "D", "mode": 1, "physical": {**FAULT, "Dc_m": 1e-5, "h": 1000.0}},
    ),
    Row(
        "classify-points",
        "classify_points",
        {
            "ba": 2.0,
            "kappa": 2.0,
            "eps": 0.25,
            "vo": 1.0,
            "phi": [0.0, 3.0],
            "psi": [0.0, 3.0],
            "rtol": 1e-10,
        },
    ),
    # -- batches (an invalid item among them)
    Row(
        "critical-batch",
        "critical_batch",
        {"items": [{"ba": 2.0, "kappa": 2.0}, {"physical": M}, {"ba": 0.5}]},
    ),
    Row(
        "classify-batch",
        "classify_batch",
        {"items": [{"ba": 2.0, "kappa": 2.0, "size": 3.0}, {"physical": M, "factor": 3.0}]},
    ),
    # -- lab protocols
    Row("velocity-step", "velocity_step", {"physical": M, "V1_m_s": 1e-6, "V2_m_s": 1e-5}),
    Row(
        "velocity-step-all",
        "velocity_step",
        {
            "physical": M,
            "V1_m_s": 1e-6,
            "V2_m_s": 1e-5,
            "eps": 0.5,
            "f_star": 0.58,
            "rtol": 1e-9,
            "slip_total_m": 1e-4,
            "slip_after_m": 5e-5,
            "n_points": 50,
        },
    ),
    Row(
        "slide-hold-slide",
        "slide_hold_slide",
        {
            "physical": M,
            "V_m_s": 1e-6,
            "hold_s": 10.0,
            "slide_before_s": 10.0,
            "slide_after_s": 10.0,
            "n_points_per_segment": 20,
        },
    ),
    Row(
        "slide-hold-slide-all",
        "slide_hold_slide",
        {
            "physical": M,
            "V_m_s": 1e-6,
            "hold_s": 100.0,
            "slide_before_s": 20.0,
            "slide_after_s": 20.0,
            "eps": 0.5,
            "f_star": 0.58,
            "rtol": 1e-9,
        },
    ),
    Row(
        "load-history",
        "load_history",
        {
            "physical": M,
            "eps": 0.0,
            "segments": [
                {"duration_s": 10.0, "V_load_m_s": 1e-6},
                {"duration_s": 10.0, "V_load_m_s": 0.0},
                {"duration_s": 10.0, "V_load_m_s": 3e-6},
            ],
            "n_points_per_segment": 20,
            "start_state": {"V_m_s": 2e-6, "theta_s": 10.0},
            "f_star": 0.7,
            "rtol": 1e-9,
        },
    ),
    # -- a fit (queued, computed by the worker)
    Row(
        "fit",
        "fit",
        {
            "record": RECORD,
            "law": "aging",
            "compare": False,
            "k_Pa_per_m": 2e10,
            "sigma_Pa": 1e7,
            "fit_stiffness": False,
            "nagata_c": 2.0,
            "rtol": 1e-10,
            "uncertainty_samples": 20,
            "seed": 1,
            "trend": False,
            "decimal": ".",
            "time_budget_s": 120.0,
        },
    ),
    Row(
        "fit-friction-per-m",
        "fit",
        {
            "record": RECORD,
            "law": "aging",
            "compare": False,
            "k_friction_per_m": 2000.0,
            "windows": [[0.0, 60.0]],
            "steps": [0, 1, 2],
            "columns": {"t": "t_s", "v_lp": "v_lp_m_s", "mu": "mu"},
            "uncertainty_samples": 20,
        },
    ),
    Row(
        "fit-rigid",
        "fit",
        {
            "record": RECORD,
            "law": "aging",
            "compare": False,
            "rigid_machine": True,
            "uncertainty_samples": 0,
        },
    ),
    # -- small sweeps (dimensionless grid, SI grid of sizes, scattered points)
    Row(
        "sweep-grid",
        "sweep",
        {
            "axes": [
                {"name": "kappa_ratio", "start": 1.5, "stop": 3.0, "n": 2},
                {"name": "eps", "values": [0.1, 0.6]},
            ],
            "fixed": {"ba": 2.0},
        },
    ),
    Row(
        "sweep-si",
        "sweep",
        {
            "axes": [{"name": "eps", "values": [0.25, 0.75]}],
            "fixed": {"physical": M, "new_load_point_velocity_m_s": 5e-6},
            "perturbation": "load-point-jump",
            "rtol": 1e-9,
        },
    ),
    # no kappa or kappa_ratio: the sweep's default kappa/kappa_crit (2, rsfcore.limits) is the
    # single query's default kappa = 2 at the default b/a = 2 (the sweep used 1 until 0.2)
    Row("sweep-defaults", "sweep", {"axes": [{"name": "eps", "values": [0.1, 0.6]}]}),
    Row(
        "sweep-size",
        "sweep",
        {
            "axes": [{"name": "eps", "values": [0.1, 0.6]}],
            "fixed": {"ba": 2.0, "kappa": 2.0, "vo": 1.0, "size": 2.7},
        },
    ),
    Row(
        "sweep-si-factor",
        "sweep",
        {"axes": [{"name": "factor", "values": [2.0, 50.0]}], "fixed": {"physical": M}},
    ),
    Row(
        "sweep-si-new-slip-rate",
        "sweep",
        {
            "axes": [{"name": "eps", "values": [0.25, 0.75]}],
            "fixed": {"physical": ML, "new_slip_rate_m_s": 2e-5},
        },
    ),
    # -- figures of the paper: the default quality (paper) and a draft of a figure that
    #    asks critical sizes, classify, trajectories, a diagram and contours of U
    Row("figure-defaults", "figure", {"name": "velocity-step"}),
    Row("figure-draft", "figure", {"name": "stability-diagram-velocity", "quality": "draft"}),
]

#: Fields a row may not exercise, with the reason (everything else must appear in a row).
UNASKED_FIELDS: dict[tuple[str, str], str] = {
    ("fit", "posterior"): "MCMC (emcee) takes minutes; tests/api/test_fits_api.py covers it",
    ("fit", "stiffness_per_m"): "deprecated name of k_friction_per_m",
    ("fit", "smooth"): "acts only on a record given by its load-point displacement x_lp_m",
    ("sweep", "points"): "scattered sweeps: tests/api/test_sweeps_api.py; grid rows here",
    ("sweep", "x"): "the legacy 2-D form of axes",
    ("sweep", "y"): "the legacy 2-D form of axes",
    ("sweep", "chunk_points"): "changes the chunking only, never an answer",
}
#: Answer fields that legitimately differ between two askings of the same question.
VOLATILE = {
    "cached",
    "cache_key",
    "elapsed_s",  # a fit's wall-clock time
    "created_at",
    "started_at",
    "finished_at",
    "eta_s",
    "created",
    "resumed",
}


@dataclass(frozen=True)
class Question:
    """How each door asks one kind of question."""

    path: str  # HTTP route (POST, or GET with the body as path and query parameters)
    model: str  # request model in rsfapp.requests (dotted under it)
    adapter: str  # function of rsfapp.adapter
    client: str  # rsfclient.Client method
    cli: tuple[str, ...]  # `rsf` command words
    si_cli: tuple[str, ...] | None = None  # the command when the body is in SI, if other
    library_kw: dict[str, Any] = field(default_factory=dict)
    method: str = "POST"


QUESTIONS: dict[str, Question] = {
    "classify": Question(
        "/v1/classify", "ClassifyRequest", "classify", "classify", ("classify",), ("si", "classify")
    ),
    "trajectory": Question(
        "/v1/trajectory",
        "TrajectoryRequest",
        "trajectory",
        "trajectory",
        ("trajectory",),
        ("si", "trajectory"),
    ),
    "critical": Question(
        "/v1/critical", "CriticalRequest", "critical", "critical", ("critical",), ("si", "critical")
    ),
    "boundaries": Question(
        "/v1/boundaries", "BoundariesSIRequest", "boundaries", "boundaries", ("boundaries",)
    ),
    "analytic_u": Question(
        "/v1/analytic/u", "AnalyticRequest", "analytic_u", "analytic_u", ("analytic-u",)
    ),
    "stiffness": Question(
        "/v1/stiffness", "StiffnessRequest", "stiffness", "stiffness", ("stiffness",)
    ),
    "classify_points": Question(
        "/v1/classify/points",
        "ClassifyPointsRequest",
        "classify_points",
        "classify_points",
        ("classify-points",),
    ),
    "critical_batch": Question(
        "/v1/critical/batch",
        "batch.CriticalBatchRequest",
        "critical_batch",
        "critical_batch",
        ("critical-batch",),
    ),
    "classify_batch": Question(
        "/v1/classify/batch",
        "batch.ClassifyBatchRequest",
        "classify_batch",
        "classify_batch",
        ("classify-batch",),
    ),
    "velocity_step": Question(
        "/v1/protocols/velocity-step",
        "protocols.VelocityStepRequest",
        "protocol_velocity_step",
        "velocity_step",
        ("protocol", "velocity-step"),
    ),
    "slide_hold_slide": Question(
        "/v1/protocols/slide-hold-slide",
        "protocols.SlideHoldSlideRequest",
        "protocol_slide_hold_slide",
        "slide_hold_slide",
        ("protocol", "slide-hold-slide"),
    ),
    "load_history": Question(
        "/v1/protocols/load-history",
        "protocols.LoadHistoryRequest",
        "protocol_load_history",
        "load_history",
        ("protocol", "load-history"),
    ),
    "fit": Question("/v1/fits", "fits.FitRequest", "fit", "fit", ("fit",)),
    "sweep": Question("/v1/sweeps", "SweepRequest", "critical", "sweep", ("sweep", "submit")),
    "figure": Question(
        "/v1/figures/{name}",
        "figures.FigureRequest",
        "figure",
        "figure_data",
        ("figure",),
        method="GET",
    ),
}

#: Doors that are not questions (or ask the same question another way), with the reason.
NOT_QUESTIONS: dict[str, str] = {
    # routes
    "GET /v1/boundaries": "the query form of POST /v1/boundaries (asked in test_get_forms)",
    "GET /v1/fits/{key}": "the fit's result (part of the fit row)",
    "GET /v1/sweeps": "lists sweeps",
    "GET /v1/sweeps/{sweep_id}": "sweep status (part of the sweep rows)",
    "GET /v1/sweeps/{sweep_id}/spec": "the stored spec",
    "GET /v1/sweeps/{sweep_id}/points": "the sweep's data, paged (compared in the sweep rows)",
    "GET /v1/sweeps/{sweep_id}/data": "the sweep's data (compared in the sweep rows)",
    "GET /v1/sweeps/{sweep_id}/diagram": "a 2-D slice of the sweep's data",
    "GET /v1/sweeps/{sweep_id}/zarr/{key}": "the sweep as a Zarr store (lazy xarray): "
    "tests/api/test_sweep_subsets.py, tests/e2e/test_sweep_lazy.py",
    "GET /v1/sweeps/{sweep_id}/zarr/{var}/{key}": "the sweep's Zarr arrays and chunks: "
    "tests/api/test_sweep_subsets.py, tests/e2e/test_sweep_lazy.py",
    "DELETE /v1/sweeps/{sweep_id}": "cancel or delete",
    "GET /v1/figures": "the list of the paper's figures (test_figure_list_agrees)",
    "GET /v1/results/{key}": "a deferred answer (the same JSON as its question)",
    "GET /health": "service health",
    "GET /v1/cache/stats": "cache statistics",
    "GET /metrics": "Prometheus metrics",
    # CLI commands
    "rsf serve": "starts the service",
    "rsf api": "starts the API",
    "rsf worker": "starts a worker",
    "rsf keys": "API keys",
    "rsf db": "database schema migrations",
    "rsf diagram": "a local stability diagram (rsfcore.diagram), the sweep's library form",
    "rsf sweep status": "part of the sweep rows",
    "rsf sweep download": "part of the sweep rows",
    "rsf sweep cancel": "cancel or delete",
    # client methods
    "Client.close": "connection pool",
    "Client.request": "any request",
    "Client.submit_fit": "the fit row's first half (Client.fit = submit_fit + wait)",
    "Client.get_fit": "the handle of a fit",
    "Client.get_sweep": "the handle of a sweep",
    "Client.sweeps": "lists sweeps",
    "Client.figures": "the list of the paper's figures (test_figure_list_agrees)",
    "Client.figure": "the image of a figure row (test_figure_images_agree)",
    "Client.render": "the image or CSV form of a question",
    "Client.result": "a deferred answer",
    "Client.health": "service health",
    "Client.cache_stats": "cache statistics",
    "Client.metrics": "Prometheus metrics",
}


def table() -> list[Row]:
    """The table with the fit's record filled in."""
    rec = _fit_record()
    return [
        Row(r.name, r.question, {k: rec if v == RECORD else v for k, v in r.body.items()})
        for r in TABLE
    ]


# ------------------------------------------------------------------- coverage (no server)
def _model(q: Question) -> Any:
    import importlib

    mod, _, name = ("." + q.model).rpartition(".")
    return getattr(importlib.import_module("rsfapp.requests" + mod), name)


def test_every_route_is_a_row_or_named() -> None:
    from service.app import create_app

    ops = {
        f"{m.upper()} {p}"
        for p, item in create_app().openapi()["paths"].items()
        for m in item
        if m in ("get", "post", "delete", "put", "patch")
    }
    asked = {f"{q.method} {q.path}" for q in QUESTIONS.values()}
    used = {r.question for r in TABLE}
    assert used == set(QUESTIONS), f"questions without a row: {sorted(set(QUESTIONS) - used)}"
    missing = ops - asked - set(NOT_QUESTIONS)
    routes_named = {k for k in NOT_QUESTIONS if k.split(" ")[0] in ("GET", "POST", "DELETE")}
    stale = (asked | routes_named) - ops
    assert not missing, f"routes in no row of the table: {sorted(missing)}"
    assert not stale, f"table entries without a route: {sorted(stale)}"


def test_every_field_is_asked() -> None:
    """Every field of every question's request model is given in at least one row (the
    sweep's ``fixed`` fields too), unless UNASKED_FIELDS says why not."""
    from rsfapp.requests import SweepFixed

    missing = []
    for name, q in QUESTIONS.items():
        model = _model(q)
        fields = {f.alias or n for n, f in model.model_fields.items()}
        used: set[str] = set()
        for r in TABLE:
            if r.question == name:
                used |= set(r.body)
                if name == "sweep":
                    used |= set(r.body.get("fixed", {}))
                    used |= {a["name"] for a in r.body.get("axes", [])}
        if name == "sweep":
            fields |= {f.alias or n for n, f in SweepFixed.model_fields.items()}
        for f in sorted(fields - used):
            if (name, f) not in UNASKED_FIELDS:
                missing.append(f"{name}.{f}")
    # the SI machine: every field of physical in some row
    from rsfapp.requests import PhysicalSI

    machine_used = {k for r in TABLE for k in r.body.get("physical", {})}
    missing += [f"physical.{f}" for f in PhysicalSI.model_fields if f not in machine_used]
    assert not missing, f"fields in no row of the table: {missing}"


def _cli_commands() -> set[str]:
    import typer.main

    from rsfcli.main import app

    out: set[str] = set()

    def walk(cmd: Any, prefix: str) -> None:  # the click tree (rsf builds its commands lazily)
        sub = getattr(cmd, "commands", None)
        if sub is None:
            out.add(prefix)
            return
        for name in cmd.list_commands(None):
            walk(sub[name], f"{prefix} {name}")

    walk(typer.main.get_command(app), "rsf")
    return out


def test_every_cli_command_and_client_method_is_a_door_or_named() -> None:
    import rsfclient

    cli = _cli_commands()
    asked = {"rsf " + " ".join(q.cli) for q in QUESTIONS.values()}
    asked |= {"rsf " + " ".join(q.si_cli) for q in QUESTIONS.values() if q.si_cli}
    named = {k for k in NOT_QUESTIONS if k.startswith("rsf ")}
    # `rsf keys ...` is one group
    cli_left = {c for c in cli if not any(c == n or c.startswith(n + " ") for n in named)}
    assert cli_left <= asked, f"CLI commands in no row: {sorted(cli_left - asked)}"
    methods = {
        f"Client.{m}"
        for m, v in vars(rsfclient.Client).items()
        if callable(v) and not m.startswith("_")
    }
    client_asked = {f"Client.{q.client}" for q in QUESTIONS.values()}
    left = methods - client_asked - set(NOT_QUESTIONS)
    assert not left, f"client methods in no row: {sorted(left)}"


# ------------------------------------------------------------------------- the doors
def _strip(x: Any) -> Any:
    """JSON normalised: volatile fields out, tuples as lists."""
    if isinstance(x, dict):
        return {k: _strip(v) for k, v in x.items() if k not in VOLATILE}
    if isinstance(x, list | tuple):
        return [_strip(v) for v in x]
    return x


def _jsonable(x: Any) -> Any:
    return json.loads(json.dumps(x, allow_nan=False))


def library(row: Row) -> Any:
    """The library: the request model validated, its adapter called (as the service does)."""
    from rsfapp import adapter

    q = QUESTIONS[row.question]
    if row.question in ("critical_batch", "classify_batch"):
        return _jsonable(getattr(adapter, q.adapter)(row.body["items"]))
    if row.question == "sweep":
        return _library_sweep(row)
    req = _model(q).model_validate(row.body)
    return _jsonable(getattr(adapter, q.adapter)(req))


SI_SIZES = ("factor", "new_slip_rate_m_s", "new_load_point_velocity_m_s")


def _library_sweep(row: Row) -> Any:
    """A sweep point by point: each grid point asked as a single critical question; a
    point with a size is unstable iff the size exceeds the critical size (the sweep's rule,
    README "Sweeps"), the SI size converted by rsfcore.units."""
    import itertools

    import numpy as np

    from rsfapp import adapter
    from rsfapp.requests import CriticalRequest
    from rsfcore import units

    axes = row.body["axes"]
    values = [
        a["values"] if "values" in a else np.linspace(a["start"], a["stop"], a["n"]).tolist()
        for a in axes
    ]
    fixed = dict(row.body.get("fixed", {}))
    pert = row.body.get("perturbation", "velocity-jump")
    out: dict[str, list[Any]] = {"critical_size": [], "kind": [], "outcome": [], "si": []}
    for combo in itertools.product(*values):
        p = {**fixed, **{a["name"]: v for a, v in zip(axes, combo, strict=True)}}
        if "kappa_ratio" in p:
            p["kappa"] = p.pop("kappa_ratio") * (p.get("ba", 2.0) - 1.0)
        size = p.pop("size", None)
        si_size = {k: p.pop(k) for k in SI_SIZES if k in p}
        if si_size:
            phys = units.PhysicalInputs.from_dict(p["physical"])
            conv = (
                units.velocity_jump_size if pert == "velocity-jump" else units.load_point_jump_size
            )
            size = float(conv(phys, **si_size))
        body = {**p, **{k: row.body[k] for k in ("perturbation", "rtol") if k in row.body}}
        r = adapter.critical(CriticalRequest.model_validate(body))
        kind, crit = r["kind"], r["critical_size"]
        out["critical_size"].append(crit if kind != "infinite" else None)
        out["kind"].append(kind)
        unstable = kind == "zero" or (kind == "finite" and size is not None and size > crit)
        out["outcome"].append(None if size is None else ("unstable" if unstable else "stable"))
        si = r.get("si") or {}
        jump = si.get("load_point_jump") or si.get("velocity_jump")
        out["si"].append(
            None
            if jump is None or kind == "infinite"
            else jump.get("new_load_point_velocity_m_s", jump.get("new_slip_rate_m_s"))
        )
    return out


def _sweep_view(data: dict[str, Any]) -> dict[str, list[Any]]:
    """The sweep's JSON data in the form of :func:`_library_sweep`."""
    d = data["data"]
    kinds, outcomes = data["kind_legend"], data["outcome_legend"]
    si_name = next((k for k in d if k.startswith("critical_") and k.endswith("_m_s")), None)
    return {
        "critical_size": d["critical_size"],
        "kind": [kinds[k] if k >= 0 else None for k in d["kind"]],
        "outcome": [outcomes[k] if k >= 0 else None for k in d["outcome"]],
        "si": d[si_name] if si_name else [None] * len(d["kind"]),
    }


class Doors:
    """The HTTP, client and CLI doors of one running service."""

    def __init__(self, url: str, env: dict[str, str], tmp: Path) -> None:
        from rsfclient import Client

        self.url, self.env, self.tmp = url, env, tmp
        self.h = httpx.Client(base_url=url, timeout=300)
        self.c = Client(url, timeout=300, poll=0.1)

    def close(self) -> None:
        self.h.close()
        self.c.close()

    # -- http
    def http(self, row: Row) -> Any:
        q = QUESTIONS[row.question]
        if q.method == "GET":
            return self._get(q, row.body, "json").json()
        r = self.h.post(q.path, json=row.body)
        if row.question == "sweep":
            sid = r.json()["id"]
            self._wait(f"/v1/sweeps/{sid}", lambda d: d["status"] == "done")
            return _sweep_view(
                self.h.get(f"/v1/sweeps/{sid}/data", params={"format": "json"}).json()
            )
        loc = r.headers.get("location")
        while r.status_code == 202 and loc:
            time.sleep(0.1)
            r = self.h.get(loc)
        assert r.status_code == 200, f"{row.name}: HTTP {r.status_code} {r.text[:500]}"
        return r.json()

    def _get(self, q: Question, body: dict[str, Any], fmt: str) -> httpx.Response:
        """A GET question: the body's path fields in the path, the rest as the query."""
        names = {k for k in body if "{" + k + "}" in q.path}
        path = q.path.format(**{k: body[k] for k in names})
        query = {**{k: v for k, v in body.items() if k not in names}, "format": fmt}
        r = self.h.get(path, params=query)
        assert r.status_code == 200, f"{path}: HTTP {r.status_code} {r.text[:500]}"
        return r

    def _wait(self, path: str, done: Callable[[dict[str, Any]], bool]) -> None:
        t0 = time.monotonic()
        while not done(d := self.h.get(path).json()):
            assert time.monotonic() - t0 < 300, f"{path}: not done: {d}"
            time.sleep(0.1)

    # -- client
    def client(self, row: Row) -> Any:
        q = QUESTIONS[row.question]
        fn = getattr(self.c, q.client)
        if row.question in ("critical_batch", "classify_batch"):
            return fn(row.body["items"]).raw
        if row.question == "sweep":
            s = fn(row.body)
            s.wait(poll=0.1, timeout=300)
            return _sweep_view(json.loads(s.data("json")))
        return fn(**row.body).raw

    # -- cli
    def cli(self, row: Row) -> Any:
        argv = self.cli_argv(row)
        r = subprocess.run(
            [sys.executable, "-m", "rsfcli.main", *argv],
            env=self.env,
            cwd=ROOT,
            capture_output=True,
            text=True,
            timeout=600,
        )
        if r.returncode != 0:
            raise DoorError(f"exit {r.returncode}: {r.stderr.strip()[-400:]}")
        if row.question == "sweep":
            sid = r.stdout.strip().splitlines()[-1]
            out = self.tmp / f"{row.name}.json"
            d = subprocess.run(
                [sys.executable, "-m", "rsfcli.main", "sweep", "download", sid, "-o", str(out)],
                env=self.env,
                cwd=ROOT,
                capture_output=True,
                text=True,
                timeout=300,
            )
            if d.returncode != 0:
                raise DoorError(f"download exit {d.returncode}: {d.stderr.strip()[-400:]}")
            return _sweep_view(json.loads(out.read_text()))
        try:
            return json.loads(r.stdout)
        except ValueError as exc:
            raise DoorError(f"not one JSON object on stdout: {r.stdout[:300]!r}") from exc

    def cli_argv(self, row: Row) -> list[str]:
        """``rsf`` words and options for a row: each JSON field ``f`` as ``--f`` (the one
        spelling, docs/lab-api.md: ``--Dc_m``, ``--n_points``); booleans as ``--f`` /
        ``--no-f``; lists of numbers repeated; the SI machine by its fields; objects as JSON
        text; the record and sweep spec as files."""
        q = QUESTIONS[row.question]
        body = dict(row.body)
        words = list(q.si_cli if q.si_cli and "physical" in body else q.cli)
        args: list[str] = []
        if row.question == "figure":  # rsf figure NAME [--quality Q] [--out FILE | --json]
            words.append(body.pop("name"))
        if row.question == "fit":
            rec = self.tmp / f"{row.name}.csv"
            rec.write_text(body.pop("record"))
            words.append(str(rec))
            body.setdefault("series", True)  # the whole answer (series included), as HTTP
        if row.question in ("sweep", "critical_batch", "classify_batch"):
            spec = self.tmp / f"{row.name}-spec.json"
            spec.write_text(json.dumps(body))
            return [*words, str(spec), *(["--wait"] if row.question == "sweep" else ["--json"])]
        for k, v in {**body.pop("physical", {}), **body}.items():
            flag = "--" + k
            if isinstance(v, bool):
                args.append(flag if v else "--no-" + flag[2:])
            elif isinstance(v, list) and all(not isinstance(x, dict) for x in v):
                for x in v:
                    args += [flag, repr(x)]
            elif isinstance(v, dict | list):
                args += [flag, json.dumps(v)]
            else:
                args += [flag, repr(v) if isinstance(v, float) else str(v)]
        return [*words, *args, "--json"]


class DoorError(Exception):
    """A door could not answer a row at all."""


def diff(a: Any, b: Any, path: str = "") -> list[str]:
    """Where ``b`` differs from ``a`` (bitwise for numbers), as 'path: a != b' lines."""
    if isinstance(a, dict) and isinstance(b, dict):
        out = []
        for k in sorted(set(a) | set(b)):
            p = f"{path}.{k}" if path else k
            if k not in b:
                out.append(f"{p}: missing")
            elif k not in a:
                out.append(f"{p}: extra ({json.dumps(b[k])[:80]})")
            else:
                out += diff(a[k], b[k], p)
        return out
    if isinstance(a, list) and isinstance(b, list):
        if len(a) != len(b):
            return [f"{path}: length {len(a)} != {len(b)}"]
        out = []
        for i, (x, y) in enumerate(zip(a, b, strict=True)):
            out += diff(x, y, f"{path}[{i}]")
            if len(out) > 3:
                return out[:3] + [f"{path}: ..."]
        return out
    same = a == b and type(a) is type(b)
    if isinstance(a, float) and isinstance(b, float):
        same = a == b or (math.isnan(a) and math.isnan(b))
    elif isinstance(a, int | float) and isinstance(b, int | float) and not isinstance(a, bool):
        same = float(a) == float(b) and not isinstance(b, bool)
    return [] if same else [f"{path}: {json.dumps(a)[:60]} != {json.dumps(b)[:60]}"]


@pytest.fixture(scope="module")
def service(tmp_path_factory: pytest.TempPathFactory, redis_exe: str) -> Any:
    """uvicorn + a Celery worker on Redis (kombu's filesystem transport can hand a worker a
    message file still being written), and the doors on it."""
    d = tmp_path_factory.mktemp("rsf-conformance")
    started: list[Any] = []
    try:
        started.append(redis := Redis(redis_exe, d))
        started.append(srv := Server(d, redis.url, RSF_INLINE_BUDGET_S="120"))
        started.append(Worker(d, redis.url))
        doors = Doors(srv.url, service_env(d, redis.url, RSF_URL=srv.url), d)
        try:
            yield doors
        finally:
            doors.close()
    finally:
        for p in reversed(started):
            p.stop()


#: Cells known to disagree with the library (row, door) -> why, each a defect of that door
#: (issue 20, items 1/2: a CLI command without the question, or without an option of the
#: one spelling; none left).  A listed cell that agrees is reported on stdout (remove it);
#: any other disagreement fails the test.  HTTP, the client and the CLI agree in every cell.
KNOWN_DISAGREEMENTS: dict[tuple[str, str], str] = {}


def test_doors_agree(service: Doors) -> None:
    """Every row through every door: the same JSON as the library, bit for bit.

    The CLI door's subprocesses (one ``rsf`` start per row: nine tenths of the test's
    time) run two at a time in background threads while this thread asks the library,
    HTTP and the client; every answer is compared exactly as before."""
    from concurrent.futures import Future, ThreadPoolExecutor

    cells: dict[tuple[str, str], list[str]] = {}
    rows = table()
    with ThreadPoolExecutor(max_workers=2, thread_name_prefix="cli-door") as pool:
        by_cli: dict[str, Future[Any]] = {row.name: pool.submit(service.cli, row) for row in rows}
        for row in rows:
            want = _strip(library(row))
            for door in DOORS[1:]:
                try:
                    got = _strip(
                        by_cli[row.name].result() if door == "cli" else getattr(service, door)(row)
                    )
                except Exception as exc:  # noqa: BLE001  (every cell is reported, not the first)
                    cells[(row.name, door)] = [f"no answer: {type(exc).__name__}: {exc}"]
                    continue
                if d := diff(want, got):
                    cells[(row.name, door)] = d[:6]
    agree_now = sorted(set(KNOWN_DISAGREEMENTS) - set(cells))
    if agree_now:
        print("known disagreements that now agree (remove them):", agree_now)
    bad = [
        f"{r} x {door}: {line}"
        for (r, door), lines in cells.items()
        if (r, door) not in KNOWN_DISAGREEMENTS
        for line in lines
    ]
    assert not bad, f"{len(bad)} disagreeing cells:\n" + "\n".join(bad)


def _figure_rows() -> list[Row]:
    return [r for r in TABLE if r.question == "figure"]


@pytest.mark.parametrize("fmt", ["png", "svg"])
def test_figure_images_agree(service: Doors, fmt: str) -> None:
    """The image of every figure row, byte for byte: the library (the figure adapter's data
    drawn by rsfplots), ``rsf figure NAME --out FILE``, HTTP and the client."""
    import hashlib

    from rsfapp.adapter.figures import figure_arrays
    from rsfapp.requests.figures import FigureRequest
    from rsfplots import render_figure

    q = QUESTIONS["figure"]
    bad = []
    for row in _figure_rows():
        want = render_figure(figure_arrays(FigureRequest.model_validate(row.body)), fmt)
        assert isinstance(want, bytes) and len(want) > 10_000
        out = service.tmp / f"{row.name}.{fmt}"
        argv = [*service.cli_argv(row)[:-1], "--out", str(out)]  # no --json
        r = subprocess.run(
            [sys.executable, "-m", "rsfcli.main", *argv],
            env=service.env,
            cwd=ROOT,
            capture_output=True,
            text=True,
            timeout=600,
        )
        assert r.returncode == 0, r.stderr[-400:]
        got = {
            "cli": out.read_bytes(),
            "http": service._get(q, row.body, fmt).content,
            "client": service.c.figure(row.body["name"], fmt, row.body.get("quality")),
        }
        for door, blob in got.items():
            if blob != want:
                digest = hashlib.sha256(blob).hexdigest()[:12]
                bad.append(f"{row.name} x {door}: {len(blob)} bytes ({digest}) != library")
    assert not bad, "\n".join(bad)


def test_figure_list_agrees(service: Doors) -> None:
    """The catalogue of figures: the library, `rsf figure --list --json`, HTTP, the client."""
    import dataclasses

    from rsfapp.adapter.figures import figure_list

    want = _jsonable(figure_list())
    r = subprocess.run(
        [sys.executable, "-m", "rsfcli.main", "figure", "--list", "--json"],
        env=service.env,
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert r.returncode == 0, r.stderr[-400:]
    assert diff(want, json.loads(r.stdout)) == []
    assert diff(want, service.h.get("/v1/figures").json()) == []
    got = [dataclasses.asdict(f) for f in service.c.figures()]
    assert diff(want["figures"], got) == []


def test_get_forms(service: Doors) -> None:
    """GET /v1/boundaries (query form) answers as POST does."""
    q = {"ba": 2.0, "kappa": 2.0, "eps": 0.25, "phi": [0.0, 1.0]}
    got = service.h.get("/v1/boundaries", params=q).json()
    want = service.h.post("/v1/boundaries", json=q).json()
    assert _strip(got) == _strip(want)


def test_known_disagreements_name_rows_and_doors() -> None:
    names = {r.name for r in TABLE}
    assert len(names) == len(TABLE), "row names must be unique"
    stale = [c for c in KNOWN_DISAGREEMENTS if c[0] not in names or c[1] not in DOORS[1:]]
    assert not stale, stale
