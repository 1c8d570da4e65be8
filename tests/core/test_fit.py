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
        a=A,
        b=B,
        Dc_m=DC,
        sigma_Pa=sigma,
        k_Pa_per_m=k * sigma,
        V_star_m_s=1e-6,
        V_load_m_s=1e-6,
        eps=0.5,
        f_star=MU0,
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


@pytest.mark.parametrize(
    "law, k, trend",
    [
        ("aging", 800.0, 0.0),
        ("slip", 2000.0, 0.0),
        ("eps", 2000.0, 20.0),
        ("nagata", 800.0, 0.0),
        ("eps", math.inf, 0.0),
    ],
)
def test_jacobian_by_engine_directions_equals_central_differences(
    law: str, k: float, trend: float
) -> None:
    """ForwardModel.jacobian (forward differences along b/a, ln kappa, ln s, eps and the
    chain rule; 2-4 runs) against central differences in every fitted coordinate (mu0, a,
    b, ln Dc, eps, ln k, trend; 2 runs each, step 1e-4: truncation error ~1e-8 relative).
    The forward differences' own error is the forward model's step-sequence noise
    (~1e-9 in phi under a 1e-6 change of a parameter) over the step 1e-6.  Measured,
    relative to each column's largest entry: 5e-13 .. 1.2e-5 for aging, slip, eps and the
    rigid machine, 1e-4 for the Nagata record near kappa_crit (k = 800 /m; per-coordinate
    forward differences, the fit's former Jacobian, 3e-5 there); allowed 3e-4.  A wrong
    chain-rule term is an O(1) error."""
    eps = {"aging": 1.0, "slip": 0.0, "eps": 0.5, "nagata": nagata_eps(A, B, 2.0)}[law]
    rec = synthetic_record(*design(), **TRUE, eps=eps, k_per_m=k, trend_per_m=trend)
    fit_k = math.isfinite(k)
    spec = ModelSpec(Law(law), fit_k, k, trend=trend != 0.0)
    model = ForwardModel(rec, spec)
    names = spec.fitted
    p = model.full(
        {**TRUE, "eps": eps, "k_per_m": k, "trend_per_m": trend}
        if law == "eps"
        else {**TRUE, "k_per_m": k, "trend_per_m": trend}
    )
    phi, lth, n_ok = model.states(*model.engine_params(p))
    assert n_ok == rec.n
    J = model.jacobian(p, names, (phi, lth))
    assert J is not None and J.shape == (rec.n, len(names))
    log = ("Dc_m", "k_per_m")
    for j, nm in enumerate(names):
        h = 1e-4
        mus = []
        for sgn in (1.0, -1.0):
            q = {n: p[n] for n in names}
            q[nm] = q[nm] * math.exp(sgn * h) if nm in log else q[nm] + sgn * h * max(abs(q[nm]), A)
            mu, n_q = model.friction(model.full(q))
            assert n_q == rec.n
            mus.append(mu)
        step = 2.0 * h * (1.0 if nm in log else max(abs(p[nm]), A))
        ref = (mus[0] - mus[1]) / step
        scale = float(np.max(np.abs(ref)))
        assert scale > 0.0, nm
        assert float(np.max(np.abs(J[:, j] - ref))) < 3e-4 * scale, nm


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
        fit_record(rec, "aging", stiffness=math.inf)
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
    res = fit_record(synthetic_record(*design(), **TRUE, eps=1.0), "aging", stiffness=math.inf)
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


# ---------------------------------------------------------------------------------------
# Never confidently wrong (issue 23, item 1)
# ---------------------------------------------------------------------------------------
SOFT = {**TRUE, "eps": 1.0, "k_per_m": 1000.0}  # k = 2 k_crit (k_crit = (b - a)/Dc = 500 /m)


def _soft_record(noise: float = 1e-4, n: int = 1201) -> Record:
    """The issue's soft machine: 1 -> 10 -> 1 um/s, 20 s each, ~1 s of elastic loading
    after each step (a/(k dv) = 1.1 s), aging law."""
    t = np.linspace(0.0, 60.0, n)
    v = np.where(t < 20, 1e-6, np.where(t < 40, 1e-5, 1e-6))
    return synthetic_record(t, v, **SOFT, noise=noise, seed=1)


