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
        vo: V_o/V_*, load-point velocity; 0 (stationary load point) or [1e-300, 1e300]
            (limits.VO_MIN: below it times, ~1/v_o, leave the double range).
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
        if 0.0 < self.vo < lim.VO_MIN:
            raise ParameterError("vo", self.vo, lim.VO_VALID_TEXT)

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


#: The older keyword names of PhysicalParams (accepted with a DeprecationWarning).
_OLD_NAMES: dict[str, str] = {
    "Dc": "Dc_m",
    "sigma": "sigma_Pa",
    "k": "k_Pa_per_m",
    "V_star": "V_star_m_s",
    "Vo": "V_load_m_s",
}


def _renamed(old: dict[str, float], where: str) -> dict[str, float]:
    """The new names of old-style keywords, warning once per call that they are deprecated."""
    if not old:
        return {}
    bad = sorted(set(old) - set(_OLD_NAMES))
    if bad:
        raise TypeError(f"{where}() got an unexpected keyword argument {bad[0]!r}")
    import warnings

    names = ", ".join(f"{k} -> {_OLD_NAMES[k]}" for k in old)
    warnings.warn(
        f"{where}: the SI names are spelled as over HTTP now ({names}); the old keywords "
        "will be removed",
        DeprecationWarning,
        stacklevel=3,
    )
    return {_OLD_NAMES[k]: v for k, v in old.items()}


