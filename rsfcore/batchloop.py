"""The compiled loop of :mod:`rsfcore.batch`: critical sizes (and outcomes) at the points of
a flat index range whose parameters are given as value tables.

A table ``t`` with stride ``s`` gives the point with flat index ``i`` the value
``t[(i // s) % len(t)]``.  That one map covers both callers of :func:`points_kernel`:

* arrays of n points (:func:`rsfcore.batch.critical_points`): every table is an array of
  length n with stride 1, over the range [0, n);
* a grid in C order (:func:`rsfcore.batch.critical_grid`, a sweep's chunk): the table of a
  swept parameter is its axis's values with the stride of that axis (the product of the
  lengths of the axes after it), a fixed parameter is a table of one value; the range is
  the chunk's [i0, i1), so no parameter array of the chunk is ever laid out.

Each point goes through :func:`rsfcore.critical.critical_point` (the per-point kernel of
every batch and diagram) and :func:`finish_point` (the zero / infinite values, the
boundary flag and the outcome of a size >= 0), the same operations in the same order for
both callers, so the same bits.  Points that need Python afterwards (``FLAG_FALLBACK``:
bisection; a negative size: classify) are listed with their flags and parameters
(:func:`rsfcore.batch.critical_points` finishes them).

Each output also reports whether every element of the range has the bits of its first
(``same``); with ``lazy`` an output is written only from the point where it stops being
one repeated value (its leading run then filled in), so a range of cheap points decided
alike writes nothing but its first element.
"""

from __future__ import annotations

import math
from enum import IntEnum

import numba as nb
import numpy as np

from .decision import (
    FLAG_FALLBACK,
    FLAG_LOG_VALUE,
    FLAG_ON_KCRIT,
    FLAG_ON_X1,
    KIND_FINITE,
    KIND_INFINITE,
    KIND_ZERO,
    critical_point,
)
from .separatrix import N_WORK

__all__ = [
    "N_OUT",
    "OUT_KIND",
    "OUT_VALUE",
    "OUT_ACC",
    "OUT_METHOD",
    "OUT_ON_BOUNDARY",
    "OUT_OUTCOME",
    "OUT_UNCERTAIN",
    "OUTCOME_STABLE",
    "OUTCOME_UNSTABLE",
    "OUTCOME_NONE",
    "OUTCOMES",
    "BatchOutcome",
    "OUTCOME_NEAR_FLOOR",
    "finish_point",
    "points_kernel",
    "stored_value",
]

#: outcome codes (``BatchResult.outcome``); OUTCOME_NONE where not computed or failed
#: (plain ints: the compiled loop writes them; :class:`BatchOutcome` names them)
OUTCOME_STABLE, OUTCOME_UNSTABLE, OUTCOME_NONE = 0, 1, -1
#: names of the decided outcome codes, indexed by the code (OUTCOMES[OUTCOME_STABLE] =
#: "stable"; the ``outcome_legend`` of a stability diagram)
OUTCOMES: tuple[str, ...] = ("stable", "unstable")


class BatchOutcome(IntEnum):
    """Outcome code of a batch / grid / diagram point (the ``outcome`` arrays)."""

    STABLE = OUTCOME_STABLE
    UNSTABLE = OUTCOME_UNSTABLE
    #: not computed (no size) or the point failed
    NONE = OUTCOME_NONE

    @property
    def text(self) -> str:
        """ "stable" | "unstable" (ValueError for NONE, which has no name in OUTCOMES)."""
        if self is BatchOutcome.NONE:
            raise ValueError("OUTCOME_NONE has no outcome name")
        return OUTCOMES[int(self)]


#: Smallest relative band |size/critical - 1| within which an outcome is uncertain
#: (a few ulp: exact decisions report accuracy 0).
OUTCOME_NEAR_FLOOR = 4e-16
#: Indices of the outputs in ``same`` (kind, value, rel_accuracy, method, on_boundary,
#: outcome, outcome_uncertain).
OUT_KIND, OUT_VALUE, OUT_ACC, OUT_METHOD, OUT_ON_BOUNDARY, OUT_OUTCOME, OUT_UNCERTAIN = range(7)
N_OUT = 7