def test_no_stiffness_given_fits_it() -> None:
    """With no stiffness the default fits it (the loading slope after a step determines
    it): the soft machine's k and a, b, Dc within 3 stated standard errors (noise 1e-4),
    status ok, and the stability answer is the finite machine's (not "rigid-machine")."""
    res = fit_record(_soft_record(), "aging", uncertainty_samples=50)
    assert res.status is FitStatus.OK and res.stiffness_mode == "fitted", res.message
    for k in ("a", "b", "Dc_m", "k_per_m"):
        assert abs(res.params[k] - SOFT[k]) < 3.0 * res.stderr[k], k
    assert res.stability is not None and res.stability.regime != "rigid-machine"
    assert res.stability.kappa_ratio == pytest.approx(2.0, rel=0.05)


def test_unresolved_stiffness_is_not_ok_and_names_the_options() -> None:
    """A machine far stiffer than the record resolves (k = inf): the fitted k is not
    determined, so the fit is not ok and the message names the estimate and the options
    (k_Pa_per_m with sigma_Pa, --rigid); asked for a rigid machine it is ok."""
    rec = _soft_record()
    rigid = synthetic_record(
        rec.t_s, rec.v_lp_m_s, **{**SOFT, "k_per_m": math.inf}, noise=1e-4, seed=1
    )
    res = fit_record(rigid, "aging", uncertainty_samples=0)
    assert res.status is FitStatus.ILL_CONDITIONED and res.stability is None
    assert "k_Pa_per_m" in res.message and "--rigid" in res.message
    assert "k = " in res.message  # the estimate, a plain number
    assert "np." not in res.message
    assert fit_record(rigid, "aging", stiffness=math.inf, uncertainty_samples=0).ok


def _named_k(message: str) -> float:
    """The stiffness [1/m] a contradiction message names ("... stiffness free, k = X")."""
    import re

    m = re.search(r"stiffness free, k = ([0-9.e+-]+)", message)
    assert m is not None, message
    return float(m.group(1))


def test_given_stiffness_the_record_contradicts_is_never_plain_ok() -> None:
    """The soft machine (k = 1000 /m = 2 k_crit) fitted as rigid, or with k given 3x or
    10 % too stiff: the fit with k free lowers the AIC by far more than 10 (measured
    ~9e3, 8e3 and 1e3 on 1201-sample records), so the status is not ok and the message
    names the record's stiffness (within 1 %: its standard error is 0.08 %) and the
    option to fit it; the stability answer of a suspect fit carries the warning.  The
    right stiffness (3 noise seeds: a false alarm needs chi^2_1 > 12, p = 5e-4), a rigid
    record fitted as rigid and a noise-free record with the right k stay ok."""
    rec = _soft_record()
    # as rigid, this record also leaves a and Dc undetermined (ill_conditioned): the
    # message leads with the stiffness, not with sampling advice
    res = fit_record(rec, "aging", stiffness=math.inf, uncertainty_samples=0)
    assert res.status is FitStatus.ILL_CONDITIONED, res.message
    assert res.message.startswith("The record contradicts an infinitely stiff machine")
    assert "without --rigid" in res.message
    assert _named_k(res.message) == pytest.approx(1000.0, rel=0.01)
    # a longer record (30 s per velocity) determines every parameter as rigid: suspect
    t = np.linspace(0.0, 90.0, 1201)
    v = np.where(t < 30, 1e-6, np.where(t < 60, 1e-5, 1e-6))
    longer = synthetic_record(t, v, **SOFT, noise=1e-4, seed=1)
    res = fit_record(longer, "aging", stiffness=math.inf, uncertainty_samples=20)
    assert res.status is FitStatus.SUSPECT, res.message
    assert "contradicts an infinitely stiff machine" in res.message
    assert _named_k(res.message) == pytest.approx(1000.0, rel=0.01)
    assert res.stability is not None and res.stability.warning is not None
    assert "contradicts" in res.stability.warning
    for given in (3000.0, 1100.0):
        res = fit_record(rec, "aging", stiffness=given, uncertainty_samples=0)
        assert res.status is FitStatus.SUSPECT, (given, res.message)
        assert f"the given stiffness k = {given:g} /m" in res.message
        assert "--fit-stiffness" in res.message
        assert _named_k(res.message) == pytest.approx(1000.0, rel=0.01)
        assert res.warnings and "contradicts" in res.warnings[-1]
    # in Pa/m too when sigma is given
    res = fit_record(rec, "aging", k_Pa_per_m=3000.0 * 1e7, sigma_Pa=1e7, uncertainty_samples=0)
    assert res.status is FitStatus.SUSPECT and "Pa/m" in res.message
    for seed in (1, 2, 3):
        ok = synthetic_record(rec.t_s, rec.v_lp_m_s, **SOFT, noise=1e-4, seed=seed)
        res = fit_record(ok, "aging", stiffness=1000.0, uncertainty_samples=0)
        assert res.status is FitStatus.OK, res.message
    rigid = synthetic_record(
        rec.t_s, rec.v_lp_m_s, **{**SOFT, "k_per_m": math.inf}, noise=1e-4, seed=1
    )
    assert fit_record(rigid, "aging", stiffness=math.inf, uncertainty_samples=0).ok
    clean = _soft_record(noise=0.0)
    assert fit_record(clean, "aging", stiffness=1000.0, uncertainty_samples=0).ok


