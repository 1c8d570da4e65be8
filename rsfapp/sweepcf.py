"""CF metadata of a sweep's files (NetCDF and Zarr): what every variable is, in the
Climate and Forecast conventions (CF-1.10) that xarray, cf-xarray, Panoply and ncview read.

* global: ``Conventions``, ``title``, ``source`` (software and numerics version),
  ``history`` (when and how the file was made), ``references``, ``request`` (the sweep's
  canonical spec, JSON), ``selection`` (the subset, JSON), plus the sweep's status, fixed
  parameters and SI scales;
* every coordinate and variable: ``long_name`` and ``units`` ("1" for dimensionless);
* the codes (``kind``, ``outcome``, ``method``, and the 0/1 flags ``failed``,
  ``outcome_uncertain``, ``computed``): ``flag_values`` and ``flag_meanings`` with one
  distinct word per code; -1 "missing" is the ``_FillValue`` (decoded as NaN), as is NaN
  for the floats.
"""

from __future__ import annotations

import json
from datetime import UTC, datetime
from typing import Any

import numpy as np

from rsfcore.critical import KINDS, METHODS

from .grid import SweepSpec

__all__ = [
    "CONVENTIONS",
    "METHOD_FLAGS",
    "method_flags",
    "coordinate_attrs",
    "global_attrs",
    "software_version",
    "variable_attrs",
]

CONVENTIONS = "CF-1.10"

#: One distinct word per entry of rsfcore.critical.METHODS (same order), for
#: ``flag_meanings`` (the labels' first words repeat: 2, 3 and 4 all begin "closed form").
METHOD_FLAGS: tuple[str, ...] = (
    "zero_linear_instability",
    "infinite_no_runaway",
    "closed_form_limiting_trajectory",
    "closed_form_load_point_jump_at_kappa_crit",
    "closed_form_phi_crit_vo_0",
    "separatrix_backward_integration",
    "bisection_of_classify_outcomes",
    "zero_kappa_0_stationary_load_point",
    "separatrix_beyond_double_range",
    "asymptote_load_point_jump",
    "infinite_kappa_0_no_spring",
)


def method_flags() -> tuple[str, ...]:
    """:data:`METHOD_FLAGS` for every entry of METHODS: a method added to rsfcore without
    its word here gets ``method_<k>`` (still distinct); tests/api/test_sweep_subsets.py
    asks for a word for each."""
    return tuple(
        METHOD_FLAGS[k] if k < len(METHOD_FLAGS) else f"method_{k}" for k in range(len(METHODS))
    )


_AXES: dict[str, tuple[str, str]] = {
    "ba": ("b/a: ratio of the evolution and direct-effect parameters", "1"),
    "kappa": ("kappa: spring stiffness k Dc/(a sigma)", "1"),
    "kappa_ratio": ("kappa/kappa_crit with kappa_crit = b/a - 1", "1"),
    "eps": ("eps: evolution-law parameter (0 aging, 1 slip law)", "1"),
    "vo": ("v_o: load-point velocity V_load/V_*", "1"),
    "size": (
        "dimensionless perturbation size (d for a velocity jump, dv for a load-point jump)",
        "1",
    ),
    "factor": ("velocity jump factor V_new/V_before", "1"),
    "new_slip_rate_m_s": ("slip rate right after the velocity jump", "m/s"),
    "new_load_point_velocity_m_s": ("new load-point velocity after the jump", "m/s"),
    "point": ("flat index of the scattered point", "1"),
}


def software_version() -> str:
    """The installed rsf-stability version ('unknown' when run from a source tree)."""
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version("rsf-stability")
    except PackageNotFoundError:  # pragma: no cover - always installed here
        return "unknown"


def coordinate_attrs(name: str) -> dict[str, Any]:
    """long_name and units of a sweep dimension or swept parameter."""
    long_name, units = _AXES.get(name, (name, "1"))
    return {"long_name": long_name, "units": units}


def _flags(meanings: tuple[str, ...] | list[str], start: int = 0) -> dict[str, Any]:
    return {
        "flag_values": np.arange(start, start + len(meanings), dtype=np.int8),
        "flag_meanings": " ".join(meanings),
    }


