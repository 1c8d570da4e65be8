"""Sweep downloads in process: subsets on the server (sel, isel, variables) in every
format agree with the same subset cut from the whole file by xarray; the NetCDF carries CF
metadata that xarray's CF decoding reads back; slabs smaller than a block give the same
bytes; a download beyond the per-process limits (downloads, NetCDF builds) is a 503 with
Retry-After."""

from __future__ import annotations

import csv
import io
import json
import math
from typing import Any

import numpy as np
import pytest
from fastapi.testclient import TestClient

from tests.api.test_sweeps_api import run_all, submit

pytestmark = pytest.mark.timeout(300)

GRID = {
    "axes": [
        {"name": "ba", "values": [2.0, 3.0]},
        {"name": "kappa_ratio", "start": 0.5, "stop": 3.0, "n": 6},
        {"name": "eps", "start": 0.0, "stop": 0.9, "n": 7},
    ],
    "fixed": {"vo": 1.0},
    "chunk_points": 10,  # blocks do not align with rows: slabs cross blocks
}


@pytest.fixture(scope="module")
def done(api_stack: tuple[TestClient, Any]) -> tuple[TestClient, str]:
    c = api_stack[0]
    sid = submit(c, GRID)["id"]
    run_all(c, sid)
    return c, sid


def _nc(c: TestClient, sid: str, **params: str) -> Any:
    import xarray as xr

    r = c.get(f"/v1/sweeps/{sid}/data", params={"format": "netcdf", **params})
    assert r.status_code == 200, r.text
    return xr.open_dataset(io.BytesIO(r.content), engine="h5netcdf").load()


def test_subset_in_every_format_equals_the_cut_of_the_whole(done: tuple[TestClient, str]) -> None:
    c, sid = done
    full = _nc(c, sid)
    q = {"sel": "kappa_ratio:1.0:2.5", "isel": "eps:1:6:2,ba:1"}
    sub = _nc(c, sid, **q)
    # the same cut by xarray's own indexing of the whole file
    want = full.sel(kappa_ratio=slice(1.0, 2.5)).isel(eps=slice(1, 6, 2), ba=[1])
    assert sub["critical_size"].shape == (1, 4, 3)
    for v in ("critical_size", "kind", "method", "rel_accuracy", "failed", "computed"):
        np.testing.assert_array_equal(sub[v].values, want[v].values)
    for d in ("ba", "kappa_ratio", "eps"):
        np.testing.assert_array_equal(sub[d].values, want[d].values)
    assert json.loads(sub.attrs["selection"])["eps"] == [1, 5, 3]
    # CSV: the same points in flat order, with their flat indices
    r = c.get(f"/v1/sweeps/{sid}/data", params={"format": "csv", **q})
    assert r.status_code == 200 and r.headers["x-sweep-selection"] == "12"
    rows = list(csv.DictReader(io.StringIO(r.text)))
    flat = np.ravel_multi_index(
        np.meshgrid([1], [1, 2, 3, 4], [1, 3, 5], indexing="ij"), (2, 6, 7)
    ).ravel()
    assert [int(x["idx"]) for x in rows] == flat.tolist()
    cs = np.array([float(x["critical_size"] or "nan") for x in rows])
    np.testing.assert_array_equal(cs, want["critical_size"].values.ravel())
    assert [float(x["eps"]) for x in rows] == want["eps"].values.tolist() * 4
    # JSON
    r = c.get(f"/v1/sweeps/{sid}/data", params={"format": "json", **q})
    j = r.json()
    assert j["shape"] == [1, 4, 3] and j["coords"]["eps"] == want["eps"].values.tolist()
    got = np.array([math.inf if v is None else v for v in j["data"]["critical_size"]])
    ref = want["critical_size"].values.ravel()
    np.testing.assert_array_equal(got, np.where(np.isnan(ref), math.inf, ref))


def test_variables_list(done: tuple[TestClient, str]) -> None:
    c, sid = done
    ds = _nc(c, sid, variables="kind,critical_size")
    assert set(ds.data_vars) == {"kind", "critical_size"}
    r = c.get(f"/v1/sweeps/{sid}/data", params={"format": "csv", "variables": "kind"})
    assert r.text.splitlines()[0] == "idx,ba,kappa_ratio,eps,kind"
    j = c.get(f"/v1/sweeps/{sid}/data", params={"format": "json", "variables": "failed"}).json()
    assert list(j["data"]) == ["failed"] and len(j["data"]["failed"]) == 84


