"""Response models of the main endpoints, for the OpenAPI docs (units stated per field).

The endpoints send the cached JSON text as is (no re-validation on the hot path); these
models document its fields.  Times are dimensionless, T = V_* t/Dc; phi = ln(V/V_*).
"""

from __future__ import annotations

from typing import Literal

from pydantic import BaseModel, Field

__all__ = ["ClassifyResult", "TrajectoryResult", "CriticalResult"]


class _Cached(BaseModel):
    cached: bool = Field(description="True when answered from the result cache.")
    cache_key: str = Field(description="sha256 of (kind, canonical request, numerics version).")


class _Params(BaseModel):
    ba: float = Field(description="b/a (-).")
    kappa: float = Field(description="k Dc/(a sigma) (-).")
    eps: float = Field(description="evolution-law parameter (-), 0 slip .. 1 aging.")
    vo: float = Field(
        description="V_o/V_* (-) the trajectory ran with (v_o (1 + dv) after a load-point jump)."
    )


class _Start(BaseModel):
    phi: float = Field(description="phi at T = 0 (-).")
    psi: float = Field(description="psi = (tau - tau_*)/(a sigma) at T = 0 (-).")


class ClassifyResult(_Cached):
    """Certified outcome of one perturbation."""

    outcome: Literal["stable", "unstable"] = Field(
        description="stable: returns (or arrests when v_o = 0); unstable: runaway in finite time."
    )
    certificate: str = Field(
        description="What decided the outcome, e.g. L_above_Lstar, returned_to_steady_state, U_negative_closed_orbit."
    )
    blowup_time: float | None = Field(
        description="T at which phi -> infinity (unstable), else null."
    )
    return_time: float | None = Field(
        description="T at which phi first falls back to ln v_o after the excursion (stable, v_o > 0), else null."
    )
    peak_phi: float | None = Field(
        description="True maximum of phi (located on every step); null for a runaway."
    )
    peak_time: float | None = Field(description="T of the peak (the blow-up time for a runaway).")
    rel_accuracy: float = Field(
        description="Estimated relative accuracy of the reported times and peak (-)."
    )
    n_steps: int = Field(description="Integrator steps (accepted + rejected).")
    n_rhs: int = Field(description="Right-hand-side evaluations.")
    params: _Params
    start: _Start
    perturbation: str | None = Field(
        description="velocity-jump, load-point-jump, or null for an explicit start."
    )
    size: float | None = Field(description="Perturbation size (-).")
    complete: bool = Field(
        description="False when the outcome is certain but the step budget ended before the final "
        "times/peak, when such times could not be checked within the budget, or when a "
        "trajectory's samples end before the extent asked (t_end, or the blow-up): see reason."
    )
    reason: str = Field(
        description="Why complete is false, e.g. where the samples end and which step budget "
        "stopped the run ('' when complete)."
    )


class TrajectoryResult(ClassifyResult):
    """Outcome plus the downsampled trajectory."""

    trajectory: dict[str, list[float | None]] = Field(
        description="Columns T, phi, psi, ln_theta (ln of V_* theta/Dc), slip (delta/Dc), "
        "load_point (delta_o/Dc); with physical scales also t_s [s], V_m_s [m/s], "
        "tau_change_Pa [Pa], friction (-), theta_s [s], slip_m [m], load_point_m [m]."
    )


class CriticalResult(_Cached):
    """Critical perturbation size (same fields as `rsf critical --json`)."""

    kind: Literal["zero", "finite", "infinite"] = Field(
        description="zero: every perturbation grows; finite: sizes above critical_size run away; infinite: none does."
    )
    critical_size: float | None = Field(
        description="Critical d (velocity jump) or dv/v_o (load-point jump) (-); null when "
        "infinite or beyond the double range (see log_critical_size), 0 when zero."
    )
    log_critical_size: float | None = Field(
        description="d (velocity jump) or ln(1 + dv) (load-point jump) (-): finite for every "
        "finite size, also beyond the double range; classify's log_size checks it."
    )
    rel_accuracy: float = Field(
        description="Relative accuracy of critical_size: a tested upper bound (-)."
    )
    accuracy_met: bool = Field(description="rel_accuracy <= the requested rtol.")
    reason: str = Field(description="Why the requested rtol is not met ('' when it is).")
    method: str = Field(
        description="How it was obtained: closed form (with the equation), separatrix integration, or bisection."
    )
    perturbation: str
    params: _Params
    on_boundary: bool = Field(
        description="True on a kind boundary (eps kappa = kappa_crit or kappa = kappa_crit) up to rounding."
    )
