"""The metric hooks in process (issue 25, item 1): a lease that expires is counted as an
expiry and a requeue by the reaper, a fit is counted and timed (ok or error), the
exposition parses, and ``/metrics`` needs a key when keys are on.  The real-process
version (uvicorn, prefork Celery workers, a sweep, a killed worker) is
tests/e2e/test_metrics.py."""

from __future__ import annotations

import time
from pathlib import Path

import pytest
from sqlalchemy import update

from rsfapp import metrics
from rsfapp.config import Settings
from rsfapp.db.tables import chunks
from rsfapp.reaper import Reaper
from rsfapp.store import stores_for
from tests.app.test_sweep_store import grid


def _v(name: str, **labels: str) -> float:
    v = metrics.registry().get_sample_value(name, labels or None)
    return 0.0 if v is None else v


def test_an_expired_lease_is_counted_by_the_reaper(tmp_path: Path) -> None:
    s = Settings(data_dir=tmp_path, lease_s=5.0)
    st = stores_for(s).sweeps
    st.create("s1", grid(4, 5), 10, "t", window=2)  # 20 points, 2 chunks
    assert st.claim("s1", 0, s.lease_s) is not None
    with st.db.write() as conn:  # its worker went silent a lease ago
        conn.execute(update(chunks).where(chunks.c.idx == 0).values(heartbeat=time.time() - 60))
    e0 = _v("rsf_lease_expiries_total")
    q0 = _v("rsf_chunk_requeues_total", reason="lease_expired")
    sent: list[tuple[str, int]] = []
    r = Reaper(s, "test-reaper", 1, lambda sid, idx: sent.append((sid, idx)))
    r.tick()
    assert ("s1", 0) in sent
    assert _v("rsf_lease_expiries_total") - e0 == 1
    assert _v("rsf_chunk_requeues_total", reason="lease_expired") - q0 == 1


def test_fits_are_counted_and_timed() -> None:
    ok0, err0 = _v("rsf_fits_total", result="ok"), _v("rsf_fits_total", result="error")
    n0 = _v("rsf_fit_duration_seconds_count")
    with metrics.timed_fit():
        time.sleep(0.01)
    with pytest.raises(ValueError), metrics.timed_fit():
        raise ValueError("bad record")
    assert _v("rsf_fits_total", result="ok") - ok0 == 1
    assert _v("rsf_fits_total", result="error") - err0 == 1
    assert _v("rsf_fit_duration_seconds_count") - n0 == 2
    # the 10 ms sleep lies in a bucket above 0.01 s: the +Inf bucket holds both fits
    assert _v("rsf_fit_duration_seconds_bucket", le="+Inf") - n0 == 2


def test_exposition_names_every_metric() -> None:
    text = metrics.render().decode()
    for name in (
        "rsf_http_requests_total",
        "rsf_http_request_duration_seconds",
        "rsf_cache_lookups_total",
        "rsf_sweep_points_total",
        "rsf_sweep_chunks_total",
        "rsf_sweep_chunk_duration_seconds",
        "rsf_lease_expiries_total",
        "rsf_chunk_requeues_total",
        "rsf_fits_total",
        "rsf_fit_duration_seconds",
    ):
        assert f"# HELP {name} " in text, name


def test_compose_prometheus_scrapes_the_metrics_port() -> None:
    """docker-compose.yml parses (a YAML error would only show at `docker compose up`),
    its API and workers serve metrics on the port prometheus.yml scrapes, and Prometheus
    mounts that file."""
    import yaml

    root = Path(__file__).resolve().parents[2]
    compose = yaml.safe_load((root / "docker-compose.yml").read_text())
    prom = yaml.safe_load((root / "prometheus.yml").read_text())
    svc = compose["services"]
    ports = {name: svc[name]["environment"]["RSF_METRICS_PORT"] for name in ("api", "worker")}
    assert ports == {"api": "9464", "worker": "9464"}
    jobs = {j["job_name"]: j for j in prom["scrape_configs"]}
    assert jobs["rsf-api"]["static_configs"][0]["targets"] == ["api:9464"]
    dns = jobs["rsf-worker"]["dns_sd_configs"][0]
    assert dns["names"] == ["worker"] and dns["port"] == 9464
    assert any(v.startswith("./prometheus.yml:") for v in svc["prometheus"]["volumes"])
