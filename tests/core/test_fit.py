"""Fitting lab velocity-step records (rsfcore.fit): records, forward model, recovery of
known parameters, law choice, honest failure, an independent (scipy solve_ivp) record,
uncertainty calibration and the stability answer.

Standard synthetic record: a = 0.01, b = 0.015, Dc = 10 um, mu0 = 0.6; load point at
1 um/s for 200 s (20 Dc), 10 um/s for 30 s (30 Dc), 1 um/s for 300 s (30 Dc).  Machine
stiffness in friction per metre [1/m]: kappa = k Dc/a, so k = 800 /m is kappa = 0.8
(kappa/kappa_crit = 1.6) and k = 2000 /m is kappa = 2 (ratio 4).
"""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from rsfcore.critical import critical_perturbation
from rsfcore.fit import (
    FitStatus,
    ForwardModel,
    Law,
    ModelSpec,
    Record,
    compare_laws,
    fit_record,
    nagata_eps,
    read_record,
    sample_posterior,
    synthetic_record,
)
from rsfcore.laws import nagata_to_intermediate
from rsfcore.params import ParameterError, Params, PhysicalParams
from rsfcore.protocols import load_history

A, B, DC, MU0 = 0.01, 0.015, 1e-5, 0.6
TRUE = {"mu0": MU0, "a": A, "b": B, "Dc_m": DC}


def design(n: int = 2000) -> tuple[np.ndarray, np.ndarray]:
    t = np.linspace(0.0, 530.0, n)
    v = np.where(t < 200.0, 1e-6, np.where(t < 230.0, 1e-5, 1e-6))
    return t, v


def _json_ok(d: dict) -> None:
    json.dumps(d, allow_nan=False)


def _max_rel(res, true: dict) -> float:
    return max(abs(res.params[n] / true[n] - 1.0) for n in res.fitted)


# ---------------------------------------------------------------------------------------
# Records
# ---------------------------------------------------------------------------------------
def test_record_csv_json_and_displacement(tmp_path) -> None:
    t, v = design(50)
    mu = 0.6 + 0.001 * np.sin(t)
    rec = Record(t_s=t, v_lp_m_s=v, mu=mu, name="r")
    assert rec.n_steps == 2 and list(rec.segment_starts) == [
        0,
        int(np.argmax(v > 1e-6)),
        int(np.argmax(t >= 230.0)),
    ]
    # CSV text (repr round-trips floats exactly), with a comment and an extra column
    csv = "# lab run 17\n" + rec.to_csv().replace("t_s,v_lp_m_s,mu", "t_s,v_lp_m_s,mu,extra", 1)
    csv = "\n".join(ln + (",9" if i > 1 else "") for i, ln in enumerate(csv.splitlines())) + "\n"
    back = read_record(csv)
    assert (
        np.array_equal(back.t_s, t)
        and np.array_equal(back.mu, mu)
        and np.array_equal(back.v_lp_m_s, v)
    )
    # JSON text and file; semicolon CSV file
    assert read_record(json.dumps(rec.to_dict())).digest() == rec.digest()
    p = tmp_path / "rec.csv"
    p.write_text(rec.to_csv().replace(",", ";"))
    assert read_record(str(p)).digest() == rec.digest()
    assert read_record(p).name == "rec.csv"
    # displacement instead of time: x = cumulative v dt reproduces t up to rounding
    x = rec.load_point_m
    recx = read_record({"x_lp_m": x, "v_lp_m_s": v, "mu": mu})
    assert np.allclose(recx.t_s, t, rtol=1e-12, atol=1e-12)


