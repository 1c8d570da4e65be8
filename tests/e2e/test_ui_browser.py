"""The dashboard page driven in a real headless browser (Debian's chromium).

A real uvicorn and a real Celery worker serve the page (one of each for the module);
chromium is started with a fresh profile and driven over the Chrome DevTools Protocol (a
websocket, with the ``websockets`` package that uvicorn already depends on).

* the page as a new user meets it: "loading" until the sweep list answers, a single query
  (outcome + phase-plane PNG), a 3 x 3 sweep submitted from the form whose progress, ETA
  ("estimating" until the page saw two progress samples) and cancel button stay in view
  at 1280 px, then the finished diagram with the form's symbols and the download links;
* a 3-D sweep opened by a deep link (``/ui?sweep=ID&slice=ba:1.4``) shows that slice,
  drawn from the server's answer; another slice changes the image and the address;
  another pair of axes; clicking another sweep never shows the previous image;
* a refused request (422 slice, 404 sweep) is shown once and never asked again;
* an SI sweep submitted from the form carries the API's SI names; its view is labelled in
  SI, and the page's SI scale agrees with the server's SI values;
* scattered points: a scatter plot over two chosen parameters.

The worker is slowed down (0.5 s a point, via tests/e2e/test_worker_faultplugin.py) while
the first test's sweep runs, so that it runs for a few seconds and the 1 s polling of the
page can show it in progress; the other tests watch finished sweeps only, at full speed.

chromium is required under CI=true (.ci/run installs it): missing, the test fails;
locally it is skipped with the reason.  ``RSF_UI_SCREENSHOTS=<dir>`` writes a screenshot
of each state there (docs/ui-*.png are made that way); ``RSF_UI_SCREENSHOT=<path>`` the
whole page of the first test.
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

from tests.conftest import Proc, Redis, Server, Worker

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


def shoot(
    browser: Browser, tmp_path: Path, name: str, width: int = 1400, height: int | None = 900
) -> bytes:
    """A screenshot of the window (``width`` x ``height`` CSS pixels, scrolled to the top)
    or with ``height=None`` of the whole page, kept in ``tmp_path`` and, when
    ``RSF_UI_SCREENSHOTS=<dir>`` is set, also in that directory (docs/ui-*.png are made so)."""
    if height is None:
        shot = browser.screenshot(width=width)
    else:
        browser.call(
            "Emulation.setDeviceMetricsOverride",
            width=width,
            height=height,
            deviceScaleFactor=1,
            mobile=False,
        )
        browser.js("window.scrollTo(0, 0), true")
        time.sleep(0.3)
        shot = base64.b64decode(browser.call("Page.captureScreenshot", format="png")["data"])
    w, _ = png_size(shot)
    assert w == width and len(shot) > 30_000, (w, len(shot))
    (tmp_path / f"ui-{name}.png").write_bytes(shot)
    out = os.environ.get("RSF_UI_SCREENSHOTS")
    if out:
        Path(out, f"ui-{name}.png").write_bytes(shot)
    browser.call(  # back to a normal window
        "Emulation.setDeviceMetricsOverride",
        width=width,
        height=1000,
        deviceScaleFactor=1,
        mobile=False,
    )
    return shot


class UI:
    """The page's server, worker and browser, shared by the tests of this module."""

    def __init__(self, srv: Server, browser: Browser, tmp_path: Path, delay_file: Path) -> None:
        self.srv, self.b, self.tmp, self.delay_file = srv, browser, tmp_path, delay_file
        self.b.call("Network.enable")

    def slow_worker(self, seconds_per_point: float) -> None:
        """Slow the worker down to ``seconds_per_point`` (0: full speed) from its next batch."""
        self.delay_file.write_text(repr(seconds_per_point))

    def submit(self, body: dict[str, Any]) -> str:
        r = httpx.post(self.srv.url + "/v1/sweeps", json=body, timeout=60)
        assert r.status_code in (200, 202), r.text
        return str(r.json()["id"])

    def done(self, sid: str, timeout: float = 120) -> dict[str, Any]:
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            st = httpx.get(f"{self.srv.url}/v1/sweeps/{sid}", timeout=30).json()
            if st["status"] == "done":
                return dict(st)
            time.sleep(0.2)
        raise AssertionError(f"sweep {sid} did not finish: {st}")

    def open(self, query: str) -> None:
        self.b.navigate(f"{self.srv.url}/ui?{query}")

    def view(self, sid: str, what: str, extra: str = "true", timeout: float = 60) -> Any:
        """Wait for the figure of sweep ``sid`` (``extra``: a further JS condition on c,
        the canvas) and return its state."""
        return self.b.wait(
            f"(() => {{ const c = document.querySelector('#diagram-canvas');"
            f" return !c.hidden && c.dataset.sweep === '{sid}' && ({extra}) ? {VIEW_STATE} : null; }})()",
            timeout,
            what,
        )

    def requests(self, part: str) -> list[str]:
        """URLs of the page's requests so far (since the last navigation) containing ``part``."""
        return [
            e["params"]["request"]["url"]
            for e in self.b.events
            if e["method"] == "Network.requestWillBeSent" and part in e["params"]["request"]["url"]
        ]


