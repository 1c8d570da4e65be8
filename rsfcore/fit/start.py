"""Start values of a fit: variable projection on the infinitely-stiff closed form over a
(Dc, eps) grid, shared by the laws of a comparison; the machine stiffness from the loading
slope after the first velocity step.

For fixed Dc and eps the stiff-machine friction mu0 + a phi + b ln(V0 theta/Dc)
[+ trend x_lp] is linear in mu0, a, b [, trend], so each grid point is one linear least
squares problem.  The columns 1, phi = ln(v_lp/V0) [and x_lp] do not depend on the grid
point: they are projected out once (orthonormal basis by SVD, rank-revealing), and the
residual sum of squares of every Dc of one eps follows from one (n_Dc, n) array of the
state column ln(V0 theta/Dc) (vectorised over Dc).  The grid is START_N_DC values of Dc
(log-spaced over the record's slip range) times START_EPS (the
eps values a law leaves free: aging 1, slip 0, nagata and eps all five), so one
StartScan serves every law of a comparison (aging and slip read rows of the eps law's
table).  The chosen point's coefficients are then an ordinary least-squares solve
(numpy.linalg.lstsq) of its columns, as before the scan was vectorised.

Measured (bench/bench_fit.py records, 10^4 samples): the scan of the four laws took
480 least-squares solves (40 % of a comparison's CPU time); now 5 vectorised rows.
The chosen grid point is the same as the per-point solves chose on every test record
(tests/core/test_fit.py compares them); start values agree to rounding.
"""

from __future__ import annotations

import math
from collections.abc import Mapping

import numpy as np
from numpy.typing import NDArray

from .model import Law, ModelSpec
from .record import Record

__all__ = [
    "START_EPS",
    "START_N_DC",
    "StartScan",
    "StartScans",
    "initial_guess",
    "stiff_columns",
    "stiffness_guess",
]

#: eps values of the start grid (laws with eps free scan all of them).
START_EPS: tuple[float, ...] = (0.0, 0.25, 0.5, 0.75, 1.0)
#: Dc values of the start grid (log-spaced over the record's slip range).
START_N_DC = 40


def stiff_columns(
    rec: Record, Dc: float, eps: float
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.bool_]]:
    """phi = ln(V/V0), ln(V0 theta/Dc) on an infinitely stiff machine; holds: theta grows by
    dt (aging, eps = 1) or stays (eps < 1: the state rate vanishes with V).  Returns the
    columns and the mask of moving samples.  (One Dc; StartScan evaluates a whole grid.)"""
    phi, lth, moving = _stiff_grid(rec, np.array([Dc]), eps)
    return phi, lth[0], moving


def _stiff_grid(
    rec: Record, Dcs: NDArray[np.float64], eps: float
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.bool_]]:
    """:func:`stiff_columns` for every Dc of ``Dcs`` at once: phi (n,), ln(V0 theta/Dc)
    (len(Dcs), n), moving (n,)."""
    t = rec.t_s - rec.t_s[0]
    v = rec.v_lp_m_s
    V0 = rec.v_ref_m_s
    n = rec.n
    nd = Dcs.shape[0]
    starts = list(rec.segment_starts) + [n]
    phi = np.zeros(n)
    lth = np.zeros((nd, n))
    moving = v > 0.0
    lth_now = np.zeros(nd)  # ln(V0 theta/Dc) at the segment start, per Dc
    for j in range(len(starts) - 1):
        i0, i1 = int(starts[j]), int(starts[j + 1])
        t_end = t[i1] if i1 < n else t[-1]
        vj = float(v[i0])
        if vj <= 0.0:
            if eps >= 1.0:
                dth = ((t[i0:i1] - t[i0]) * V0)[None, :] / Dcs[:, None]
                lth[:, i0:i1] = np.logaddexp(lth_now[:, None], np.log(np.maximum(dth, 1e-300)))
                end = np.maximum((t_end - t[i0]) * V0 / Dcs, 1e-300)
                lth_now = np.logaddexp(lth_now, np.log(end))
            else:
                lth[:, i0:i1] = lth_now[:, None]
            continue
        ph = math.log(vj / V0)
        L0 = ph + lth_now
        rate = vj / Dcs
        x = (t[i0:i1] - t[i0])[None, :] * rate[:, None]
        x_end = (t_end - t[i0]) * rate
        if eps == 0.0:
            L = L0[:, None] * np.exp(-x)
            L_end = L0 * np.exp(-x_end)
        else:
            w = np.expm1(np.minimum(eps * L0, 700.0))
            L = np.log1p(w[:, None] * np.exp(-x)) / eps
            L_end = np.log1p(w * np.exp(-x_end)) / eps
        phi[i0:i1] = ph
        lth[:, i0:i1] = L - ph
        lth_now = L_end - ph
    return phi, lth, moving


