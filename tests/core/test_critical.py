"""Tests of rsfcore.critical: critical perturbation sizes (closed forms, separatrix, bisection).

Every expected value here comes from outside the code under test: the trusted reference
file, an independent method (bisection on certified classify() outcomes, the closed
forms of rsfcore.analytic), or direct classification of perturbations just below and
above the computed critical size.
"""

from __future__ import annotations

import json
import math
from fractions import Fraction

import numpy as np
import pytest

from rsfcore import ParameterError, Params, analytic, classify
from rsfcore.analytic import _vjump_kcrit
from rsfcore.critical import (
    METHODS,
    asymptotic_start,
    bisect_critical,
    critical_perturbation,
    separatrix_raw,
)
from rsfcore.laws import L_star
from rsfcore.separatrix import _EXPLICIT, N_WORK, _scalar_run, asym_coeffs

from .reference import reference_cases

VJ, LJ = "velocity-jump", "load-point-jump"


def _reference_cases() -> list[dict]:
    return reference_cases()


def _critical_cases() -> list[dict]:
    out = []
    for c in _reference_cases():
        i = c["inputs"]
        if c["kind"] in ("zero", "finite", "infinite") and all(
            k in i for k in ("ba", "kappa", "eps", "vo")
        ):
            out.append(c)
    return out


def _pert(case: dict) -> str:
    text = case["quantity"] + " " + str(case["inputs"].get("perturbation", ""))
    return LJ if "load" in text else VJ


def test_reference_file_has_critical_cases():
    cases = _critical_cases()
    assert len(cases) >= 15
    assert {c["kind"] for c in cases} == {"zero", "finite", "infinite"}


def test_reference_values():
    """Every critical-size case of values.json, within 2 x trusted_rel_tol.

    Tolerance: the reference's trusted_rel_tol is the agreement of its independent methods;
    a factor 2 allows for the reference's own rounding (for ljump_ba2_r2_eps0.25 `value` and
    `value_digits` differ by 0.6 x trusted_rel_tol).  The separatrix is run at
    rtol = min(1e-10, trusted_rel_tol), so the requested accuracy never exceeds what the
    reference can check; closed forms are exact to ~1e-15.
    """
    for c in _critical_cases():
        i = c["inputs"]
        p = Params(i["ba"], i["kappa"], i["eps"], i["vo"])
        tol = c["trusted_rel_tol"]
        rtol = 1e-10 if not tol else max(1e-13, min(1e-10, tol))
        r = critical_perturbation(p, _pert(c), rtol=rtol)
        assert r.kind == c["kind"], c["id"]
        if c["kind"] == "infinite":
            assert r.critical_size is None, c["id"]
        elif c["kind"] == "zero":
            assert r.critical_size == 0.0, c["id"]
        else:
            ref = float(c["value_digits"] or c["value"])
            err = abs(r.critical_size - ref) / ref
            assert err <= 2.0 * tol, (c["id"], r.critical_size, ref, err, r.method)
            assert r.rel_accuracy <= max(10 * rtol, 1e-15), c["id"]
        json.dumps(r.to_dict(), allow_nan=False)


# --- separatrix vs bisection -------------------------------------------------------------
# (ba, kappa/kappa_crit, eps): near kappa = kappa_crit, b/a -> 1 and 100, eps = 0, 1e-300,
# 1e-12, 0.99, large kappa (bisection on classify cannot exceed |d| = 1e4, hence 9e3)
SAMPLE = [
    (2.0, 1 + 1e-6, 0.25),
    (2.0, 1 + 1e-3, 0.0),
    (1 + 1e-6, 2.0, 0.0),
    (1 + 1e-6, 1.5, 0.3),
    (100.0, 1.5, 0.0),
    (100.0, 3.0, 0.2),
    (2.0, 1.5, 1e-300),
    (2.0, 1.5, 1e-12),
    (2.0, 1.005, 0.99),
    (2.0, 9.0e3, 0.0),
    (2.0, 5.0e3, 1e-5),
    (2.0, 30.0, 0.01),
    (2.0, 1.2, 0.8),
    (1.25, 1.5, 0.5),
    (2.0, 4.2, 0.2),
]


def _sample_tol(ba: float, bis_acc: float) -> float:
    # classify itself is limited near the separatrix when excursions reach phi ~ 1e7
    # (b/a - 1 = 1e-6): bisection there is trusted to ~1e-9 only (measured 7.7e-10)
    base = 3e-9 if ba - 1.0 < 1e-3 else 1e-9
    return max(base, 3 * bis_acc)