@pytest.mark.parametrize(
    "cols, field",
    [
        ({"t_s": [0, 1, 1, 2] * 3, "v_lp_m_s": [1e-6] * 12, "mu": [0.6] * 12}, "record.t_s[2]"),
        (
            {"t_s": list(range(12)), "v_lp_m_s": [1e-6] * 11 + [-1.0], "mu": [0.6] * 12},
            "record.v_lp_m_s[11]",
        ),
        (
            {"t_s": list(range(12)), "v_lp_m_s": [0.0] + [1e-6] * 11, "mu": [0.6] * 12},
            "record.v_lp_m_s[0]",
        ),
        (
            {
                "t_s": list(range(12)),
                "v_lp_m_s": [1e-6] * 12,
                "mu": [0.6] * 5 + [float("nan")] + [0.6] * 6,
            },
            "record.mu[5]",
        ),
        ({"t_s": list(range(12)), "v_lp_m_s": [1e-6] * 12}, "record.mu"),
        ({"t_s": list(range(5)), "v_lp_m_s": [1e-6] * 5, "mu": [0.6] * 5}, "record"),
        (
            {"x_lp_m": list(range(12)), "v_lp_m_s": [1e-6] * 5 + [0.0] * 7, "mu": [0.6] * 12},
            "record.v_lp_m_s[5]",
        ),
    ],
)
def test_record_errors_name_the_field(cols: dict, field: str) -> None:
    with pytest.raises(ParameterError) as e:
        read_record(cols)
    assert e.value.field == field


def test_record_text_errors() -> None:
    with pytest.raises(ParameterError) as e:
        read_record("time,velocity,friction\n1,2,3\n")
    assert e.value.field == "record.header"
    with pytest.raises(ParameterError) as e:
        read_record("t_s,v_lp_m_s,mu\n0,1e-6,0.6\n1,1e-6,abc\n")
    assert e.value.field == "record.mu[1]"
    with pytest.raises(ParameterError) as e:
        read_record("/nonexistent/file.csv")
    assert e.value.field == "record"


# ---------------------------------------------------------------------------------------
# Forward model against other computations
# ---------------------------------------------------------------------------------------
def test_forward_model_equals_protocols_load_history() -> None:
    """The fit's forward model and rsfcore.protocols.load_history integrate the same system
    through different parameter mappings (k [1/m] with mu0 as f_* here, PhysicalParams
    with sigma there).  Compared at load_history's own output times: agreement within
    1e-10 in friction (both at rtol 1e-11; their integration error is ~3e-12)."""
    sigma = 1e7
    k = 800.0
    ph = PhysicalParams(
        a=A, b=B, Dc=DC, sigma=sigma, k=k * sigma, V_star=1e-6, Vo=1e-6, eps=0.5, f_star=MU0
    )
    res = load_history(
        ph, [(200.0, 1e-6), (30.0, 1e-5), (300.0, 1e-6)], n_points_per_segment=300, rtol=1e-11
    )
    t = res.t_s
    # segment of each sample: v on [t_i, t_i+1) -> a junction sample carries the new velocity
    v = np.where(t < 200.0, 1e-6, np.where(t < 230.0, 1e-5, 1e-6))
    rec = Record(t_s=t, v_lp_m_s=v, mu=np.zeros_like(t))
    model = ForwardModel(rec, ModelSpec(Law.EPS, False, k, rtol=1e-11))
    mu, n_ok = model.friction({"mu0": MU0, "a": A, "b": B, "Dc_m": DC, "eps": 0.5, "k_per_m": k})
    assert n_ok == rec.n
    assert np.max(np.abs(mu - res.friction)) < 1e-10