def variable_attrs(spec: SweepSpec) -> dict[str, dict[str, Any]]:
    """{variable: attributes} of the result variables (without ``_FillValue``, which
    the writers set with the variable: see :data:`rsfapp.sweepselect.FILL`)."""
    size_unit = "d = ln(V_new/V_before)" if spec.perturbation == "velocity-jump" else "dv/v_o"
    return {
        "critical_size": {
            "long_name": f"critical perturbation size ({size_unit}); 0 for kind zero, "
            "inf for kind infinite",
            "units": "1",
        },
        "kind": {
            "long_name": "kind of critical size",
            "units": "1",
            **_flags(list(KINDS)),
            "comment": "-1 (fill): not computed yet or failed",
        },
        "outcome": {
            "long_name": "outcome of the perturbation of the given size",
            "units": "1",
            **_flags(["stable", "unstable"]),
            "comment": "-1 (fill): not computed yet, failed, or no size asked",
        },
        "rel_accuracy": {
            "long_name": "estimated relative accuracy of critical_size",
            "units": "1",
        },
        "failed": {
            "long_name": "the point could not be computed (messages in the sweep status)",
            "units": "1",
            **_flags(["computed_or_pending", "failed"]),
        },
        "method": {
            "long_name": "method that decided the critical size (rsfcore.critical.METHODS)",
            "units": "1",
            **_flags(list(method_flags())),
            "comment": "-1 (fill): not computed yet or failed. "
            + " | ".join(f"{k} {m}" for k, m in enumerate(METHODS)),
        },
        "outcome_uncertain": {
            "long_name": "the outcome is within the accuracy of the critical size "
            "(or kappa = kappa_crit up to rounding): it may flip",
            "units": "1",
            **_flags(["certain", "uncertain"]),
        },
        "computed": {
            "long_name": "the point's chunk is stored (0: not computed yet)",
            "units": "1",
            **_flags(["pending", "computed"]),
        },
    }


def global_attrs(
    spec: SweepSpec,
    status: dict[str, Any],
    selection: dict[str, Any] | None,
    how: str,
    when: str | None = None,
) -> dict[str, Any]:
    """Global attributes: CF identification, the request and the sweep's state.
    ``how`` says how the file was made (e.g. the request path), for ``history``, at
    ``when`` (ISO 8601; default now)."""
    from rsfcore import NUMERICS_VERSION

    now = when or datetime.now(UTC).isoformat(timespec="seconds").replace("+00:00", "Z")
    attrs: dict[str, Any] = {
        "Conventions": CONVENTIONS,
        "title": "Critical perturbation sizes of a rate-and-state spring-slider "
        f"({spec.perturbation}, sweep {status.get('id', '')})",
        "source": f"rsf-stability {software_version()} (rsfcore numerics version "
        f"{status.get('numerics_version') or NUMERICS_VERSION})",
        "history": f"{now} {how}",
        "references": "Non-linear slip stability of rate-and-state friction "
        "(spring-slider, aging-to-slip laws); docs/ of rsf-stability",
        "request": json.dumps(spec.to_json(), sort_keys=True),
        "sweep_id": status.get("id", ""),
        "status": status.get("status", ""),
        "perturbation": spec.perturbation,
        "rtol": spec.rtol,
        "output": spec.output,
        "n_total": spec.n_total,
        "n_done": int(status.get("n_done", 0)),
        "n_failed": int(status.get("n_failed", 0)),
        "numerics_version": str(status.get("numerics_version", "")),
    }
    if selection is not None:
        attrs["selection"] = json.dumps(selection, sort_keys=True)
    for name, fv in spec.fixed.items():
        if fv is not None:
            attrs[f"fixed_{name}"] = float(fv)
    phys = spec.physical_inputs()
    if phys is not None:
        for name, pv in phys.to_dict().items():
            attrs[f"physical_{name}"] = float(pv)
        attrs["time_scale_s"] = phys.time_scale_s
        attrs["stress_scale_Pa"] = phys.stress_scale_Pa
        attrs["k_crit_Pa_per_m"] = phys.k_crit_Pa_per_m
    return attrs