VIEW_STATE = """{sweep: c.dataset.sweep, status: c.dataset.status, progress: c.dataset.progress,
  slice: c.dataset.slice, axes: c.dataset.axes, key: c.dataset.key, image: c.toDataURL(),
  title: document.querySelector('#diagram-title').textContent,
  labels: document.querySelector('#diagram-axes').textContent,
  caption: document.querySelector('#diagram-caption').textContent,
  links: document.querySelector('#diagram-links').innerHTML,
  error: document.querySelector('#diagram-error').hidden ? '' :
    document.querySelector('#diagram-error').textContent,
  href: location.href}"""

SET_SWEEP_FORM = """(() => {
  const f = document.querySelector('#sweep-form');
  const set = (n, v) => { f.elements[n].value = v;
    f.elements[n].dispatchEvent(new Event('change', {bubbles: true})); };
  set('ax0_name', 'kappa_ratio'); set('ax0_start', '1.1'); set('ax0_stop', '3'); set('ax0_n', '3');
  set('ax1_name', 'eps'); set('ax1_start', '0'); set('ax1_stop', '0.8'); set('ax1_n', '3');
  set('f_ba', '2'); set('f_vo', '1'); set('f_size', '');
  document.querySelector('#sweep-submit').click();
  return true;
})()"""

ROW_STATE = """(() => {
  const tr = document.querySelector('#sweeps-table tr.sweep');
  if (!tr) return null;
  const p = tr.querySelector('.progress'), eta = tr.querySelector('td.eta');
  const cancel = tr.querySelector('[data-cancel]');
  const inView = el => { if (!el) return null; const r = el.getBoundingClientRect();
    return r.width > 0 && r.left >= 0 && r.right <= innerWidth && r.top >= 0 && r.bottom <= innerHeight; };
  return {id: tr.dataset.id, status: tr.dataset.status, done: +p.dataset.done,
          total: +p.dataset.total, label: p.querySelector('.label').textContent,
          badge: tr.querySelector('.badge').textContent,
          eta: eta.querySelector('.eta-text').textContent, cancel: !!cancel,
          visible: inView(p) && inView(eta.querySelector('.eta-text')) && (!cancel || inView(cancel)),
          hscroll: document.scrollingElement.scrollWidth > innerWidth,
          shown: document.querySelector('#diagram-canvas').dataset.progress || ''};
})()"""

GRID_3D = {
    "axes": [
        {"name": "kappa_ratio", "start": 1.1, "stop": 3.0, "n": 3},
        {"name": "eps", "start": 0.0, "stop": 0.8, "n": 3},
        {"name": "ba", "values": [1.4, 2.0]},
    ],
    "fixed": {"vo": 1.0},
}
MACHINE = {
    "a": 0.01,
    "b": 0.015,
    "Dc_m": 1e-5,
    "sigma_Pa": 1e8,
    "k_Pa_per_m": 2e11,
    "V_star_m_s": 1e-6,
    "V_load_m_s": 1e-5,
}