@pytest.mark.parametrize("eps", [0.0, 0.3, 1.0])
def test_stiff_closed_form_against_ode_and_large_stiffness(eps: float) -> None:
    """k = inf uses the exact solution of the law at constant V.  Checked (1) against
    solve_ivp of d ln theta/dt = G(L) V/Dc at rtol 1e-12 (agreement 1e-10 in friction:
    the ODE's error), and (2) as the limit of the engine for k -> inf: away from the step
    instants (where a rigid machine jumps by a ln(v2/v1) and a finite one rises over
    ~a/(k v) seconds) the deviation falls like 1/k (ratio 10 +- 20 % between k = 1e6 and
    1e7 /m, i.e. kappa 1e3 and 1e4)."""
    t, v = design(400)
    rec = Record(t_s=t, v_lp_m_s=v, mu=np.zeros_like(t))
    p = {"mu0": MU0, "a": A, "b": B, "Dc_m": DC, "eps": eps, "k_per_m": math.inf}
    mu_cf, _ = ForwardModel(rec, ModelSpec(Law.EPS, False, math.inf)).friction(p)

    def G(L: float) -> float:
        return -L if eps == 0.0 else math.expm1(-eps * L) / eps

    lth = 0.0  # ln(V0 theta/Dc)
    V0 = v[0]
    mu_ode = np.empty_like(t)
    starts = [0, int(np.argmax(v > 1e-6)), int(np.argmax(t >= 230.0)), t.shape[0]]
    for j in range(3):
        i0, i1 = starts[j], starts[j + 1]
        Vj = v[i0]
        t_end = t[i1] if i1 < t.shape[0] else t[-1]
        sol = solve_ivp(
            lambda _t, y, Vj=Vj: [G(math.log(Vj / V0) + y[0]) * Vj / DC],
            (t[i0], t_end),
            [lth],
            method="DOP853",
            rtol=1e-12,
            atol=1e-14,
            dense_output=True,
        )
        lt = sol.sol(t[i0:i1])[0]
        mu_ode[i0:i1] = MU0 + A * math.log(Vj / V0) + B * lt
        lth = float(sol.y[0, -1])
    assert np.max(np.abs(mu_cf - mu_ode)) < 1e-10
    devs = []
    away = np.ones(t.shape[0], dtype=bool)
    away[rec.segment_starts] = False
    for k in (1e6, 1e7):
        mu_k, n_ok = ForwardModel(rec, ModelSpec(Law.EPS, False, k)).friction({**p, "k_per_m": k})
        assert n_ok == rec.n
        devs.append(float(np.max(np.abs(mu_k - mu_cf)[away])))
    assert 8.0 < devs[0] / devs[1] < 12.0


# ---------------------------------------------------------------------------------------
# Noise-free recovery
# ---------------------------------------------------------------------------------------
CASES = [
    # (law, eps, k_true [1/m], fit_stiffness)
    ("aging", 1.0, 800.0, False),
    ("aging", 1.0, 800.0, True),
    ("aging", 1.0, math.inf, False),
    ("slip", 0.0, 2000.0, False),
    ("slip", 0.0, 2000.0, True),
    ("eps", 0.5, 2000.0, False),
    ("eps", 0.5, 2000.0, True),
    ("eps", 0.5, math.inf, False),
]


@pytest.mark.parametrize("law, eps, k, fit_k", CASES)
def test_noise_free_recovery(law: str, eps: float, k: float, fit_k: bool) -> None:
    """Synthetic records from the forward model (rtol 1e-10): the fit recovers the true
    parameters to 1e-6 relative (the issue's bound; measured 1e-15 .. 1e-9, limited by
    the forward model's ~3e-11 friction error amplified by the condition number ~10)."""
    true = {**TRUE, "eps": eps, "k_per_m": k}
    rec = synthetic_record(*design(), **true)
    res = fit_record(rec, law, stiffness=None if fit_k else k, fit_stiffness=fit_k)
    assert res.status is FitStatus.OK, res.message
    assert _max_rel(res, true) < 1e-6
    assert res.rms < 1e-9
    _json_ok(res.to_dict())


def test_noise_free_nagata() -> None:
    """Nagata law (c = 2) is the intermediate law with eps = b/(b + 2a) = 3/7; the record
    made with that eps is fitted to 1e-6 and the Nagata parameters map back
    (rsfcore.laws.nagata_to_intermediate) to the intermediate ones to 1e-12."""
    eps = nagata_eps(A, B, 2.0)
    assert abs(eps - 3.0 / 7.0) < 1e-15
    true = {**TRUE, "eps": eps, "k_per_m": 2000.0}
    res = fit_record(synthetic_record(*design(), **true), "nagata", stiffness=2000.0, nagata_c=2.0)
    assert res.ok and _max_rel(res, true) < 1e-6
    back = nagata_to_intermediate(
        res.params["aN"], res.params["bN"], res.params["DcN_m"], res.params["cN"]
    )
    for key, name in (("a", "a"), ("b", "b"), ("Dc", "Dc_m"), ("eps", "eps")):
        assert abs(back[key] / res.params[name] - 1.0) < 1e-12