class StartScan:
    """The (eps, Dc) start grid of one record (and sample selection, trend choice, Dc
    bounds): residual sums of squares of the variable projection, computed per eps row
    on first use and kept, so the laws of a comparison share them.

    Attributes:
        Dcs: the Dc grid [m] (START_N_DC values).
    """

    def __init__(
        self,
        rec: Record,
        Dc_bounds: tuple[float, float],
        used: NDArray[np.bool_] | None,
        trend: bool,
    ) -> None:
        self.rec = rec
        self.used = used
        self.trend = trend
        self.key = (Dc_bounds, trend)
        xlp = rec.load_point_m
        total = float(xlp[-1]) if xlp[-1] > 0 else float(rec.v_ref_m_s * (rec.t_s[-1] - rec.t_s[0]))
        dx = np.diff(xlp)
        dx = dx[dx > 0]
        step = float(np.median(dx)) if dx.size else total / rec.n
        lo = max(Dc_bounds[0] * 1.01, 0.3 * step)
        hi = min(Dc_bounds[1] * 0.99, max(3.0 * total, 2 * lo))
        self.Dcs: NDArray[np.float64] = np.geomspace(lo, hi, START_N_DC)
        self._rows: dict[float, NDArray[np.float64]] = {}

    def matches(
        self,
        rec: Record,
        Dc_bounds: tuple[float, float],
        used: NDArray[np.bool_] | None,
        trend: bool,
    ) -> bool:
        """Whether this scan is the one of these inputs (same record object, selection,
        trend choice and Dc bounds)."""
        if rec is not self.rec or self.key != (Dc_bounds, trend):
            return False
        if used is None or self.used is None:
            return used is None and self.used is None
        return bool(np.array_equal(used, self.used))

    def _columns(
        self, phi: NDArray[np.float64], lth: NDArray[np.float64], m: NDArray[np.bool_]
    ) -> list[NDArray[np.float64]]:
        cols = [np.ones(int(m.sum())), phi[m]]
        if self.trend:
            cols.append(self.rec.load_point_m[m])
        return cols

    def row(self, eps: float) -> NDArray[np.float64]:
        """RSS of the variable projection at every Dc of the grid for this eps."""
        if eps in self._rows:
            return self._rows[eps]
        phi, lth, m = _stiff_grid(self.rec, self.Dcs, eps)
        if self.used is not None:
            m = m & self.used
        F = np.column_stack(self._columns(phi, lth, m))
        mu = self.rec.mu[m]
        # orthonormal basis of the fixed columns (rank-revealing: phi may be constant)
        U, s, _ = np.linalg.svd(F, full_matrices=False)
        Q = U[:, s > s[0] * max(F.shape) * np.finfo(float).eps]
        mu_p = mu - Q @ (Q.T @ mu)
        L = lth[:, m]
        L_p = L - (L @ Q) @ Q.T
        nn = np.einsum("ij,ij->i", L_p, L_p)
        big = nn > 1e-28 * np.maximum(np.einsum("ij,ij->i", L, L), 1e-300)
        c = np.where(big, (L_p @ mu_p) / np.where(big, nn, 1.0), 0.0)
        res = mu_p[None, :] - c[:, None] * L_p
        rss = np.einsum("ij,ij->i", res, res)
        self._rows[eps] = rss
        return rss

    def best(self, epss: tuple[float, ...]) -> tuple[float, float]:
        """(eps, Dc) of the smallest RSS over these eps rows (first in (eps, Dc) order on
        ties, as a loop with a strict comparison would pick)."""
        table = np.vstack([self.row(e) for e in epss])
        i = int(np.argmin(table))
        return epss[i // START_N_DC], float(self.Dcs[i % START_N_DC])

    def coefficients(self, eps: float, Dc: float) -> dict[str, float]:
        """mu0, a, b [, trend_per_m] of one grid point by an ordinary least-squares solve."""
        phi, lth, m = stiff_columns(self.rec, Dc, eps)
        if self.used is not None:
            m = m & self.used
        cols = [np.ones(int(m.sum())), phi[m], lth[m]]
        if self.trend:
            cols.append(self.rec.load_point_m[m])
        A = np.column_stack(cols)
        coef, *_ = np.linalg.lstsq(A, self.rec.mu[m], rcond=None)
        return {
            "mu0": float(coef[0]),
            "a": float(coef[1]),
            "b": float(coef[2]),
            "Dc_m": float(Dc),
            "eps": eps,
            "trend_per_m": float(coef[3]) if self.trend else 0.0,
        }


def _law_eps(law: Law) -> tuple[float, ...]:
    if law is Law.AGING:
        return (1.0,)
    if law is Law.SLIP:
        return (0.0,)
    return START_EPS


class StartScans:
    """The StartScans of the fits of one comparison (one per record, selection, trend
    choice and Dc bounds; laws with equal inputs share one)."""

    def __init__(self) -> None:
        self._scans: list[StartScan] = []

    def get(
        self,
        rec: Record,
        Dc_bounds: tuple[float, float],
        used: NDArray[np.bool_] | None,
        trend: bool,
    ) -> StartScan:
        for sc in self._scans:
            if sc.matches(rec, Dc_bounds, used, trend):
                return sc
        sc = StartScan(rec, Dc_bounds, used, trend)
        self._scans.append(sc)
        return sc


def initial_guess(
    rec: Record,
    spec: ModelSpec,
    bounds: Mapping[str, tuple[float, float]],
    used: NDArray[np.bool_] | None = None,
    scans: StartScans | None = None,
) -> dict[str, float]:
    """Start values: variable projection on the stiff closed form over the (Dc, eps) grid
    (``scans``: the StartScans to share with the other laws of a comparison); k from the
    loading slope."""
    dcb = (float(bounds["Dc_m"][0]), float(bounds["Dc_m"][1]))
    scan = (scans or StartScans()).get(rec, dcb, used, spec.trend)
    eps, Dc = scan.best(_law_eps(spec.law))
    p = scan.coefficients(eps, Dc)
    if not (p["a"] > 0.0):
        p["a"] = (
            0.01
            if bounds["a"][0] < 0.01 < bounds["a"][1]
            else math.sqrt(bounds["a"][0] * bounds["a"][1])
        )
    if spec.law is Law.NAGATA and not p["b"] > 0.0:
        p["b"] = p["a"]
    if spec.fit_stiffness:
        p["k_per_m"] = stiffness_guess(rec, p)
    return p


def stiffness_guess(rec: Record, p: Mapping[str, float]) -> float:
    """k from the loading slope after the first step: d mu/dt = k (v_new - v_old) while V lags.

    First the largest slope of the first few sample intervals; then, 4 times, the slope of
    a least-squares line through the samples of the first third of the elastic loading
    time a/(k |dv|) of the current estimate (at least 4 intervals, within the segment).
    On noisy 10^4-sample records the single-interval slopes are mostly noise (noise 1e-4
    over 0.01 s: 5-11x the true k on bench/bench_fit.py's records); the line brings the
    start within 20 % (965, 997, 818 /m for 1000) and the slide-hold-slide fit from 26
    to 12 optimiser evaluations.
    """
    s = rec.segment_starts
    fallback = 10.0 * max(abs(p["b"] - p["a"]), p["a"]) / p["Dc_m"]
    if s.shape[0] < 2:
        return fallback
    i = int(s[1])
    dv = float(rec.v_lp_m_s[i] - rec.v_lp_m_s[i - 1])
    j1 = min(rec.n - 1, i + 3)
    if j1 <= i - 1 or dv == 0.0:
        return fallback
    slopes = np.diff(rec.mu[i - 1 : j1 + 1]) / np.diff(rec.t_s[i - 1 : j1 + 1]) / dv
    slopes = slopes[np.isfinite(slopes) & (slopes > 0)]
    if slopes.size == 0:
        return fallback
    k = float(np.max(slopes))
    end = int(s[2]) if s.shape[0] > 2 else rec.n
    for _ in range(4):
        tau = p["a"] / (k * abs(dv))
        j = int(np.searchsorted(rec.t_s, rec.t_s[i - 1] + tau / 3.0))
        j = min(max(j, i + 3), end - 1)
        if j <= i:
            break
        tt = rec.t_s[i - 1 : j + 1] - rec.t_s[i - 1]
        mm = rec.mu[i - 1 : j + 1] - rec.mu[i - 1]
        tc = tt - tt.mean()
        slope = float(tc @ (mm - mm.mean())) / float(tc @ tc) / dv
        if not (math.isfinite(slope) and slope > 0.0):
            break
        k = slope
    return k
