"""Coefficients of RODASP, the 6-stage L-stable Rosenbrock method of order 4(3) that keeps
its order on stiff problems of Prothero-Robinson type.

Published by G. Steinebach, Order-reduction of ROW-methods for DAEs and method of lines
applications, Preprint 1741, Technische Hochschule Darmstadt, 1995: the structure of
RODAS (Hairer & Wanner, Solving Ordinary Differential Equations II, 2nd ed., Springer
1996, Sec. VI.4; gamma = 1/4, stiffly accurate, embedded solution at stage 5) with
coefficients chosen so that the method keeps order 4 on y' = lambda (y - g(x)) + g'(x)
for |h lambda| -> infinity, where RODAS4 drops to order ~1 (on the separatrix's stiff
scalar ODE, rsfcore.separatrix, RODAS4 needs ~10x the steps per decade of tolerance,
RODASP ~1.8x).  The literals below are the published ones in the method's original
notation (Hairer & Wanner II, eq. (7.4)):

    (I - gamma h J) k_i = h f(y + sum_{j<i} alpha_ij k_j) + h J sum_{j<i} gamma_ij k_j,
    y_1 = y + sum_j b_j k_j,

with beta_ij = alpha_ij + gamma_ij as printed (``ALPHA``, ``BETA``), b_j = beta_6j
(j < 6), b_6 = gamma, and the embedded b^_j = beta_5j (j < 5), b^_5 = gamma.

The transformed coefficients that rsfcore.ode.rodas4's step kernel takes (its eq.
(7.4') form, the same stiffly accurate layout as RODAS4: stage 6 at the embedded solution
"stage-5 argument + k_5", the solution that plus k_6) are derived here from the printed
literals in exact rational arithmetic (:class:`fractions.Fraction`) and rounded once:
with Gamma = (gamma_ij) (diagonal gamma), a = alpha Gamma^-1 and c = diag(1/gamma) -
Gamma^-1 (Hairer & Wanner II, Sec. IV.7).  tests/core/test_rodasp.py checks the layout
(rows 5 and 6 of a, the weights) and the orders.

The continuous extension (``D2``, ``D3``; used by rsfcore.engine to bound the error of
its cubic Hermite dense output, as with RODAS4) is derived here too, not printed: it has
RODAS4's form

    y(t0 + s h) = y0 + s (y1 - y0) + s (1 - s) D2 + s^2 (1 - s) D3,
    D2 = sum_j d2_j k_j,  D3 = sum_j d3_j k_j  (j = 1..5),

whose weights b_j(s) = s b_j + s (1 - s) d2_j + s^2 (1 - s) d3_j must satisfy the
Rosenbrock order conditions up to order 3 for every s (Hairer & Wanner II, Sec. VI.4):
sum b_j(s) = s, sum b_j(s) beta'_j = s^2/2 - gamma s, sum b_j(s) alpha_j^2 = s^3/3,
sum b_j(s) beta_jk beta'_k = s^3/6 - gamma s^2 + gamma^2 s, i.e. four linear conditions
on each of d2 and d3 (``_dense``).  RODAS4's published d2, d3 are the solution of these
four and the index-1 condition sum b_j(s) w_jk alpha_k^2 = s^2 (w = (beta_jk + gamma
delta_jk)^-1), to rounding (tests/core/test_rodasp.py); for RODASP that fifth condition
gives weights of ~1e4 (a near-singular system: rounding of the stages amplified 1e4x), so
its extension is the solution of the four of least Euclidean norm (weights below 21).
"""

from __future__ import annotations

from fractions import Fraction

__all__ = [
    "GAMMA",
    "ALPHA",
    "BETA",
    "A",
    "C",
    "D2",
    "D3",
    "ORDER",
    "DENSE_ORDER",
]

#: order of the solution; the embedded estimate is of order 3 (error exponent 1/4)
ORDER = 4
#: order of the continuous extension (D2, D3)
DENSE_ORDER = 3

_GAMMA_TEXT = "0.25"
#: alpha_ij as printed (row i = stage i+1, 0-based; rows of fewer entries end in zeros)
_ALPHA_TEXT = (
    (),
    ("0.75",),
    ("8.6120400814152190E-2", "0.1238795991858478"),
    ("0.7749345355073236", "0.1492651549508680", "-0.2941996904581916"),
    ("5.308746682646142", "1.330892140037269", "-5.374137811655562", "-0.2655010110278497"),
    (
        "-1.764437648774483",
        "-0.4747565572063027",
        "2.369691846915802",
        "0.6195023590649829",
        "0.25",
    ),
)
#: beta_ij = alpha_ij + gamma_ij as printed (beta_21 = 0; row 6 gives the solution weights)
_BETA_TEXT = (
    (),
    ("0.0",),
    ("-0.049392", "-0.014112"),
    ("-0.4820494693877561", "-0.1008795555555556", "0.9267290249433117"),
    ("-1.764437648774483", "-0.4747565572063027", "2.369691846915802", "0.6195023590649829"),
    (
        "-8.0368370789113464E-2",
        "-5.6490613592447572E-2",
        "0.4882856300427991",
        "0.5057162114816189",
        "-0.1071428571428569",
    ),
)