def test_displacement_record_fits_like_time_record() -> None:
    true = {**TRUE, "eps": 1.0, "k_per_m": 800.0}
    rec = synthetic_record(*design(), **true)
    recx = read_record({"x_lp_m": rec.load_point_m + 1e-3, "v_lp_m_s": rec.v_lp_m_s, "mu": rec.mu})
    res = fit_record(recx, "aging", stiffness=800.0)
    assert res.ok and _max_rel(res, true) < 1e-6


def test_slide_hold_slide_record() -> None:
    """Holds (v_lp = 0) need a finite stiffness; a slide-hold-slide record (aging law) is
    fitted to 1e-6, and the same record with an infinitely stiff machine is refused."""
    t = np.linspace(0.0, 400.0, 2000)
    v = np.where((t >= 100.0) & (t < 200.0), 0.0, 1e-6)
    true = {**TRUE, "eps": 1.0, "k_per_m": 2000.0}
    rec = synthetic_record(t, v, **true)
    res = fit_record(rec, "aging", stiffness=2000.0)
    assert res.ok and _max_rel(res, true) < 1e-6
    with pytest.raises(ParameterError) as e:
        fit_record(rec, "aging")
    assert e.value.field.startswith("record.v_lp_m_s")


@pytest.mark.parametrize("eps, want", [(1.0, "aging"), (0.0, "slip"), (0.5, "eps")])
def test_law_choice_noise_free(eps: float, want: str) -> None:
    """The right law has the lowest AIC.  On aging or slip records the eps fit is as
    good (eps ends on its bound) but has one parameter more: the misfit floor (1e-9,
    far above both fits' ~1e-15 misfit) makes the simpler law win by delta AIC = 2."""
    k = 800.0 if eps == 1.0 else 2000.0
    rec = synthetic_record(*design(1000), **TRUE, eps=eps, k_per_m=k)
    cmp = compare_laws(rec, stiffness=k)
    assert cmp.best == want
    scores = {s.law: s for s in cmp.scores}
    assert scores[want].delta_aic == 0.0
    others = [s.delta_aic for name, s in scores.items() if name != want]
    assert min(others) >= 2.0 - 1e-9
    assert cmp.fits[want].stability is not None
    _json_ok(cmp.to_dict())


# ---------------------------------------------------------------------------------------
# A record computed independently of rsfcore
# ---------------------------------------------------------------------------------------
def textbook_record(
    t: np.ndarray,
    v: np.ndarray,
    *,
    mu0: float,
    a: float,
    b: float,
    Dc: float,
    k: float,
    law: str,
    rtol: float = 1e-12,
) -> np.ndarray:
    """Spring-slider in SI, textbook form, integrated by scipy solve_ivp (DOP853):

        mu = mu0 + a ln(V/V0) + b ln(V0 theta/Dc)  ->  V = V0 exp((mu - mu0 - b ln(V0 theta/Dc))/a)
        d mu/dt = k (v_lp - V)
        d theta/dt = 1 - V theta/Dc (aging)   or   -(V theta/Dc) ln(V theta/Dc) (slip)

    from steady state at V0 = v_lp[0] (theta = Dc/V0, mu = mu0), segment by segment."""
    V0 = float(v[0])

    def rhs(_t: float, y: np.ndarray, vlp: float) -> list[float]:
        mu, th = y
        V = V0 * math.exp((mu - mu0 - b * math.log(V0 * th / Dc)) / a)
        om = V * th / Dc
        dth = 1.0 - om if law == "aging" else -om * math.log(om)
        return [k * (vlp - V), dth]

    y = np.array([mu0, Dc / V0])
    starts = [0] + [i for i in range(1, len(t)) if v[i] != v[i - 1]] + [len(t)]
    out = np.empty(len(t))
    atol = np.array([1e-15, 1e-15 * Dc / V0])
    for j in range(len(starts) - 1):
        i0, i1 = starts[j], starts[j + 1]
        t_end = t[i1] if i1 < len(t) else t[-1]
        sol = solve_ivp(
            rhs,
            (t[i0], t_end),
            y,
            method="DOP853",
            rtol=rtol,
            atol=atol,
            dense_output=True,
            args=(float(v[i0]),),
        )
        assert sol.success
        out[i0:i1] = sol.sol(t[i0:i1])[0]
        y = sol.y[:, -1]
    return out


