"""The dashboard page driven in a real headless browser (Debian's chromium).

A real uvicorn and a real Celery worker serve the page; chromium is started by the test
with a fresh profile and driven over the Chrome DevTools Protocol (a websocket, with the
``websockets`` package that uvicorn already depends on).  The test loads the page, runs a
single query (outcome + phase-plane PNG), submits a 3 x 3 sweep from the form, watches
the sweep list show its progress, then waits for the finished stability diagram image,
and saves a screenshot of the page.

The worker is slowed down (0.5 s a point, via tests/e2e/test_worker_faultplugin.py) so the
sweep runs for a few seconds and the 1 s polling of the page can show it in progress.

chromium is required under CI=true (.ci/run installs it): missing, the test fails;
locally it is skipped with the reason.  ``RSF_UI_SCREENSHOT=<path>`` also copies the
screenshot there (docs/ui-screenshot.png is made that way).
"""

from __future__ import annotations

import base64
import contextlib
import io
import itertools
import json
import os
import shutil
import struct
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import httpx
import pytest

from tests.conftest import Proc, Server, Worker

pytestmark = pytest.mark.timeout(240)

CHROME_FLAGS = [
    "--headless",
    "--no-sandbox",
    "--disable-gpu",
    "--disable-quic",
    "--no-first-run",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--disable-dev-shm-usage",
    "--disable-extensions",
    "--mute-audio",
    "--hide-scrollbars",
    "--remote-allow-origins=*",
    "--window-size=1400,1000",
]


@pytest.fixture(scope="session")
def chromium_exe() -> str:
    """Path of chromium; a failure under CI=true when absent, else a skip."""
    for name in ("chromium", "chromium-browser", "google-chrome", "google-chrome-stable"):
        exe = shutil.which(name)
        if exe:
            return exe
    if Path("/usr/bin/chromium").exists():
        return "/usr/bin/chromium"
    msg = "chromium not installed (apt-get install -y chromium chromium-driver)"
    if os.environ.get("CI", "").lower() == "true":
        pytest.fail(msg + " -- required under CI=true")
    pytest.skip(msg)


