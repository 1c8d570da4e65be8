"""A sweep opened lazily from xarray over real HTTP: uvicorn with API keys required, a
real Celery worker, the client's ``Sweep.to_xarray(lazy=True)`` (zarr + fsspec + aiohttp
sending the key in the Authorization header): the lazy Dataset equals the downloaded
NetCDF, a running sweep shows missing points as NaN, and without the key the store is
401."""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np
import pytest

from tests.conftest import Worker
from tests.e2e.test_auth_server import AuthServer

pytestmark = [pytest.mark.e2e, pytest.mark.timeout(300)]


def test_lazy_xarray_through_fsspec_with_the_key(tmp_path: Path, procs: list) -> None:
    import httpx
    import xarray as xr

    from rsfclient import Client

    srv = AuthServer(tmp_path, RSF_QUOTA_FRESH_PER_S="1000")
    procs.append(srv)
    key = srv.key("lab", "submit")
    body = {
        "axes": [
            {"name": "ba", "values": [2.0, 3.0]},
            {"name": "kappa_ratio", "start": 0.5, "stop": 3.0, "n": 8},
            {"name": "eps", "start": 0.0, "stop": 0.9, "n": 10},
        ],
        "fixed": {"vo": 1.0},
        "chunk_points": 20,  # two rows of eps: Zarr chunks (1, 2, 10), one block each
    }
    with Client(srv.url, api_key=key) as c:
        sw = c.sweep(body)
        lazy = sw.to_xarray(lazy=True)  # queued: nothing computed, all missing
        # lazy: a backend array, not numpy (dask optional); chunks = the stored blocks
        assert not isinstance(lazy["critical_size"].variable._data, np.ndarray)
        assert tuple(lazy["critical_size"].encoding["chunks"]) == (1, 2, 10)
        assert np.isnan(lazy["critical_size"].values).all()
        procs.append(Worker(tmp_path))
        deadline = time.monotonic() + 120
        while sw.status().status != "done":
            assert time.monotonic() < deadline, "sweep did not finish"
            time.sleep(0.2)
        lazy = sw.to_xarray(lazy=True)
        whole = sw.to_xarray()
        for v in whole.data_vars:
            np.testing.assert_array_equal(lazy[v].values, whole[v].values)
        # one slice: a lazy computation touching a few chunks
        m = float(lazy["critical_size"].sel(ba=3.0).isel(kappa_ratio=slice(0, 2)).mean())
        ref = float(whole["critical_size"].sel(ba=3.0).isel(kappa_ratio=slice(0, 2)).mean())
        assert m == ref
        assert lazy.attrs["Conventions"] == "CF-1.10"
    r = httpx.get(f"{srv.url}/v1/sweeps/{sw.id}/zarr/.zmetadata")
    assert r.status_code == 401
    with pytest.raises(Exception):  # noqa: B017 - fsspec wraps the 401 its own way
        xr.open_zarr(f"{srv.url}/v1/sweeps/{sw.id}/zarr", consolidated=True, zarr_format=2)