@pytest.mark.parametrize("law, k", [("aging", 800.0), ("slip", 2000.0)])
@pytest.mark.parametrize("fit_k", [False, True])
def test_fit_independent_solve_ivp_record(law: str, k: float, fit_k: bool) -> None:
    """A record from the textbook SI equations integrated by scipy (no rsfcore code) is
    fitted to 1e-6 relative (measured ~5e-11: both integrations are accurate to ~1e-12
    in friction)."""
    t, v = design(1000)
    mu = textbook_record(t, v, mu0=MU0, a=A, b=B, Dc=DC, k=k, law=law)
    res = fit_record(
        Record(t_s=t, v_lp_m_s=v, mu=mu), law, stiffness=None if fit_k else k, fit_stiffness=fit_k
    )
    assert res.ok, res.message
    assert _max_rel(res, {**TRUE, "k_per_m": k}) < 1e-6
    assert res.rms < 1e-10


# ---------------------------------------------------------------------------------------
# Honest failure
# ---------------------------------------------------------------------------------------
@pytest.mark.parametrize("noise", [0.0, 1e-4])
def test_no_velocity_step_is_a_clear_failure(noise: float) -> None:
    t = np.linspace(0.0, 300.0, 1000)
    rec = synthetic_record(t, np.full(1000, 1e-6), **TRUE, eps=1.0, k_per_m=1000.0, noise=noise)
    res = fit_record(rec, "aging", stiffness=1000.0)
    assert res.status is FitStatus.ILL_CONDITIONED and not res.ok
    assert "no velocity step" in res.message
    assert not res.identified["Dc_m"] and res.stability is None
    _json_ok(res.to_dict())


@pytest.mark.parametrize("seed", range(4))
@pytest.mark.parametrize("slip_dc", [0.1, 1.0, 3.0])
def test_too_short_step_is_a_clear_failure(slip_dc: float, seed: int) -> None:
    """A step followed by only 0.1 - 3 Dc of load-point slip with noise 1e-4 (the friction
    change is ~2e-2): Dc is not determined.  The fit must say so (ILL_CONDITIONED, Dc not
    identified, no stability answer) rather than report a value.  At 3 Dc the covariance
    alone looks acceptable in some realisations (relative error 0.2 on Dc with the truth
    3.5 standard errors away); the linearity check (misfit 2 sd away is 60-150x the
    quadratic prediction) catches those."""
    t = np.linspace(0.0, 200.0 + slip_dc, 2000)
    v = np.where(t < 200.0, 1e-6, 1e-5)
    rec = synthetic_record(t, v, **TRUE, eps=1.0, k_per_m=1000.0, noise=1e-4, seed=seed)
    res = fit_record(rec, "aging", stiffness=1000.0)
    assert res.status is FitStatus.ILL_CONDITIONED, (res.params, res.stderr)
    assert not res.identified["Dc_m"]
    assert "Dc" in res.message and res.stability is None


def test_enough_slip_is_determined() -> None:
    """The same design with 10 Dc after the step is OK, the truth within 3 standard errors."""
    t = np.linspace(0.0, 210.0, 2000)
    v = np.where(t < 200.0, 1e-6, 1e-5)
    rec = synthetic_record(t, v, **TRUE, eps=1.0, k_per_m=1000.0, noise=1e-4, seed=0)
    res = fit_record(rec, "aging", stiffness=1000.0)
    assert res.ok
    assert res.linearity is not None and 0.9 < res.linearity[0] <= res.linearity[1] < 1.1
    for n in res.fitted:
        assert abs(res.params[n] - {**TRUE}[n]) < 3 * res.stderr[n]