def test_stiffness_in_pa_per_m_and_critical_stiffness_in_both() -> None:
    """k_Pa_per_m with sigma_Pa is k [1/m] = k_Pa_per_m/sigma_Pa: the same fit bit for
    bit, and the critical stiffness is answered in 1/m and in Pa/m (x sigma)."""
    rec = _soft_record(noise=0.0, n=601)
    a = fit_record(rec, "aging", stiffness=1000.0, uncertainty_samples=0)
    b = fit_record(rec, "aging", k_Pa_per_m=1e10, sigma_Pa=1e7, uncertainty_samples=0)
    assert a.params["b"] == b.params["b"] and a.params["Dc_m"] == b.params["Dc_m"]
    st = b.stability
    assert st is not None and st.critical_stiffness_per_m == pytest.approx(500.0, rel=1e-6)
    assert st.to_dict()["critical_stiffness_Pa_per_m"] == pytest.approx(5e9, rel=1e-6)
    assert st.to_dict()["stiffness_Pa_per_m"] == 1e10 and b.params["k_Pa_per_m"] == 1e10
    with pytest.raises(ParameterError) as e:
        fit_record(rec, k_Pa_per_m=1e10)
    assert e.value.field == "sigma_Pa"
    with pytest.raises(ParameterError) as e:
        fit_record(rec, fit_stiffness=False)
    assert e.value.field == "fit_stiffness"


def test_rejected_law_is_never_plain_ok() -> None:
    """The slip law on an aging record: the comparison rejects it (AIC thousands of units
    above aging; margin 10), so its status is 'rejected', its message names the law the
    record supports, and its stability answer carries the warning."""
    cmp = compare_laws(_soft_record(), laws=("aging", "slip"), uncertainty_samples=20)
    assert cmp.best == "aging" and cmp.fits["aging"].ok
    slip = cmp.fits["slip"]
    assert slip.status is FitStatus.REJECTED and not slip.ok
    assert "aging law" in slip.message and "rejected" in slip.message
    from rsfcore.fit import attach_stability

    st = attach_stability(slip, uncertainty_samples=10)
    assert st is not None and st.warning and st.message.startswith("REJECTED")
    assert {s.law: s.status for s in cmp.scores}["slip"] == "rejected"


@pytest.mark.parametrize(
    "scale_t, scale_v, needle",
    [
        (1.0, 1e6, "is the velocity column in um/s?"),  # velocities in um/s under m/s
        (1e3, 1.0, "is the time column in ms"),  # times in ms under s: Dc 1000x
    ],
)
def test_unit_slips_are_suspect(scale_t: float, scale_v: float, needle: str) -> None:
    """Unit slips fit as well as the truth (the model is scale-free) but give values
    implausible for a lab: status 'suspect', the message names the likely slip, and the
    stability answer carries it."""
    rec = _soft_record(n=601)
    slipped = Record(t_s=rec.t_s * scale_t, v_lp_m_s=rec.v_lp_m_s * scale_v, mu=rec.mu)
    res = fit_record(slipped, "aging", uncertainty_samples=10)
    assert res.status is FitStatus.SUSPECT and needle in res.message, res.message
    assert res.stability is not None and res.stability.warning and needle in res.stability.message