@pytest.mark.parametrize(
    ("params", "field"),
    [
        ({"sel": "vo:1"}, "sel"),  # vo is fixed, not a dimension
        ({"isel": "eps:7"}, "isel"),
        ({"sel": "eps:5:6"}, "sel"),
        ({"variables": "critical_size,nope"}, "variables"),
    ],
)
def test_bad_subsets_are_422_naming_the_field(
    done: tuple[TestClient, str], params: dict[str, str], field: str
) -> None:
    c, sid = done
    for fmt in ("netcdf", "csv", "json"):
        r = c.get(f"/v1/sweeps/{sid}/data", params={"format": fmt, **params})
        assert r.status_code == 422, r.text
        assert r.json()["field"] == field


def test_small_slabs_give_the_same_file_values(
    done: tuple[TestClient, str], monkeypatch: pytest.MonkeyPatch
) -> None:
    """Slabs of 4 points (every slab crosses blocks of 10) give the values of one slab."""
    c, sid = done
    full = _nc(c, sid)
    r1 = c.get(f"/v1/sweeps/{sid}/data", params={"format": "csv"}).text
    monkeypatch.setattr("rsfapp.sweepselect.SLAB_POINTS", 4)
    small = _nc(c, sid)
    for v in full.data_vars:
        np.testing.assert_array_equal(small[v].values, full[v].values)
    assert c.get(f"/v1/sweeps/{sid}/data", params={"format": "csv"}).text == r1
    # the chunks (edge chunks of 3 points padded with the fill value) decode to the
    # values of the JSON download, written without HDF5
    js = c.get(f"/v1/sweeps/{sid}/data", params={"format": "json"}).json()
    for v in ("critical_size", "rel_accuracy", "kind", "method", "failed", "computed"):
        want = np.array([math.nan if x is None else x for x in js["data"][v]], dtype=float)
        got = small[v].values.reshape(-1).astype(float)
        if v in ("critical_size", "rel_accuracy"):  # JSON: null for inf too
            got = np.where(np.isfinite(got), got, math.nan)
        np.testing.assert_array_equal(got, want, err_msg=v)


def test_netcdf_is_cf(done: tuple[TestClient, str]) -> None:
    """CF attributes read back through xarray's CF decoding: identification, the request,
    long_name and units everywhere, distinct flag meanings, fill values, compression."""
    from rsfcore import NUMERICS_VERSION

    c, sid = done
    ds = _nc(c, sid)
    a = ds.attrs
    assert a["Conventions"] == "CF-1.10"
    assert a["title"] and sid in a["title"]
    assert f"numerics version {NUMERICS_VERSION}" in a["source"]
    assert "rsf-stability" in a["source"]
    assert f"/v1/sweeps/{sid}/data" in a["history"]
    assert json.loads(a["request"]) == c.get(f"/v1/sweeps/{sid}/spec").json()
    for name in [*ds.data_vars, *ds.coords]:
        assert ds[name].attrs.get("long_name"), name
        assert "units" in ds[name].attrs, name
    for name in ("kind", "outcome", "method", "failed", "outcome_uncertain", "computed"):
        v = ds[name].attrs
        words = v["flag_meanings"].split()
        assert len(words) == len(set(words)) == len(v["flag_values"]), name
    assert ds["method"].attrs["flag_meanings"].split()[2:5] == [
        "closed_form_limiting_trajectory",
        "closed_form_load_point_jump_at_kappa_crit",
        "closed_form_phi_crit_vo_0",
    ]
    from rsfapp.sweepcf import METHOD_FLAGS
    from rsfcore.critical import METHODS

    assert len(METHOD_FLAGS) == len(METHODS), "a word for each method in rsfapp/sweepcf.py"
    for name in ("kind", "outcome", "method"):
        assert ds[name].encoding["_FillValue"] == -1, name
    assert np.isnan(ds["critical_size"].encoding["_FillValue"])
    enc = ds["critical_size"].encoding
    assert enc.get("zlib") is True or enc.get("compression") in ("gzip", "zlib"), enc
    assert enc.get("shuffle") is True, enc