# ---------------------------------------------------------------------------------------
# Uncertainty calibration
# ---------------------------------------------------------------------------------------
@pytest.mark.slow
@pytest.mark.parametrize(
    "law, eps, k, fit_k",
    [("aging", 1.0, 800.0, True), ("slip", 0.0, 2000.0, False), ("eps", 0.5, 2000.0, True)],
)
def test_noisy_records_within_two_sigma(law: str, eps: float, k: float, fit_k: bool) -> None:
    """50 records with Gaussian noise 3e-4 (1.3 % of the step's friction change): each
    parameter lies within 2 stated standard errors of the truth in >= 90 % of them (the
    issue's criterion; 95.4 % expected for exact Gaussian errors, binomial sd 3 %).
    Measured with these seeds: aging 90-96 %, slip 94-98 %, eps 92-96 %; the median
    |error|/stderr is 0.56-0.82 (0.674 expected)."""
    true = {**TRUE, "eps": eps, "k_per_m": k}
    t, v = design()
    inside: dict[str, int] = {}
    for s in range(50):
        rec = synthetic_record(t, v, **true, noise=3e-4, seed=100 + s)
        res = fit_record(
            rec, law, stiffness=None if fit_k else k, fit_stiffness=fit_k, stability=False
        )
        assert res.ok, res.message
        for n in res.fitted:
            inside[n] = inside.get(n, 0) + (abs(res.params[n] - true[n]) <= 2.0 * res.stderr[n])
    frac = {n: c / 50 for n, c in inside.items()}
    assert min(frac.values()) >= 0.9, frac


def test_posterior_agrees_with_linearised_errors() -> None:
    """emcee posterior of a well-determined fit (slip law, 500 samples, noise 3e-4):
    posterior standard deviations within 30 % of the linearised standard errors
    (measured 0.97-1.02 with a 16 x 600-step chain; the chain's Monte Carlo error on a
    standard deviation is ~10 %) and medians within 1 standard error of the fit."""
    t, v = design(500)
    rec = synthetic_record(t, v, **TRUE, eps=0.0, k_per_m=2000.0, noise=3e-4, seed=3)
    res = fit_record(rec, "slip", stiffness=2000.0)
    post = sample_posterior(res, n_walkers=16, n_steps=600, burn=200, thin=5, stability_samples=100)
    for n in res.fitted:
        assert 0.7 < post.std[n] / res.stderr[n] < 1.3, n
        assert abs(post.median[n] - res.params[n]) < res.stderr[n], n
    assert 0.2 < post.acceptance_fraction < 0.8
    assert post.stability is not None and post.stability.velocity_jump.size is not None
    _json_ok(post.to_dict())


# ---------------------------------------------------------------------------------------
# Stability answer
# ---------------------------------------------------------------------------------------
def test_stability_answer_in_si() -> None:
    """Slip law, k = 2000 /m: kappa = k Dc/a = 2, kappa_crit = b/a - 1 = 0.5, so
    kappa/kappa_crit = 4 and k_crit = (b - a)/Dc = 500 /m (hand values, from the noise-free
    fit to 1e-9).  The critical sizes are those of rsfcore.critical at the fitted point,
    in SI: new slip rate = v_ref e^d_crit, new load-point velocity = v_ref (1 + dv_crit)."""
    rec = synthetic_record(*design(), **TRUE, eps=0.0, k_per_m=2000.0)
    res = fit_record(rec, "slip", stiffness=2000.0)
    st = res.stability
    assert st is not None and st.regime == "finite-critical"
    assert (
        abs(st.kappa - 2.0) < 1e-9
        and abs(st.kappa_crit - 0.5) < 1e-9
        and abs(st.kappa_ratio - 4.0) < 1e-8
    )
    assert abs(st.critical_stiffness_per_m - 500.0) < 1e-6
    p = res.params
    c_v = critical_perturbation(
        Params(ba=p["b"] / p["a"], kappa=p["k_per_m"] * p["Dc_m"] / p["a"], eps=0.0),
        "velocity-jump",
    )
    c_l = critical_perturbation(
        Params(ba=p["b"] / p["a"], kappa=p["k_per_m"] * p["Dc_m"] / p["a"], eps=0.0),
        "load-point-jump",
    )
    vj = st.velocity_jump.estimate.velocity_jump
    lj = st.load_point_jump.estimate.load_point_jump
    assert abs(vj.d - c_v.critical_size) <= 1e-15 * c_v.critical_size
    assert abs(vj.new_slip_rate_m_s / (1e-6 * math.exp(c_v.critical_size)) - 1) < 1e-14
    assert abs(lj.new_load_point_velocity_m_s / (1e-6 * (1 + c_l.critical_size)) - 1) < 1e-14
    _json_ok(res.to_dict())


