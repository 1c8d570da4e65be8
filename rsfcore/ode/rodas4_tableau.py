"""Coefficients of RODAS4, the 6-stage L-stable Rosenbrock method of order 4(3).

Published by Hairer and Wanner with their code RODAS (E. Hairer, G. Wanner, Solving
Ordinary Differential Equations II, Stiff and Differential-Algebraic Problems, 2nd ed.,
Springer 1996, Sec. VI.4; the Fortran code rodas.f, subroutine ROCOE, METH = 1), typed
here as the decimal literals published there, with the same names: ``aIJ`` stage
weights, ``cIJ`` the coefficients of the transformed form (Hairer & Wanner II, eq. (7.4')),
``gamma`` the diagonal, ``cI`` nodes, ``dIJ`` the dense-output weights.

One step of length h for y' = f(y) with Jacobian J (autonomous form, as used here):

    (I/(h gamma) - J) k_i = f(y + sum_{j<i} a_ij k_j) + sum_{j<i} (c_ij/h) k_j,  i = 1..6

with the stiffly accurate structure of RODAS: stage 6 is evaluated at
y + a51 k1 + ... + a54 k4 + k5 (the embedded 3rd-order solution), the new solution is
that plus k6, and k6 itself is the error estimate.  The continuous output is
y(t0 + s h) = (1 - s) y0 + s [y1 + (1 - s)(D2 + s D3)], D2 = sum d2j k_j, D3 = sum d3j k_j.
"""

from __future__ import annotations

__all__ = [
    "GAMMA",
    "A",
    "C",
    "NODES",
    "D2",
    "D3",
    "ORDER",
]

#: order of the solution; the embedded estimate is of order 3 (error exponent 1/4)
ORDER = 4

gamma = 0.2500000000000000e00
c2 = 0.386e0
c3 = 0.21e0
c4 = 0.63e0

a21 = 0.1544000000000000e01
a31 = 0.9466785280815826e00
a32 = 0.2557011698983284e00
a41 = 0.3314825187068521e01
a42 = 0.2896124015972201e01
a43 = 0.9986419139977817e00
a51 = 0.1221224509226641e01
a52 = 0.6019134481288629e01
a53 = 0.1253708332932087e02
a54 = -0.6878860361058950e00

c21 = -0.5668800000000000e01
c31 = -0.2430093356833875e01
c32 = -0.2063599157091915e00
c41 = -0.1073529058151375e00
c42 = -0.9594562251023355e01
c43 = -0.2047028614809616e02
c51 = 0.7496443313967647e01
c52 = -0.1024680431464352e02
c53 = -0.3399990352819905e02
c54 = 0.1170890893206160e02
c61 = 0.8083246795921522e01
c62 = -0.7981132988064893e01
c63 = -0.3152159432874371e02
c64 = 0.1631930543123136e02
c65 = -0.6058818238834054e01

d21 = 0.1012623508344586e02
d22 = -0.7487995877610167e01
d23 = -0.3480091861555747e02
d24 = -0.7992771707568823e01
d25 = 0.1025137723295662e01
d31 = -0.6762803392801253e00
d32 = 0.6087714651680015e01
d33 = 0.1643084320892478e02
d34 = 0.2476722511418386e02
d35 = -0.6594389125716872e01

GAMMA = gamma
#: a_ij as nested tuples: A[i] holds the weights of stage i+1 (0-based rows, i = 1..4)
A = ((), (a21,), (a31, a32), (a41, a42, a43), (a51, a52, a53, a54))
#: c_ij of the transformed form, C[i] for stage i+1 (i = 1..5)
C = (
    (),
    (c21,),
    (c31, c32),
    (c41, c42, c43),
    (c51, c52, c53, c54),
    (c61, c62, c63, c64, c65),
)
#: nodes of stages 1..6 (autonomous problems do not use them; documented for completeness)
NODES = (0.0, c2, c3, c4, 1.0, 1.0)
#: dense-output weights over k_1..k_5
D2 = (d21, d22, d23, d24, d25)
D3 = (d31, d32, d33, d34, d35)
