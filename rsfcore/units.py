"""SI <-> dimensionless conversions: the one place where lab units meet the model's groups.

A lab states a spring-slider in SI units,

    physical = {a, b, Dc_m, sigma_Pa, k_Pa_per_m, V_star_m_s, V_load_m_s}

(``V_load_m_s`` defaults to ``V_star_m_s``), while the numerical core works with the
dimensionless groups of `eq: characteristic scales` (Ciardo & Viesca):

    b/a,   kappa = k Dc/(a sigma),   v_o = V_load/V_*,   eps (evolution law, given separately),
    phi = ln(V/V_*),   psi = (tau - tau_*)/(a sigma),   T = V_* t/Dc,   s = delta/Dc.

This module converts parameters (:class:`PhysicalInputs` <-> :class:`rsfcore.params.Params`),
perturbations stated in SI (a velocity jump as a factor V/V_before or as a new slip rate
in m/s -> size d = ln(factor); a load-point jump as a new load-point velocity in m/s ->
size dv = V_new/V_load - 1) and answers (critical slip-rate factor and slip rate in m/s,
critical load-point velocity in m/s, times in s, stress changes in Pa, friction changes).
The lab convention for machine stiffness, friction per metre of load-point displacement
[1/m], is converted here too (k_Pa_per_m = k_per_m sigma, kappa = k_per_m Dc/a).

Accuracy: every conversion is one or two correctly rounded floating-point operations, so
a round trip SI -> dimensionless -> SI is exact to a few ulp (tested to 1e-14 relative in
tests/core/test_units.py); ln and exp are used directly on the ratio (d = ln(V_new/V_before),
never ln V_new - ln V_before) so that small jumps keep their relative accuracy.

Invalid input raises :class:`rsfcore.params.ParameterError` whose ``field`` is the
dotted name of the input (``"physical.b"``, ``"perturbation.new_slip_rate_m_s"``) and
whose ``valid`` states the range.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Literal

from .params import BA_MAX, KAPPA_MAX, VO_MAX, ParameterError, Params, PhysicalParams, check_range

if TYPE_CHECKING:
    from .trajectory import TrajectoryResult

__all__ = [
    "PHYSICAL_FIELDS",
    "PhysicalInputs",
    "VelocityJumpSI",
    "LoadPointJumpSI",
    "CriticalSI",
    "ClassifySI",
    "velocity_jump_size",
    "load_point_jump_size",
    "velocity_jump_si",
    "load_point_jump_si",
    "critical_si",
    "classify_si",
    "kappa_from_lab_stiffness",
    "SI_SIZE_FIELDS",
    "SI_SIZE_FOR_KIND",
    "size_from_si",
    "lab_stiffness_from_kappa",
    "lab_stiffness_to_Pa_per_m",
]

#: Field names of the SI parameter set, in the documented order (lab scripts rely on them).
PHYSICAL_FIELDS: tuple[str, ...] = (
    "a",
    "b",
    "Dc_m",
    "sigma_Pa",
    "k_Pa_per_m",
    "V_star_m_s",
    "V_load_m_s",
)

#: Largest |d| accepted for a velocity jump (same bound as rsfcore.trajectory.SIZE_MAX).
_D_MAX = 1.0e4


def _exp_or_none(x: float) -> float | None:
    """e^x, or None when it is not representable (x > 709.78)."""
    if x > 709.0:
        try:
            v = math.exp(x)
        except OverflowError:
            return None
        return v if math.isfinite(v) else None
    return math.exp(x)


def _finite_or_none(x: float | None) -> float | None:
    if x is None:
        return None
    x = float(x)
    return x if math.isfinite(x) else None


# ---------------------------------------------------------------------------------------
# Parameters
# ---------------------------------------------------------------------------------------
@dataclass(frozen=True)
class PhysicalInputs:
    """A spring-slider in SI units (`eq: characteristic scales`).

    Attributes:
        a: direct-effect coefficient (-), (0, 1].
        b: evolution-effect coefficient (-), b > a (rate weakening) and b <= 1e6 a.
        Dc_m: characteristic slip distance Dc [m], > 0.
        sigma_Pa: effective normal stress sigma [Pa], > 0.
        k_Pa_per_m: machine (spring) stiffness k [Pa/m], >= 0, with
            kappa = k Dc/(a sigma) <= 1e6.
        V_star_m_s: reference slip rate V_* [m/s], > 0.
        V_load_m_s: load-point velocity V_o [m/s], >= 0 (0: stationary load point),
            V_o/V_* <= 1e300; None (default) means V_o = V_*.

    Validation raises ParameterError with field ``"physical.<name>"``.
    """

    a: float
    b: float
    Dc_m: float
    sigma_Pa: float
    k_Pa_per_m: float
    V_star_m_s: float
    V_load_m_s: float | None = None

    def __post_init__(self) -> None:
        a = check_range("physical.a", self.a, 0.0, 1.0, lo_open=True)
        b_raw = self.b
        b = check_range("physical.b", b_raw, 0.0, None, lo_open=True)
        if not (b > a and b <= a * BA_MAX):
            raise ParameterError(
                "physical.b",
                b_raw,
                f"(a, {BA_MAX:g} a] = ({a!r}, {a * BA_MAX!r}] (b > a: rate weakening)",
            )
        Dc = check_range("physical.Dc_m", self.Dc_m, 0.0, None, lo_open=True)
        sigma = check_range("physical.sigma_Pa", self.sigma_Pa, 0.0, None, lo_open=True)
        k = check_range("physical.k_Pa_per_m", self.k_Pa_per_m, 0.0, None)
        Vs = check_range("physical.V_star_m_s", self.V_star_m_s, 0.0, None, lo_open=True)
        Vl = (
            Vs
            if self.V_load_m_s is None
            else check_range("physical.V_load_m_s", self.V_load_m_s, 0.0, None)
        )
        kappa = k * Dc / (a * sigma)
        if not kappa <= KAPPA_MAX:
            raise ParameterError(
                "physical.k_Pa_per_m",
                self.k_Pa_per_m,
                f"[0, {KAPPA_MAX:g} a sigma/Dc] = [0, {KAPPA_MAX * a * sigma / Dc:g}] Pa/m "
                f"(kappa = k Dc/(a sigma) <= {KAPPA_MAX:g})",
            )
        if not Vl / Vs <= VO_MAX:
            raise ParameterError(
                "physical.V_load_m_s", self.V_load_m_s, f"[0, {VO_MAX:g} V_star_m_s]"
            )
        for name, v in (
            ("a", a),
            ("b", b),
            ("Dc_m", Dc),
            ("sigma_Pa", sigma),
            ("k_Pa_per_m", k),
            ("V_star_m_s", Vs),
            ("V_load_m_s", Vl),
        ):
            object.__setattr__(self, name, v)

    # -- construction ----------------------------------------------------------------
    @classmethod
    def from_dict(cls, d: Mapping[str, Any], *, prefix: str = "physical") -> PhysicalInputs:
        """Build from a mapping with exactly the names of PHYSICAL_FIELDS (V_load_m_s optional).

        Unknown or missing names raise ParameterError naming ``"<prefix>.<name>"`` and
        listing the valid names.
        """
        if not isinstance(d, Mapping):
            raise ParameterError(prefix, d, "an object with fields " + ", ".join(PHYSICAL_FIELDS))
        for key in d:
            if key not in PHYSICAL_FIELDS:
                raise ParameterError(
                    f"{prefix}.{key}",
                    d[key],
                    "not a field; valid fields are " + ", ".join(PHYSICAL_FIELDS),
                )
        for key in PHYSICAL_FIELDS[:-1]:
            if key not in d:
                raise ParameterError(
                    f"{prefix}.{key}",
                    None,
                    "required ("
                    + ", ".join(PHYSICAL_FIELDS[:-1])
                    + " are required; V_load_m_s defaults to V_star_m_s)",
                )
        try:
            return cls(**{k: d[k] for k in PHYSICAL_FIELDS if k in d})
        except ParameterError as e:
            if prefix != "physical" and e.field.startswith("physical."):
                raise ParameterError(
                    prefix + e.field[len("physical") :], e.value, e.valid
                ) from None
            raise

    @classmethod
    def from_params(
        cls, p: Params, *, a: float, Dc_m: float, sigma_Pa: float, V_star_m_s: float
    ) -> PhysicalInputs:
        """Invert :meth:`to_params` given the scales a, Dc [m], sigma [Pa] and V_* [m/s].

        b = (b/a) a, k = kappa a sigma/Dc, V_load = v_o V_*.
        """
        if not isinstance(p, Params):
            raise ParameterError("params", p, "an rsfcore.Params")
        a = check_range("physical.a", a, 0.0, 1.0, lo_open=True)
        Dc = check_range("physical.Dc_m", Dc_m, 0.0, None, lo_open=True)
        sigma = check_range("physical.sigma_Pa", sigma_Pa, 0.0, None, lo_open=True)
        Vs = check_range("physical.V_star_m_s", V_star_m_s, 0.0, None, lo_open=True)
        return cls(
            a=a,
            b=p.ba * a,
            Dc_m=Dc,
            sigma_Pa=sigma,
            k_Pa_per_m=p.kappa * a * sigma / Dc,
            V_star_m_s=Vs,
            V_load_m_s=p.vo * Vs,
        )

    @classmethod
    def from_physical_params(cls, ph: PhysicalParams) -> PhysicalInputs:
        """From an rsfcore.params.PhysicalParams (eps and f_star are not part of this set)."""
        return cls(
            a=ph.a,
            b=ph.b,
            Dc_m=ph.Dc,
            sigma_Pa=ph.sigma,
            k_Pa_per_m=ph.k,
            V_star_m_s=ph.V_star,
            V_load_m_s=ph.Vo,
        )

    # -- dimensionless groups (`eq: characteristic scales`) ---------------------------
    @property
    def V_load(self) -> float:
        """Load-point velocity [m/s] (V_load_m_s with the default applied)."""
        v = self.V_load_m_s
        assert v is not None  # set in __post_init__
        return v

    @property
    def ba(self) -> float:
        """b/a (-)."""
        return self.b / self.a

    @property
    def kappa(self) -> float:
        """kappa = k Dc/(a sigma) (-)."""
        return self.k_Pa_per_m * self.Dc_m / (self.a * self.sigma_Pa)

    @property
    def vo(self) -> float:
        """v_o = V_load/V_* (-)."""
        return self.V_load / self.V_star_m_s

    @property
    def kappa_crit(self) -> float:
        """kappa_crit = b/a - 1 (`eq: dimensionless critical stiffness`)."""
        return self.ba - 1.0

    @property
    def k_crit_Pa_per_m(self) -> float:
        """Critical stiffness sigma (b - a)/Dc [Pa/m] (`eq: critical stiffness`)."""
        return self.sigma_Pa * (self.b - self.a) / self.Dc_m

    @property
    def time_scale_s(self) -> float:
        """Dc/V_* [s]: one unit of dimensionless time T."""
        return self.Dc_m / self.V_star_m_s

    @property
    def stress_scale_Pa(self) -> float:
        """a sigma [Pa]: one unit of dimensionless stress psi."""
        return self.a * self.sigma_Pa

    @property
    def slip_rate_before_m_s(self) -> float:
        """Steady slip rate before a perturbation [m/s]: V_load, or V_* when V_load = 0.

        (rsfcore.trajectory.start_point starts from steady state at v_o, or from the
        origin phi = 0, V = V_*, when the load point is stationary.)
        """
        return self.V_load if self.V_load > 0.0 else self.V_star_m_s

    def to_params(self, eps: float) -> Params:
        """Params(b/a, k Dc/(a sigma), eps, V_load/V_*); eps in [0, 1] (0 slip law, 1 aging law)."""
        return Params(ba=self.ba, kappa=self.kappa, eps=eps, vo=self.vo)

    def to_physical_params(self, eps: float, f_star: float = 0.6) -> PhysicalParams:
        """The same machine as an rsfcore.params.PhysicalParams (for rsfcore.protocols)."""
        return PhysicalParams(
            a=self.a,
            b=self.b,
            Dc_m=self.Dc_m,
            sigma_Pa=self.sigma_Pa,
            k_Pa_per_m=self.k_Pa_per_m,
            V_star_m_s=self.V_star_m_s,
            V_load_m_s=self.V_load,
            eps=eps,
            f_star=f_star,
        )

    def to_dict(self) -> dict[str, float]:
        """The seven SI fields (V_load_m_s with its default applied)."""
        return {
            "a": self.a,
            "b": self.b,
            "Dc_m": self.Dc_m,
            "sigma_Pa": self.sigma_Pa,
            "k_Pa_per_m": self.k_Pa_per_m,
            "V_star_m_s": self.V_star_m_s,
            "V_load_m_s": self.V_load,
        }

    # -- variables: dimensionless -> SI and back --------------------------------------
    def time_s(self, T: float) -> float:
        """t = T Dc/V_* [s]."""
        return T * self.Dc_m / self.V_star_m_s

    def T_from_time(self, t_s: float) -> float:
        """T = t V_*/Dc (-)."""
        return t_s * self.V_star_m_s / self.Dc_m

    def slip_m(self, s: float) -> float:
        """delta = s Dc [m]."""
        return s * self.Dc_m

    def slip_rate_m_s(self, phi: float) -> float | None:
        """V = V_* e^phi [m/s]; None when not representable (phi > ~709 - ln V_*)."""
        e = _exp_or_none(phi)
        if e is None:
            return None
        v = self.V_star_m_s * e
        return v if math.isfinite(v) else None

    def phi_from_slip_rate(self, V_m_s: float) -> float:
        """phi = ln(V/V_*) for V > 0 [m/s]."""
        V = check_range("V_m_s", V_m_s, 0.0, None, lo_open=True)
        return math.log(V / self.V_star_m_s)

    def shear_stress_change_Pa(self, psi: float) -> float:
        """tau - tau_* = a sigma psi [Pa]."""
        return self.a * self.sigma_Pa * psi

    def psi_from_shear_stress_change(self, dtau_Pa: float) -> float:
        """psi = (tau - tau_*)/(a sigma) (-)."""
        return dtau_Pa / (self.a * self.sigma_Pa)

    def friction_change(self, psi: float) -> float:
        """f - f_* = a psi (-)."""
        return self.a * psi


def kappa_from_lab_stiffness(k_per_m: float, Dc_m: float, a: float) -> float:
    """kappa = k Dc/a for a lab stiffness k in friction per metre of load-point displacement [1/m].

    (k [1/m] = k [Pa/m]/sigma, so sigma cancels in kappa = k Dc/(a sigma).)  inf stays inf.
    """
    return k_per_m * Dc_m / a


def lab_stiffness_from_kappa(kappa: float, Dc_m: float, a: float) -> float:
    """Lab stiffness k = kappa a/Dc [1/m] (inverse of :func:`kappa_from_lab_stiffness`)."""
    return kappa * a / Dc_m


def lab_stiffness_to_Pa_per_m(k_per_m: float, sigma_Pa: float) -> float:
    """k [Pa/m] = k [1/m] sigma [Pa]."""
    return k_per_m * sigma_Pa


# ---------------------------------------------------------------------------------------
# Perturbations stated in SI
# ---------------------------------------------------------------------------------------
def velocity_jump_size(
    phys: PhysicalInputs, *, factor: float | None = None, new_slip_rate_m_s: float | None = None
) -> float:
    """Size d of a velocity jump stated in SI: d = ln(factor) = ln(V_new/V_before).

    Exactly one of ``factor`` (V_new/V_before > 0) or ``new_slip_rate_m_s`` (V_new > 0 [m/s])
    must be given.  V_before is the steady slip rate before the jump,
    ``phys.slip_rate_before_m_s`` (V_load, or V_* when V_load = 0).  |d| <= 1e4.
    """
    if (factor is None) == (new_slip_rate_m_s is None):
        raise ParameterError(
            "perturbation",
            {"factor": factor, "new_slip_rate_m_s": new_slip_rate_m_s},
            "exactly one of factor (V_new/V_before) or new_slip_rate_m_s",
        )
    if factor is not None:
        f = check_range("perturbation.factor", factor, 0.0, None, lo_open=True)
        d = math.log(f)
        name, val = "perturbation.factor", factor
    else:
        V = check_range(
            "perturbation.new_slip_rate_m_s", new_slip_rate_m_s, 0.0, None, lo_open=True
        )
        d = math.log(V / phys.slip_rate_before_m_s)
        name, val = "perturbation.new_slip_rate_m_s", V
    if not abs(d) <= _D_MAX:
        raise ParameterError(name, val, f"a jump with |ln(V_new/V_before)| <= {_D_MAX:g}")
    return d


def load_point_jump_size(
    phys: PhysicalInputs,
    *,
    new_load_point_velocity_m_s: float | None = None,
    factor: float | None = None,
) -> float:
    """Size dv of a load-point jump stated in SI: dv = V_new/V_load - 1 (or factor - 1).

    Needs V_load > 0.  V_new > 0 [m/s] with V_new/V_* <= 1e300 (factor > 0 likewise).
    """
    if phys.V_load == 0.0:
        raise ParameterError(
            "physical.V_load_m_s",
            phys.V_load_m_s,
            "> 0 for a load-point jump (relative jump of a moving load point)",
        )
    if (factor is None) == (new_load_point_velocity_m_s is None):
        raise ParameterError(
            "perturbation",
            {"factor": factor, "new_load_point_velocity_m_s": new_load_point_velocity_m_s},
            "exactly one of new_load_point_velocity_m_s or factor (V_new/V_load)",
        )
    vmax = VO_MAX * phys.V_star_m_s
    if factor is not None:
        f = check_range("perturbation.factor", factor, 0.0, VO_MAX / phys.vo, lo_open=True)
        return f - 1.0
    V = check_range(
        "perturbation.new_load_point_velocity_m_s",
        new_load_point_velocity_m_s,
        0.0,
        vmax,
        lo_open=True,
    )
    return V / phys.V_load - 1.0


#: The names a perturbation size may be stated under in SI (instead of the dimensionless
#: size), in the documented order: the one list every door reads (request models, sweeps).
SI_SIZE_FIELDS: tuple[str, ...] = ("factor", "new_slip_rate_m_s", "new_load_point_velocity_m_s")
#: Which of them each perturbation kind reads (the other is refused naming it).
SI_SIZE_FOR_KIND: dict[str, tuple[str, ...]] = {
    "velocity-jump": ("factor", "new_slip_rate_m_s"),
    "load-point-jump": ("factor", "new_load_point_velocity_m_s"),
}
_KIND_WORDS = {"velocity-jump": "velocity jump", "load-point-jump": "load-point jump"}


def size_from_si(phys: PhysicalInputs, perturbation: str, name: str, value: float) -> float:
    """The dimensionless size of a perturbation stated in SI as ``name`` = ``value``
    (``factor``, ``new_slip_rate_m_s`` or ``new_load_point_velocity_m_s``): the one place
    that says which statement a kind reads and converts it (:func:`velocity_jump_size`,
    :func:`load_point_jump_size`).  ParameterError names ``perturbation.<name>``."""
    if perturbation not in SI_SIZE_FOR_KIND:
        raise ParameterError("perturbation", perturbation, "one of " + ", ".join(SI_SIZE_FOR_KIND))
    allowed = SI_SIZE_FOR_KIND[perturbation]
    if name not in allowed:
        raise ParameterError(
            f"perturbation.{name}",
            value,
            f"not used by a {_KIND_WORDS[perturbation]} (give {' or '.join(allowed)})",
        )
    if perturbation == "velocity-jump":
        return velocity_jump_size(phys, **{name: value})
    return load_point_jump_size(phys, **{name: value})


# ---------------------------------------------------------------------------------------
# Answers in SI
# ---------------------------------------------------------------------------------------
@dataclass(frozen=True)
class VelocityJumpSI:
    """A velocity jump of size d in SI.

    Attributes:
        d: size ln(V_new/V_before) (-), any finite value (a critical size may exceed
            the double range of e^d: d is then the answer's logarithm).
        factor: V_new/V_before = e^d (None if not representable, d > 709).
        slip_rate_before_m_s: steady slip rate before the jump [m/s].
        new_slip_rate_m_s: V_before e^d [m/s] (None if not representable).

    ``to_dict`` adds log10_factor = d/ln 10 and log10_new_slip_rate_m_s =
    log10(V_before) + d/ln 10, finite whenever d is.
    """

    d: float
    factor: float | None
    slip_rate_before_m_s: float
    new_slip_rate_m_s: float | None

    def to_dict(self) -> dict[str, float | None]:
        return {
            "d": self.d,
            "factor": self.factor,
            "log10_factor": self.d / math.log(10.0),
            "slip_rate_before_m_s": self.slip_rate_before_m_s,
            "new_slip_rate_m_s": self.new_slip_rate_m_s,
            "log10_new_slip_rate_m_s": math.log10(self.slip_rate_before_m_s)
            + self.d / math.log(10.0),
        }


@dataclass(frozen=True)
class LoadPointJumpSI:
    """A load-point jump of size dv in SI.

    Attributes:
        dv: relative jump (V_new - V_load)/V_load (-); None when beyond the double range
            (a critical size known only by its logarithm).
        log_factor: ln(V_new/V_load) = ln(1 + dv) (-), always finite.
        factor: V_new/V_load = 1 + dv (None if not representable).
        load_point_velocity_before_m_s: V_load [m/s].
        new_load_point_velocity_m_s: V_load (1 + dv) [m/s] (None if not representable).

    ``to_dict`` adds log10_factor = log_factor/ln 10 and
    log10_new_load_point_velocity_m_s = log10(V_load) + log_factor/ln 10.
    """

    dv: float | None
    log_factor: float
    factor: float | None
    load_point_velocity_before_m_s: float
    new_load_point_velocity_m_s: float | None

    def to_dict(self) -> dict[str, float | None]:
        return {
            "dv": _finite_or_none(self.dv),
            "factor": self.factor,
            "log_factor": self.log_factor,
            "log10_factor": self.log_factor / math.log(10.0),
            "load_point_velocity_before_m_s": self.load_point_velocity_before_m_s,
            "new_load_point_velocity_m_s": self.new_load_point_velocity_m_s,
            "log10_new_load_point_velocity_m_s": math.log10(self.load_point_velocity_before_m_s)
            + self.log_factor / math.log(10.0),
        }


def velocity_jump_si(phys: PhysicalInputs, d: float) -> VelocityJumpSI:
    """Velocity jump of size d (ln units, any finite value) in SI: factor e^d and new slip
    rate V_before e^d [m/s] (None where not representable; d itself is the logarithm)."""
    d = check_range("d", d)
    f = _exp_or_none(d)
    Vb = phys.slip_rate_before_m_s
    Vn = None if f is None else _finite_or_none(Vb * f)
    return VelocityJumpSI(d=d, factor=f, slip_rate_before_m_s=Vb, new_slip_rate_m_s=Vn)


def load_point_jump_si(
    phys: PhysicalInputs, dv: float | None = None, *, log_factor: float | None = None
) -> LoadPointJumpSI:
    """Load-point jump in SI: new load-point velocity V_load (1 + dv) [m/s].

    Give ``dv`` > -1 (finite), or ``log_factor`` = ln(1 + dv) (any finite value) for a
    size beyond the double range (a critical size's ``log_critical_size``); with both,
    ``log_factor`` is the one used for the logarithms."""
    if dv is None and log_factor is None:
        raise ParameterError("dv", None, "dv > -1 or log_factor = ln(1 + dv) finite")
    if dv is not None and log_factor is not None and not math.isfinite(dv):
        dv = None  # beyond the double range: the logarithm states it
    if dv is not None:
        dv = check_range("dv", dv, -1.0, None, lo_open=True)
    if log_factor is not None:
        lf = check_range("log_factor", log_factor)
    else:
        assert dv is not None
        lf = math.log1p(dv)
    if dv is None:
        e = _exp_or_none(lf)
        dv = None if e is None else e - 1.0
    f = None if dv is None else _finite_or_none(1.0 + dv)
    Vn = None if f is None else _finite_or_none(phys.V_load * f)
    return LoadPointJumpSI(
        dv=dv,
        log_factor=lf,
        factor=f,
        load_point_velocity_before_m_s=phys.V_load,
        new_load_point_velocity_m_s=Vn,
    )


@dataclass(frozen=True)
class CriticalSI:
    """Critical perturbation of one kind, dimensionless and in SI.

    Attributes:
        perturbation: "velocity-jump" | "load-point-jump".
        kind: "zero" | "finite" | "infinite" (rsfcore.critical.KINDS).
        critical_size: d_crit (velocity jump, ln units) or dv_crit (load-point jump);
            0.0 for "zero", None for "infinite".
        rel_accuracy: relative accuracy of critical_size (from rsfcore.critical).
        method: how it was obtained (rsfcore.critical.METHODS).
        on_boundary: parameter point on x = 1 or kappa = kappa_crit up to rounding.
        velocity_jump: the critical velocity jump in SI (factor and new slip rate [m/s]),
            for kind "finite" or "zero" of a velocity jump, else None.
        load_point_jump: the critical load-point jump in SI (new load-point velocity
            [m/s]), for kind "finite" or "zero" of a load-point jump, else None.
    """

    perturbation: str
    kind: str
    critical_size: float | None
    rel_accuracy: float
    method: str
    on_boundary: bool
    velocity_jump: VelocityJumpSI | None
    load_point_jump: LoadPointJumpSI | None

    def to_dict(self) -> dict[str, Any]:
        return {
            "perturbation": self.perturbation,
            "kind": self.kind,
            "critical_size": _finite_or_none(self.critical_size),
            "rel_accuracy": float(self.rel_accuracy),
            "method": self.method,
            "on_boundary": self.on_boundary,
            "velocity_jump": None if self.velocity_jump is None else self.velocity_jump.to_dict(),
            "load_point_jump": None
            if self.load_point_jump is None
            else self.load_point_jump.to_dict(),
        }


def critical_si(
    phys: PhysicalInputs,
    eps: float,
    perturbation: Literal["velocity-jump", "load-point-jump"] = "velocity-jump",
    *,
    rtol: float = 1e-10,
) -> CriticalSI:
    """rsfcore.critical.critical_perturbation on ``phys.to_params(eps)``, answered also in SI.

    The dimensionless answer is exactly the one of critical_perturbation on the same
    Params (no other arithmetic happens before the call); the SI values are
    V_before e^d_crit [m/s] and V_load (1 + dv_crit) [m/s].
    """
    from .critical import critical_perturbation

    p = phys.to_params(eps)
    r = critical_perturbation(p, perturbation, rtol=rtol)
    vj: VelocityJumpSI | None = None
    lj: LoadPointJumpSI | None = None
    if perturbation == "velocity-jump":
        if r.critical_size is not None:
            vj = velocity_jump_si(phys, r.critical_size)
    elif r.log_critical_size is not None and math.isfinite(r.log_critical_size):
        lj = load_point_jump_si(phys, r.critical_size, log_factor=r.log_critical_size)
    return CriticalSI(
        perturbation=r.perturbation,
        kind=r.kind,
        critical_size=r.critical_size,
        rel_accuracy=float(r.rel_accuracy),
        method=r.method,
        on_boundary=bool(r.on_boundary),
        velocity_jump=vj,
        load_point_jump=lj,
    )


@dataclass(frozen=True)
class ClassifySI:
    """Outcome of one perturbation stated in SI.

    Attributes:
        outcome: "stable" | "unstable"; certificate: how it was certified.
        size: the dimensionless perturbation size used (d or dv).
        blowup_time_s, return_time_s, peak_time_s: times [s] after the perturbation
            (None when not applicable or not final).
        peak_slip_rate_m_s: true peak slip rate [m/s] (None for a runaway).
        rel_accuracy: relative accuracy of times and peak (rsfcore.trajectory).
        result: the dimensionless rsfcore.trajectory.TrajectoryResult.
    """

    outcome: str
    certificate: str
    size: float
    blowup_time_s: float | None
    return_time_s: float | None
    peak_time_s: float | None
    peak_slip_rate_m_s: float | None
    rel_accuracy: float
    result: TrajectoryResult

    def to_dict(self) -> dict[str, Any]:
        return {
            "outcome": self.outcome,
            "certificate": self.certificate,
            "size": self.size,
            "blowup_time_s": self.blowup_time_s,
            "return_time_s": self.return_time_s,
            "peak_time_s": self.peak_time_s,
            "peak_slip_rate_m_s": self.peak_slip_rate_m_s,
            "rel_accuracy": float(self.rel_accuracy),
        }


def classify_si(
    phys: PhysicalInputs,
    eps: float,
    perturbation: Literal["velocity-jump", "load-point-jump"] = "velocity-jump",
    *,
    factor: float | None = None,
    new_slip_rate_m_s: float | None = None,
    new_load_point_velocity_m_s: float | None = None,
    rtol: float = 1e-10,
) -> ClassifySI:
    """rsfcore.trajectory.classify of a perturbation stated in SI, with times in seconds.

    velocity-jump: ``factor`` or ``new_slip_rate_m_s``; load-point-jump:
    ``new_load_point_velocity_m_s`` or ``factor``.  The dimensionless call is exactly
    classify(phys.to_params(eps), perturbation, size) with the size of
    :func:`velocity_jump_size` / :func:`load_point_jump_size`.
    """
    from .trajectory import classify

    stated = {
        k: v
        for k, v in (
            ("factor", factor),
            ("new_slip_rate_m_s", new_slip_rate_m_s),
            ("new_load_point_velocity_m_s", new_load_point_velocity_m_s),
        )
        if v is not None
    }
    if perturbation not in SI_SIZE_FOR_KIND:
        raise ParameterError("perturbation", perturbation, "one of " + ", ".join(SI_SIZE_FOR_KIND))
    wrong = [k for k in stated if k not in SI_SIZE_FOR_KIND[perturbation]]
    if wrong:  # named before counting, as a request with the other kind's unit is told
        size_from_si(phys, perturbation, wrong[0], stated[wrong[0]])
    if len(stated) != 1:
        raise ParameterError(
            "perturbation", stated, "exactly one of " + ", ".join(SI_SIZE_FOR_KIND[perturbation])
        )
    ((name, value),) = stated.items()
    size = size_from_si(phys, perturbation, name, value)
    r = classify(phys.to_params(eps), perturbation, size, rtol=rtol)

    def ts(T: float | None) -> float | None:
        return None if T is None or not math.isfinite(T) else phys.time_s(T)

    peak = phys.slip_rate_m_s(r.peak_phi) if math.isfinite(r.peak_phi) else None
    return ClassifySI(
        outcome=r.outcome,
        certificate=r.certificate,
        size=size,
        blowup_time_s=ts(r.blowup_time),
        return_time_s=ts(r.return_time),
        peak_time_s=ts(r.peak_time),
        peak_slip_rate_m_s=peak,
        rel_accuracy=float(r.rel_accuracy),
        result=r,
    )
