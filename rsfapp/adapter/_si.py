"""SI inputs of a single query (``physical`` and the perturbation stated in SI) and the
``si`` blocks of the answers; every conversion is rsfcore.units'."""

from __future__ import annotations

import math
from typing import Any

from rsfcore.params import ParameterError, Params
from rsfcore.units import (
    SI_SIZE_FIELDS,
    PhysicalInputs,
    load_point_jump_si,
    size_from_si,
    velocity_jump_si,
)

from ..requests import PhysicalSI
from ._common import dim_params, guard

__all__ = [
    "critical_si",
    "jump_si",
    "outcome_si",
    "resolve_params",
    "resolve_size",
    "scales_si",
    "si_inputs",
]


# --- single queries: dimensionless or SI (conversions: rsfcore.units only) ---------------
def si_inputs(req: Any) -> PhysicalInputs | None:
    """The request's ``physical`` SI set as rsfcore.units.PhysicalInputs (None without);
    its cross-field checks raise ParameterError naming ``physical.<field>``."""
    phys = getattr(req, "physical", None)
    if phys is None or not isinstance(phys, PhysicalSI):
        return None
    inputs: PhysicalInputs = guard(PhysicalInputs.from_dict, phys.model_dump(exclude_none=True))
    return inputs


def resolve_params(req: Any) -> tuple[Params, PhysicalInputs | None]:
    """(Params, PhysicalInputs or None): from ``physical`` and ``eps`` when SI, else from
    the dimensionless ba, kappa, eps, vo."""
    phys = si_inputs(req)
    if phys is None:
        return dim_params(req), None
    p: Params = guard(phys.to_params, req.eps)
    return p, phys


def resolve_size(req: Any, phys: PhysicalInputs | None) -> float:
    """The dimensionless perturbation size: ``size``, or the SI statement (``factor``,
    ``new_slip_rate_m_s``, ``new_load_point_velocity_m_s``) converted by
    rsfcore.units.size_from_si (the one place of the SI size rules); ParameterError names
    the request's field."""
    given: dict[str, float] = {
        f: float(v) for f in SI_SIZE_FIELDS if (v := getattr(req, f, None)) is not None
    }
    if not given or phys is None:
        return float(req.size)
    ((name, value),) = given.items()  # the request model allows one statement
    try:
        return float(size_from_si(phys, req.perturbation, name, value))
    except ParameterError as exc:  # name the request's field, not units' dotted one
        field = exc.field.removeprefix("perturbation.")
        raise ParameterError(field, exc.value, exc.valid) from None


def jump_si(
    phys: PhysicalInputs, perturbation: str, size: float | None, log_size: float | None = None
) -> dict[str, Any]:
    """A perturbation of dimensionless ``size`` in SI: the velocity jump (factor, new slip
    rate [m/s], shear-stress jump a sigma d [Pa] at constant state) or the load-point jump
    (new load-point velocity [m/s]).  A size beyond the double range (a critical size
    known by its logarithm ``log_size``) is answered by its logarithms (log10 of the
    factor and of the new velocity), the values it overflows as null."""
    if perturbation == "velocity-jump":
        d = size if size is not None and math.isfinite(size) else log_size
        if d is None or not math.isfinite(d):
            return {}
        out = guard(velocity_jump_si, phys, d).to_dict()
        out["shear_stress_jump_Pa"] = phys.shear_stress_change_Pa(d)
        out["friction_jump"] = phys.friction_change(d)
        return {"velocity_jump": out}
    if log_size is not None and math.isfinite(log_size):
        lp = guard(load_point_jump_si, phys, size, log_factor=log_size)
    elif size is not None and math.isfinite(size):
        lp = guard(load_point_jump_si, phys, size)
    else:
        return {}
    return {"load_point_jump": lp.to_dict()}


def scales_si(phys: PhysicalInputs) -> dict[str, Any]:
    return {
        "inputs": phys.to_dict(),
        "kappa": phys.kappa,
        "kappa_crit": phys.kappa_crit,
        "k_crit_Pa_per_m": phys.k_crit_Pa_per_m,
        "time_scale_s": phys.time_scale_s,
        "stress_scale_Pa": phys.stress_scale_Pa,
        "slip_rate_before_m_s": phys.slip_rate_before_m_s,
    }


def outcome_si(
    phys: PhysicalInputs, out: dict[str, Any], log_size: float | None = None
) -> dict[str, Any]:
    """The ``si`` block of a classify/trajectory answer: times [s], peak slip rate [m/s],
    start shear-stress change [Pa] and friction change, the perturbation in SI."""

    def ts(T: Any) -> float | None:
        return None if T is None else phys.time_s(float(T))

    peak = out.get("peak_phi")
    start = out.get("start") or {}
    si: dict[str, Any] = {
        **scales_si(phys),
        "blowup_time_s": ts(out.get("blowup_time")),
        "return_time_s": ts(out.get("return_time")),
        "peak_time_s": ts(out.get("peak_time")),
        "peak_slip_rate_m_s": None if peak is None else phys.slip_rate_m_s(float(peak)),
    }
    if start.get("psi") is not None:
        si["start_shear_stress_change_Pa"] = phys.shear_stress_change_Pa(float(start["psi"]))
        si["start_friction_change"] = phys.friction_change(float(start["psi"]))
        si["start_slip_rate_m_s"] = phys.slip_rate_m_s(float(start["phi"]))
    if out.get("perturbation") is not None:
        si.update(jump_si(phys, str(out["perturbation"]), out.get("size"), log_size))
    return si


def critical_si(phys: PhysicalInputs, out: dict[str, Any]) -> dict[str, Any]:
    return {
        **scales_si(phys),
        **jump_si(
            phys,
            str(out["perturbation"]),
            out.get("critical_size"),
            out.get("log_critical_size"),
        ),
    }