def test_stability_uncertainty_covers_truth() -> None:
    """With noise the sampled 95 % range of the critical velocity jump contains the true
    one (slip law, kappa/kappa_crit = 4: d_crit of the true parameters), and the spread of
    kappa/kappa_crit contains 4."""
    rec = synthetic_record(*design(), **TRUE, eps=0.0, k_per_m=2000.0, noise=3e-4, seed=5)
    res = fit_record(rec, "slip", stiffness=2000.0)
    st = res.stability
    assert st is not None
    d_true = critical_perturbation(
        Params(ba=1.5, kappa=2.0, eps=0.0), "velocity-jump"
    ).critical_size
    sz = st.velocity_jump.size
    assert sz is not None and sz.p2_5 < d_true < sz.p97_5
    assert st.kappa_ratio_spread.p2_5 < 4.0 < st.kappa_ratio_spread.p97_5
    assert st.velocity_jump.kind_probability["finite"] == 1.0


def test_velocity_strengthening_and_rigid_machine() -> None:
    """b < a: stable for any stiffness (both kinds infinite); k = inf: rigid machine."""
    rec = synthetic_record(*design(), mu0=MU0, a=0.015, b=0.01, Dc_m=DC, eps=1.0, k_per_m=2000.0)
    res = fit_record(rec, "aging", stiffness=2000.0)
    assert res.ok and res.stability.regime == "velocity-strengthening"
    assert (
        res.stability.velocity_jump.kind == "infinite"
        and res.stability.critical_stiffness_per_m is None
    )
    res = fit_record(synthetic_record(*design(), **TRUE, eps=1.0), "aging")
    assert res.ok and res.stability.regime == "rigid-machine"
    _json_ok(res.to_dict())


# ---------------------------------------------------------------------------------------
# Options
# ---------------------------------------------------------------------------------------
@pytest.mark.parametrize(
    "kwargs, field",
    [
        (dict(law="rate"), "law"),
        (dict(stiffness=-1.0), "stiffness"),
        (dict(bounds={"Dc": (1e-6, 1e-4)}), "bounds.Dc"),
        (dict(bounds={"Dc_m": (1e-4, 1e-6)}), "bounds.Dc_m"),
        (dict(initial={"k": 1.0}), "initial.k"),
        (dict(rtol=1e-2), "rtol"),
    ],
)
def test_option_errors(kwargs: dict, field: str) -> None:
    rec = synthetic_record(*design(100), **TRUE, eps=1.0)
    with pytest.raises(ParameterError) as e:
        fit_record(rec, **kwargs)
    assert e.value.field == field


def test_runaway_record_is_refused_by_synthesis_and_fit_never_nan() -> None:
    """Trial parameters that run away must not break a fit: fitting a slip-law record
    with an aging law at a soft stiffness returns a finite answer (any status), and
    to_dict is JSON-safe."""
    rec = synthetic_record(*design(500), **TRUE, eps=0.0, k_per_m=2000.0, noise=1e-4)
    res = fit_record(rec, "aging", stiffness=600.0)
    _json_ok(res.to_dict())
    with pytest.raises(RuntimeError):
        synthetic_record(*design(500), **TRUE, eps=0.0, k_per_m=800.0)
