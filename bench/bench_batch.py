"""Benchmark: 10^4 critical sizes in one POST /v1/critical/batch vs 10^4 POST /v1/critical.

Runs the real FastAPI app in process (TestClient, SQLite result cache in a temporary data
directory, no network), after a warm-up, with every item distinct (no cache hits for the
single requests).  Prints wall-clock times; the target (issue 15) is < 0.2 s for the batch
on one core.  Also splits the batch time into validation, compiled compute and JSON.

    NUMBA_CACHE_DIR=.numba_cache taskset -c 0 .venv/bin/python bench/bench_batch.py [N] [N_SINGLE]
"""

from __future__ import annotations

import json
import os
import sys
import tempfile
import time
from typing import Any

__all__ = ["items", "main"]


def items(n: int, seed: int = 1) -> list[dict[str, Any]]:
    """n distinct parameter points in the separatrix region (the costly finite kind):
    kappa_crit < kappa < kappa_crit/eps, v_o = 1, velocity jumps."""
    import numpy as np

    rng = np.random.default_rng(seed)
    ba = rng.uniform(1.5, 5.0, n)
    eps = rng.uniform(0.0, 0.8, n)
    kc = ba - 1.0
    hi = np.where(eps > 0, kc / np.maximum(eps, 1e-300), 10 * kc)
    kappa = kc * (1.05 + (np.minimum(hi / kc, 10.0) - 1.1) * rng.uniform(0, 1, n))
    return [
        {"ba": float(b), "kappa": float(k), "eps": float(e)}
        for b, k, e in zip(ba, kappa, eps, strict=True)
    ]


def main() -> None:
    n = int(sys.argv[1]) if len(sys.argv) > 1 else 10_000
    n_single = int(sys.argv[2]) if len(sys.argv) > 2 else n
    data = tempfile.mkdtemp(prefix="rsf-bench-batch-")
    os.environ.update(RSF_DATA_DIR=data, RSF_INLINE_BUDGET_S="600")
    import orjson
    from fastapi.testclient import TestClient

    from rsfapp import adapter
    from rsfapp.adapter import batch as adapter_batch
    from rsfapp.requests import CriticalRequest
    from rsfcore.batch import critical_points
    from service.app import create_app

    its = items(n)
    with TestClient(create_app()) as c:
        warm = items(200, seed=2)
        c.post("/v1/critical/batch", json={"items": warm})
        for it in warm[:20]:
            c.post("/v1/critical", json=it)

        reps = []
        for _ in range(3):
            t0 = time.perf_counter()
            r = c.post("/v1/critical/batch", json={"items": its})
            reps.append(time.perf_counter() - t0)
            assert r.status_code == 200 and r.json()["n_failed"] == 0, r.text[:500]
        t_batch = min(reps)

        # the parts of the batch route, each next to the obvious alternative
        t0 = time.perf_counter()
        adapter_batch._plain_critical_items(its)
        t_cols = time.perf_counter() - t0
        t0 = time.perf_counter()
        adapter.validate_items(CriticalRequest, its)
        t_val = time.perf_counter() - t0
        cols = adapter_batch._plain_critical_items(its)[1]
        t0 = time.perf_counter()
        critical_points(
            cols["ba"], cols["kappa"], cols["eps"], cols["vo"], perturbation="velocity-jump"
        )
        t_core = time.perf_counter() - t0
        t0 = time.perf_counter()
        res = adapter.critical_batch(its)
        t_all = time.perf_counter() - t0
        t0 = time.perf_counter()
        orjson.dumps(res)
        t_orjson = time.perf_counter() - t0
        t0 = time.perf_counter()
        json.dumps(res, separators=(",", ":"), allow_nan=False)
        t_json = time.perf_counter() - t0

        t0 = time.perf_counter()
        for it in its[:n_single]:
            rs = c.post("/v1/critical", json=it)
            assert rs.status_code == 200
        t_single = time.perf_counter() - t0
    kinds = {
        k: sum(1 for x in res["results"] if x["kind"] == k) for k in ("zero", "finite", "infinite")
    }
    print(f"items: {n} distinct (kinds {kinds}); data dir {data}")
    print(
        f"one batch request        : {t_batch:.3f} s  (best of 3: "
        f"{', '.join(f'{x:.3f}' for x in reps)})  = {1e6 * t_batch / n:.1f} us/item"
    )
    print(
        f"  of which: item validation as columns {t_cols:.3f} s (through the pydantic model "
        f"{t_val:.3f} s), compiled loop {t_core:.3f} s, adapter.critical_batch in all "
        f"{t_all:.3f} s, JSON by orjson {t_orjson:.3f} s (stdlib json {t_json:.3f} s)"
    )
    print(
        f"{n_single} single requests   : {t_single:.3f} s  = "
        f"{1e6 * t_single / n_single:.1f} us/request"
        + ("" if n_single == n else f"  (x{n / n_single:.0f} -> {t_single * n / n_single:.1f} s)")
    )
    print(f"speed-up of the batch    : {t_single * n / n_single / t_batch:.0f}x")
    print(f"target < 0.2 s for 10^4  : {'met' if t_batch * 1e4 / n < 0.2 else 'NOT met'}")


if __name__ == "__main__":
    main()