@pytest.mark.parametrize("pert", [VJ, LJ])
def test_separatrix_matches_bisection(pert):
    for ba, r, eps in SAMPLE:
        if pert == LJ and r > 100:
            continue  # load-point jumps there exceed the double range (tested below)
        p = Params.from_ratio(ba, r, eps)
        c = critical_perturbation(p, pert)
        assert c.kind == "finite" and c.method == METHODS[5], (ba, r, eps, c)
        b = bisect_critical(p, pert, rtol=1e-11)
        err = abs(c.critical_size - b.critical_size) / b.critical_size
        assert err <= _sample_tol(ba, b.rel_accuracy), (
            pert,
            ba,
            r,
            eps,
            c.critical_size,
            b.critical_size,
            err,
        )


@pytest.mark.parametrize("pert", [VJ, LJ])
def test_classification_around_separatrix_result(pert):
    """d_crit (1 - 1e-8) is stable and d_crit (1 + 1e-8) unstable, by direct integration."""
    for ba, r, eps in SAMPLE + [(2.0, 2.0, 0.25), (2.0, 1.5, 0.05), (2.0, 3.0, 0.3)]:
        if pert == LJ and r > 100:
            continue
        for vo in (1.0, 7.5):  # the critical size does not depend on v_o > 0
            p = Params.from_ratio(ba, r, eps, vo)
            d = critical_perturbation(p, pert).critical_size
            lo = classify(p, pert, d * (1 - 1e-8))
            hi = classify(p, pert, d * (1 + 1e-8))
            assert lo.outcome == "stable", (pert, ba, r, eps, vo, d, lo.certificate)
            assert hi.outcome == "unstable", (pert, ba, r, eps, vo, d, hi.certificate)
            if ba > 1.5:
                break


def _integrate_outcome(p: Params, pert: str, size: float) -> str:
    return classify(p, pert, size, method="integrate").outcome


@pytest.mark.parametrize("ba", [1.25, 2.0, 10.0, 100.0])
@pytest.mark.parametrize("eps", [0.0, 1e-12, 0.1, 0.5, 0.9, 0.99])
def test_closed_forms_against_direct_integration(ba, eps):
    """kappa = kappa_crit closed forms and the v_o = 0 form, certified by integration only."""
    p = Params(ba, ba - 1.0, eps)
    for pert in (VJ, LJ):
        r = critical_perturbation(p, pert)
        assert r.kind == "finite" and "closed form" in r.method
        assert r.on_boundary  # kappa = kappa_crit is a boundary (zero | finite)
        assert _integrate_outcome(p, pert, r.critical_size * (1 - 1e-8)) == "stable"
        assert _integrate_outcome(p, pert, r.critical_size * (1 + 1e-8)) == "unstable"
    for kappa in (0.3 * (ba - 1.0), ba - 1.0, 1.7 * (ba - 1.0)):
        p0 = Params(ba, kappa, eps, 0.0)
        r = critical_perturbation(p0, VJ)
        if eps * kappa >= ba - 1.0:
            assert r.kind == "infinite"
            continue
        assert r.method == METHODS[4]
        assert _integrate_outcome(p0, VJ, r.critical_size * (1 - 1e-8)) == "stable"
        assert _integrate_outcome(p0, VJ, r.critical_size * (1 + 1e-8)) == "unstable"