def test_velocity_step_by_1e6_is_suspect() -> None:
    t = np.linspace(0.0, 60.0, 601)
    v = np.where(t < 20, 1e-9, 1e-3)
    rec = synthetic_record(t, v, **{**SOFT, "k_per_m": math.inf})
    res = fit_record(rec, "aging", stiffness=math.inf, uncertainty_samples=0)
    assert res.status is FitStatus.SUSPECT and "factor 1e+06" in res.message, res.message


# ---------------------------------------------------------------------------------------
# Bounded failure (item 4)
# ---------------------------------------------------------------------------------------
def test_start_below_critical_stiffness_is_moved_not_minutes() -> None:
    """A start at k = 0.2 k_crit runs away: it is moved to a stable machine (recorded in
    warnings, naming the start) and the fit converges to the truth."""
    res = fit_record(
        _soft_record(n=601), "aging", initial={"k_per_m": 100.0}, uncertainty_samples=0
    )
    assert res.ok and any("runs away" in w for w in res.warnings)
    assert res.params["k_per_m"] == pytest.approx(1000.0, rel=0.05)


def test_time_budget_stops_the_fit_with_a_message() -> None:
    """A budget too small for the fit: NOT_CONVERGED with the budget in the message
    (bounded), never an exception.  The budget (1 us) is below the cost of one forward run
    on any machine, so the outcome does not depend on the machine's speed (0.05 s did: a
    quiet machine converged in 0.051 s)."""
    res = fit_record(_soft_record(n=601), "eps", time_budget_s=1e-6, uncertainty_samples=0)
    assert res.status is FitStatus.NOT_CONVERGED and "time budget" in res.message
    _json_ok(res.to_dict())


def test_start_that_cannot_be_repaired_fails_at_once_naming_the_start() -> None:
    """Fixed stiffness below the critical one of a start with b far above a: the start is
    moved to b = a + k Dc/2; a start on a record whose every trial runs away is FAILED at
    once with the start named (no optimisation)."""
    rec = _soft_record(n=601)
    res = fit_record(
        rec, "aging", stiffness=1000.0, initial={"b": 0.2, "Dc_m": 1e-4}, uncertainty_samples=0
    )
    assert res.status is not FitStatus.FAILED or "start" in res.message
    assert any("runs away" in w for w in res.warnings) or res.status is FitStatus.FAILED


# ---------------------------------------------------------------------------------------
# What real records contain (item 3): several steps, a trend, windows
# ---------------------------------------------------------------------------------------
def _multistep(trend: float, noise: float, seed: int = 0) -> Record:
    t = np.linspace(0.0, 200.0, 4001)
    v = np.full(t.shape, 1e-6)
    for t0, t1, vv in ((30, 60, 1e-5), (60, 90, 3e-6), (90, 120, 3e-5), (120, 150, 1e-6)):
        v[(t >= t0) & (t < t1)] = vv
    v[t >= 150] = 1e-5
    return synthetic_record(t, v, **SOFT, trend_per_m=trend, noise=noise, seed=seed)


@pytest.mark.parametrize("noise", [0.0, 1e-4])
def test_multistep_record_with_trend_fitted_jointly(noise: float) -> None:
    """Five steps, slip hardening 20 /m (2e-2 friction per mm, ~0.01 over the record),
    k fitted: one a, b, Dc, k and the trend; noise-free to 1e-6, noisy within 3 stated
    standard errors.  Without the trend term the same record is fitted worse (AIC)."""
    rec = _multistep(20.0, noise)
    res = fit_record(rec, "aging", trend=True, uncertainty_samples=0)
    assert res.ok, res.message
    true = {**SOFT, "trend_per_m": 20.0}
    for k in ("a", "b", "Dc_m", "k_per_m", "trend_per_m"):
        if noise == 0.0:
            assert res.params[k] == pytest.approx(true[k], rel=1e-6), k
        else:
            assert abs(res.params[k] - true[k]) < 3.0 * res.stderr[k], k
    plain = fit_record(rec, "aging", uncertainty_samples=0)
    assert plain.aic > res.aic + 10
    steps = res.step_residuals()
    assert len(steps) == 6 and all(s["rms"] is not None for s in steps)
    if noise:
        assert all(0.5e-4 < s["rms"] < 2e-4 for s in steps)