@pytest.fixture(scope="module")
def ui(chromium_exe: str, redis_exe: str, tmp_path_factory: pytest.TempPathFactory) -> Any:
    """Server, worker and browser for the module.  The broker is Redis: kombu's
    filesystem transport (the single-machine default) lets a worker read a message file
    before it is written under load ("Unrecoverable error: JSONDecodeError"), which
    stalls the page's sweeps for reasons that are not the page's."""
    tmp_path = tmp_path_factory.mktemp("ui")
    started: list[Proc] = []
    browser = None
    try:
        started.append(redis := Redis(redis_exe, tmp_path))
        started.append(srv := Server(tmp_path, redis.url, RSF_INLINE_BUDGET_S="120"))
        delay_file = tmp_path / "point-delay-s"
        delay_file.write_text("0")
        started.append(
            Worker(tmp_path, redis.url, plugin=True, RSF_TEST_POINT_DELAY_FILE=str(delay_file))
        )
        browser = Browser(chromium_exe, tmp_path)
        yield UI(srv, browser, tmp_path, delay_file)
    finally:
        if browser is not None:
            browser.close()
        for p in reversed(started):
            p.stop()


def test_dashboard_in_headless_chromium(ui: UI) -> None:
    t0 = time.monotonic()
    srv, browser, tmp_path = ui.srv, ui.b, ui.tmp
    # -- before its first answer the list says "loading", never "no sweeps yet"
    page = httpx.get(srv.url + "/ui", timeout=30).text
    assert "loading&hellip;" in page and "no sweeps yet" not in page
    # -- the page loads, talks to the API, lists the paper figures
    browser.call(
        "Emulation.setDeviceMetricsOverride",
        width=1280,
        height=800,
        deviceScaleFactor=1,
        mobile=False,
    )
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
    browser.wait(
        "document.querySelector('#sweeps-table tbody').innerText.includes('no sweeps yet')",
        30,
        "the empty sweep list",
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

    # -- submit a 3 x 3 sweep from the form; at 1280 px the list shows its progress, ETA
    #    and cancel without scrolling; the ETA says "estimating" until two samples.  The
    #    worker takes 0.5 s a point meanwhile, so the page sees the sweep half-way.
    ui.slow_worker(0.5)
    browser.js(SET_SWEEP_FORM)
    seen: list[dict[str, Any]] = []

    def record(v: Any) -> None:
        row = browser.js(ROW_STATE)
        if row and (not seen or row != seen[-1]):
            seen.append(row)
        if (  # a screenshot of the running sweep once it shows progress and an ETA
            row
            and row["status"] == "running"
            and 0 < row["done"] < row["total"]
            and row["eta"][:1].isdigit()
            and row["shown"] == f"{row['done']}/{row['total']}"  # the view has caught up
            and not (tmp_path / "ui-running.png").exists()
        ):
            shoot(browser, tmp_path, "running", width=1280, height=800)
            browser.call(
                "Emulation.setDeviceMetricsOverride",
                width=1280,
                height=800,
                deviceScaleFactor=1,
                mobile=False,
            )

    browser.wait(
        "(() => { const tr = document.querySelector('#sweeps-table tr.sweep');"
        " return !!tr && tr.dataset.status === 'done'; })()",
        120,
        "the sweep to finish in the list",
        each=record,
    )
    ui.slow_worker(0.0)
    sid = seen[-1]["id"]
    assert len(sid) == 32 and seen[-1]["total"] == 9 and seen[-1]["done"] == 9
    assert seen[-1]["label"].startswith("9 / 9"), seen[-1]
    active = [s for s in seen if s["status"] in ("queued", "running")]
    assert active, seen
    assert any(0 < s["done"] < 9 for s in seen), f"no partial progress shown: {seen}"
    assert all(s["visible"] and s["cancel"] and not s["hscroll"] for s in active), active
    # the first sample of the page cannot give a rate: "estimating" until progress moved
    assert active[0]["eta"].startswith("estimating"), active
    first_move = next(k for k, s in enumerate(seen) if s["done"] != seen[0]["done"])
    assert all(s["eta"].startswith("estimating") for s in seen[:first_move]), seen
    assert any(s["eta"][:1].isdigit() or s["eta"].startswith("<") for s in active), active
    st = httpx.get(f"{srv.url}/v1/sweeps/{sid}", timeout=30).json()
    assert st["status"] == "done" and st["n_done"] == 9
    data = httpx.get(
        f"{srv.url}/v1/sweeps/{sid}/data", params={"format": "json"}, timeout=30
    ).json()
    assert data["coords"][st["dims"][0]["name"]] == [1.1, 2.05, 3.0]

    # -- then the finished stability diagram, labelled with the form's symbols
    v = ui.view(sid, "the finished diagram", "c.dataset.status === 'done'")
    assert v["progress"] == "9/9" and "done" in v["caption"], v
    assert sid[:8] in v["title"] and "\u03ba/\u03ba_crit \u00d7 \u03b5" in v["title"], v
    assert v["labels"].startswith("x: \u03ba/\u03ba_crit \u00b7 y: \u03b5"), v
    assert "colour: critical velocity jump d = ln(V_new/V)" in v["labels"], v
    for fmt_ in ("netcdf", "csv", "json"):
        assert f"/v1/sweeps/{sid}/data?format={fmt_}" in v["links"], v["links"]
    # the address names the submitted sweep: the view can be shared
    assert f"sweep={sid}" in v["href"], v["href"]

    # -- a paper figure, then a screenshot of the whole page
    browser.js(
        "(() => { const s = document.querySelector('#figure-select');"
        " s.value = 'stability-diagram-velocity';"
        " s.dispatchEvent(new Event('change')); return true; })()"
    )
    browser.wait("document.querySelector('#figure-img').naturalWidth > 0", 90, "the paper figure")
    shot = shoot(browser, tmp_path, "screenshot", height=None)
    from matplotlib.image import imread

    px = imread(io.BytesIO(shot), format="png")
    assert px.std() > 0.05, "screenshot looks blank"
    if os.environ.get("RSF_UI_SCREENSHOT"):
        Path(os.environ["RSF_UI_SCREENSHOT"]).write_bytes(shot)
    # offline: every request of the page went to its own server (no CDN, no fonts)
    foreign = [u for u in ui.requests("") if not u.startswith((srv.url, "blob:", "data:"))]
    assert foreign == [], foreign
    assert browser.exceptions() == []
    print(f"browser test took {time.monotonic() - t0:.1f} s; screenshot {tmp_path}")


def test_3d_sweep_deep_link_and_slices(ui: UI) -> None:
    """A 3-D sweep opened by a deep link shows its own slice; another slice changes the
    image and the address; selecting a sweep never shows another sweep's image."""
    sid = ui.submit(GRID_3D)
    other = ui.submit(
        {
            "axes": [
                {"name": "kappa_ratio", "start": 1.1, "stop": 3.0, "n": 2},
                {"name": "eps", "start": 0.0, "stop": 0.5, "n": 2},
            ],
            "fixed": {"ba": 2.0},
        }
    )
    ui.done(sid)
    ui.done(other)
    srv = ui.srv.url
    d14 = httpx.get(f"{srv}/v1/sweeps/{sid}/diagram", params={"slice": "ba:1.4"}).json()
    d2 = httpx.get(f"{srv}/v1/sweeps/{sid}/diagram", params={"slice": "ba:2"}).json()
    assert d14["critical_size"] != d2["critical_size"]  # else the slices could not be told apart

    ui.open(f"sweep={sid}&slice=ba:1.4")
    v1 = ui.view(sid, "the deep-linked slice", "c.dataset.slice === 'ba:1.4'")
    assert sid[:8] in v1["title"] and "b/a" in v1["title"], v1
    assert "slice: b/a = 1.4" in v1["caption"], v1
    assert "slice=ba:1.4" in v1["href"] and "axes=kappa_ratio,eps" in v1["href"], v1
    asked = ui.requests(f"/v1/sweeps/{sid}/diagram")
    assert asked and all("slice=ba%3A1.4" in u for u in asked), asked
    # the page drew the server's slice: its answer is the server's, cell for cell
    shown = ui.b.js("window.rsfUi.view.answer")
    assert shown["critical_size"] == d14["critical_size"] and shown["slice"] == {"ba": 1.4}
    ctl = ui.b.js(
        "[...document.querySelectorAll('#view-controls [data-slice]')].map(e => e.dataset.slice)"
    )
    assert ctl == ["ba"], ctl
    # a pointer over the map reads the cell out: its coordinates and its value
    readout = ui.b.js(
        "(() => { const c = document.querySelector('#diagram-canvas'), r = c.getBoundingClientRect();"
        " c.dispatchEvent(new MouseEvent('mousemove', {clientX: r.left + r.width * 0.4,"
        " clientY: r.top + r.height * 0.5, bubbles: true}));"
        " return document.querySelector('#diagram-readout').textContent; })()"
    )
    assert readout.startswith("\u03ba/\u03ba_crit = ") and ", \u03b5 = " in readout, readout
    assert any(w in readout for w in ("critical", "zero", "infinite")), readout
    # the slice's own download: the server's subset of this slice, the same numbers
    link = ui.b.js(
        "[...document.querySelectorAll('#diagram-links a')]"
        ".find(a => a.textContent === 'slice CSV').getAttribute('href')"
    )
    assert link == f"/v1/sweeps/{sid}/data?format=csv&isel=ba%3A0", link
    rows = httpx.get(srv + link, timeout=30).text.strip().splitlines()
    head = rows[0].split(",")
    got = sorted(float(r.split(",")[head.index("critical_size")] or "inf") for r in rows[1:])
    want = sorted(x if x is not None else float("inf") for row in d14["critical_size"] for x in row)
    assert got == want, (got, want)
    # the lazy (Zarr) access: the store's consolidated metadata names the sweep's variables
    zlink = ui.b.js(
        "[...document.querySelectorAll('#diagram-links a')]"
        ".find(a => a.textContent === 'Zarr (lazy)').getAttribute('href')"
    )
    meta = httpx.get(srv + zlink, timeout=30)
    assert meta.status_code == 200 and "critical_size/.zarray" in meta.json()["metadata"], zlink
    shoot(ui.b, ui.tmp, "slice")

    # -- the other slice: new image, new address
    ui.b.js(
        "(() => { const s = document.querySelector('#view-controls [data-slice=ba]');"
        " s.value = '1'; s.dispatchEvent(new Event('change', {bubbles: true})); return true; })()"
    )
    v2 = ui.view(sid, "the second slice", "c.dataset.slice === 'ba:2'")
    assert v2["image"] != v1["image"], "the image did not change with the slice"
    assert "slice=ba:2" in v2["href"] and "slice: b/a = 2" in v2["caption"], v2
    assert ui.b.js("window.rsfUi.view.answer")["critical_size"] == d2["critical_size"]

    # -- other axes shown: eps x ba at a kappa_ratio slice (the server's kappa_ratio:1.1)
    ui.b.js(
        "(() => { const s = document.querySelector('#view-x');"
        " s.value = 'ba'; s.dispatchEvent(new Event('change', {bubbles: true})); return true; })()"
    )
    v3 = ui.view(sid, "the view over (b/a, eps)", "c.dataset.axes === 'ba,eps'")
    assert v3["labels"].startswith("x: b/a \u00b7 y: \u03b5"), v3
    assert "axes=ba,eps" in v3["href"] and "slice=kappa_ratio:" in v3["href"], v3
    # the server's x is its first free axis (eps): the page transposes, cell for cell
    d3 = httpx.get(f"{srv}/v1/sweeps/{sid}/diagram", params={"slice": "kappa_ratio:1.1"}).json()
    assert d3["x_name"] == "eps" and d3["y_name"] == "ba", d3
    checked = 0
    for i_eps, row in enumerate(d3["critical_size"]):
        for j_ba, cs in enumerate(row):
            if cs is None:
                continue
            text = ui.b.js(f"window.rsfUi.view.readout({{i: {j_ba}, j: {i_eps}}})")
            x, y = d3["y"][j_ba], d3["x"][i_eps]
            assert text.startswith(f"b/a = {x:g}, \u03b5 = {y:.4g}:"), (text, x, y)
            assert text.endswith(f"critical {cs:.6g}"), (text, cs)
            checked += 1
    assert checked >= 2, d3

    # -- clicking another sweep: its title at once, never the previous image
    now = ui.b.js(
        f"(() => {{ document.querySelector('#sweeps-table tr.sweep[data-id=\"{other}\"]').click();"
        " const c = document.querySelector('#diagram-canvas');"
        " return {hidden: c.hidden, sweep: c.dataset.sweep,"
        " title: document.querySelector('#diagram-title').textContent}; })()"
    )
    assert now["hidden"] and now["sweep"] != sid and other[:8] in now["title"], now
    v4 = ui.view(other, "the other sweep's diagram")
    assert other[:8] in v4["title"] and f"sweep={other}" in v4["href"], v4
    assert ui.b.exceptions() == []


def test_no_request_repeats_after_a_4xx(ui: UI) -> None:
    """A refused slice (422) and an unknown sweep (404) are shown once and never asked
    again; the page keeps its 1 s list refresh going meanwhile."""
    sid = ui.submit(GRID_3D)
    ui.done(sid)
    ui.open(f"sweep={sid}&slice=bogus:1")
    ui.b.wait(
        "document.querySelector('#diagram-empty').textContent.includes('is not <axis>:<value>')",
        30,
        "the 422 of the slice",
    )
    lists0 = len(ui.requests("/v1/sweeps?limit"))
    # watch the page for five more list refreshes (1 s apart): the diagram is not asked again
    polls = ui.b.js("window.rsfUi.polls")
    ui.b.wait(f"window.rsfUi.polls >= {polls + 5}", 30, "five more refreshes of the sweep list")
    assert len(ui.requests("/v1/sweeps?limit")) > lists0
    bad = ui.requests(f"/v1/sweeps/{sid}/diagram")
    assert len(bad) == 1 and "slice=bogus%3A1" in bad[0], bad
    text = ui.b.js("document.querySelector('#diagram-card').innerText")
    assert text.count("is not <axis>:<value>") == 1, text
    assert "slice=bogus:1" in ui.b.js("location.href")
    shoot(ui.b, ui.tmp, "error")

    missing = "0" * 28 + "abcd"
    ui.open(f"sweep={missing}")
    ui.b.wait(
        "document.querySelector('#diagram-empty').textContent.includes('no sweep with id')",
        30,
        "the 404 of an unknown sweep",
    )
    ui.b.wait("window.rsfUi.polls >= 6", 30, "six refreshes of the sweep list")
    # a 404 status is not asked again (the list's 1 s refresh goes on)
    assert len(ui.requests(f"/v1/sweeps/{missing}")) == 1, ui.requests(missing)
    assert ui.b.exceptions() == []


def test_si_sweep_shows_si_labels(ui: UI) -> None:
    """An SI sweep submitted from the form carries the API's SI names; its view says SI
    units, and the page's SI scale agrees with the server's SI values (rsfcore.units)."""
    ui.open("")
    ui.b.wait("window.rsfUi.polls >= 1", 30, "the sweep list")
    form = {"sp_" + k: v for k, v in MACHINE.items()}
    ui.b.js(
        "(() => { const f = document.querySelector('#sweep-form');"
        " f.querySelector('[name=sweep_units][value=si]').click();"
        " while (f.querySelectorAll('[data-remove-axis]').length > 1)"
        "   f.querySelector('[data-remove-axis]').click();"
        " const set = (n, v) => { f.elements[n].value = v;"
        "   f.elements[n].dispatchEvent(new Event('change', {bubbles: true})); };"
        f" const m = {json.dumps(form)}; for (const k in m) set(k, String(m[k]));"
        " set('ax0_name', 'eps'); set('ax0_start', '0'); set('ax0_stop', '0.6'); set('ax0_n', '4');"
        " document.querySelector('#sweep-submit').click(); return true; })()"
    )
    sid = ui.b.wait(
        "(() => { const t = document.querySelector('#sweep-status').textContent;"
        " return /submitted|already/.test(t) && window.rsfUi.selected; })()",
        30,
        "the SI sweep to be submitted",
    )
    st = ui.done(sid)
    assert st["physical"] == MACHINE, st  # the form sent the API's names and values
    assert [d["name"] for d in st["dims"]] == ["eps"] and st["output"] == "critical"
    v = ui.view(sid, "the SI sweep's curve", "c.dataset.status === 'done'")
    assert "y: critical V_new [m/s]" in v["labels"], v
    assert "machine (SI)" in v["caption"] and "\u03c3 = 1e+8 Pa" in v["caption"], v
    assert "k = 2e+11 Pa/m" in v["caption"] and "V_load = 1e-5 m/s" in v["caption"], v
    # the page's SI scale: the server's SI value of every computed point (rsfcore.units)
    pts = httpx.get(f"{ui.srv.url}/v1/sweeps/{sid}/points", timeout=30).json()["points"]
    finite = [p for p in pts if p["kind"] == "finite"]
    assert finite, pts
    for p in finite:
        mine = ui.b.js(
            "window.rsfUi.colourLabels({perturbation: 'velocity-jump', physical: "
            f"{json.dumps(MACHINE)}}}).si.of({p['critical_size']!r})"
        )
        # exp() of the browser and of numpy differ by at most a few ulp
        assert mine == pytest.approx(p["critical_slip_rate_m_s"], rel=1e-13), (mine, p)
    shoot(ui.b, ui.tmp, "si")

    # -- an SI outcome map: eps x factor, axes and caption in the form's SI terms
    sid2 = ui.submit(
        {
            "axes": [
                {"name": "eps", "start": 0.0, "stop": 0.8, "n": 3},
                {"name": "factor", "start": 2.0, "stop": 100.0, "n": 3, "log": True},
            ],
            "fixed": {"physical": MACHINE},
        }
    )
    ui.done(sid2)
    ui.open(f"sweep={sid2}")
    v2 = ui.view(sid2, "the SI outcome map")
    assert v2["labels"] == (
        "x: \u03b5 \u00b7 y: V_new/V_before \u00b7 colour: outcome (stable / unstable)"
    ), v2
    assert "machine (SI)" in v2["caption"], v2
    assert ui.b.exceptions() == []


def test_scattered_sweep_scatter_plot(ui: UI) -> None:
    """Scattered points: a scatter plot over two chosen parameters."""
    sid = ui.submit(
        {
            "points": {"ba": [1.5, 2.0, 3.0, 2.5], "eps": [0.1, 0.5, 0.2, 0.3], "vo": [1, 2, 1, 3]},
            "fixed": {"kappa_ratio": 2.0},
        }
    )
    ui.done(sid)
    ui.open(f"sweep={sid}&axes=eps,vo")
    v = ui.view(sid, "the scatter plot")
    assert v["axes"] == "eps,vo" and v["labels"].startswith("x: \u03b5 \u00b7 y: v"), v
    ui.b.js(
        "(() => { const s = document.querySelector('#view-py');"
        " s.value = 'ba'; s.dispatchEvent(new Event('change', {bubbles: true})); return true; })()"
    )
    v2 = ui.view(sid, "the scatter over (eps, b/a)", "c.dataset.axes === 'eps,ba'")
    assert v2["image"] != v["image"] and "axes=eps,ba" in v2["href"], v2
    shoot(ui.b, ui.tmp, "scatter")
    assert ui.b.exceptions() == []


def test_failures_back_off(ui: UI) -> None:
    """With the service gone, the page asks again only with back-off (1 s, 2 s, 4 s, ...),
    once per scheduled try, and says so once.  (Last test of the module: it stops the
    server.)"""
    ui.open("")
    ui.b.wait("window.rsfUi.polls >= 2", 30, "the sweep list")
    ui.srv.stop()
    f = ui.b.wait(
        "(() => { const f = window.rsfUi.failures.get('list');"
        " return f && f.tries >= 4 ? {tries: f.tries, delays: f.delays} : null; })()",
        60,
        "four failed tries of the sweep list",
    )
    # the page's own schedule: each delay twice the one before (no Retry-After here)
    assert f["delays"][:4] == [1000, 2000, 4000, 8000], f
    note = ui.b.js("document.querySelector('#sweeps-note').textContent")
    assert note.startswith("sweep list unavailable") and "retrying in" in note, note
    assert ui.b.js("document.body.innerText.split('sweep list unavailable').length") == 2
    # one request per try: the failed polls were not repeated in between
    tries = ui.b.js("window.rsfUi.failures.get('list').tries")
    after = [u for u in ui.requests("/v1/sweeps?limit")]
    polls = ui.b.js("window.rsfUi.polls")
    assert len(after) == polls + tries, (len(after), polls, tries)