def test_compiled_closed_form_matches_analytic_and_mpmath():
    """The compiled kappa = kappa_crit velocity-jump form against analytic.py (ba <= 100,
    where both are well conditioned) and against a 60-digit mpmath root of the same
    equation (`eq: limiting trajectory 1` with psi = phi) up to b/a = 1e6."""
    import mpmath  # a test dependency (pyproject [test])

    mpmath.mp.dps = 60
    for ba in (1 + 1e-6, 1.25, 2.0, 10.0, 100.0, 1e4, 1e6):
        for eps in (0.0, 1e-300, 1e-9, 0.1, 0.5, 0.9, 0.999):
            a = _vjump_kcrit(ba, eps)
            if ba <= 100.0:
                ref_a = analytic.velocity_jump_crit_kcrit(ba, eps)
                # analytic.py's log1p(eps R) loses ~1/(1 - eps) ulp as eps -> 1 (2e-14 vs
                # mpmath at eps = 0.999) and its Lambert-W/brentq forms lose a few ulp at b/a = 100
                # (4.4e-15): compare at 1e-14, and 1e-13 as eps -> 1
                assert abs(a - ref_a) <= (1e-14 if eps <= 0.9 else 1e-13) * ref_a, (ba, eps)
            B, e = mpmath.mpf(ba), mpmath.mpf(eps)
            D = B * (1 - e) + e
            q = (1 - e) * (B - 1) / D

            def h(d, q=q, e=e, slip=eps < 1e-100):
                if slip:
                    return d + q * mpmath.e ** (-d) - 1
                return d + mpmath.log1p(e * (q * mpmath.e ** (-d) - 1)) / e

            ref = mpmath.findroot(h, mpmath.mpf(a))
            # the root is ill-conditioned as eps -> 1 with large b/a (h' ~ (1 - eps) e^d):
            # the tolerance is the condition-number bound the closed form reports
            # (tests/core/test_closed_form_accuracy.py checks it at >= 1000 points)
            tol = analytic.velocity_jump_crit_kcrit_acc(ba, eps)[1]
            assert abs(float((a - ref) / ref)) <= tol, (ba, eps, a)
    assert math.isinf(_vjump_kcrit(2.0, 1.0))


@pytest.mark.parametrize("ba", [1.25, 2.0, 100.0])
@pytest.mark.parametrize("eps", [0.0, 0.3, 0.9])
def test_separatrix_at_kcrit_reproduces_closed_forms(ba, eps):
    """Independent check: the separatrix integrated at kappa = kappa_crit exactly lands on
    the closed forms (`eq: limiting trajectory 1`; dv = 1/(kappa_crit (1 - eps)))."""
    p = Params(ba, ba - 1.0, eps)
    st, d, _, _ = separatrix_raw(p, VJ, 1e-12)
    assert st == 0
    assert abs(d - analytic.velocity_jump_crit_kcrit(ba, eps)) <= 1e-10 * d
    st, dv, _, _ = separatrix_raw(p, LJ, 1e-12)
    assert st == 0
    ref = analytic.load_point_jump_crit_kcrit(ba, eps)
    assert abs(dv - ref) <= 1e-10 * ref


def test_asymptotic_start_truncation():
    """u = L* - c1 z - c2 z^2 + O(z^3): starting further out changes the result by O(z0^3),
    far below the tolerance at the z0 used (c z0 ~ 1e-5 at rtol 1e-10)."""
    K = np.empty(N_WORK)
    for ba, r, eps in [(2.0, 2.0, 0.25), (2.0, 1.5, 0.05), (2.0, 1.01, 0.9), (100.0, 1.5, 0.0)]:
        p = Params.from_ratio(ba, r, eps)
        kc = p.kappa_crit
        Ls, c1, c2 = asym_coeffs(p.kappa, kc, eps)
        cz = max(c1, math.sqrt(abs(c2)))
        res = {}
        for zt in (1e-8, 1e-5, 1e-4):
            s0 = min(Ls + math.log(zt / cz), -5.0)
            a = asymptotic_start(p, s0)
            # DOP853 alone (no stiffness switch, no relaxation, no profile recorded)
            rec, rec_n = np.empty((2, 1)), np.zeros(1, dtype=np.int64)
            st, t, u, *_ = _scalar_run(
                _EXPLICIT, 0, s0, a["u"], 0.0, p.kappa, kc, eps, 1e-14, 1e-17, math.inf, 0.0,
                1.0, K, 0.5, 0.0, 1.0, math.nan, False, rec, rec_n, rec, 0, 0.0,
            )  # fmt: skip
            assert st == 0 and t == 0.0
            res[zt] = u
        ref = res[1e-8]
        assert abs(res[1e-5] - ref) <= 1e-12 * ref, (ba, r, eps, res)
        # cubic scaling: 10x larger z0 gives a change <= ~1e3 x larger, and below 1e-9
        assert abs(res[1e-4] - ref) <= 1e-9 * ref
        assert a["phi"] > 5.0