@nb.njit(cache=True, nogil=True)
def stored_value(value: float, flags: int) -> float:
    """The critical size a batch stores for :func:`rsfcore.critical.critical_point`'s
    ``value``: inf where ``flags`` has FLAG_LOG_VALUE (the kernel's value is then
    l = ln(1 + dv) of a finite load-point jump dv beyond the double range), else ``value``."""
    return math.inf if flags & FLAG_LOG_VALUE else value


@nb.njit(cache=True, nogil=True)
def finish_point(
    kind: int, value: float, acc: float, flags: int, size: float, vo: float, has_size: bool
) -> tuple[float, bool, int, bool]:
    """A point's stored value, boundary flag, outcome and outcome_uncertain from its
    kind, value, accuracy and flags (those of :func:`critical_point`, or of the
    bisection that replaced them): value 0 for kind zero and inf for infinite;
    on_boundary where flagged on x = 1 or kappa = kappa_crit; for a size >= 0 (with
    ``has_size``) the outcome unstable iff size > critical size (kind zero: any size >
    0), uncertain where |size/critical - 1| <= max(rel_accuracy, OUTCOME_NEAR_FLOOR) or on
    kappa = kappa_crit with v_o > 0.  Without a size (or for a negative one, classified
    by the caller): OUTCOME_NONE, False."""
    if kind == KIND_ZERO:
        value = 0.0
    elif kind == KIND_INFINITE:
        value = math.inf
    on_b = (flags & (FLAG_ON_X1 | FLAG_ON_KCRIT)) != 0
    if not has_size or not (size >= 0.0):
        return value, on_b, OUTCOME_NONE, False
    unstable = (kind == KIND_ZERO and size > 0.0) or (kind == KIND_FINITE and size > value)
    near = False
    if kind == KIND_FINITE and value != 0.0:  # size/0 is inf or nan: never near
        band = acc if (acc != acc or acc > OUTCOME_NEAR_FLOOR) else OUTCOME_NEAR_FLOOR
        near = abs(size / value - 1.0) <= band
    uncertain = near or ((flags & FLAG_ON_KCRIT) != 0 and vo > 0.0)
    return value, on_b, OUTCOME_UNSTABLE if unstable else OUTCOME_STABLE, uncertain


@nb.njit(cache=True, nogil=True)
def _same_f64(x: float, first: float, bits: np.ndarray) -> bool:
    """``x`` has the IEEE bits of ``first``: equal and non-zero (one representation),
    or equal zeros of one sign; NaNs compared by their bits (through ``bits``, two float64
    slots and their int64 view)."""
    if x == first:
        return x != 0.0 or math.copysign(1.0, x) == math.copysign(1.0, first)
    if x != x and first != first:
        bits[0] = x
        bits[1] = first
        b = bits.view(np.int64)
        return b[0] == b[1]
    return False


@nb.njit(cache=True, nogil=True)
def _run_limit(pos, rem, stride, length, inner, run):
    """``run`` cut to the points before the table's value changes (an inner table, stride
    1: before its end; another: before its next step; a table of one value: never)."""
    if length == 1:
        return run
    if inner:
        return min(run, length - pos)
    return min(run, stride - rem)


@nb.njit(cache=True, nogil=True)
def _advance(pos, rem, stride, length, inner, run):
    """A table's odometer (position, points into its run of equal indices) ``run`` points
    on (``run`` from :func:`_run_limit`)."""
    if length == 1:
        return 0, 0
    if inner:
        pos += run
        return (0 if pos == length else pos), 0
    rem += run
    if rem == stride:
        pos += 1
        return (0 if pos == length else pos), 0
    return pos, rem


