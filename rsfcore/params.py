"""Model parameters in dimensionless and physical form, with validation.

Dimensionless groups follow `eq: characteristic scales` of Ciardo & Viesca:

    kappa = k Dc / (a sigma),  psi = (tau - tau_*) / (a sigma),  phi = ln(V / V_*),
    v_o = V_o / V_*,           T = V_* t / Dc,

and the rate-weakening ratio ``ba = b/a`` together with the evolution-law parameter
``eps`` of `eq: intermediate state evolution law` (eps -> 0 slip law, eps = 1 aging law).
The linear-stability critical stiffness is `eq: dimensionless critical stiffness`,
kappa_crit = b/a - 1.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

from . import limits as lim
from .errors import ParameterError
from .limits import BA_MAX, KAPPA_MAX, VO_MAX, check_range

__all__ = [
    "ParameterError",
    "Params",
    "PhysicalParams",
    "BA_MAX",
    "KAPPA_MAX",
    "VO_MAX",
    "check_range",
]

# BA_MAX (largest b/a), KAPPA_MAX (largest kappa) and VO_MAX (largest v_o) and every other
# range live in rsfcore.limits; they are re-exported here for old import paths.


def _finite(name: str, value: float) -> float:
    return lim.check_finite(name, value)


@dataclass(frozen=True)
class Params:
    """Dimensionless spring-slider parameters (`eq:psi_T`, `eq:phi_T`).

    Attributes:
        ba: b/a, rate-weakening ratio; valid range (1, 1e6].
        kappa: k Dc/(a sigma), absolute dimensionless stiffness; valid range [0, 1e6].
        eps: evolution-law parameter of `eq: intermediate state evolution law`;
            [0, 1], 0 = slip law (exact limit), 1 = aging law.
        vo: V_o/V_*, load-point velocity; 0 (stationary load point) or (0, 1e300].
    """

    ba: float
    kappa: float
    eps: float
    vo: float = 1.0

    def __post_init__(self) -> None:
        object.__setattr__(self, "ba", lim.BA.check(self.ba))
        object.__setattr__(self, "kappa", lim.KAPPA.check(self.kappa))
        object.__setattr__(self, "eps", lim.EPS.check(self.eps))
        object.__setattr__(self, "vo", lim.VO.check(self.vo))

    @classmethod
    def from_ratio(cls, ba: float, kappa_ratio: float, eps: float, vo: float = 1.0) -> Params:
        """Build from kappa/kappa_crit instead of kappa (kappa_ratio in [0, 1e6/(ba-1)])."""
        ba = lim.BA.check(ba)
        r = lim.KAPPA_RATIO.check(kappa_ratio)
        return cls(ba=ba, kappa=r * (ba - 1.0), eps=eps, vo=vo)

    @property
    def kappa_crit(self) -> float:
        """kappa_crit = b/a - 1 (`eq: dimensionless critical stiffness`)."""
        return self.ba - 1.0

    @property
    def kappa_ratio(self) -> float:
        """kappa / kappa_crit."""
        return self.kappa / self.kappa_crit

    def with_(self, **changes: float) -> Params:
        """Copy with some fields changed (validated again)."""
        return replace(self, **changes)

    def as_dict(self) -> dict[str, float]:
        return {"ba": self.ba, "kappa": self.kappa, "eps": self.eps, "vo": self.vo}


@dataclass(frozen=True)
class PhysicalParams:
    """Physical spring-slider parameters in SI units.

    Attributes:
        a: direct-effect coefficient (-), (0, 1].
        b: evolution-effect coefficient (-), b > a (rate weakening), b <= 1e6 a.
        Dc: characteristic slip distance [m], > 0.
        sigma: normal stress [Pa], > 0.
        k: spring stiffness per unit area [Pa/m], >= 0.
        V_star: reference slip rate V_* [m/s], > 0.
        Vo: load-point velocity [m/s], >= 0.
        eps: evolution-law parameter (-), [0, 1].
        f_star: reference friction coefficient f_* (-), used only to report absolute
            friction f = f_* + a psi (psi = (tau - tau_*)/(a sigma)).
    """

    a: float
    b: float
    Dc: float
    sigma: float
    k: float
    V_star: float
    Vo: float
    eps: float
    f_star: float = field(default=0.6)

    def __post_init__(self) -> None:
        a = lim.A.check(self.a)
        b = check_range("b", self.b, a, a * BA_MAX, lo_open=True)
        object.__setattr__(self, "a", a)
        object.__setattr__(self, "b", b)
        object.__setattr__(self, "Dc", lim.DC.check(self.Dc))
        object.__setattr__(self, "sigma", lim.SIGMA.check(self.sigma))
        object.__setattr__(self, "k", lim.K.check(self.k))
        object.__setattr__(self, "V_star", lim.V_STAR.check(self.V_star))
        object.__setattr__(self, "Vo", lim.VO_SI.check(self.Vo))
        object.__setattr__(self, "eps", lim.EPS.check(self.eps))
        object.__setattr__(self, "f_star", _finite("f_star", self.f_star))
        # Validate the dimensionless image too, so that out-of-range combinations are
        # reported here with the physical field names.
        kappa = self.k * self.Dc / (self.a * self.sigma)
        if kappa > KAPPA_MAX:
            raise ParameterError("k", self.k, f"k*Dc/(a*sigma) <= {KAPPA_MAX:g}")
        if self.Vo / self.V_star > VO_MAX:
            raise ParameterError("Vo", self.Vo, f"Vo/V_star <= {VO_MAX:g}")

    # -- scales (`eq: characteristic scales`) ---------------------------------------
    @property
    def time_scale(self) -> float:
        """Dc / V_* [s]: one unit of dimensionless time T."""
        return self.Dc / self.V_star

    @property
    def stress_scale(self) -> float:
        """a sigma [Pa]: one unit of dimensionless stress psi."""
        return self.a * self.sigma

    @property
    def k_crit(self) -> float:
        """Critical stiffness sigma (b - a)/Dc [Pa/m] (`eq: critical stiffness`)."""
        return self.sigma * (self.b - self.a) / self.Dc

    def to_dimensionless(self) -> Params:
        """(a, b, Dc, sigma, k, V*, Vo, eps) -> Params(ba, kappa, eps, vo)."""
        return Params(
            ba=self.b / self.a,
            kappa=self.k * self.Dc / (self.a * self.sigma),
            eps=self.eps,
            vo=self.Vo / self.V_star,
        )

    @classmethod
    def from_dimensionless(
        cls,
        p: Params,
        *,
        a: float,
        Dc: float,
        sigma: float,
        V_star: float,
        f_star: float = 0.6,
    ) -> PhysicalParams:
        """Invert :meth:`to_dimensionless` given the scales a, Dc [m], sigma [Pa], V_* [m/s]."""
        a = lim.A.check(a)
        Dc = lim.DC.check(Dc)
        sigma = lim.SIGMA.check(sigma)
        V_star = lim.V_STAR.check(V_star)
        return cls(
            a=a,
            b=p.ba * a,
            Dc=Dc,
            sigma=sigma,
            k=p.kappa * a * sigma / Dc,
            V_star=V_star,
            Vo=p.vo * V_star,
            eps=p.eps,
            f_star=f_star,
        )

    # -- variable conversions -------------------------------------------------------
    def velocity(self, phi: float) -> float:
        """Slip rate V = V_* e^phi [m/s]."""
        return self.V_star * math.exp(phi)

    def friction(self, psi: float) -> float:
        """Friction coefficient f = f_* + a psi (-)."""
        return self.f_star + self.a * psi

    def shear_stress_change(self, psi: float) -> float:
        """tau - tau_* = a sigma psi [Pa]."""
        return self.a * self.sigma * psi

    def time(self, T: float) -> float:
        """Physical time t = T Dc/V_* [s]."""
        return T * self.time_scale

    def slip(self, s: float) -> float:
        """Slip delta = s Dc [m]."""
        return s * self.Dc
