"""rsfapp.grid (specs, lazy flat-index map, chunk plan) and rsfapp.sweepdata.compute_chunk."""

from __future__ import annotations

import numpy as np
import pytest

from rsfapp.config import Settings
from rsfapp.grid import Axis, SweepSpec, expand, plan_chunks
from rsfapp.requests import SweepRequest
from rsfapp.sweepdata import compute_chunk
from rsfcore import batch, critical
from rsfcore.params import Params


def spec_of(body: dict) -> SweepSpec:
    return expand(SweepRequest.model_validate(body), 10**8, 10**6)


def test_axis_values_exact_end_points_and_spacing() -> None:
    a = Axis("eps", 7, None, 0.1, 0.7)
    v = a.all()
    assert v[0] == 0.1 and v[-1] == 0.7
    np.testing.assert_allclose(np.diff(v), 0.1, rtol=1e-14)  # linear spacing
    g = Axis("kappa_ratio", 5, None, 1.0, 16.0, log=True).all()
    np.testing.assert_allclose(g, [1, 2, 4, 8, 16], rtol=1e-15)
    assert g[-1] == 16.0
    assert Axis("ba", 1, None, 3.0, 3.0).all().tolist() == [3.0]


def test_flat_index_is_c_order_and_matches_outer_product() -> None:
    sp = spec_of(
        {
            "axes": [
                {"name": "ba", "values": [2.0, 3.0]},
                {"name": "eps", "values": [0.1, 0.2, 0.3]},
                {"name": "kappa_ratio", "start": 1.0, "stop": 2.0, "n": 2},
            ]
        }
    )
    assert sp.shape == (2, 3, 2) and sp.n_total == 12
    p = sp.params(0, 12)
    B, E, K = np.meshgrid([2.0, 3.0], [0.1, 0.2, 0.3], [1.0, 2.0], indexing="ij")
    assert p["ba"].tolist() == B.ravel().tolist() and p["eps"].tolist() == E.ravel().tolist()
    assert p["kappa"].tolist() == (K * (B - 1.0)).ravel().tolist()
    assert p["vo"].tolist() == [1.0] * 12 and p["size"] is None
    # a chunk is the same slice of the flat order
    q = sp.params(5, 9)
    assert q["eps"].tolist() == p["eps"][5:9].tolist()


def test_spec_json_round_trip_is_small() -> None:
    sp = spec_of(
        {
            "axes": [
                {"name": n, "start": 0.5, "stop": 0.9, "n": 100}
                for n in ("eps", "kappa_ratio", "vo", "size")
            ]
        }
    )
    d = sp.to_json()
    assert sp.n_total == 10**8 and len(str(d)) < 1000
    back = SweepSpec.from_json(d)
    assert (
        back.to_json() == d
        and back.params(123456, 123460)["size"].tolist()
        == sp.params(123456, 123460)["size"].tolist()
    )


def test_chunk_plan() -> None:
    s = Settings()
    assert (
        plan_chunks(
            spec_of(
                {
                    "axes": [
                        {"name": "eps", "start": 0, "stop": 1, "n": 100},
                        {"name": "ba", "start": 2, "stop": 3, "n": 100},
                    ]
                }
            ),
            s,
        )
        == 1250
    )  # 10^4 points: 8 chunks
    big = spec_of(
        {
            "axes": [
                {"name": n, "start": 0.5, "stop": 0.9, "n": 100}
                for n in ("eps", "kappa_ratio", "vo", "size")
            ]
        }
    )
    c = plan_chunks(big, s)
    assert 1000 <= -(-(10**8) // c) <= s.sweep_max_chunks
    assert plan_chunks(big, s, 7) == 1000  # at most sweep_max_chunks chunks


def test_compute_chunk_isolates_a_point_that_breaks_the_batch(monkeypatch) -> None:
    sp = spec_of(
        {
            "axes": [{"name": "eps", "values": [0.1, 0.2, 0.3, 0.4]}],
            "fixed": {"ba": 2.0, "kappa_ratio": 2.0},
        }
    )
    orig = batch.critical_points

    def fragile(ba, kappa, eps, vo, **kw):
        if np.any(np.asarray(eps) == 0.3):
            raise ZeroDivisionError("kernel defect at eps=0.3")
        return orig(ba, kappa, eps, vo, **kw)

    monkeypatch.setattr(batch, "critical_points", fragile)
    arrays, errors = compute_chunk(sp, 0, 4)
    assert arrays["failed"].tolist() == [False, False, True, False]
    assert errors == {2: "ZeroDivisionError: kernel defect at eps=0.3"}
    ref = critical.critical_perturbation(Params(2.0, 2.0, 0.4, 1.0)).critical_size
    assert arrays["critical_size"][3] == ref and np.isnan(arrays["critical_size"][2])


@pytest.mark.parametrize(
    "body",
    [
        {"x": {"name": "eps", "values": [0.1]}, "y": {"name": "ba", "values": [2.0]}},
        {"axes": [{"name": "eps", "values": [0.1]}, {"name": "ba", "values": [2.0]}]},
    ],
)
def test_xy_form_is_the_same_sweep_as_two_axes(body: dict) -> None:
    assert (
        spec_of(body).to_json()
        == spec_of(
            {"axes": [{"name": "eps", "values": [0.1]}, {"name": "ba", "values": [2.0]}]}
        ).to_json()
    )
