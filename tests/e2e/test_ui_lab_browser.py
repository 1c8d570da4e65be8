"""The dashboard's lab side in a real headless chromium against a real uvicorn and a real
Celery worker: an SI query (the page's outcome equals POST /v1/classify with the same SI
body, and the facts are in s and m/s), then the fit page (a synthetic record uploaded as
a file, queued, fitted by the worker; the page shows the parameters, the law comparison,
the stability answer and the plot, equal to GET /v1/fits/{key})."""

from __future__ import annotations

import json
import time
from pathlib import Path

import httpx
import numpy as np
import pytest

from rsfcore.fit import synthetic_record
from tests.conftest import Server, Worker
from tests.e2e.test_ui_browser import Browser, chromium_exe, png_size  # noqa: F401

pytestmark = pytest.mark.timeout(240)

PHYS = {
    "a": 0.01,
    "b": 0.015,
    "Dc_m": 1e-5,
    "sigma_Pa": 1e8,
    "k_Pa_per_m": 6e10,
    "V_star_m_s": 1e-6,
}

SET_SI = """(() => {
  const f = document.querySelector('#query-form');
  f.querySelector('input[name=units][value=si]').click();
  const set = (n, v) => { f.elements[n].value = v; };
  set('si_a', '0.01'); set('si_b', '0.015'); set('si_Dc_m', '1e-5'); set('si_sigma_Pa', '1e8');
  set('si_k_Pa_per_m', '6e10'); set('si_V_star_m_s', '1e-6'); set('si_V_load_m_s', '');
  set('si_factor', '20'); set('eps', '0.5');
  document.querySelector('#query-submit').click();
  return true;
})()"""


def upload(csv_text: str) -> str:
    return """(() => {
  const f = document.querySelector('#fit-form');
  const dt = new DataTransfer();
  dt.items.add(new File([RECORD], 'record.csv', {type: 'text/csv'}));
  f.elements.record.files = dt.files;
  f.elements.k_friction_per_m.value = '2000';
  document.querySelector('#fit-submit').click();
  return true;
})()""".replace("RECORD", json.dumps(csv_text))


def test_si_query_and_fit_page(chromium_exe: str, tmp_path: Path, procs: list) -> None:  # noqa: F811
    procs.append(srv := Server(tmp_path, RSF_INLINE_BUDGET_S="120"))
    procs.append(Worker(tmp_path))
    browser = Browser(chromium_exe, tmp_path)
    try:
        browser.navigate(srv.url + "/")
        browser.wait(
            "document.readyState === 'complete' && "
            "document.querySelector('#health').classList.contains('ok')",
            30,
            "the page to load",
        )
        browser.js(SET_SI)
        browser.wait("!document.querySelector('#phase-figure').hidden", 60, "the SI query")
        assert browser.js("document.querySelector('#dimless-fields').hidden") is True
        outcome = browser.js("document.querySelector('#outcome-badge').textContent")
        ref = httpx.post(
            srv.url + "/v1/classify", json={"physical": PHYS, "eps": 0.5, "factor": 20}, timeout=60
        ).json()
        assert outcome == ref["outcome"]
        facts = browser.js("document.querySelector('#outcome-facts').innerText")
        assert "[s]" in facts and "m/s" in facts, facts
        browser.wait(
            "/m\\/s|infinite|zero/.test(document.querySelector('#critical-size').textContent)",
            60,
            "the critical size in SI",
        )

        t = np.linspace(0.0, 60.0, 601)
        v = np.where(t < 20, 1e-6, np.where(t < 40, 1e-5, 1e-6))
        rec = synthetic_record(t, v, mu0=0.6, a=0.01, b=0.015, Dc_m=1e-5, eps=1.0, k_per_m=2000.0)
        t0 = time.monotonic()
        browser.js(upload(rec.to_csv()))
        browser.wait(
            "!document.querySelector('#fit-figure').hidden && "
            "document.querySelector('#fit-img').naturalWidth > 0",
            120,
            "the fit, queued and computed by the worker",
        )
        dt = time.monotonic() - t0
        badge = browser.js("document.querySelector('#fit-badge').textContent")
        assert badge == "aging: ok", badge
        laws = browser.js("document.querySelector('#fit-laws').innerText")
        for law in ("aging", "slip", "nagata", "eps"):
            assert law in laws
        key = browser.js("document.querySelector('#fit-csv').dataset.key")
        fit = httpx.get(f"{srv.url}/v1/fits/{key}", timeout=30).json()
        shown = browser.js(
            "[...document.querySelectorAll('#fit-params tbody tr')].map("
            "tr => [...tr.cells].map(td => td.textContent))"
        )
        rows = {r[0]: r for r in shown}
        # the page shows 6 significant digits of the API's values
        for label, k in (("a", "a"), ("b", "b"), ("\u03bc0", "mu0")):
            assert float(rows[label][1]) == pytest.approx(fit["params"][k], rel=1e-5)
        assert float(rows["D_c [m]"][1]) == pytest.approx(1e-5, rel=1e-5)
        stab = browser.js("document.querySelector('#fit-stability').innerText")
        assert "critical stiffness" in stab and "500" in stab, stab
        assert not browser.exceptions(), browser.exceptions()
        print(f"fit page round trip (upload, queue, worker fit, plot) in {dt:.2f} s")
    finally:
        browser.close()
