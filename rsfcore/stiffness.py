"""Equivalent stiffness of a continuum frictional interface (Ciardo & Viesca).

The spring-slider results carry over to a fault once the elastic operator L of the
fault is replaced by an equivalent spring: an eigenstiffness k with L[delta] = k delta
(`eq: eigenequation`).  Table `tab: table` lists five configurations; each gives
k = eta * k_* with a dimensionless eigenvalue eta = k/k_*:

    case  configuration                               k_*          eta (smallest)
    A     infinite interface, unbounded medium        mu'/lambda   2 pi
    B     interface of length 2L, unbounded medium    mu'/L        1.1577738836976 (computed)
    C     infinite interface at depth h << lambda     E'h/lambda^2 4 pi^2
    D     interface 2L at depth h << L                E'h/L^2      (pi/2)^2
    E     circular interface of radius R, nu = 0      mu/R         1.0030595164694 (computed)

Equating k with the spring-slider critical stiffness k_crit = sigma (b - a)/Dc gives
the critical dimensions of `eq: critical dimensions` (lambda_c, L_c or R_c).

Numerical method (cases B and E): Ritz-Galerkin in a basis that carries the
square-root tip behaviour, in which the operator acts in closed form, so no singular
quadrature is needed and every matrix entry is exact to rounding.

* B, operator (1/pi) int_{-1}^{1} delta'(s)/(x - s) ds (`eq: eigenvalue problem
  Uenishi-Rice`).  Basis sin(j theta) = sqrt(1 - x^2) U_{j-1}(x), x = cos theta,
  j = 1..n.  Because d/dx[sqrt(1-x^2) U_{j-1}] = -j T_j/sqrt(1-x^2) and the finite
  Hilbert transform (1/pi) int T_j(s)/(sqrt(1-s^2)(s - x)) ds = U_{j-1}(x), the operator
  maps the j-th basis function to j U_{j-1}(x).  Stiffness matrix diag(j pi/2); mass
  matrix int_0^pi sin(i t) sin(j t) sin t dt in closed form.
* E, operator of `eq: eigenequation circular`, i.e. (1/2)(-Delta)^{1/2} on the unit
  disk acting on radial slip (for nu = 0 a unidirectional shear slip has the isotropic
  Fourier symbol (mu/2)|xi|).  Basis sqrt(1 - r^2) P_j^{(1/2,0)}(2r^2 - 1), j = 0..n-1,
  which the operator maps to (Gamma(j+3/2)/Gamma(j+1))^2 P_j^{(1/2,0)}(2r^2 - 1)
  (Dyda, Kuznetsov & Kwasnicki 2017, closed form for (-Delta)^s on the ball).  With
  the area weight r dr the stiffness matrix is diagonal by Jacobi orthogonality; the
  mass matrix is integrated exactly by Gauss-Legendre quadrature.  That this action is
  the one of the printed elliptic-integral kernel is checked by
  :func:`circular_operator`, a direct quadrature of the printed operator.

Convergence (measured against the reference values, double precision):
the error of the smallest eigenvalue decays *algebraically*, as n^-6, not
geometrically.  For B the eigenvector coefficients fall off like j^-4
(j^4 c_j -> -2.108 with c_1 = 1), the signature of a sqrt(d) * d log d term at the
tips (d = distance to the tip), so the eigenfunction is not sqrt(d) times an analytic
function and no polynomial basis of this kind converges geometrically; E shows the
same n^-6 rate.  Doubling n divides the error by 64.  Errors of eta_0:

    n      8        16       32       64       128
    B   1.3e-6   2.3e-8   3.8e-10  6.1e-12  9.5e-14
    E   4.8e-8   8.9e-10  1.5e-11  2.4e-13  3.3e-15

``N_FOR_1E12`` holds the smallest n whose error (and that of every larger n) is
below 1e-12; ``DEFAULT_N`` is the n used when none is given (error ~1e-15, a few ms).

Checks of the paper's printed material (see also the module tests):

* B: the printed 1.157773882... is not converged in the 9th digit; the value is
  1.1577738836976 (this Ritz solver, an independent collocation, and the reference values).
* E: the printed kernel of `eq: functional circular` / `eq: eigenequation circular` is
  right as printed (minus sign between the E and F terms) provided f(U) is read as the
  *modulus* k of the complete elliptic integrals, i.e. scipy's parameter m = f^2.  With
  m = f, or with a plus sign, it does not map sqrt(1 - r^2) to the constant pi/4 it must
  (the penny-crack solution).  The only typo is ``\\bar{s+1}`` for ``\\bar{s}+1``.
* The sentence after the table reads "mu' = mu/2(1-nu) in mode II and mu'/2 in
  mode III"; the mode III value is mu/2 (as in the table caption).
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Callable
from functools import lru_cache

import numpy as np

from .params import ParameterError, check_range

__all__ = [
    "CASES",
    "DEFAULT_N",
    "N_FOR_1E12",
    "eigen_stiffness",
    "eigen_mode",
    "circular_operator",
    "critical_dimension",
    "stiffness_of_fault",
    "kappa_of_fault",
    "stiffness_summary",
]

CASES = ("A", "B", "C", "D", "E")
#: Basis size used when ``n`` is not given (error of eta_0 ~1e-15).
DEFAULT_N = {"B": 256, "E": 128}
#: Smallest basis size that delivers |eta_0 - exact| < 1e-12 (and so does every larger n).
N_FOR_1E12 = {"B": 87, "E": 51}

_K_STAR = {"A": "mu'/lambda", "B": "mu'/L", "C": "E'h/lambda^2", "D": "E'h/L^2", "E": "mu/R"}
_DIM_NAME = {"A": "lambda_c", "B": "L_c", "C": "lambda_c", "D": "L_c", "E": "R_c"}
_SIZE_NAME = {"A": "lambda", "B": "L", "C": "lambda", "D": "L", "E": "R"}
_THIN_SLAB = ("C", "D")  # operator -E' h d2/dx2, needs the depth h


# --------------------------------------------------------------------------- validation
def _check_case(case: str) -> str:
    c = case.strip().upper() if isinstance(case, str) else None
    if c not in CASES:
        raise ParameterError("case", case, "one of 'A', 'B', 'C', 'D', 'E' (tab: table)")
    return c


def _check_mode(case: str, mode: int) -> int:
    if isinstance(mode, bool) or not isinstance(mode, (int, np.integer)) or mode < 0:
        raise ParameterError("mode", mode, "an integer >= 0 (0 = smallest eigenvalue)")
    if case in ("A", "C") and mode > 0:
        raise ParameterError(
            "mode",
            mode,
            f"0 only: case {case} is unbounded, its spectrum is continuous "
            "(k/k_* holds for every wavelength) and has no discrete higher modes",
        )
    return int(mode)


def _check_n(case: str, mode: int, n: int | None) -> int:
    if n is None:
        n = DEFAULT_N[case]
    if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or not mode < n <= 4096:
        raise ParameterError("n", n, f"an integer with mode < n <= 4096 (mode = {mode})")
    return int(n)


def _check_slip_mode(mode_of_slip: str) -> str:
    m = mode_of_slip.strip().upper() if isinstance(mode_of_slip, str) else None
    if m not in ("II", "III"):
        raise ParameterError("mode_of_slip", mode_of_slip, "'II' (in-plane) or 'III' (anti-plane)")
    return m


# --------------------------------------------------------------------------- eigen-solvers
def _jacobi_half0(nmax: int, t: np.ndarray) -> np.ndarray:
    """P_j^{(1/2,0)}(t) for j = 0..nmax-1 (rows) by the three-term recurrence."""
    al, be = 0.5, 0.0
    p = np.empty((nmax, t.size))
    p[0] = 1.0
    if nmax > 1:
        p[1] = (al + 1.0) + (al + be + 2.0) * (t - 1.0) / 2.0
    for j in range(2, nmax):
        s = 2 * j + al + be
        a1 = 2 * j * (j + al + be) * (s - 2)
        a2 = (s - 1) * (s * (s - 2) * t + al * al - be * be)
        a3 = 2 * (j + al - 1) * (j + be - 1) * s
        p[j] = (a2 * p[j - 1] - a3 * p[j - 2]) / a1
    return p


@lru_cache(maxsize=16)
def _solve(case: str, n: int) -> tuple[np.ndarray, np.ndarray]:
    """Eigenvalues (ascending) and basis coefficients (columns) for case B or E."""
    if case == "B":
        j = np.arange(1, n + 1)

        # c(m) = int_0^pi cos(m t) sin t dt = (1 + (-1)^m)/(1 - m^2), and 0 for |m| = 1
        def c(m: np.ndarray) -> np.ndarray:
            m = np.abs(m)
            return np.where(m % 2 == 0, 2.0 / (1.0 - m.astype(float) ** 2 + (m == 1)), 0.0)

        mass = 0.5 * (c(j[:, None] - j[None, :]) - c(j[:, None] + j[None, :]))
        stiff = j * math.pi / 2.0
    else:
        j = np.arange(n)
        # (Gamma(j+3/2)/Gamma(j+1))^2 by its product form: gammaln differences lose ~1e-12
        ratio = np.cumprod(np.r_[math.sqrt(math.pi) / 2.0, (j[1:] + 0.5) / j[1:]])
        gam = ratio * ratio
        stiff = gam / (4.0 * j + 3.0)  # int_0^1 phi_j L[phi_j] r dr
        # int_0^1 (1 - r^2) P_i P_j r dr = (1/8) int_{-1}^{1} (1 - t) P_i P_j dt, exact with
        # n + 1 Gauss-Legendre nodes (roots_jacobi(., 1, 0) is ~10x noisier here)
        from scipy import special  # here only: cases A-D need no scipy (fast `rsf stiffness`)

        t, w = special.roots_legendre(n + 1)
        p = _jacobi_half0(n, t)
        mass = (p * (w * (1.0 - t))) @ p.T / 8.0
    # Scale the basis so that the stiffness matrix is the identity; then eta = 1/mu where
    # mu are the eigenvalues of the (compact, well-conditioned) scaled mass matrix.
    s = 1.0 / np.sqrt(stiff)
    mu, vec = np.linalg.eigh(mass * s[:, None] * s[None, :])
    order = np.argsort(mu)[::-1]
    values = 1.0 / mu[order]
    coeffs = vec[:, order] * s[:, None]
    values.flags.writeable = False
    coeffs.flags.writeable = False
    return values, coeffs


def eigen_stiffness(case: str, mode: int = 0, n: int | None = None) -> float:
    """Normalized eigenstiffness eta = k/k_* of table `tab: table` (dimensionless).

    Args:
        case: 'A'..'E' (see module docstring; k_* is mu'/lambda, mu'/L, E'h/lambda^2,
            E'h/L^2, mu/R).
        mode: 0 = smallest eigenvalue, 1 = next, ...  Cases A and C are unbounded: eta
            holds for every wavelength and ``mode`` must be 0.  For E only axisymmetric
            (radial-slip) modes are represented, as in `eq: eigenequation circular`.
        n: basis size for B and E (default ``DEFAULT_N``); ignored for A, C, D.

    Returns:
        A: 2 pi; C: 4 pi^2; D: (pi/2)^2 (mode+1)^2 (exact, delta(+-L) = 0).
        B: eigenvalue of `eq: eigenvalue problem Uenishi-Rice`, smallest 1.1577738836976.
        E: eigenvalue of `eq: eigenequation circular` (nu = 0), smallest 1.0030595164694.
        B and E are Ritz values (upper bounds); with the default n the smallest is
        accurate to ~1e-15 relative (1e-12 needs n >= ``N_FOR_1E12``), higher modes
        converge the same way but need n several times larger than the mode index.
    """
    case = _check_case(case)
    mode = _check_mode(case, mode)
    if case == "A":
        return 2.0 * math.pi
    if case == "C":
        return 4.0 * math.pi**2
    if case == "D":
        return (math.pi / 2.0) ** 2 * (mode + 1) ** 2
    return float(_solve(case, _check_n(case, mode, n))[0][mode])


def eigen_mode(
    case: str, mode: int = 0, n: int | None = None, x: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """Eigenmode shape delta(x) of case B, D or E, scaled so that max |delta| = 1 (> 0).

    Args:
        case: 'B' or 'D' (x = position / L in [-1, 1]) or 'E' (x = r/R in [0, 1]).
        mode: 0 = mode of the smallest eigenvalue, 1 = next, ...
        n: basis size (B, E), as in :func:`eigen_stiffness`.
        x: where to evaluate (default 201 equispaced points on the interval).

    Returns:
        (x, delta), with delta normalized over the whole interval (not only over the
        given x) and its largest excursion positive.  Modes of B and D alternate
        symmetric (even ``mode``) / antisymmetric; delta vanishes at the tips like
        sqrt(1 - x^2) for B and E and linearly for D.
    """
    case = _check_case(case)
    if case not in ("B", "D", "E"):
        raise ParameterError("case", case, "'B', 'D' or 'E' (cases A and C have no discrete modes)")
    mode = _check_mode(case, mode)
    lo = 0.0 if case == "E" else -1.0
    if x is None:
        x = np.linspace(lo, 1.0, 201)
    x = np.asarray(x, dtype=float)
    if x.ndim != 1 or not np.all(np.isfinite(x)) or np.any(x < lo) or np.any(x > 1.0):
        raise ParameterError("x", "array", f"a 1-D array of values in [{lo:g}, 1]")

    coef = None if case == "D" else _solve(case, _check_n(case, mode, n))[1][:, mode]

    def shape(z: np.ndarray) -> np.ndarray:
        if case == "D":  # cos for symmetric, sin for antisymmetric modes
            q = (mode + 1) * math.pi / 2.0
            return np.cos(q * z) if mode % 2 == 0 else np.sin(q * z)
        assert coef is not None  # cases B and E
        if case == "B":  # sum_j c_j sin(j theta), x = cos(theta)
            return np.sin(np.outer(np.arccos(z), np.arange(1, coef.size + 1))) @ coef
        return np.sqrt(1.0 - z * z) * (coef @ _jacobi_half0(coef.size, 2.0 * z * z - 1.0))

    dense = shape(np.linspace(lo, 1.0, 4001))
    peak = dense[np.argmax(np.abs(dense))]
    return x, shape(x) / peak


def circular_operator(g: Callable[[float], float], r: float) -> float:
    """The printed operator of `eq: functional circular`, by direct quadrature, in mu/R.

    Evaluates (1/2pi) int_0^1 delta'(s) [E(m)/(r - s) - K(m)/(s + r)] ds with
    m = f(r/s)^2 = 4 r s/(r + s)^2 (scipy's parameter convention, f being the modulus),
    r and s in units of R.  With s = sin(u), delta'(s) ds = g(s) du where
    g(s) = sqrt(1 - s^2) delta'(s) stays bounded at the rim for slip vanishing like
    sqrt(1 - s^2).  The Cauchy singularity at s = r is removed by subtracting the
    numerator's value there (its principal value is a logarithm; the remainder keeps
    only the weak (s - r) log|s - r| of E); the logarithmic singularity of K is left to
    adaptive quadrature split at s = r, K being evaluated through ``ellipkm1`` with
    1 - m = ((r - s)/(r + s))^2 so that it stays accurate there.  Measured accuracy
    3e-13 absolute for polynomial g on 1e-3 <= r <= 0.999 (~20 ms a point); meant for
    checking the printed kernel, not for solving (use :func:`eigen_stiffness`).

    Args:
        g: s -> sqrt(1 - s^2) d delta/ds, for s in [0, 1].
        r: evaluation radius r/R, 0 < r < 1.
    """
    from scipy import integrate, special  # here only (a check of the printed kernel)

    r = check_range("r", r, 0.0, 1.0, lo_open=True, hi_open=True)
    ur = math.asin(r)

    def cauchy_part(u: float) -> float:  # divided by (u - ur): g E(m)/(r - s) du
        s = math.sin(u)
        half = 0.5 * (u - ur)  # r - s = -2 cos((u + ur)/2) sin(half)
        ratio = half / math.sin(half) if half != 0.0 else 1.0
        return -g(s) * special.ellipe(4.0 * r * s / (r + s) ** 2) * ratio / math.cos(0.5 * (u + ur))

    def log_part(u: float) -> float:
        s = math.sin(u)
        return g(s) * special.ellipkm1(((r - s) / (r + s)) ** 2) / (s + r)

    c0 = cauchy_part(ur)

    def regular_part(u: float) -> float:  # cauchy_part minus its value at ur, over (u - ur)
        return (cauchy_part(u) - c0) / (u - ur)

    opts = dict(epsabs=1e-13, epsrel=1e-13, limit=200)
    pieces = ((0.0, ur), (ur, math.pi / 2))
    with warnings.catch_warnings():
        # the difference quotient cancels near u = ur; QUADPACK then reports roundoff at
        # the 1e-13 level it was asked for (measured accuracy is still ~3e-13)
        warnings.simplefilter("ignore", integrate.IntegrationWarning)
        pv = sum(integrate.quad(regular_part, lo, hi, **opts)[0] for lo, hi in pieces)
    pv += c0 * math.log((math.pi / 2 - ur) / ur)
    lg = sum(integrate.quad(log_part, lo, hi, **opts)[0] for lo, hi in pieces)
    return (pv - lg) / (2.0 * math.pi)


# --------------------------------------------------------------------------- physical scales
def _moduli(case: str, mu: float, nu: float, mode_of_slip: str) -> tuple[float, float]:
    """(mu', E') in Pa for the case: mu' = mu/(2(1-nu)) (II), mu/2 (III), mu (case E);
    E' = 2 mu/(1-nu) (II), mu (III)."""
    mu = check_range("mu", mu, 0.0, None, lo_open=True)
    nu = check_range("nu", nu, 0.0, 0.5, hi_open=True)
    slip = _check_slip_mode(mode_of_slip)
    if case == "E":
        return mu, float("nan")
    if slip == "II":
        return mu / (2.0 * (1.0 - nu)), 2.0 * mu / (1.0 - nu)
    return mu / 2.0, mu


def _check_h(case: str, h: float | None) -> float | None:
    if h is None:
        if case in _THIN_SLAB:
            raise ParameterError("h", h, f"a depth > 0 in metres (required for case {case})")
        return None
    return check_range("h", h, 0.0, None, lo_open=True)


def _modulus_times(case: str, mu: float, nu: float, mode_of_slip: str, h: float | None) -> float:
    """M such that k = eta M/size (A, B, E) or k = eta M/size^2 (C, D)."""
    mu_p, e_p = _moduli(case, mu, nu, mode_of_slip)
    h = _check_h(case, h)
    if case in _THIN_SLAB:
        assert h is not None  # _check_h requires it for these cases
        return e_p * h
    return mu_p


def critical_dimension(
    case: str,
    *,
    mu: float,
    nu: float,
    mode_of_slip: str,
    sigma: float,
    a: float,
    b: float,
    Dc: float,
    h: float | None = None,
    mode: int = 0,
) -> float:
    """Critical dimension of `eq: critical dimensions`, in metres.

    Solves eta k_*(size) = k_crit = sigma (b - a)/Dc (`eq: critical stiffness`) for the
    size: lambda_c (A, C), half-length L_c (B, D) or radius R_c (E).  This reproduces
    the printed forms with L_b = mu' Dc/(sigma b) and L_bh = sqrt(E' h Dc/(sigma b)):

        A: lambda_c = 2 pi L_b/(1 - a/b)          B: L_c = eta_B L_b/(1 - a/b)
        C: lambda_c = 2 pi L_bh/sqrt(1 - a/b)     D: L_c = (pi/2) L_bh/sqrt(1 - a/b)
        E: R_c = eta_E L_b/(1 - a/b), mu' = mu

    B and E use the converged eigenvalues (1.1577738836976, 1.0030595164694; the paper
    prints 1.157773882 for B), so the result is accurate to ~1e-15 relative.  Case E
    assumes nu = 0 (nu and mode_of_slip are validated but not used); for nu != 0 it is
    the paper's leading-order approximation.

    Args (SI units):
        case: 'A'..'E'.
        mu: shear modulus, Pa, > 0.
        nu: Poisson's ratio, 0 <= nu < 0.5.
        mode_of_slip: 'II' (in-plane) or 'III' (anti-plane).
        sigma: effective normal stress, Pa, > 0.
        a, b: rate-and-state parameters, 0 < a < b (velocity weakening).
        Dc: characteristic slip distance, m, > 0.
        h: depth of the interface below the free surface, m, > 0; required for C and D
            (valid while h << the returned size), ignored otherwise.
        mode: eigenmode whose stiffness is used (0 = smallest, the critical one).

    Raises:
        ParameterError (a ValueError) naming the invalid field and its valid range.
    """
    case = _check_case(case)
    sigma = check_range("sigma", sigma, 0.0, None, lo_open=True)
    a = check_range("a", a, 0.0, None, lo_open=True)
    b = check_range("b", b, 0.0, None, lo_open=True)
    if not b > a:
        raise ParameterError("b", b, f"b > a = {a!r} (velocity weakening: 0 < a < b)")
    Dc = check_range("Dc", Dc, 0.0, None, lo_open=True)
    modulus = _modulus_times(case, mu, nu, mode_of_slip, h)
    eta = eigen_stiffness(case, mode)
    ratio = eta * modulus * Dc / (sigma * (b - a))
    return math.sqrt(ratio) if case in _THIN_SLAB else ratio


def stiffness_of_fault(
    case: str,
    size: float,
    *,
    mu: float,
    nu: float,
    mode_of_slip: str,
    h: float | None = None,
    mode: int = 0,
) -> float:
    """Equivalent stiffness k = eta k_*(size) of a fault, in Pa/m (`tab: table`).

    Args: ``size`` is the wavelength lambda (A, C), half-length L (B, D) or radius R (E)
    in metres, > 0; the other arguments as in :func:`critical_dimension`.
    """
    case = _check_case(case)
    if (
        isinstance(size, bool)
        or not isinstance(size, (int, float, np.floating, np.integer))
        or not 0.0 < size < math.inf
    ):
        raise ParameterError("size", size, f"the {_SIZE_NAME[case]} in metres, > 0 and finite")
    size = float(size)
    modulus = _modulus_times(case, mu, nu, mode_of_slip, h)
    return eigen_stiffness(case, mode) * modulus / (size * size if case in _THIN_SLAB else size)


def kappa_of_fault(
    case: str,
    size: float,
    *,
    mu: float,
    nu: float,
    mode_of_slip: str,
    sigma: float,
    a: float,
    Dc: float,
    h: float | None = None,
    mode: int = 0,
) -> float:
    """Dimensionless stiffness kappa = k Dc/(a sigma) of a fault of the given size.

    Compare with kappa_crit = b/a - 1: kappa < kappa_crit (a fault larger than the
    critical dimension) means steady sliding is linearly unstable.  Units and ranges as
    in :func:`critical_dimension` (sigma, a, Dc > 0); exact up to rounding.
    """
    sigma = check_range("sigma", sigma, 0.0, None, lo_open=True)
    a = check_range("a", a, 0.0, None, lo_open=True)
    Dc = check_range("Dc", Dc, 0.0, None, lo_open=True)
    k = stiffness_of_fault(case, size, mu=mu, nu=nu, mode_of_slip=mode_of_slip, h=h, mode=mode)
    return k * Dc / (a * sigma)


_PHYSICAL = ("mu", "nu", "mode_of_slip", "sigma", "a", "b", "Dc", "h")


def stiffness_summary(case: str, mode: int = 0, **physical: object) -> dict[str, object]:
    """Eigenvalue and, given physical parameters, critical dimension of one case.

    Returns a dict with keys ``case``, ``mode``, ``eigenvalue`` (k/k_*), ``k_star_formula``
    (e.g. "mu'/L") and, when any of mu, nu, mode_of_slip, sigma, a, b, Dc, h is given
    (all but h are then required, h for C and D), ``critical_dimension_m`` (metres) and
    ``critical_dimension_name`` ('lambda_c', 'L_c' or 'R_c').
    """
    case = _check_case(case)
    out: dict[str, object] = {
        "case": case,
        "mode": _check_mode(case, mode),
        "eigenvalue": eigen_stiffness(case, mode),
        "k_star_formula": _K_STAR[case],
    }
    if physical:
        unknown = sorted(set(physical) - set(_PHYSICAL))
        if unknown:
            raise ParameterError(unknown[0], physical[unknown[0]], f"one of {', '.join(_PHYSICAL)}")
        missing = [f for f in _PHYSICAL[:-1] if physical.get(f) is None]
        if missing:
            raise ParameterError(missing[0], None, "required when physical parameters are given")
        dimension = critical_dimension(case, mode=mode, **physical)  # type: ignore[arg-type]
        out["critical_dimension_m"] = dimension
        out["critical_dimension_name"] = _DIM_NAME[case]
    return out
