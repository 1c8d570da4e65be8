"""Lab protocols (POST /v1/protocols/*; rsfcore.protocols, SI units): velocity step,
slide-hold-slide, any load history, with the lab's friction changes."""

from __future__ import annotations

from typing import Any

import numpy as np

from rsfcore import protocols as _protocols
from rsfcore.jsonsafe import jsonsafe
from rsfcore.params import PhysicalParams

from ..requests.protocols import LoadHistoryRequest, SlideHoldSlideRequest, VelocityStepRequest
from ._common import guard, json_dict
from ._si import si_inputs

__all__ = [
    "PROTOCOL_COLUMNS",
    "protocol_load_history",
    "protocol_slide_hold_slide",
    "protocol_table",
    "protocol_velocity_step",
]


def _machine(req: Any) -> PhysicalParams:
    """The protocol's machine as rsfcore PhysicalParams (via rsfcore.units)."""
    phys = si_inputs(req)
    assert phys is not None  # ``physical`` is required by the protocol models
    machine: PhysicalParams = guard(phys.to_physical_params, req.eps, req.f_star)
    return machine


def _segment_changes(res: Any, phys: PhysicalParams) -> list[dict[str, Any]]:
    """Per segment: steady-state friction change from the previous load-point velocity
    (`eq: steady state`; None across a hold), and the peak friction change from the
    friction at the segment's start (true peak of rsfcore.protocols), also in Pa
    (tau = f sigma, `eq: MC criterion`)."""
    out: list[dict[str, Any]] = []
    t = np.asarray(res.t_s)
    f = np.asarray(res.friction)
    prev_v = None
    for s in res.segments:
        row: dict[str, Any] = {
            "index": s.index,
            "V_load_m_s": s.Vo_m_s,
            "status": s.status,
            "steady_state_delta_f": None,
            "steady_state_delta_tau_Pa": None,
            "peak_friction": s.peak_friction,
            "peak_delta_f": None,
            "peak_delta_tau_Pa": None,
            "peak_time_s": s.peak_friction_time_s,
            "peak_V_m_s": s.peak_V_m_s,
            "f_start": None,
        }
        if prev_v is not None and prev_v > 0 and s.Vo_m_s > 0:
            dss = _protocols.steady_state_friction(
                phys, s.Vo_m_s
            ) - _protocols.steady_state_friction(phys, prev_v)
            row.update(steady_state_delta_f=dss, steady_state_delta_tau_Pa=dss * phys.sigma)
        if s.status != "not_run" and t.size:
            k = int(np.searchsorted(t, s.t_start_s, side="right")) - 1
            f0 = float(f[max(k, 0)])
            row["f_start"] = f0
            if s.peak_friction is not None:
                row.update(
                    peak_delta_f=s.peak_friction - f0,
                    peak_delta_tau_Pa=(s.peak_friction - f0) * phys.sigma,
                )
        prev_v = s.Vo_m_s
        out.append(row)
    return out


def protocol_velocity_step(req: VelocityStepRequest) -> dict[str, Any]:
    """rsfcore.protocols.velocity_step, plus the lab's friction changes: steady state
    (a - b) ln(V2/V1) and peak (true peak minus f_ss(V1)), as friction and in Pa."""
    ph = _machine(req)
    res = guard(
        _protocols.velocity_step,
        ph,
        req.V1_m_s,
        req.V2_m_s,
        slip_after_m=req.slip_after_m,
        slip_total_m=req.slip_total_m,
        n_points=req.n_points,
        rtol=req.rtol,
    )
    out = json_dict(res.to_dict())
    f1 = _protocols.steady_state_friction(ph, req.V1_m_s)
    f2 = _protocols.steady_state_friction(ph, req.V2_m_s)
    seg = res.protocol.segments[0]
    pk = seg.peak_friction
    out["friction_changes"] = jsonsafe(
        {
            "f_ss_before": f1,
            "f_ss_after": f2,
            "steady_state_delta_f": f2 - f1,
            "steady_state_delta_tau_Pa": (f2 - f1) * ph.sigma,
            "peak_friction": pk,
            "peak_time_s": seg.peak_friction_time_s,
            "peak_delta_f": None if pk is None else pk - f1,
            "peak_delta_tau_Pa": None if pk is None else (pk - f1) * ph.sigma,
            "peak_V_m_s": seg.peak_V_m_s,
        }
    )
    out["kind"] = "velocity-step"
    return out


def protocol_slide_hold_slide(req: SlideHoldSlideRequest) -> dict[str, Any]:
    """rsfcore.protocols.slide_hold_slide: healing (peak on reslide - f_ss) and relaxation
    (f_ss - friction at the end of the hold), as friction and in Pa, plus segment peaks."""
    ph = _machine(req)
    res = guard(
        _protocols.slide_hold_slide,
        ph,
        req.V_m_s,
        req.hold_s,
        slide_before_s=req.slide_before_s,
        slide_after_s=req.slide_after_s,
        n_points_per_segment=req.n_points_per_segment,
        rtol=req.rtol,
    )
    out = json_dict(res.to_dict())
    heal, relax = res.healing_delta_f, res.relaxation_delta_f
    out["friction_changes"] = jsonsafe(
        {
            "healing_delta_f": heal,
            "healing_delta_tau_Pa": None if heal is None else heal * ph.sigma,
            "relaxation_delta_f": relax,
            "relaxation_delta_tau_Pa": None if relax is None else relax * ph.sigma,
            "segments": _segment_changes(res.protocol, ph),
        }
    )
    out["kind"] = "slide-hold-slide"
    return out


def protocol_load_history(req: LoadHistoryRequest) -> dict[str, Any]:
    """rsfcore.protocols.load_history for any piecewise-constant load-point history (e.g.
    several velocity steps), with per-segment steady-state and peak friction changes."""
    ph = _machine(req)
    st = req.start_state
    start: Any = "steady" if st == "steady" else (st.V_m_s, st.theta_s)
    res = guard(
        _protocols.load_history,
        ph,
        [(s.duration_s, s.V_load_m_s) for s in req.segments],
        n_points_per_segment=req.n_points_per_segment,
        rtol=req.rtol,
        start=start,
    )
    out = json_dict(res.to_dict())
    out["friction_changes"] = jsonsafe({"segments": _segment_changes(res, ph)})
    out["kind"] = "load-history"
    return out


#: Columns of a protocol's CSV (the sampled history), in order.
PROTOCOL_COLUMNS = (
    "t_s",
    "friction",
    "tau_change_Pa",
    "V_m_s",
    "theta_s",
    "slip_m",
    "load_point_m",
    "segment",
    "Vo_m_s",
)


def protocol_table(result: dict[str, Any]) -> dict[str, list[Any]]:
    """The sampled history of a protocol answer as columns (velocity steps add
    slip_since_step_m and the simulated and analytic (tau - tau_ss)/(b sigma))."""
    prot = result.get("protocol", result)
    cols = {k: prot[k] for k in PROTOCOL_COLUMNS if k in prot}
    for k in ("slip_since_step_m", "delta_tau_over_b_sigma", "analytic_over_b_sigma"):
        if k in result:
            cols[k] = result[k]
    return cols