@pytest.mark.slow
def test_accuracy_estimate_and_delivered_accuracy():
    """rel_accuracy bounds the actual error (vs rtol = 1e-13) and the error meets rtol."""
    rng = np.random.default_rng(4)
    for pert in (VJ, LJ):
        for _ in range(60):
            ba = float(np.exp(rng.uniform(np.log(1.01), np.log(50.0))))
            r = float(rng.uniform(1.01, 6.0))
            eps = float(rng.uniform(0.0, min(1.0, 0.99 / r)))
            p = Params.from_ratio(ba, r, eps)
            for rtol in (1e-8, 1e-10):
                a = critical_perturbation(p, pert, rtol=rtol)
                t = critical_perturbation(p, pert, rtol=1e-13)
                if a.kind != "finite" or a.method != METHODS[5]:
                    continue
                err = abs(a.critical_size - t.critical_size) / t.critical_size
                assert err <= rtol, (pert, ba, r, eps, rtol, err)
                assert err <= a.rel_accuracy + 1e-13, (pert, ba, r, eps, rtol, err, a.rel_accuracy)


def test_eps_to_zero_is_continuous():
    for pert in (VJ, LJ):
        for r in (1.5, 3.0):
            v0 = critical_perturbation(Params.from_ratio(2.0, r, 0.0), pert).critical_size
            v300 = critical_perturbation(Params.from_ratio(2.0, r, 1e-300), pert).critical_size
            v12 = critical_perturbation(Params.from_ratio(2.0, r, 1e-12), pert).critical_size
            assert abs(v300 - v0) <= 1e-13 * v0
            assert abs(v12 - v0) <= 1e-10 * v0


def test_kinds_and_boundaries():
    # zero: kappa < kappa_crit with a moving load point (both perturbations)
    for pert in (VJ, LJ):
        r = critical_perturbation(Params.from_ratio(2.0, 0.7, 0.3), pert)
        assert r.kind == "zero" and r.critical_size == 0.0 and not r.on_boundary
        assert classify(Params.from_ratio(2.0, 0.7, 0.3), pert, 1e-3).outcome == "unstable"
        r = critical_perturbation(Params(2.0, 0.0, 0.3), pert)
        # kappa = 0: no spring, so a load-point jump changes nothing (issue 22)
        assert r.kind == ("zero" if pert == VJ else "infinite")
    # infinite: eps kappa >= kappa_crit; huge perturbations stay stable by direct integration
    for pert, size in ((VJ, 40.0), (LJ, 1e6)):
        p = Params.from_ratio(2.0, 5.0, 0.25)
        r = critical_perturbation(p, pert)
        assert r.kind == "infinite" and r.critical_size is None
        assert classify(p, pert, size).outcome == "stable"
    # aging law at kappa = kappa_crit: infinite (x = 1), flagged
    r = critical_perturbation(Params(2.0, 1.0, 1.0), VJ)
    assert r.kind == "infinite" and r.on_boundary
    # x = 1 up to rounding: 25/9 * 0.36 (numerics.md): flagged; the kind follows the exact
    # sign of 1 - x of the input doubles (issue 22; referee: exact rationals)
    p = Params.from_ratio(2.0, 25.0 / 9.0, 0.36)
    r = critical_perturbation(p, VJ)
    omx = 1 - Fraction(p.eps) * Fraction(p.kappa) / (Fraction(p.ba) - 1)
    assert r.kind == ("finite" if omx > 0 else "infinite") and r.on_boundary
    if omx > 0:  # then d_crit <= L* = -ln(1 - x)/eps (~85 here)
        assert r.critical_size is not None
        assert 0 < r.critical_size <= -math.log(float(omx)) / p.eps * (1 + 1e-9)
    # just inside: finite and not flagged
    p = Params.from_ratio(2.0, 25.0 / 9.0, 0.36 * (1 - 1e-9))
    r = critical_perturbation(p, VJ)
    assert r.kind == "finite" and not r.on_boundary
    assert r.critical_size > 0.99 * float(L_star(p.kappa, p.kappa_crit, 0.0))
    # kappa = kappa_crit up to rounding uses the closed form and is flagged
    kc = 1.1 - 1.0
    p = Params(1.1, kc * (1 + 4e-16), 0.2)
    r = critical_perturbation(p, VJ)
    assert r.on_boundary and "closed form" in r.method
    # ... and just below it (exactly, for these doubles) it is zero (issue 22)
    p = Params(1.1, kc * (1 - 4e-16), 0.2)
    assert Fraction(p.kappa) < Fraction(1.1) - 1
    r = critical_perturbation(p, VJ)
    assert r.on_boundary and r.kind == "zero"
    # stationary load point
    r = critical_perturbation(Params(2.0, 0.5, 0.0, 0.0), VJ)
    assert r.kind == "finite" and r.method == METHODS[4]
    r = critical_perturbation(Params(2.0, 0.0, 0.3, 0.0), VJ)
    assert r.kind == "zero"
    r = critical_perturbation(Params(2.0, 4.0, 0.3, 0.0), VJ)
    assert r.kind == "infinite"
    with pytest.raises(ParameterError) as e:
        critical_perturbation(Params(2.0, 1.5, 0.3, 0.0), LJ)
    assert e.value.field == "vo"