def test_file_size_within_2x_of_stored(api_stack: tuple[TestClient, Any]) -> None:
    """A 40 x 50 grid: NetCDF bytes per point within 2x of the stored blocks' bytes per
    point (was 21 bytes against ~5: no compression)."""
    c = api_stack[0]
    body = {
        "axes": [
            {"name": "kappa_ratio", "start": 0.3, "stop": 2.5, "n": 40},
            {"name": "eps", "start": 0.05, "stop": 0.95, "n": 50},
        ],
        "fixed": {"ba": 2.0, "vo": 1.0},
    }
    sid = submit(c, body)["id"]
    run_all(c, sid)
    from service.app import app

    stores = app.state.stores if hasattr(app.state, "stores") else None
    r = c.get(f"/v1/sweeps/{sid}/data")
    if stores is None:
        from rsfapp.config import get_settings
        from rsfapp.store import stores_for

        stores = stores_for(get_settings())
    stored = stores.sweeps.disk_bytes(sid)
    assert len(r.content) < 2 * stored + 40_000, (len(r.content), stored)  # + HDF5 header


def test_downloads_beyond_the_limit_are_503_with_retry_after(
    done: tuple[TestClient, str], monkeypatch: pytest.MonkeyPatch
) -> None:
    from service import downloads

    c, sid = done
    for fmt in ("csv", "json", "netcdf"):  # slots are given back after each download
        for _ in range(3):
            r = c.get(f"/v1/sweeps/{sid}/data", params={"format": fmt})
            assert r.status_code == 200
            assert downloads.SLOTS.in_use == 0, fmt
    slots = downloads.DownloadSlots(downloads=1, builds=1)
    monkeypatch.setattr(downloads, "SLOTS", slots)
    held = slots.admit(downloads.DownloadKind.STREAM)  # one download in flight
    r = c.get(f"/v1/sweeps/{sid}/data", params={"format": "json"})
    assert r.status_code == 503 and int(r.headers["retry-after"]) > 0
    assert r.headers["content-type"].startswith("application/problem+json")
    assert "1 sweep downloads" in r.json()["reason"] and "subset" in r.json()["hint"]
    held.release()
    held.release()  # idempotent: the place is not given twice
    assert slots.in_use == 0
    assert c.get(f"/v1/sweeps/{sid}/data", params={"format": "json"}).status_code == 200
    assert slots.in_use == 0


def test_a_second_netcdf_build_is_503_with_the_builds_time_left(
    done: tuple[TestClient, str], monkeypatch: pytest.MonkeyPatch
) -> None:
    """While a NetCDF file is being built, another NetCDF download is answered 503 with
    Retry-After = the build's estimated time left (elapsed (1 - f)/f at fraction f
    done, + 1 s, rounded up), a CSV or JSON download is served; once the build is
    written (the file is then being sent) the next build is admitted."""
    from service import downloads

    c, sid = done
    clock = [1000.0]
    monkeypatch.setattr(downloads.time, "monotonic", lambda: clock[0])
    slots = downloads.DownloadSlots(downloads=3, builds=1)
    monkeypatch.setattr(downloads, "SLOTS", slots)
    build = slots.admit(downloads.DownloadKind.NETCDF)
    r = c.get(f"/v1/sweeps/{sid}/data", params={"format": "netcdf"})
    # no progress yet: no estimate, the configured Retry-After (RSF_RETRY_AFTER_S = 5)
    assert r.status_code == 503 and r.headers["retry-after"] == "5"
    assert "NetCDF file is being built" in r.json()["reason"]
    assert "CSV, JSON and the Zarr store" in r.json()["hint"]
    clock[0] += 12.0
    build.progress(1, 4)  # a quarter in 12 s: 36 s left
    r = c.get(f"/v1/sweeps/{sid}/data", params={"format": "netcdf"})
    assert r.status_code == 503 and r.headers["retry-after"] == "37", r.headers
    assert c.get(f"/v1/sweeps/{sid}/data", params={"format": "csv"}).status_code == 200
    build.progress(4, 4)  # written: now being sent, the next build may start
    assert c.get(f"/v1/sweeps/{sid}/data", params={"format": "netcdf"}).status_code == 200
    assert slots.in_use == 1  # the first one, still "sending"
    build.release()
    assert slots.in_use == 0


def test_retry_after_of_a_build_is_capped() -> None:
    from service import downloads

    slots = downloads.DownloadSlots(downloads=2, builds=1)
    build = slots.admit(downloads.DownloadKind.NETCDF)
    build.started -= 1000.0  # 1000 s for a millionth of the file
    build.progress(1, 10**6)
    with pytest.raises(downloads.Busy) as e:
        slots.admit(downloads.DownloadKind.NETCDF)
    assert e.value.retry_after_s == downloads.RETRY_AFTER_MAX_S
    with pytest.raises(ValueError, match="downloads and builds"):
        downloads.DownloadSlots(0, 1)