def test_windows_and_step_selection() -> None:
    """Only the selected samples enter the misfit (the model still runs through the whole
    record): fitting steps 1-2 or a window over them recovers the truth to 1e-6."""
    rec = _multistep(0.0, 0.0)
    for kw in ({"steps": [1, 2]}, {"windows": [(30.0, 90.0)]}):
        res = fit_record(rec, "aging", stiffness=1000.0, uncertainty_samples=0, **kw)
        assert res.ok and res.n < rec.n / 2
        for k in ("a", "b", "Dc_m"):
            assert res.params[k] == pytest.approx(SOFT[k], rel=1e-6)
    with pytest.raises(ParameterError) as e:
        fit_record(rec, steps=[9])
    assert e.value.field == "steps"


# ---------------------------------------------------------------------------------------
# Lab files as they come (item 2)
# ---------------------------------------------------------------------------------------
def _lab_text(rec: Record, *, decimal: str = ".", units_row: bool = False) -> str:
    sep = ";" if decimal == "," else ","
    head = sep.join(["Time (s)", "LP Velocity", "Friction", "Comment"])
    lines = ["# exported by the rig", head]
    if units_row:
        lines.append(sep.join(["s", "um/s", "-", ""]))
    for t, v, m in zip(rec.t_s, rec.v_lp_m_s, rec.mu, strict=True):
        row = [repr(float(t)), repr(float(v * 1e6)), repr(float(m)), "x"]
        if decimal == ",":
            row = [c.replace(".", ",") for c in row]
        lines.append(sep.join(row))
    return "\n".join(lines) + "\n"


def test_lab_file_with_column_mapping_units_and_decimal_comma() -> None:
    rec = _soft_record(noise=0.0, n=201)
    cols = ["t=Time (s)", "v_lp=LP Velocity:um/s", "mu=Friction"]
    a = read_record(_lab_text(rec), columns=cols)
    assert np.array_equal(a.t_s, rec.t_s) and np.allclose(a.v_lp_m_s, rec.v_lp_m_s, rtol=1e-15)
    b = read_record(
        _lab_text(rec, units_row=True), columns=["t=Time (s)", "v_lp=LP Velocity", "mu=Friction"]
    )
    assert np.array_equal(b.v_lp_m_s, a.v_lp_m_s)
    c = read_record(_lab_text(rec, decimal=","), columns=cols, decimal=",")
    assert np.array_equal(c.mu, a.mu)
    # shear and normal stress in MPa form mu
    tau = rec.mu * 10.0
    text = "t_s,v_lp_m_s,Shear (MPa),Normal (MPa)\n" + "\n".join(
        f"{t!r},{v!r},{s!r},10.0"
        for t, v, s in zip(rec.t_s.tolist(), rec.v_lp_m_s.tolist(), tau.tolist(), strict=True)
    )
    d = read_record(text, columns={"tau": "Shear (MPa)", "sigma_n": "Normal (MPa)"})
    assert np.allclose(d.mu, rec.mu, rtol=1e-15)


def test_lab_file_errors_give_line_numbers_and_plain_numbers() -> None:
    rec = _soft_record(noise=0.0, n=20)
    text = _lab_text(rec).splitlines()
    text[5] = text[5].replace(repr(float(rec.mu[3])), "n/a", 1)  # line 6 of the file
    with pytest.raises(ParameterError) as e:
        read_record("\n".join(text), columns=["t=Time (s)", "v_lp=LP Velocity:um/s", "mu=Friction"])
    assert e.value.field == "record.Friction[3]" and "line 6" in str(e.value)
    bad = "t_s,v_lp_m_s,mu\n" + "\n".join(
        f"{t},1e-6,0.6" for t in [0, 1, 2, 3, 3, 5, 6, 7, 8, 9, 10]
    )
    with pytest.raises(ParameterError) as e:
        read_record(bad)
    assert "line 6" in str(e.value) and "np.float64" not in str(e.value)
    with pytest.raises(ParameterError) as e:
        read_record(_lab_text(rec), columns=["v_lp=LP Velocity:furlong/s"])
    assert e.value.field == "columns.v_lp"
    with pytest.raises(ParameterError) as e:
        read_record(_lab_text(rec, decimal=","))
    assert "decimal" in str(e.value) or e.value.field.startswith("record")