def test_load_point_jump_beyond_double_range():
    """For kappa >> kappa_crit the critical load-point jump exceeds e^709 (dv > 8e307): it is
    finite, reported by log_critical_size = ln(1 + dv) (critical_size inf, null in JSON)."""
    from rsfcore.phase import trace_separatrix

    p = Params.from_ratio(10.0, 1000.0, 0.0)
    r = critical_perturbation(p, LJ)
    assert r.kind == "finite" and "double range" in r.method
    assert r.critical_size == math.inf and r.to_dict()["critical_size"] is None
    lg = r.log_critical_size
    assert lg is not None and 709.0 < lg < 1e4 and r.to_dict()["log_critical_size"] == lg
    # the separatrix reaches L = 0 at s_theta = ln(1 + dv) > 709 (status OVERFLOW, value l)
    st, val, _, _ = separatrix_raw(p, LJ)
    assert st == 5 and val == lg
    # independent tracing of the same curve (rsfcore.phase: own driver, dense output)
    sep = trace_separatrix(p, 1e-12)
    assert sep is not None
    assert float(sep.t_of_u(0.0)[0]) == pytest.approx(lg, rel=1e-9)
    # below the range: the log is log1p of the size
    r2 = critical_perturbation(Params.from_ratio(2.0, 300.0, 0.0), LJ)
    assert r2.kind == "finite" and 1e100 < r2.critical_size < 1e300
    assert r2.log_critical_size == pytest.approx(math.log1p(r2.critical_size), rel=1e-15)


def test_accuracy_met_and_log_fields():
    # closed form at kappa = kappa_crit, b/a = 1e6, eps -> 1: ill-conditioned, bound ~3e-12
    p = Params(1e6, 1e6 - 1.0, 0.9972673220817913)
    strict = critical_perturbation(p, VJ, rtol=1e-13)
    assert not strict.accuracy_met and "ill-conditioned" in strict.reason
    assert strict.rel_accuracy > 1e-13
    loose = critical_perturbation(p, VJ, rtol=1e-10)
    assert loose.accuracy_met and loose.reason == ""
    assert loose.log_critical_size == loose.critical_size  # velocity jump: d is the log
    lj = critical_perturbation(Params(2.0, 1.0, 0.3), LJ)
    assert lj.log_critical_size == pytest.approx(math.log1p(lj.critical_size), rel=1e-15)
    d = critical_perturbation(Params(2.0, 3.0, 0.5), VJ).to_dict()  # infinite
    assert d["log_critical_size"] is None and d["accuracy_met"] is True


def test_invalid_inputs():
    p = Params(2.0, 1.5, 0.1)
    with pytest.raises(ParameterError) as e:
        critical_perturbation(p, "stress-step")
    assert e.value.field == "perturbation"
    with pytest.raises(ParameterError) as e:
        critical_perturbation(p, VJ, rtol=0.5)
    assert e.value.field == "rtol"
    with pytest.raises(ParameterError):
        critical_perturbation({"ba": 2.0}, VJ)  # type: ignore[arg-type]


def test_to_dict_json_safe():
    for p, pert in (
        (Params(2.0, 1.5, 0.1), VJ),
        (Params(2.0, 5.0, 0.5), VJ),
        (Params(2.0, 0.5, 0.5), LJ),
    ):
        d = critical_perturbation(p, pert).to_dict()
        s = json.dumps(d, allow_nan=False)
        assert set(d) >= {
            "kind",
            "critical_size",
            "rel_accuracy",
            "method",
            "perturbation",
            "params",
        }
        assert json.loads(s)["params"]["ba"] == 2.0


def test_bisection_fallback_consistency():
    """bisect_critical gives the same kinds as critical_perturbation, and the closed forms
    by integration."""
    p = Params(2.0, 1.0, 0.25)
    b = bisect_critical(p, LJ, rtol=1e-9)
    assert b.kind == "finite" and abs(b.critical_size - 4.0 / 3.0) <= 1e-8
    assert bisect_critical(Params(2.0, 3.0, 0.5), VJ).kind == "infinite"
    assert bisect_critical(Params(2.0, 0.5, 0.5), VJ).kind == "zero"