@dataclass(frozen=True, init=False)
class PhysicalParams:
    """Physical spring-slider parameters in SI units, spelled as over HTTP and the CLI
    (``a, b, Dc_m, sigma_Pa, k_Pa_per_m, V_star_m_s, V_load_m_s``; rsfcore.units
    .PhysicalInputs is the same machine without eps and f_star).

    Attributes:
        a: direct-effect coefficient (-), (0, 1].
        b: evolution-effect coefficient (-), b > a (rate weakening), b <= 1e6 a.
        Dc_m: characteristic slip distance [m], > 0.
        sigma_Pa: normal stress [Pa], > 0.
        k_Pa_per_m: spring stiffness per unit area [Pa/m], >= 0.
        V_star_m_s: reference slip rate V_* [m/s], > 0.
        V_load_m_s: load-point velocity [m/s], >= 0 (default: V_star_m_s).
        eps: evolution-law parameter (-), [0, 1] (default rsfcore.limits.EPS.default).
        f_star: reference friction coefficient f_* (-), used only to report absolute
            friction f = f_* + a psi (psi = (tau - tau_*)/(a sigma)).

    Deprecated: the keywords ``Dc, sigma, k, V_star, Vo`` (accepted with a
    DeprecationWarning) and the read-only attributes of those names (no warning; the
    numerical modules use them).
    """

    a: float
    b: float
    Dc_m: float
    sigma_Pa: float
    k_Pa_per_m: float
    V_star_m_s: float
    V_load_m_s: float
    eps: float
    f_star: float = field(default=0.6)

    def __init__(
        self,
        a: float,
        b: float,
        Dc_m: float | None = None,
        sigma_Pa: float | None = None,
        k_Pa_per_m: float | None = None,
        V_star_m_s: float | None = None,
        V_load_m_s: float | None = None,
        eps: float | None = None,
        f_star: float | None = None,
        **old: float,
    ) -> None:
        given = {
            "Dc_m": Dc_m,
            "sigma_Pa": sigma_Pa,
            "k_Pa_per_m": k_Pa_per_m,
            "V_star_m_s": V_star_m_s,
            "V_load_m_s": V_load_m_s,
        }
        for new, v in _renamed(old, "PhysicalParams").items():
            if given[new] is not None:
                raise TypeError(f"PhysicalParams() got {new!r} twice (old and new name)")
            given[new] = v
        for name in ("Dc_m", "sigma_Pa", "k_Pa_per_m", "V_star_m_s"):
            if given[name] is None:
                raise TypeError(f"PhysicalParams() missing required argument: {name!r}")
        if given["V_load_m_s"] is None:
            given["V_load_m_s"] = given["V_star_m_s"]
        object.__setattr__(self, "a", a)
        object.__setattr__(self, "b", b)
        for name, value in given.items():
            object.__setattr__(self, name, value)
        object.__setattr__(self, "eps", lim.EPS.default if eps is None else eps)
        object.__setattr__(self, "f_star", lim.F_STAR.default if f_star is None else f_star)
        self.__post_init__()

    def __post_init__(self) -> None:
        a = lim.A.check(self.a)
        b = check_range("b", self.b, a, a * BA_MAX, lo_open=True)
        object.__setattr__(self, "a", a)
        object.__setattr__(self, "b", b)
        object.__setattr__(self, "Dc_m", lim.DC.check(self.Dc_m))
        object.__setattr__(self, "sigma_Pa", lim.SIGMA.check(self.sigma_Pa))
        object.__setattr__(self, "k_Pa_per_m", lim.K.check(self.k_Pa_per_m))
        object.__setattr__(self, "V_star_m_s", lim.V_STAR.check(self.V_star_m_s))
        object.__setattr__(self, "V_load_m_s", lim.VO_SI.check(self.V_load_m_s))
        object.__setattr__(self, "eps", lim.EPS.check(self.eps))
        object.__setattr__(self, "f_star", _finite("f_star", self.f_star))
        # Validate the dimensionless image too, so that out-of-range combinations are
        # reported here with the physical field names.
        kappa = self.k * self.Dc / (self.a * self.sigma)
        if kappa > KAPPA_MAX:
            raise ParameterError("k_Pa_per_m", self.k, f"k*Dc/(a*sigma) <= {KAPPA_MAX:g}")
        if self.Vo / self.V_star > VO_MAX:
            raise ParameterError("V_load_m_s", self.Vo, f"V_load/V_star <= {VO_MAX:g}")

    # -- the older names (read-only; the numerical modules use them) -------------------
    @property
    def Dc(self) -> float:  # noqa: N802
        """Dc_m [m]."""
        return self.Dc_m

    @property
    def sigma(self) -> float:
        """sigma_Pa [Pa]."""
        return self.sigma_Pa

    @property
    def k(self) -> float:
        """k_Pa_per_m [Pa/m]."""
        return self.k_Pa_per_m

    @property
    def V_star(self) -> float:  # noqa: N802
        """V_star_m_s [m/s]."""
        return self.V_star_m_s

    @property
    def Vo(self) -> float:  # noqa: N802
        """V_load_m_s [m/s]."""
        return self.V_load_m_s

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
        Dc_m: float | None = None,
        sigma_Pa: float | None = None,
        V_star_m_s: float | None = None,
        f_star: float | None = None,
        **old: float,
    ) -> PhysicalParams:
        """Invert :meth:`to_dimensionless` given the scales a, Dc_m [m], sigma_Pa [Pa],
        V_star_m_s [m/s] (the older keywords Dc, sigma, V_star are deprecated)."""
        given = {"Dc_m": Dc_m, "sigma_Pa": sigma_Pa, "V_star_m_s": V_star_m_s}
        for new, v in _renamed(old, "PhysicalParams.from_dimensionless").items():
            if new not in given or given[new] is not None:
                raise TypeError(f"from_dimensionless() got an unexpected or repeated {new!r}")
            given[new] = v
        a = lim.A.check(a)
        Dc = lim.DC.check(given["Dc_m"])
        sigma = lim.SIGMA.check(given["sigma_Pa"])
        V_star = lim.V_STAR.check(given["V_star_m_s"])
        return cls(
            a=a,
            b=p.ba * a,
            Dc_m=Dc,
            sigma_Pa=sigma,
            k_Pa_per_m=p.kappa * a * sigma / Dc,
            V_star_m_s=V_star,
            V_load_m_s=p.vo * V_star,
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
