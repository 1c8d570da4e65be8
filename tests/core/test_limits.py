"""rsfcore.limits: one valid range and default per parameter, used by every rsfcore entry point."""

from __future__ import annotations

import math

import numpy as np
import pytest

from rsfcore import ParameterError, Params, PhysicalParams, classify, limits, simulate
from rsfcore.critical import RTOL_RANGE as CRIT_RTOL_RANGE
from rsfcore.critical import critical_perturbation
from rsfcore.diagram import stability_diagram
from rsfcore.protocols import load_history
from rsfcore.trajectory import RTOL_RANGE as TRAJ_RTOL_RANGE


def test_range_text() -> None:
    assert limits.BA.text == "(1, 1e6]"
    assert limits.RTOL.text == "[1e-13, 1e-3]"
    assert limits.VO.text == "[0, 1e300]"
    assert limits.VELOCITY_JUMP_SIZE.text == "[-1e4, 1e4]"
    assert limits.LOAD_POINT_JUMP_SIZE.text == "(-1, 1e300]"
    assert limits.N_POINTS.text == "[2, 1e5]"
    assert limits.KAPPA_RATIO.text == "[0, inf)"
    assert limits.EPS.text == "[0, 1]"
    assert limits.F_STAR.text == "(-inf, inf)"
    assert limits.format_number(0.25) == "0.25"
    assert limits.format_number(2.5e-7) == "2.5e-7"


def test_defaults_are_the_papers_running_example() -> None:
    # one set of defaults for library, CLI and HTTP (issue 10 item 8)
    assert (limits.BA.default, limits.KAPPA.default, limits.EPS.default, limits.VO.default) == (
        2.0,
        2.0,
        0.25,
        1.0,
    )
    assert limits.KAPPA_RATIO.default == limits.KAPPA.default / (limits.BA.default - 1.0)
    assert limits.VELOCITY_JUMP_SIZE.default == limits.LOAD_POINT_JUMP_SIZE.default == 1.0
    assert limits.RTOL.default == limits.DEFAULT_RTOL == 1e-10
    # every default lies in its own range
    for lim in limits.LIMITS.values():
        if lim.default is not None:
            assert lim.check(lim.default) == lim.default, lim.name


@pytest.mark.parametrize("lim", list(limits.LIMITS.values()), ids=list(limits.LIMITS))
def test_check_rejects_outside_and_accepts_ends(lim: limits.Limit) -> None:
    for bad in (math.nan, math.inf, "x", None):
        with pytest.raises(ParameterError) as e:
            lim.check(bad)
        assert e.value.field == lim.name
    if lim.lo is not None:
        if lim.lo_open:
            with pytest.raises(ParameterError) as e:
                lim.check(lim.lo)
            assert e.value.valid == lim.text
        else:
            assert lim.check(lim.lo) == lim.lo
        below = lim.lo - max(1.0, abs(lim.lo)) * 1e-3
        with pytest.raises(ParameterError):
            lim.check(below)
    if lim.hi is not None:
        if lim.hi_open:
            with pytest.raises(ParameterError):
                lim.check(lim.hi)
        else:
            assert lim.check(lim.hi) == lim.hi
        with pytest.raises(ParameterError):
            lim.check(lim.hi * (1 + 1e-3) + 1e-3)
    # the vectorised form agrees with the scalar one
    probe = [v for v in (lim.lo, lim.hi, lim.default) if v is not None] + [math.nan]
    mask = lim.bad_mask(probe)
    assert mask.tolist() == [not lim.contains(v) for v in probe]


def test_integer_limits() -> None:
    assert limits.N_POINTS.check_int(200.0) == 200
    with pytest.raises(ParameterError, match="an integer"):
        limits.N_POINTS.check(2.5)
    with pytest.raises(ParameterError) as e:
        limits.N_POINTS.check(1, name="n_points_per_segment")
    assert e.value.field == "n_points_per_segment" and e.value.valid == "[2, 1e5]"


def test_integer_limit_accepts_valid_value() -> None:
    assert limits.N_POINTS.check(3, name="n_points_per_segment") == 3.0


def test_one_rtol_range_everywhere() -> None:
    """Every rsfcore entry point accepts exactly RTOL = [1e-13, 1e-3] (issue 10 item 3)."""
    assert (
        CRIT_RTOL_RANGE == TRAJ_RTOL_RANGE == limits.RTOL_RANGE == (limits.RTOL.lo, limits.RTOL.hi)
    )
    p = Params(2.0, 2.0, 0.25)
    calls = [
        lambda r: classify(p, "velocity-jump", 0.5, rtol=r),
        lambda r: simulate(p, "velocity-jump", 0.5, rtol=r),
        lambda r: critical_perturbation(p, "velocity-jump", rtol=r),
        lambda r: stability_diagram("kappa_ratio", [2.0], "eps", [0.25], rtol=r),
        lambda r: load_history(_phys(), [(1.0, 1e-6)], rtol=r),
    ]
    for call in calls:
        call(limits.RTOL.lo)  # the tightest accepted tolerance runs
        call(limits.RTOL.hi)
        for bad in (limits.RTOL.lo * 0.5, limits.RTOL.hi * 2.0):
            with pytest.raises(ParameterError) as e:
                call(bad)
            assert e.value.field == "rtol" and e.value.valid == "[1e-13, 1e-3]"


def _phys() -> PhysicalParams:
    return PhysicalParams(
        a=0.01,
        b=0.015,
        Dc_m=1e-5,
        sigma_Pa=1e7,
        k_Pa_per_m=5e9,
        V_star_m_s=1e-6,
        V_load_m_s=1e-6,
        eps=0.3,
    )


def test_sizes_and_starts_use_the_limits() -> None:
    p = Params(2.0, 2.0, 0.25)
    with pytest.raises(ParameterError) as e:
        classify(p, "velocity-jump", 2e4)
    assert (e.value.field, e.value.valid) == ("size", limits.VELOCITY_JUMP_SIZE.text)
    with pytest.raises(ParameterError) as e:
        classify(p, "load-point-jump", -1.0)
    assert e.value.field == "size"
    with pytest.raises(ParameterError) as e:
        classify(p, start=(2e4, 0.0))
    assert (e.value.field, e.value.valid) == ("phi0", limits.PHI_START.text)
    with pytest.raises(ParameterError) as e:
        simulate(p, "velocity-jump", 0.5, n_points=1)
    assert (e.value.field, e.value.valid) == ("n_points", limits.N_POINTS.text)
    with pytest.raises(ParameterError) as e:
        simulate(p, "velocity-jump", 0.5, t_end=0.0)
    assert (e.value.field, e.value.valid) == ("t_end", limits.T_END.text)
    with pytest.raises(ParameterError) as e:
        Params(2.0, 2e6, 0.25)
    assert (e.value.field, e.value.valid) == ("kappa", limits.KAPPA.text)
    with pytest.raises(ParameterError) as e:
        stability_diagram("ba", np.array([0.5, 2.0]), "eps", [0.25])
    assert (e.value.field, e.value.valid) == ("ba", limits.BA.text)