class Browser:
    """A headless chromium process and a CDP session on its one page."""

    def __init__(self, exe: str, workdir: Path) -> None:
        profile = workdir / "chromium-profile"
        profile.mkdir(parents=True, exist_ok=True)
        (profile / "DevToolsActivePort").unlink(missing_ok=True)
        env = {k: v for k, v in os.environ.items() if not k.startswith("RSF_")}
        self.proc = Proc(
            [
                exe,
                *CHROME_FLAGS,
                f"--user-data-dir={profile}",
                "--remote-debugging-port=0",
                "about:blank",
            ],
            env,
            workdir / "chromium.log",
        )
        self._stack = contextlib.ExitStack()
        try:
            self._connect(profile)
        except BaseException:
            self.close()
            raise

    def _connect(self, profile: Path) -> None:
        from websockets.sync.client import connect

        port_file = profile / "DevToolsActivePort"
        deadline = time.monotonic() + 30
        while not (port_file.exists() and port_file.read_text().strip()):
            if not self.proc.alive() or time.monotonic() > deadline:
                raise RuntimeError("chromium did not start:\n" + self.proc.tail())
            time.sleep(0.05)
        port = int(port_file.read_text().split()[0])
        pages: list[dict[str, Any]] = []
        while not pages:
            if time.monotonic() > deadline:
                raise RuntimeError("chromium has no page target:\n" + self.proc.tail())
            with contextlib.suppress(httpx.HTTPError):
                pages = [
                    t
                    for t in httpx.get(f"http://127.0.0.1:{port}/json/list", timeout=10).json()
                    if t.get("type") == "page"
                ]
            if not pages:
                time.sleep(0.1)
        self.ws = self._stack.enter_context(
            connect(pages[0]["webSocketDebuggerUrl"], max_size=None, open_timeout=20)
        )
        self._ids = itertools.count(1)
        self.events: list[dict[str, Any]] = []
        self.call("Page.enable")
        self.call("Runtime.enable")

    def call(self, method: str, timeout: float = 60, **params: Any) -> dict[str, Any]:
        """Send one CDP command and return its result (events are kept in ``events``)."""
        mid = next(self._ids)
        self.ws.send(json.dumps({"id": mid, "method": method, "params": params}))
        deadline = time.monotonic() + timeout
        while True:
            msg = json.loads(self.ws.recv(timeout=max(0.1, deadline - time.monotonic())))
            if msg.get("id") == mid:
                if "error" in msg:
                    raise RuntimeError(f"{method}: {msg['error']}")
                return msg.get("result", {})
            if "method" in msg:
                self.events.append(msg)

    def navigate(self, url: str, timeout: float = 30) -> None:
        """Open ``url`` and wait for its load event."""
        self.events.clear()
        self.call("Page.navigate", url=url)
        deadline = time.monotonic() + timeout
        while not any(e["method"] == "Page.loadEventFired" for e in self.events):
            if time.monotonic() > deadline:
                raise AssertionError(f"{url} did not load in {timeout} s")
            msg = json.loads(self.ws.recv(timeout=max(0.1, deadline - time.monotonic())))
            if "method" in msg:
                self.events.append(msg)

    def js(self, expr: str) -> Any:
        """Evaluate ``expr`` in the page (promises awaited) and return its value."""
        r = self.call("Runtime.evaluate", expression=expr, returnByValue=True, awaitPromise=True)
        if "exceptionDetails" in r:
            raise RuntimeError(f"{expr!r} raised: {r['exceptionDetails']}")
        return r["result"].get("value")

    def wait(
        self, expr: str, timeout: float, what: str, each: Callable[[Any], None] | None = None
    ) -> Any:
        """Poll ``expr`` every 0.1 s until truthy; ``each`` sees every value."""
        deadline = time.monotonic() + timeout
        error = None
        while time.monotonic() < deadline:
            try:
                v = self.js(expr)
            except RuntimeError as exc:  # e.g. an element not rendered yet
                v, error = None, exc
            if each:
                each(v)
            if v:
                return v
            time.sleep(0.1)
        raise AssertionError(
            f"timed out after {timeout} s waiting for {what} (last error: "
            f"{error}); page says: " + str(self.js("document.body.innerText.slice(0, 1500)"))
        )

    def exceptions(self) -> list[str]:
        """JavaScript exceptions thrown in the page so far."""
        return [
            json.dumps(e["params"])[:500]
            for e in self.events
            if e["method"] == "Runtime.exceptionThrown"
        ]

    def screenshot(self, width: int = 1400, scale: float = 1.0) -> bytes:
        """A PNG of the whole page laid out ``width`` CSS pixels wide, scaled by ``scale``."""
        self.call(
            "Emulation.setDeviceMetricsOverride",
            width=width,
            height=1000,
            deviceScaleFactor=1,
            mobile=False,
        )
        time.sleep(0.3)
        height = int(self.js("Math.ceil(document.documentElement.scrollHeight)"))
        self.call(
            "Emulation.setDeviceMetricsOverride",
            width=width,
            height=height,
            deviceScaleFactor=1,
            mobile=False,
        )
        time.sleep(0.3)
        shot = self.call(
            "Page.captureScreenshot",
            format="png",
            captureBeyondViewport=True,
            clip={"x": 0, "y": 0, "width": width, "height": height, "scale": scale},
        )
        return base64.b64decode(shot["data"])

    def close(self) -> None:
        try:
            self._stack.close()
        finally:
            self.proc.stop(timeout=10)


def png_size(data: bytes) -> tuple[int, int]:
    """(width, height) of a PNG, checking its signature."""
    assert data[:8] == b"\x89PNG\r\n\x1a\n", data[:16]
    assert data[12:16] == b"IHDR"
    return struct.unpack(">II", data[16:24])


SET_SWEEP_FORM = """(() => {
  const f = document.querySelector('#sweep-form');
  const set = (n, v) => { f.elements[n].value = v;
    f.elements[n].dispatchEvent(new Event('change', {bubbles: true})); };
  set('x_name', 'kappa_ratio'); set('x_start', '1.1'); set('x_stop', '3'); set('x_n', '3');
  set('y_name', 'eps'); set('y_start', '0'); set('y_stop', '0.8'); set('y_n', '3');
  set('f_ba', '2'); set('f_vo', '1'); set('f_size', '');
  document.querySelector('#sweep-submit').click();
  return true;
})()"""

ROW_STATE = """(() => {
  const tr = document.querySelector('#sweeps-table tr.sweep');
  if (!tr) return null;
  const p = tr.querySelector('.progress');
  return {id: tr.dataset.id, status: tr.dataset.status, done: +p.dataset.done,
          total: +p.dataset.total, label: p.querySelector('.label').textContent,
          badge: tr.querySelector('.badge').textContent};
})()"""

DIAGRAM_STATE = """(() => {
  const img = document.querySelector('#diagram-img');
  return {sweep: img.dataset.sweep || null, status: img.dataset.status || null,
          progress: img.dataset.progress || null, hidden: img.hidden,
          complete: img.complete, width: img.naturalWidth, height: img.naturalHeight,
          caption: document.querySelector('#diagram-caption').textContent};
})()"""