def test_measured_displacement_record() -> None:
    """A displacement-controlled record: time, measured load-point displacement (noise
    2 nm, 1/50 of the displacement per sample at 1 um/s... of the steps), friction.  The
    commanded velocity is recovered (piecewise constant, steps at the right samples) and
    the fit recovers a, b, Dc, k within 3 standard errors."""
    rec = _soft_record(noise=1e-4, n=2401)
    x = rec.load_point_m
    noisy = x + np.random.default_rng(3).normal(0.0, 2e-9, x.shape)
    got = read_record({"t_s": rec.t_s, "x_lp_m": noisy, "mu": rec.mu})
    assert got.n_steps == 2
    assert np.array_equal(got.segment_starts, rec.segment_starts)
    assert np.allclose(got.v_lp_m_s, rec.v_lp_m_s, rtol=1e-2)
    exact = read_record({"t_s": rec.t_s, "x_lp_m": x, "mu": rec.mu})
    assert np.allclose(exact.v_lp_m_s, rec.v_lp_m_s, rtol=1e-9)
    res = fit_record(got, "aging", uncertainty_samples=0)
    assert res.ok, res.message
    for k in ("a", "b", "Dc_m", "k_per_m"):
        assert abs(res.params[k] - SOFT[k]) < 3.0 * res.stderr[k] + 0.02 * SOFT[k], k


# ---------------------------------------------------------------------------------------
# Protocol output is a fit record (issue 20, item 3)
# ---------------------------------------------------------------------------------------
def _machine() -> PhysicalParams:
    # k = 2 k_crit: k_crit [1/m] = (b - a)/Dc = 500, sigma 1e7 -> k = 1e10 Pa/m
    return PhysicalParams(
        a=A,
        b=B,
        Dc_m=DC,
        sigma_Pa=1e7,
        k_Pa_per_m=1e10,
        V_star_m_s=1e-6,
        V_load_m_s=1e-6,
        eps=1.0,
        f_star=0.6,
    )


@pytest.mark.parametrize("kind", ["velocity-step", "slide-hold-slide", "load-history"])
def test_protocol_output_is_a_fit_record(kind: str) -> None:
    """What rsfcore.protocols writes (its JSON, to_dict()) is read by read_record unchanged
    (friction, Vo_m_s, load_point_m; the junction belongs to the new segment, the velocity
    step starts with the steady state before it) and fitted, stiffness fitted, to the
    machine's a, b, Dc, k within 1e-6 relative (both computed at rtol 1e-10: ~1e-10)."""
    from rsfcore import protocols as P

    ph = _machine()
    if kind == "velocity-step":
        out = P.velocity_step(ph, 1e-6, 1e-5, slip_total_m=30 * DC, n_points=1500).to_dict()
    elif kind == "slide-hold-slide":
        out = P.slide_hold_slide(
            ph, 1e-6, 30.0, slide_before_s=10.0, slide_after_s=40.0, n_points_per_segment=600
        ).to_dict()
    else:
        out = P.load_history(
            ph, [(10.0, 1e-6), (4.0, 1e-5), (20.0, 1e-6)], n_points_per_segment=600
        ).to_dict()
    rec = read_record(json.loads(json.dumps(out)))
    res = fit_record(rec, "aging", uncertainty_samples=0)
    assert res.ok, res.message
    v1 = float(rec.v_lp_m_s[0])
    true = {
        "a": A,
        "b": B,
        "Dc_m": DC,
        "k_per_m": 1000.0,
        "mu0": 0.6 + (A - B) * math.log(v1 / 1e-6),
    }
    for k, val in true.items():
        assert res.params[k] == pytest.approx(val, rel=1e-6), k