def test_diagram_png_draws_long_axes_thinned(
    done: tuple[TestClient, str], monkeypatch: pytest.MonkeyPatch
) -> None:
    """A PNG diagram with more points on an axis than PNG_AXIS_POINTS is drawn every
    k-th point (header X-Diagram-Step); the JSON diagram is never thinned."""
    c, sid = done
    r = c.get(f"/v1/sweeps/{sid}/diagram", params={"slice": "ba:3", "format": "png"})
    assert r.status_code == 200 and "x-diagram-step" not in r.headers
    monkeypatch.setattr("service.routes.sweeps.PNG_AXIS_POINTS", 3)
    r = c.get(f"/v1/sweeps/{sid}/diagram", params={"slice": "ba:3", "format": "png"})
    assert r.status_code == 200 and r.content[:4] == b"\x89PNG"
    assert r.headers["x-diagram-step"] == "kappa_ratio:2,eps:3"  # 6 and 7 points
    r = c.get(
        f"/v1/sweeps/{sid}/diagram",
        params={"slice": "ba:3", "format": "png", "isel": "eps:0:3"},
    )
    assert r.headers["x-diagram-step"] == "kappa_ratio:2"  # the window has 3 eps values
    d = c.get(f"/v1/sweeps/{sid}/diagram", params={"slice": "ba:3"}).json()
    assert (len(d["x"]), len(d["y"])) == (6, 7)


def test_a_large_json_diagram_takes_a_download_place(
    done: tuple[TestClient, str], monkeypatch: pytest.MonkeyPatch
) -> None:
    """A JSON diagram of more than DIAGRAM_FREE_POINTS points is admitted like a
    download (503 with Retry-After when every place is taken); a small one never is."""
    from service import downloads

    c, sid = done
    slots = downloads.DownloadSlots(downloads=1, builds=1)
    monkeypatch.setattr(downloads, "SLOTS", slots)
    monkeypatch.setattr("service.routes.sweeps.DIAGRAM_FREE_POINTS", 41)  # 6 x 7 = 42
    held = slots.admit(downloads.DownloadKind.STREAM)
    r = c.get(f"/v1/sweeps/{sid}/diagram", params={"slice": "ba:3"})
    assert r.status_code == 503 and int(r.headers["retry-after"]) > 0, r.text
    small = c.get(f"/v1/sweeps/{sid}/diagram", params={"slice": "ba:3", "isel": "eps:0:6"})
    assert small.status_code == 200  # 36 points: no place needed
    assert (
        c.get(f"/v1/sweeps/{sid}/diagram", params={"slice": "ba:3", "format": "png"}).status_code
        == 200
    )
    held.release()
    r = c.get(f"/v1/sweeps/{sid}/diagram", params={"slice": "ba:3"})
    assert r.status_code == 200 and len(r.json()["y"]) == 7
    assert slots.in_use == 0


def test_diagram_window(done: tuple[TestClient, str]) -> None:
    c, sid = done
    whole = c.get(f"/v1/sweeps/{sid}/diagram", params={"slice": "ba:3"}).json()
    win = c.get(
        f"/v1/sweeps/{sid}/diagram",
        params={"slice": "ba:3", "isel": "kappa_ratio:1:4", "sel": "eps:0.2:0.7"},
    ).json()
    keep = [k for k, e in enumerate(whole["y"]) if 0.2 <= e <= 0.7]
    assert win["x"] == whole["x"][1:4] and win["y"] == [whole["y"][k] for k in keep]
    assert win["critical_size"] == [[whole["critical_size"][i][k] for k in keep] for i in (1, 2, 3)]