def test_dashboard_in_headless_chromium(chromium_exe: str, tmp_path: Path, procs: list) -> None:
    t0 = time.monotonic()
    procs.append(srv := Server(tmp_path, RSF_INLINE_BUDGET_S="120"))
    procs.append(Worker(tmp_path, plugin=True, RSF_TEST_POINT_DELAY_S="0.5"))
    browser = Browser(chromium_exe, tmp_path)
    try:
        # -- the page loads, talks to the API, lists the paper figures
        browser.navigate(srv.url + "/")
        browser.wait(
            "document.readyState === 'complete' && "
            "document.querySelector('#health').classList.contains('ok')",
            30,
            "the page to load and reach /health",
        )
        assert browser.js("document.title").startswith("rsf-stability")
        browser.wait(
            "document.querySelectorAll('#figure-select option').length >= 10",
            30,
            "the list of paper figures",
        )
        assert browser.js(
            "document.querySelector('#sweeps-table tbody').innerText.includes('no sweeps yet')"
        )

        # -- a single query: outcome and the phase-plane PNG
        browser.js("document.querySelector('#query-submit').click(), true")
        browser.wait(
            "document.querySelector('#phase-img').naturalWidth > 0 && "
            "!document.querySelector('#phase-figure').hidden",
            60,
            "the phase-plane plot",
        )
        outcome = browser.js("document.querySelector('#outcome-badge').textContent")
        ref = httpx.post(
            srv.url + "/v1/classify",
            json={"ba": 2, "kappa": 2, "eps": 0.25, "vo": 1, "size": 2.7},
            timeout=60,
        )
        assert outcome == ref.json()["outcome"], (outcome, ref.text)
        browser.wait(
            "!/\\u2026/.test(document.querySelector('#critical-size').textContent)",
            60,
            "the critical size",
        )

        # -- submit a 3 x 3 sweep from the form; the list shows its progress
        browser.js(SET_SWEEP_FORM)
        seen: list[dict[str, Any]] = []

        def record(v: Any) -> None:
            row = browser.js(ROW_STATE)
            if row and (not seen or row != seen[-1]):
                seen.append(row)

        browser.wait(
            "(() => { const tr = document.querySelector('#sweeps-table tr.sweep');"
            " return !!tr && tr.dataset.status === 'done'; })()",
            120,
            "the sweep to finish in the list",
            each=record,
        )
        sid = seen[-1]["id"]
        assert len(sid) == 32 and seen[-1]["total"] == 9 and seen[-1]["done"] == 9
        assert seen[-1]["label"].startswith("9 / 9"), seen[-1]
        assert any(s["status"] in ("queued", "running") for s in seen), seen
        assert any(0 < s["done"] < 9 for s in seen), f"no partial progress shown: {seen}"
        st = httpx.get(f"{srv.url}/v1/sweeps/{sid}", timeout=30).json()
        assert st["status"] == "done" and st["n_done"] == 9
        data = httpx.get(
            f"{srv.url}/v1/sweeps/{sid}/data", params={"format": "json"}, timeout=30
        ).json()
        assert data["coords"][st["dims"][0]["name"]] == [1.1, 2.05, 3.0]

        # -- then the finished stability diagram
        diagram = browser.wait(
            f"(() => {{ const d = {DIAGRAM_STATE}; return d.sweep === '{sid}' && "
            "d.status === 'done' && d.complete && d.width > 0 && !d.hidden ? d : null; })()",
            60,
            "the finished diagram image",
        )
        assert diagram["width"] >= 400 and diagram["height"] >= 300, diagram
        assert diagram["progress"] == "9/9" and "done" in diagram["caption"], diagram
        png = httpx.get(f"{srv.url}/v1/sweeps/{sid}/diagram?format=png", timeout=30)
        assert png.status_code == 200 and png_size(png.content) == (
            diagram["width"],
            diagram["height"],
        )

        # -- a paper figure, then a screenshot of the whole page
        browser.js(
            "(() => { const s = document.querySelector('#figure-select');"
            " s.value = 'stability-diagram-velocity';"
            " s.dispatchEvent(new Event('change')); return true; })()"
        )
        browser.wait(
            "document.querySelector('#figure-img').naturalWidth > 0", 90, "the paper figure"
        )
        shot = browser.screenshot()
        (tmp_path / "ui.png").write_bytes(shot)
        w, h = png_size(shot)
        assert w == 1400 and h >= 900 and len(shot) > 50_000, (w, h, len(shot))
        from matplotlib.image import imread

        px = imread(io.BytesIO(shot), format="png")
        assert px.std() > 0.05, "screenshot looks blank"
        if os.environ.get("RSF_UI_SCREENSHOT"):
            Path(os.environ["RSF_UI_SCREENSHOT"]).write_bytes(shot)
        assert browser.exceptions() == []
    finally:
        browser.close()
    print(f"browser test took {time.monotonic() - t0:.1f} s; screenshot {tmp_path / 'ui.png'}")
