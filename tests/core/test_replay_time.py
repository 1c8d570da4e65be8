"""Samples evenly in T read from the classification run's step log
(engine.replay_samples_T) instead of a second run with the samples (issue 22 item 3:
slow outward spirals sampled in T took two runs of ~3,500 steps, 15 ms)."""

from __future__ import annotations

import numpy as np
import pytest

from rsfcore import Params, simulate
from rsfcore.engine import (
    LOG_Y,
    NSTATE,
    EngineOptions,
    Status,
    _replay_step,
    replay_samples_T,
    run,
)
from rsfcore.ode import radau5, rk, rodas4

#: (params, perturbation, size, rtol, integrator): each takes a different path through
#: replay_samples_T
CASES = [
    # DOP853, returns (a located stop: the last sample at the stop itself)
    (Params(2, 2, 0.25, 1), "velocity-jump", 2.7, 1e-8, "auto"),
    # runaway to blow-up
    (Params(2, 2, 0.25, 1), "load-point-jump", 14.0, 1e-10, "auto"),
    # RODASP steps (Hermite dense output)
    (Params(49434.88, 61036.76, 1.0, 3.2e20), "load-point-jump", 8e45, 1e-8, "auto"),
    # Radau IIA throughout (collocation dense output, replayed with the logged Newton
    # iterations)
    (Params(2, 2, 0.25, 1), "velocity-jump", 2.7, 1e-10, "implicit"),
    (Params(100.0, 150.0, 1.0, 1e-3), "load-point-jump", 30.0, 1e-8, "implicit"),
    # fast-slip legs in closed form (samples that fall inside a leg: a second run)
    (
        Params(1.0000000247933079, 1.5676244919750778e-08, 1.0, 4.1e-7),
        "velocity-jump",
        0.0174,
        1e-8,
        "auto",
    ),
    # v_o = 0, peak passed
    (Params(2, 1, 0.3, 0), "velocity-jump", 1.5, 1e-6, "auto"),
    # slow outward spirals (kappa < kappa_crit near b/a = 1): to the budget, and to blow-up
    (
        Params(1.0000000000430638, 7.706221673638276e-12, 0.43432546839273345, 6.843e-06),
        "load-point-jump",
        -0.017153579760950312,
        1e-8,
        "auto",
    ),
    (Params(1.000001, 1e-8, 0.0, 1.0), "load-point-jump", -0.5067365898367624, 1e-8, "auto"),
]


@pytest.mark.parametrize(("p", "pert", "size", "rtol", "integ"), CASES)
def test_time_samples_from_the_step_log_equal_a_second_run(
    monkeypatch: pytest.MonkeyPatch, p: Params, pert: str, size: float, rtol: float, integ: str
) -> None:
    """Bit-identical to the second run with the samples in T (a log of 1 row overflows and
    falls back to it): the replayed steps are the run's own steps, and each sample's point
    in its step is found by the same Newton iteration from the same start; and the T
    column is the requested grid, evenly spaced up to the run's end, to rounding (the
    inversion stops within 4 ulp of the target: rk.dense_invert)."""
    import rsfcore.trajectory as tr

    kw = {"rtol": rtol, "n_points": 200, "sampling": "time", "integrator": integ}
    got: list[int] = []
    replay = tr.replay_samples_T

    def spy(*args: object) -> int:
        got.append(int(replay(*args)))
        return got[-1]

    monkeypatch.setattr(tr, "replay_samples_T", spy)
    new = simulate(p, pert, size, **kw)  # type: ignore[arg-type]
    # read from the log (none of these has a sample inside a closed-form leg)
    assert got == [200]
    monkeypatch.setattr(tr, "STEP_LOG_ROWS", 1)
    old = simulate(p, pert, size, **kw)  # type: ignore[arg-type]
    assert new.trajectory is not None and old.trajectory is not None
    assert len(new.trajectory.T) == len(old.trajectory.T) == 200
    for name in ("T", "phi", "psi", "ln_theta", "slip", "load_point"):
        np.testing.assert_array_equal(getattr(new.trajectory, name), getattr(old.trajectory, name))
    T = new.trajectory.T
    grid = np.linspace(0.0, T[-1], 200)
    np.testing.assert_allclose(T, grid, rtol=1e-14, atol=0.0)
    assert (new.outcome, new.rel_accuracy, new.n_steps) == (
        old.outcome,
        old.rel_accuracy,
        old.n_steps,
    )


def test_a_sample_inside_a_closed_form_leg_is_not_replayed() -> None:
    """A closed-form leg advances T between two logged steps without a step: a sample
    inside it is not in the log (-1: the caller takes a second run, which integrates the
    leg); samples elsewhere equal a run with them, bit for bit (that run takes the same
    steps and legs).  A start at phi = 200 > PHI_LEG + LEG_MIN_RISE near T = 0: its falling
    flank is taken in closed form after the first step, a gap of ~e^-50 in T that T near
    0 resolves."""
    p = Params(2.0, 2.0, 0.25, 1.0)
    y0 = np.array([200.0, -205.0, 0.0, 0.0, 0.0])  # (phi, ln theta, T, s, s_o): L = -5
    opts = EngineOptions(
        rtol=1e-10, atol=1e-10, max_steps=100_000, fast_leg=True, stop_on_return=True
    )
    log = np.empty((100_000, LOG_Y + NSTATE))
    res = run(y0, p.ba, p.kappa, p.eps, p.vo, opts, steplog=log)
    n_log = res.n_logged
    assert res.n_legs > 0 and n_log > 10
    stopped = res.status != Status.BUDGET
    n = NSTATE
    bufs = [np.empty((rk.N_STAGES_EXTENDED, n)), np.empty((7, n))]
    bufs += [np.empty((rodas4.N_STAGES, n)), np.empty((n, 2))]
    bufs += [np.empty(n) for _ in range(7)]
    bufs += [np.empty((radau5.N_STAGES, n)), np.empty((radau5.N_STAGES, n)), np.ones(2)]
    ynew = bufs[5]
    one = np.empty((1, NSTATE))
    gaps = []
    for k in range(n_log - 1):
        # each logged step again: its end, where the next row starts unless a leg follows
        _replay_step(log, k, p.ba, p.kappa, p.eps, p.vo, 1.0, 0.0, *bufs)
        T_end, T_next = ynew[2], log[k + 1, LOG_Y + 2]
        assert T_end <= T_next
        if T_end < T_next:
            gaps.append((T_end, T_next))
            mid = np.array([0.5 * (T_end + T_next)])
            got = replay_samples_T(log, n_log, y0, p.ba, p.kappa, p.eps, p.vo, mid, stopped, one)
            assert got == -1
    assert gaps
    # samples evenly in T outside the gaps
    sT = np.linspace(0.0, float(res.y_end[2]), 400)
    sT = sT[[not any(a < t < b for a, b in gaps) for t in sT]]
    got_s = np.empty((sT.shape[0], NSTATE))
    m = replay_samples_T(log, n_log, y0, p.ba, p.kappa, p.eps, p.vo, sT, stopped, got_s)
    assert m == sT.shape[0]
    want = np.empty((sT.shape[0], NSTATE))
    res2 = run(y0, p.ba, p.kappa, p.eps, p.vo, opts, sample_T=sT, samples=want)
    assert res2.n_filled == m and res2.n_legs == res.n_legs
    np.testing.assert_array_equal(got_s, want)