def _zarr_copy(c: TestClient, sid: str, root: Any) -> None:
    """Every key of the sweep's Zarr store fetched over HTTP into a directory (a Zarr
    format-2 directory store has the same key names as files)."""
    import itertools

    meta = c.get(f"/v1/sweeps/{sid}/zarr/.zmetadata")
    assert meta.status_code == 200
    (root / ".zmetadata").write_bytes(meta.content)
    for key, m in meta.json()["metadata"].items():
        r = c.get(f"/v1/sweeps/{sid}/zarr/{key}")
        assert r.status_code == 200 and r.json() == m, key
        (root / key).parent.mkdir(parents=True, exist_ok=True)
        (root / key).write_bytes(r.content)
        if key.endswith(".zarray"):
            grid = [range(-(-n // ch)) for n, ch in zip(m["shape"], m["chunks"], strict=True)]
            for pos in itertools.product(*grid):
                ck = key.rsplit("/", 1)[0] + "/" + ".".join(map(str, pos))
                r = c.get(f"/v1/sweeps/{sid}/zarr/{ck}")
                assert r.status_code == 200, ck
                (root / ck).write_bytes(r.content)


def test_zarr_store_equals_the_netcdf(done: tuple[TestClient, str], tmp_path: Any) -> None:
    import xarray as xr

    c, sid = done
    _zarr_copy(c, sid, tmp_path)
    z = xr.open_zarr(tmp_path, consolidated=True, zarr_format=2)
    nc = _nc(c, sid)
    assert z["critical_size"].dims == ("ba", "kappa_ratio", "eps")
    for v in nc.data_vars:
        np.testing.assert_array_equal(z[v].values, nc[v].values)
    assert z.attrs["Conventions"] == "CF-1.10"
    assert z["kind"].attrs["flag_meanings"] == "zero finite infinite"
    assert c.get(f"/v1/sweeps/{sid}/zarr/critical_size/9.9.9").status_code == 404
    assert c.get(f"/v1/sweeps/{sid}/zarr/nope/.zarray").status_code == 404
    assert c.get(f"/v1/sweeps/{'0' * 32}/zarr/.zmetadata").status_code == 404


def test_zarr_chunks_follow_the_blocks(api_stack: tuple[TestClient, Any], tmp_path: Any) -> None:
    """Chunk size 12 on a 3 x 4 x 6 grid is two rows of 6: Zarr chunks (1, 2, 6), one block
    each; a running sweep (one chunk of six computed) shows the rest as NaN."""
    import xarray as xr

    from worker.tasks import run_chunk_body

    c = api_stack[0]
    body = {
        "axes": [
            {"name": "ba", "values": [2.0, 3.0, 4.0]},
            {"name": "kappa_ratio", "start": 0.5, "stop": 3.0, "n": 4},
            {"name": "eps", "start": 0.0, "stop": 0.9, "n": 6},
        ],
        "fixed": {"vo": 0.5},
        "chunk_points": 12,
    }
    sid = submit(c, body)["id"]
    m = c.get(f"/v1/sweeps/{sid}/zarr/critical_size/.zarray").json()
    assert m["chunks"] == [1, 2, 6] and m["shape"] == [3, 4, 6]
    run_chunk_body(sid, 1)  # flat points 12..23: ba index 0, kappa_ratio rows 2 and 3
    _zarr_copy(c, sid, tmp_path)
    z = xr.open_zarr(tmp_path, consolidated=True, zarr_format=2)
    cs = z["critical_size"].values
    done_mask = np.zeros((3, 4, 6), bool)
    done_mask[0, 2:4, :] = True
    assert not np.isnan(cs[done_mask]).any()
    assert np.isnan(cs[~done_mask]).all()
    assert (z["computed"].values == done_mask).all()
    assert np.isnan(z["kind"].values[~done_mask]).all()


def test_zarr_chunks_are_made_a_few_at_a_time() -> None:
    """However many chunk requests arrive at once, at most ZARR_CHUNKS_AT_ONCE are made
    side by side; the others wait (none is refused) and every one is answered."""
    import threading
    import time

    from service import downloads

    lock = threading.Lock()
    now = [0]
    most = [0]

    def make(key: str) -> bytes:
        with lock:
            now[0] += 1
            most[0] = max(most[0], now[0])
        time.sleep(0.02)
        with lock:
            now[0] -= 1
        return key.encode()

    got: list[bytes | None] = []
    ts = [
        threading.Thread(target=lambda k=k: got.append(downloads.zarr_chunk(make, f"v/{k}")))
        for k in range(4 * downloads.ZARR_CHUNKS_AT_ONCE)
    ]
    for t in ts:
        t.start()
    for t in ts:
        t.join()
    assert sorted(got) == sorted(f"v/{k}".encode() for k in range(len(ts)))
    assert 1 <= most[0] <= downloads.ZARR_CHUNKS_AT_ONCE