GAMMA = float(Fraction(_GAMMA_TEXT))
#: the printed alpha_ij and beta_ij as floats (nested tuples, row i = stage i+1)
ALPHA = tuple(tuple(float(Fraction(v)) for v in row) for row in _ALPHA_TEXT)
BETA = tuple(tuple(float(Fraction(v)) for v in row) for row in _BETA_TEXT)


_Matrix = list[list[Fraction]]


def _exact() -> tuple[_Matrix, _Matrix, _Matrix, _Matrix]:
    """(alpha, beta, Gamma, Gamma^-1) of the original form from the printed literals, as
    exact fractions (Gamma = beta - alpha below the diagonal, gamma on it; its inverse by
    forward substitution, column by column, as Gamma is lower triangular)."""
    n = 6
    g = Fraction(_GAMMA_TEXT)
    alpha = [[Fraction(0)] * n for _ in range(n)]
    beta = [[Fraction(0)] * n for _ in range(n)]
    gam = [[Fraction(0)] * n for _ in range(n)]
    for i in range(n):
        for j, (a_txt, b_txt) in enumerate(zip(_ALPHA_TEXT[i], _BETA_TEXT[i], strict=False)):
            alpha[i][j] = Fraction(a_txt)
            beta[i][j] = Fraction(b_txt)
            gam[i][j] = Fraction(b_txt) - Fraction(a_txt)
        gam[i][i] = g
    inv = [[Fraction(0)] * n for _ in range(n)]
    for col in range(n):
        for i in range(n):
            acc = Fraction(1) if i == col else Fraction(0)
            for j in range(i):
                acc -= gam[i][j] * inv[j][col]
            inv[i][col] = acc / gam[i][i]
    return alpha, beta, gam, inv


def _transformed() -> tuple[tuple[tuple[float, ...], ...], tuple[tuple[float, ...], ...]]:
    """(a, c) of the transformed form from the printed literals, exactly, rounded once."""
    n = 6
    alpha, _, _, inv = _exact()
    a = tuple(
        tuple(float(sum(alpha[i][m] * inv[m][j] for m in range(n))) for j in range(i))
        for i in range(n - 1)
    )
    c = tuple(tuple(float(-inv[i][j]) for j in range(i)) for i in range(n))
    return a, c


#: a_ij of the transformed form, A[i] for stage i+1 (i = 0..4; stage 6 is stage 5's
#: argument plus k_5, as in RODAS4)
#: c_ij of the transformed form, C[i] for stage i+1 (i = 1..5)
A, C = _transformed()


def _dense() -> tuple[tuple[float, ...], tuple[float, ...]]:
    """(d2, d3) of the continuous extension in the transformed form (weights of the stage
    increments R[0..4] of rsfcore.ode.rodas4.step_tableau), exactly, rounded once: the
    least-norm solution d = M^T (M M^T)^-1 t of the four order-3 conditions M d = t over
    the original k_1..k_5 (module docstring), mapped to the transformed stages by
    Gamma^-1 (sum_j d_j k_j = sum_i (d^T Gamma^-1)_i u_i, u = Gamma k)."""
    n = 6
    g = Fraction(_GAMMA_TEXT)
    alpha, beta, _, inv = _exact()
    zero = Fraction(0)
    al = [sum(row, zero) for row in alpha]
    bp = [sum(row, zero) for row in beta]
    bbp = [sum((beta[i][k] * bp[k] for k in range(n)), zero) for i in range(n)]
    m = 5
    rows: list[list[Fraction]] = [
        [Fraction(1)] * m,
        bp[:m],
        [a * a for a in al[:m]],
        bbp[:m],
    ]
    targets = {
        "d2": [Fraction(0), Fraction(-1, 2), Fraction(-1, 3), g - Fraction(1, 6)],
        "d3": [Fraction(0), Fraction(0), Fraction(-1, 3), Fraction(-1, 6)],
    }
    # M M^T (4 x 4) solved by Gauss-Jordan elimination in exact arithmetic
    mmt = [[sum((ri[k] * rj[k] for k in range(m)), zero) for rj in rows] for ri in rows]
    out: list[tuple[float, ...]] = []
    for key in ("d2", "d3"):
        aug: list[list[Fraction]] = [mmt[i][:] + [targets[key][i]] for i in range(4)]
        for c in range(4):
            p = next(i for i in range(c, 4) if aug[i][c] != 0)
            aug[c], aug[p] = aug[p], aug[c]
            for i in range(4):
                if i != c and aug[i][c] != 0:
                    f = aug[i][c] / aug[c][c]
                    aug[i] = [x - f * y for x, y in zip(aug[i], aug[c], strict=True)]
        lam = [aug[i][4] / aug[i][i] for i in range(4)]
        d = [sum((lam[r] * rows[r][k] for r in range(4)), zero) for k in range(m)] + [zero]
        out.append(tuple(float(sum((d[j] * inv[j][i] for j in range(n)), zero)) for i in range(m)))
    return out[0], out[1]


#: weights of the continuous extension over the transformed stage increments k_1..k_5
#: (rsfcore.ode.rodas4's D2, D3 layout; least-norm order-3 extension, ``_dense``)
D2, D3 = _dense()
