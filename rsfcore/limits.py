"""Valid ranges and defaults of every user-facing parameter: the one source of truth.

rsfcore validates with these objects, and the CLI and the HTTP request models read their
ranges, defaults and help texts from here (a test checks that they agree).  Quantities
are the dimensionless groups of Ciardo & Viesca, `eq: characteristic scales`:
phi = ln(V/V_*), psi = (tau - tau_*)/(a sigma), kappa = k Dc/(a sigma), v_o = V_o/V_*,
T = V_* t/Dc.

Defaults (chosen once for the library, the CLI and the HTTP API): the paper's running
example b/a = 2, kappa = 2 (kappa/kappa_crit = 2), eps = 0.25, v_o = 1, perturbation
size 1 (its load-point-jump critical size is 12.6842, tests/data/reference.json).

Why the ranges are what they are:

* ``ba`` <= 1e6 and ``kappa`` <= 1e6: beyond them nothing new happens (kappa_crit ~ b/a)
  while the explicit integrator's step shrinks like 1/kappa.
* ``vo`` <= 1e300: |ln v_o| <= 691 keeps every exponential of the engine finite.
* ``rtol`` in [1e-13, 1e-3]: the tightest tolerance every numerical path honours.  The
  trajectory engine (DOP853) still delivers its stated accuracy at 1e-13, while the
  separatrix method runs its internal tolerance 50x tighter than the request (calibration,
  rsfcore.critical), so a request of 1e-14 would ask for 2e-16, below the spacing of
  doubles; scipy's own DOP853 refuses rtol below 100 machine epsilons (2.2e-14) too.
  Above 1e-3 the certificates (return, blow-up) stay exact but the reported times carry
  no useful digits.
* velocity-jump size |d| <= 1e4: e^d is never formed, and beyond 1e4 nothing changes.
* load-point-jump size dv in (-1, 1e300]: v_o (1 + dv) must stay in (0, 1e300]; the
  upper end is therefore 1e300/v_o at a given v_o (checked where v_o is known).
* ``n_points`` in [2, 1e5]: a sampled trajectory has both ends; 1e5 samples of 7 columns
  are ~5 MB of JSON.
* ``t_end`` in (0, 1e12]: dimensionless time; 1e12 Dc/V_* is far beyond any certificate.
* ``max_steps`` in [1, 1e7]: ~10 s of integration at ~1 us per step.
* start values |phi0| <= 1e4 and |psi0| <= 1e8: the engine forms exp(-|phi|) only.

Usage::

    from rsfcore.limits import RTOL
    rtol = RTOL.check(rtol)          # float, or ParameterError("rtol", value, "[1e-13, 1e-3]")
    RTOL.text                        # "[1e-13, 1e-3]"
    RTOL.default                     # 1e-10
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .errors import ParameterError

__all__ = [
    "Limit",
    "format_number",
    "range_text",
    "check_range",
    "check_finite",
    "BA",
    "KAPPA",
    "KAPPA_RATIO",
    "EPS",
    "VO",
    "VELOCITY_JUMP_SIZE",
    "LOAD_POINT_JUMP_SIZE",
    "DIAGRAM_SIZE",
    "RTOL",
    "RTOL_RANGE",
    "DEFAULT_RTOL",
    "N_POINTS",
    "T_END",
    "MAX_STEPS",
    "PHI_START",
    "PSI_START",
    "A",
    "DC",
    "SIGMA",
    "K",
    "V_STAR",
    "VO_SI",
    "F_STAR",
    "SI_A",
    "SI_B",
    "SI_DC_M",
    "SI_SIGMA_PA",
    "SI_K_PA_PER_M",
    "SI_V_STAR_M_S",
    "SI_V_LOAD_M_S",
    "SI_DC_MAX_M",
    "SI_SIGMA_MAX_PA",
    "SI_K_MAX_PA_PER_M",
    "SI_V_MAX_M_S",
    "BA_MAX",
    "KAPPA_MAX",
    "VO_MAX",
    "VO_MIN",
    "VO_VALID_TEXT",
    "SIZE_MAX",
    "STEP_BUDGET",
    "LIMITS",
]


def format_number(x: float) -> str:
    """Short, exact-looking text for a range end: 1e6 -> "1e6", 1e-13 -> "1e-13", 0.25 -> "0.25"."""
    if math.isinf(x):
        return "inf" if x > 0 else "-inf"
    if x == 0.0 or 1e-2 <= abs(x) < 1e4:
        return f"{x:.15g}"
    mant, exp = f"{x:.15e}".split("e")
    mant = mant.rstrip("0").rstrip(".")
    return f"{mant}e{int(exp)}"


def range_text(
    lo: float | None, hi: float | None, lo_open: bool = False, hi_open: bool = False
) -> str:
    """Interval text such as "(1, 1e6]"; a missing end is written -inf / inf (always open)."""
    left = "(-inf" if lo is None else ("(" if lo_open else "[") + format_number(lo)
    right = "inf)" if hi is None else format_number(hi) + (")" if hi_open else "]")
    return f"{left}, {right}"


def check_finite(name: str, value: object) -> float:
    """Return ``float(value)`` or raise ParameterError(name, value, "a finite real number")."""
    if isinstance(value, bool):
        raise ParameterError(name, value, "a finite real number")
    try:
        v = float(value)  # type: ignore[arg-type]
    except (TypeError, ValueError):
        raise ParameterError(name, value, "a finite real number") from None
    if not math.isfinite(v):
        raise ParameterError(name, value, "a finite real number")
    return v


def check_range(
    name: str,
    value: object,
    lo: float | None = None,
    hi: float | None = None,
    *,
    lo_open: bool = False,
    hi_open: bool = False,
) -> float:
    """Return ``float(value)`` or raise :class:`ParameterError` naming ``name`` and the range.

    For ranges that depend on other inputs (e.g. b > a); fixed ranges are :class:`Limit`.
    """
    v = check_finite(name, value)
    if (lo is not None and (v < lo or (lo_open and v == lo))) or (
        hi is not None and (v > hi or (hi_open and v == hi))
    ):
        raise ParameterError(name, value, range_text(lo, hi, lo_open, hi_open))
    return v


@dataclass(frozen=True)
class Limit:
    """Valid range and default of one parameter.

    Attributes:
        name: field name used in error messages, CLI options and HTTP fields.
        lo, hi: range ends (None = unbounded on that side).
        lo_open, hi_open: whether the end itself is excluded.
        default: default value (None = "not given", e.g. t_end runs to the decision).
        unit: unit text ("-" for dimensionless).
        description: one-line meaning, for help texts and OpenAPI.
        integer: the value must be an integer (n_points, max_steps).
    """

    name: str
    lo: float | None
    hi: float | None
    lo_open: bool = False
    hi_open: bool = False
    default: float | None = None
    unit: str = "-"
    description: str = ""
    integer: bool = False

    @property
    def text(self) -> str:
        """The range as text, e.g. "(1, 1e6]"."""
        return range_text(self.lo, self.hi, self.lo_open, self.hi_open)

    def contains(self, value: float) -> bool:
        """True when the finite value lies in the range (no type conversion)."""
        if not math.isfinite(value):
            return False
        if self.lo is not None and (value < self.lo or (self.lo_open and value == self.lo)):
            return False
        return not (
            self.hi is not None and (value > self.hi or (self.hi_open and value == self.hi))
        )

    def bad_mask(self, values: ArrayLike) -> NDArray[np.bool_]:
        """Boolean mask of the array entries outside the range (non-finite entries are bad)."""
        a = np.asarray(values, dtype=np.float64)
        ok = np.isfinite(a)
        if self.lo is not None:
            ok &= (a > self.lo) if self.lo_open else (a >= self.lo)
        if self.hi is not None:
            ok &= (a < self.hi) if self.hi_open else (a <= self.hi)
        return ~ok

    def check(self, value: object, name: str | None = None) -> float:
        """Return ``float(value)`` if it is in range, else raise ParameterError(name, value, text).

        ``name`` overrides the field name in the error (e.g. "segments[2].rtol").
        """
        field = self.name if name is None else name
        v = check_finite(field, value)
        if not self.contains(v):
            raise ParameterError(field, value, self.text)
        if self.integer and v != int(v):
            raise ParameterError(field, value, f"an integer in {self.text}")
        return v

    def check_int(self, value: object, name: str | None = None) -> int:
        """:meth:`check` for integer parameters; returns an int."""
        return int(self.check(value, name))

    def help(self) -> str:
        """Help text: description, valid range and unit (for CLI options and HTTP fields)."""
        unit = "" if self.unit in ("", "-") else f" [{self.unit}]"
        return f"{self.description}{unit} Valid range: {self.text}."


# --- plain numbers, for code that builds its own messages ------------------------------
BA_MAX: float = 1.0e6
KAPPA_MAX: float = 1.0e6
VO_MAX: float = 1.0e300
#: smallest positive v_o: |ln v_o| <= 691 on both sides, so times T = V_* t/Dc, which
#: scale as 1/v_o, stay finite (at v_o = 5e-324 they overflow and v_o (1 + dv) rounds
#: to a denormal that loses the jump); v_o = 0 (stationary load point) stays valid
VO_MIN: float = 1.0e-300
#: The valid values of v_o in words, (0, VO_MIN) excluded (Params, sweep axes and fixed v_o)
VO_VALID_TEXT: str = (
    f"0 (stationary load point) or [{VO_MIN:g}, {VO_MAX:g}]: below {VO_MIN:g} the times,"
    " which scale as 1/v_o, leave the double range"
)
SIZE_MAX: float = 1.0e4
#: largest step budget of one integration
STEP_BUDGET: int = 10_000_000

#: (lo, hi) of RTOL, for code that wants the pair
RTOL_RANGE: tuple[float, float] = (1.0e-13, 1.0e-3)
DEFAULT_RTOL: float = 1.0e-10

# --- dimensionless model parameters (rsfcore.Params) ----------------------------------
BA = Limit(
    "ba",
    1.0,
    BA_MAX,
    lo_open=True,
    default=2.0,
    description="b/a, rate-weakening ratio (kappa_crit = b/a - 1).",
)
KAPPA = Limit(
    "kappa",
    0.0,
    KAPPA_MAX,
    default=2.0,
    description="kappa = k Dc/(a sigma), dimensionless spring stiffness.",
)
#: kappa/kappa_crit; the upper end is 1e6/(b/a - 1) at a given b/a (kappa <= 1e6).
KAPPA_RATIO = Limit(
    "kappa_ratio",
    0.0,
    None,
    default=2.0,
    description="kappa/kappa_crit, stiffness relative to the linear critical value"
    " (kappa = kappa_ratio (b/a - 1) <= 1e6).",
)
EPS = Limit(
    "eps",
    0.0,
    1.0,
    default=0.25,
    description="Evolution-law parameter: 0 = slip law, 1 = aging law.",
)
VO = Limit(
    "vo",
    0.0,
    VO_MAX,
    default=1.0,
    description="v_o = V_o/V_*, load-point velocity (0 = stationary load point; a moving"
    " load point needs v_o >= 1e-300).",
)

# --- perturbations ----------------------------------------------------------------------
VELOCITY_JUMP_SIZE = Limit(
    "size",
    -SIZE_MAX,
    SIZE_MAX,
    default=1.0,
    description="Velocity jump d: (phi, psi) += (d, d), slip rate times e^d at constant state.",
)
#: dv of v_o -> v_o (1 + dv); the upper end is 1e300/v_o at a given v_o.
LOAD_POINT_JUMP_SIZE = Limit(
    "size",
    -1.0,
    VO_MAX,
    lo_open=True,
    default=1.0,
    description="Load-point jump dv: v_o -> v_o (1 + dv) (v_o (1 + dv) <= 1e300).",
)
#: perturbation size of the outcome mode / size axis of a stability diagram
DIAGRAM_SIZE = Limit(
    "size", 0.0, None, default=1.0, description="Perturbation size (positive perturbations)."
)

# --- numerics ------------------------------------------------------------------------------
RTOL = Limit(
    "rtol",
    RTOL_RANGE[0],
    RTOL_RANGE[1],
    default=DEFAULT_RTOL,
    description="Relative tolerance of the integrator (requested relative accuracy).",
)
N_POINTS = Limit(
    "n_points", 2, 100_000, default=200, integer=True, description="Number of output samples."
)
T_END = Limit(
    "t_end",
    0.0,
    1.0e12,
    lo_open=True,
    default=None,
    description="Stop at this dimensionless time T = V_* t/Dc (default: at the decision).",
)
MAX_STEPS = Limit(
    "max_steps",
    1,
    STEP_BUDGET,
    default=STEP_BUDGET,
    integer=True,
    description="Step budget of one integration (~1 us per step).",
)
PHI_START = Limit(
    "phi0", -1.0e4, 1.0e4, default=0.0, description="Start phi = ln(V/V_*), log slip rate."
)
PSI_START = Limit(
    "psi0", -1.0e8, 1.0e8, default=0.0, description="Start psi = (tau - tau_*)/(a sigma), stress."
)

# --- physical parameters (rsfcore.PhysicalParams); the dimensionless image is checked too ---
A = Limit("a", 0.0, 1.0, lo_open=True, description="Direct-effect coefficient a.")
DC = Limit(
    "Dc_m", 0.0, None, lo_open=True, unit="m", description="Characteristic slip distance Dc."
)
SIGMA = Limit(
    "sigma_Pa", 0.0, None, lo_open=True, unit="Pa", description="Effective normal stress."
)
K = Limit("k_Pa_per_m", 0.0, None, unit="Pa/m", description="Spring stiffness per unit area.")
V_STAR = Limit(
    "V_star_m_s", 0.0, None, lo_open=True, unit="m/s", description="Reference slip rate V_*."
)
VO_SI = Limit("V_load_m_s", 0.0, None, unit="m/s", description="Load-point velocity V_o.")
F_STAR = Limit("f_star", None, None, default=0.6, description="Reference friction coefficient f_*.")

# --- a spring-slider in SI as the request models accept it ------------------------------
# The HTTP request models (rsfapp.requests: PhysicalSI, PhysicalScales) and the CLI's SI
# options read these ranges.  They are a first gate on each value alone, in the units
# named by ``unit``; the rules between values (b > a, b <= 1e6 a, kappa = k Dc/(a sigma)
# <= 1e6, V_load/V_* <= 1e300) are checked by rsfcore.units.PhysicalInputs.  The upper
# ends are far beyond any laboratory or natural fault (Dc <= 1 km, sigma <= 1 TPa, slip
# rates <= 1 km/s) and keep every derived scale (Dc/V_*, a sigma) finite.
#: largest Dc [m] accepted by the request models
SI_DC_MAX_M: float = 1.0e3
#: largest effective normal stress sigma [Pa] accepted by the request models
SI_SIGMA_MAX_PA: float = 1.0e12
#: largest machine stiffness k [Pa/m] accepted by the request models (before the
#: cross-field rule kappa <= 1e6)
SI_K_MAX_PA_PER_M: float = 1.0e30
#: largest reference slip rate and load-point velocity [m/s] accepted by the request models
SI_V_MAX_M_S: float = 1.0e3
#: a (-): direct-effect coefficient, (0, 1]
SI_A = Limit("a", 0.0, 1.0, lo_open=True, description="Direct-effect coefficient a.")
#: b (-): evolution-effect coefficient, (0, 1e6]; the request models state (a, 1e6 a]
SI_B = Limit("b", 0.0, BA_MAX, lo_open=True, description="Evolution-effect coefficient b (b > a).")
#: Dc [m]: characteristic slip distance, (0, 1e3]
SI_DC_M = Limit(
    "Dc_m", 0.0, SI_DC_MAX_M, lo_open=True, unit="m", description="Characteristic slip distance Dc."
)
#: sigma [Pa]: effective normal stress, (0, 1e12]
SI_SIGMA_PA = Limit(
    "sigma_Pa",
    0.0,
    SI_SIGMA_MAX_PA,
    lo_open=True,
    unit="Pa",
    description="Effective normal stress sigma.",
)
#: k [Pa/m]: machine (spring) stiffness, [0, 1e30]; the request models state the
#: cross-field bound [0, 1e6 a sigma/Dc]
SI_K_PA_PER_M = Limit(
    "k_Pa_per_m",
    0.0,
    SI_K_MAX_PA_PER_M,
    unit="Pa/m",
    description="Machine (spring) stiffness k; kappa = k Dc/(a sigma).",
)
#: V_* [m/s]: reference slip rate, (0, 1e3]
SI_V_STAR_M_S = Limit(
    "V_star_m_s",
    0.0,
    SI_V_MAX_M_S,
    lo_open=True,
    unit="m/s",
    description="Reference slip rate V_*.",
)
#: V_load [m/s]: load-point velocity, [0, 1e3] (0 = stationary load point)
SI_V_LOAD_M_S = Limit(
    "V_load_m_s",
    0.0,
    SI_V_MAX_M_S,
    unit="m/s",
    description="Load-point velocity V_o (0 = stationary load point).",
)

#: every Limit above by (distinct) attribute name
LIMITS: dict[str, Limit] = {
    "BA": BA,
    "KAPPA": KAPPA,
    "KAPPA_RATIO": KAPPA_RATIO,
    "EPS": EPS,
    "VO": VO,
    "VELOCITY_JUMP_SIZE": VELOCITY_JUMP_SIZE,
    "LOAD_POINT_JUMP_SIZE": LOAD_POINT_JUMP_SIZE,
    "DIAGRAM_SIZE": DIAGRAM_SIZE,
    "RTOL": RTOL,
    "N_POINTS": N_POINTS,
    "T_END": T_END,
    "MAX_STEPS": MAX_STEPS,
    "PHI_START": PHI_START,
    "PSI_START": PSI_START,
    "A": A,
    "DC": DC,
    "SIGMA": SIGMA,
    "K": K,
    "V_STAR": V_STAR,
    "VO_SI": VO_SI,
    "F_STAR": F_STAR,
    "SI_A": SI_A,
    "SI_B": SI_B,
    "SI_DC_M": SI_DC_M,
    "SI_SIGMA_PA": SI_SIGMA_PA,
    "SI_K_PA_PER_M": SI_K_PA_PER_M,
    "SI_V_STAR_M_S": SI_V_STAR_M_S,
    "SI_V_LOAD_M_S": SI_V_LOAD_M_S,
}