@nb.njit(cache=True, nogil=True)
def points_kernel(
    ba_t,
    kappa_t,
    eps_t,
    vo_t,
    size_t,
    strides,
    i0,
    i1,
    kappa_is_ratio,
    has_size,
    pert,
    rtol,
    lazy,
    kind,
    value,
    acc,
    method,
    on_b,
    outcome,
    uncertain,
    same,
    sp_idx,
    sp_flags,
    sp_par,
):
    """Points [i0, i1) of the tables (module docstring; ``strides`` int64[5] in the order
    ba, kappa, eps, vo, size; with ``kappa_is_ratio`` the kappa table holds
    kappa/kappa_crit and kappa = kappa_ratio (ba - 1)).  Writes the outputs at offsets
    0 .. i1 - i0 - 1 (``outcome``/``uncertain`` only with ``has_size``), with ``lazy``
    ``same[o]`` (bool[7]: output o is one repeated value, bit for bit; without ``lazy``
    every output is written and ``same`` is all False), and the points that need
    Python: their offsets ``sp_idx``, flags ``sp_flags`` and parameters ``sp_par[j] =
    (ba, kappa, eps, vo, size)``.  Returns the number of such points.

    The range is walked in runs over which every table's index is fixed or (a table of
    stride 1) steps by one, so no index arithmetic per point.  A point whose ba, kappa,
    eps and vo are the same table elements as the previous point's (only its size
    differs: a size axis innermost) reuses that point's :func:`critical_point` result
    instead of recomputing it (same inputs, same bits)."""
    n = i1 - i0
    K = np.empty(N_WORK)
    bits = np.empty(2)
    s_b, s_k, s_e, s_v, s_s = strides[0], strides[1], strides[2], strides[3], strides[4]
    n_b, n_k, n_e, n_v, n_s = (
        ba_t.shape[0], kappa_t.shape[0], eps_t.shape[0], vo_t.shape[0], size_t.shape[0]
    )  # fmt: skip
    # per table: steps by one per point (stride 1, more than one value), its position and
    # how far into its run of equal indices the next point is
    d_b, d_k, d_e = s_b == 1 and n_b > 1, s_k == 1 and n_k > 1, s_e == 1 and n_e > 1
    d_v, d_s = s_v == 1 and n_v > 1, s_s == 1 and n_s > 1
    p_b, r_b = (i0 // s_b) % n_b, i0 % s_b
    p_k, r_k = (i0 // s_k) % n_k, i0 % s_k
    p_e, r_e = (i0 // s_e) % n_e, i0 % s_e
    p_v, r_v = (i0 // s_v) % n_v, i0 % s_v
    p_s, r_s = (i0 // s_s) % n_s, i0 % s_s
    c_kind = c_val = c_acc = c_meth = c_onb = c_out = c_unc = lazy
    f_kind = f_meth = f_out = 0
    f_val = f_acc = 0.0
    f_onb = f_unc = False
    n_sp = 0
    # table elements of the previous point's parameters (none yet) and its critical_point
    l_b = l_k = l_e = l_v = -1
    k = m = fl = 0
    v0 = a = 0.0
    j = 0
    while j < n:
        run = n - j
        run = _run_limit(p_b, r_b, s_b, n_b, d_b, run)
        run = _run_limit(p_k, r_k, s_k, n_k, d_k, run)
        run = _run_limit(p_e, r_e, s_e, n_e, d_e, run)
        run = _run_limit(p_v, r_v, s_v, n_v, d_v, run)
        run = _run_limit(p_s, r_s, s_s, n_s, d_s, run)
        # index of point q of the run in each table: p + q * step
        t_b, t_k, t_e, t_v, t_s = int(d_b), int(d_k), int(d_e), int(d_v), int(d_s)
        for q in range(run):
            i_b, i_k, i_e, i_v = p_b + q * t_b, p_k + q * t_k, p_e + q * t_e, p_v + q * t_v
            ba = ba_t[i_b]
            kap = kappa_t[i_k]
            kappa = kap * (ba - 1.0) if kappa_is_ratio else kap
            eps = eps_t[i_e]
            vo = vo_t[i_v]
            sz = size_t[p_s + q * t_s]
            if i_b != l_b or i_k != l_k or i_e != l_e or i_v != l_v:
                # a new parameter point (the previous one's table elements repeat where
                # only the size changed: its critical size is reused, the same bits)
                k, v0, a, m, fl, _ = critical_point(
                    ba, kappa, eps, 1.0 if vo > 0.0 else 0.0, pert, rtol, K
                )
                v0 = stored_value(v0, fl)
                l_b, l_k, l_e, l_v = i_b, i_k, i_e, i_v
            v, ob, oc, unc = finish_point(k, v0, a, fl, sz, vo, has_size)
            i = j + q
            if fl & FLAG_FALLBACK or (has_size and sz < 0.0):
                sp_idx[n_sp] = i
                sp_flags[n_sp] = fl
                sp_par[n_sp, 0] = ba
                sp_par[n_sp, 1] = kappa
                sp_par[n_sp, 2] = eps
                sp_par[n_sp, 3] = vo
                sp_par[n_sp, 4] = sz
                n_sp += 1
            if i == 0:
                f_kind, f_val, f_acc, f_meth, f_onb, f_out, f_unc = k, v, a, m, ob, oc, unc
            if not lazy:
                kind[i], value[i], acc[i], method[i], on_b[i] = k, v, a, m, ob
                if has_size:
                    outcome[i], uncertain[i] = oc, unc
                continue
            # an output still one repeated value is not written; on the point that ends
            # its run, the run is laid out first
            if c_kind and k != f_kind:
                c_kind = False
                kind[:i] = f_kind
            if not c_kind:
                kind[i] = k
            if c_val and not _same_f64(v, f_val, bits):
                c_val = False
                value[:i] = f_val
            if not c_val:
                value[i] = v
            if c_acc and not _same_f64(a, f_acc, bits):
                c_acc = False
                acc[:i] = f_acc
            if not c_acc:
                acc[i] = a
            if c_meth and m != f_meth:
                c_meth = False
                method[:i] = f_meth
            if not c_meth:
                method[i] = m
            if c_onb and ob != f_onb:
                c_onb = False
                on_b[:i] = f_onb
            if not c_onb:
                on_b[i] = ob
            if has_size:
                if c_out and oc != f_out:
                    c_out = False
                    outcome[:i] = f_out
                if not c_out:
                    outcome[i] = oc
                if c_unc and unc != f_unc:
                    c_unc = False
                    uncertain[:i] = f_unc
                if not c_unc:
                    uncertain[i] = unc
        p_b, r_b = _advance(p_b, r_b, s_b, n_b, d_b, run)
        p_k, r_k = _advance(p_k, r_k, s_k, n_k, d_k, run)
        p_e, r_e = _advance(p_e, r_e, s_e, n_e, d_e, run)
        p_v, r_v = _advance(p_v, r_v, s_v, n_v, d_v, run)
        p_s, r_s = _advance(p_s, r_s, s_s, n_s, d_s, run)
        j += run
    # a repeated output holds its value in its first element
    if n:
        if c_kind:
            kind[0] = f_kind
        if c_val:
            value[0] = f_val
        if c_acc:
            acc[0] = f_acc
        if c_meth:
            method[0] = f_meth
        if c_onb:
            on_b[0] = f_onb
        if has_size and c_out:
            outcome[0] = f_out
        if has_size and c_unc:
            uncertain[0] = f_unc
    same[OUT_KIND], same[OUT_VALUE], same[OUT_ACC], same[OUT_METHOD] = c_kind, c_val, c_acc, c_meth
    same[OUT_ON_BOUNDARY], same[OUT_OUTCOME], same[OUT_UNCERTAIN] = c_onb, c_out, c_unc
    return n_sp
