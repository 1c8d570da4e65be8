/* rsf-stability dashboard, sweeps: the N-D / scattered / SI sweep form, the live sweep list
   (progress, ETA, cancel), and the view of the selected sweep (2-D slices of 2-5 axis grids
   with a slice control, 1-D curves, scatter plots), deep links and downloads.

   Loaded after app.js and plot.js; uses app.js's helpers ($, fmt, esc, duration, num,
   getJSON, postJSON, Problem, showProblem, clearProblem, busy) and its fetch (API key).

   Requests that fail are shown once with their message.  A 4xx is never asked again
   (until the user changes what is asked); a 5xx, 429 or a network failure is retried with
   back-off (1 s, 2 s, 4 s, ... at most 60 s; Retry-After when the server gives one).
*/
"use strict";

const LIST_MS = 1000;            // sweep list refresh while all is well
const VIEW_MS = 2000;            // partial view refresh while the selected sweep runs
const BACKOFF_MAX_MS = 60000;
const ETA_WINDOW_MS = 60000;     // the ETA's rate is measured over at most this window
const VIEW_MAX_POINTS = 50000;   // 1-D and scattered views: every k-th point beyond this
const GRID_MAX_N = 400;          // a shown grid axis: every k-th value beyond this
const MAX_AXES = 5;
const SIZE_NAMES = ["size", "factor", "new_slip_rate_m_s", "new_load_point_velocity_m_s"];
const DIMLESS_AXES = ["kappa_ratio", "eps", "ba", "vo", "size", "kappa"];
const SI_MACHINE = ["a", "b", "Dc_m", "sigma_Pa", "k_Pa_per_m", "V_star_m_s", "V_load_m_s"];

/* ------------------------------------------------------------------ symbols and units */
/** The symbol (with unit) of a parameter, as the forms write it. */
function paramLabel(name, perturbation) {
  const lp = perturbation === "load-point-jump";
  switch (name) {
    case "ba": return "b/a";
    case "kappa": return "\u03ba = k D\u1d04/(a\u03c3)";
    case "kappa_ratio": return "\u03ba/\u03ba_crit";
    case "eps": return "\u03b5";
    case "vo": return "v\u2092 = V\u2092/V*";
    case "size": return lp ? "dv\u2092/v\u2092 = V_new/V_load \u2212 1" : "d = ln(V_new/V)";
    case "factor": return lp ? "V_new/V_load" : "V_new/V_before";
    case "new_slip_rate_m_s": return "V_new [m/s]";
    case "new_load_point_velocity_m_s": return "V_load,new [m/s]";
    default: return name;
  }
}
/** Short symbol (no definition) for captions and slice controls. */
function paramSymbol(name, perturbation) {
  return { ba: "b/a", kappa: "\u03ba", kappa_ratio: "\u03ba/\u03ba_crit", eps: "\u03b5",
           vo: "v\u2092", size: perturbation === "load-point-jump" ? "dv\u2092/v\u2092" : "d",
           factor: "factor", new_slip_rate_m_s: "V_new [m/s]",
           new_load_point_velocity_m_s: "V_load,new [m/s]" }[name] || name;
}
/** What the colour of a critical-size map measures (dimensionless), and in SI. */
function colourLabels(s) {
  const lp = s.perturbation === "load-point-jump";
  const out = { label: lp ? "critical load-point jump dv\u2092/v\u2092 = V_new/V_load \u2212 1"
                          : "critical velocity jump d = ln(V_new/V)", si: null };
  const p = s.physical;
  if (p) {
    const vStar = p.V_star_m_s, vLoad = p.V_load_m_s === null || p.V_load_m_s === undefined ? vStar : p.V_load_m_s;
    // rsfapp.sweepdata.critical_si (through rsfcore.units): V_before e^d with
    // V_before = V_load (V_* when V_load = 0); V_load (1 + dv) for a load-point jump
    out.si = lp ? { label: "critical V_load,new [m/s]", of: v => vLoad * (1 + v) }
                : { label: "critical V_new [m/s]", of: v => (vLoad > 0 ? vLoad : vStar) * Math.exp(v) };
  }
  return out;
}
function machineText(p) {
  if (!p) return "";
  const v = k => fmt(p[k]);
  return `a = ${v("a")}, b = ${v("b")}, D_c = ${v("Dc_m")} m, \u03c3 = ${v("sigma_Pa")} Pa, ` +
    `k = ${v("k_Pa_per_m")} Pa/m, V* = ${v("V_star_m_s")} m/s, V_load = ${p.V_load_m_s === null || p.V_load_m_s === undefined ? "V*" : v("V_load_m_s") + " m/s"}`;
}
/** [min, max] of an array (a loop: spreading 10^5 values overflows the stack). */
function extent(a) {
  let lo = Infinity, hi = -Infinity;
  for (const x of a) { if (x < lo) lo = x; if (x > hi) hi = x; }
  return [lo, hi];
}
function num12(v) { return String(+Number(v).toPrecision(12)); }

/* ------------------------------------------------------------------ back-off */
/** Failures by request key: {status, message, tries, nextAt}.  4xx (but 408/429): final. */
const failures = new Map();
function isFinal(status) { return status >= 400 && status < 500 && status !== 408 && status !== 429; }
function noteFailure(key, err) {
  const prev = failures.get(key);
  const tries = prev ? prev.tries + 1 : 1;
  const status = err && err.status ? err.status : 0;
  let delay = Math.min(BACKOFF_MAX_MS, 1000 * 2 ** (tries - 1));
  const ra = err && err.retryAfter;
  if (ra) delay = Math.max(delay, Math.min(BACKOFF_MAX_MS, ra * 1000));
  const f = { status, message: (err && err.message) || String(err), tries, nextAt: Date.now() + delay,
              final: isFinal(status), delays: [...(prev ? prev.delays : []), delay] };
  failures.set(key, f);
  return f;
}
/** A new API key: what was refused for want of one (401/403) may be asked again. */
function forgetAuthFailures() {
  for (const [k, f] of failures) if (f.status === 401 || f.status === 403) failures.delete(k);
  if (state.view) { state.view.shownKey = null; updateView(true); }
}
function mayAsk(key) {
  const f = failures.get(key);
  return !f || (!f.final && Date.now() >= f.nextAt);
}
async function getJSONRetry(url) {
  const r = await fetch(url);
  if (!r.ok) {
    const e = await problemOf(r);
    e.retryAfter = Number(r.headers.get("retry-after")) || 0;
    throw e;
  }
  return { status: r.status, body: await r.json(), headers: r.headers };
}

/* ------------------------------------------------------------------ the sweep form */
function sweepForm() { return $("#sweep-form"); }
function siSweep() { return sweepForm().elements.sweep_units.value === "si"; }
function scattered() { return sweepForm().elements.sweep_kind.value === "points"; }
function axisChoices() {
  const lp = sweepForm().elements.perturbation.value === "load-point-jump";
  return siSweep() ? ["eps", "size", "factor", lp ? "new_load_point_velocity_m_s" : "new_slip_rate_m_s"]
                   : DIMLESS_AXES;
}
const AXIS_DEFAULTS = {
  kappa_ratio: [1.05, 4, 12, false], eps: [0, 0.9, 10, false], ba: [1.2, 3, 5, false],
  vo: [0.1, 10, 5, true], size: [0.5, 5, 8, false], kappa: [0.5, 5, 8, false],
  factor: [1.5, 1000, 8, true], new_slip_rate_m_s: [2e-6, 1e-3, 8, true],
  new_load_point_velocity_m_s: [2e-6, 1e-3, 8, true],
};
function axisRow(k, name) {
  const [a, b, n, log] = AXIS_DEFAULTS[name] || [0, 1, 5, false];
  const pert = sweepForm().elements.perturbation.value;
  const opts = axisChoices().map(o =>
    `<option value="${o}"${o === name ? " selected" : ""}>${esc(paramLabel(o, pert))}</option>`).join("");
  return `<fieldset class="axis" data-axis="${k}"><legend>axis ${k + 1}</legend>
    <select name="ax${k}_name" aria-label="axis ${k + 1} parameter">${opts}</select>
    <input name="ax${k}_start" type="number" step="any" value="${a}" aria-label="axis ${k + 1} start">
    <span class="to">&rarr;</span>
    <input name="ax${k}_stop" type="number" step="any" value="${b}" aria-label="axis ${k + 1} stop">
    <input name="ax${k}_n" type="number" min="1" value="${n}" aria-label="axis ${k + 1} points" class="n">
    <span class="hint pts">pts</span>
    <label class="inline" title="geometric spacing (start, stop > 0)"><input name="ax${k}_log" type="checkbox"${log ? " checked" : ""}> log</label>
    <button type="button" class="link" data-remove-axis="${k}" title="remove this axis">&times;</button>
  </fieldset>`;
}
function readAxes() {
  const f = sweepForm(), out = [];
  f.querySelectorAll("fieldset.axis").forEach(fs => {
    const k = fs.dataset.axis;
    out.push({ name: f.elements[`ax${k}_name`].value, start: num(f, `ax${k}_start`),
               stop: num(f, `ax${k}_stop`), n: num(f, `ax${k}_n`), log: f.elements[`ax${k}_log`].checked });
  });
  return out;
}
function renderAxes(axes) {
  const box = $("#sweep-axes");
  box.innerHTML = axes.map((a, k) => axisRow(k, a.name)).join("");
  const f = sweepForm();
  axes.forEach((a, k) => {
    if (a.start !== undefined && a.start !== null) f.elements[`ax${k}_start`].value = a.start;
    if (a.stop !== undefined && a.stop !== null) f.elements[`ax${k}_stop`].value = a.stop;
    if (a.n !== undefined && a.n !== null) f.elements[`ax${k}_n`].value = a.n;
    if (a.log !== undefined) f.elements[`ax${k}_log`].checked = !!a.log;
  });
  $("#axis-add").disabled = axes.length >= MAX_AXES;
  box.querySelectorAll("[data-remove-axis]").forEach(b => { b.disabled = axes.length < 2; });
  syncSweepForm();
}
function addAxis() {
  const axes = readAxes();
  if (axes.length >= MAX_AXES) return;
  const used = new Set(axes.map(a => a.name));
  const name = axisChoices().find(o => !used.has(o) && !(SIZE_NAMES.includes(o) && axes.some(a => SIZE_NAMES.includes(a.name))));
  if (!name) return;
  renderAxes([...axes, { name }]);
}
function removeAxis(k) {
  const axes = readAxes();
  axes.splice(k, 1);
  renderAxes(axes);
}
function changeAxisName(k) {
  const axes = readAxes();
  const d = AXIS_DEFAULTS[axes[k].name] || [0, 1, 5, false];
  axes[k] = { name: axes[k].name, start: d[0], stop: d[1], n: axes[k].n, log: d[3] };
  renderAxes(axes);
}
/** The units or perturbation changed: keep the axes that still apply. */
function changeSweepUnits() {
  const ok = new Set(axisChoices());
  let axes = readAxes().filter(a => ok.has(a.name));
  if (!axes.length) axes = siSweep() ? [{ name: "eps" }, { name: "factor" }] : [{ name: "kappa_ratio" }, { name: "eps" }];
  $("#sweep-si").hidden = !siSweep();
  const f = sweepForm();
  const lp = f.elements.perturbation.value === "load-point-jump";
  const unit = f.elements.f_size_unit;
  unit.querySelector('[value="new_slip_rate_m_s"]').hidden = lp;
  unit.querySelector('[value="new_load_point_velocity_m_s"]').hidden = !lp;
  if (unit.selectedOptions[0].hidden) unit.value = "size";
  renderAxes(axes);
}
function syncSweepForm() {
  const f = sweepForm();
  const axes = readAxes(), si = siSweep(), pts = scattered();
  const swept = new Set(axes.map(a => a.name));
  const sizeSwept = axes.some(a => SIZE_NAMES.includes(a.name));
  for (const k of ["ba", "kappa_ratio", "vo"]) {
    const el = f.elements["f_" + k];
    el.disabled = si || swept.has(k) || (k === "kappa_ratio" && swept.has("kappa"));
    el.closest("label").classList.toggle("off", el.disabled);
    el.closest("label").hidden = si;  // the machine in SI sets them
    el.title = si ? "set by the machine in SI" : swept.has(k) ? "swept" : "";
  }
  f.elements.f_eps.disabled = swept.has("eps");
  f.elements.f_size.disabled = sizeSwept;
  f.elements.f_size_unit.disabled = sizeSwept;
  f.elements.f_size_unit.closest("label").hidden = !si;
  f.querySelectorAll("fieldset.axis").forEach(fs => {
    const k = fs.dataset.axis;
    fs.querySelector(`[name=ax${k}_n]`).hidden = pts;
    fs.querySelector(".pts").hidden = pts;
  });
  $("#sweep-npts-field").hidden = !pts;
  const n = pts ? (num(f, "n_points") || 0) : axes.reduce((p, a) => p * (a.n || 0), 1);
  $("#sweep-npoints").textContent = pts
    ? `${n} scattered points over ${axes.length} parameter${axes.length > 1 ? "s" : ""}`
    : `${axes.map(a => a.n || 0).join(" \u00d7 ")} = ${n.toLocaleString("en")} points`;
}
/** A seeded generator (mulberry32), so that the same form gives the same points (sweep id). */
function rng(seed) {
  let t = seed >>> 0;
  return () => {
    t = (t + 0x6D2B79F5) >>> 0;
    let r = Math.imul(t ^ (t >>> 15), 1 | t);
    r = (r + Math.imul(r ^ (r >>> 7), 61 | r)) ^ r;
    return ((r ^ (r >>> 14)) >>> 0) / 4294967296;
  };
}
function sweepBody() {
  const f = sweepForm();
  const axes = readAxes(), si = siSweep();
  const fixed = {};
  const swept = new Set(axes.map(a => a.name));
  if (si) {
    const phys = {};
    for (const k of SI_MACHINE) {
      const v = num(f, "sp_" + k);
      if (v !== null) phys[k] = v;
    }
    fixed.physical = phys;
  } else {
    for (const k of ["ba", "kappa_ratio", "vo"]) {
      if (swept.has(k) || (k === "kappa_ratio" && swept.has("kappa"))) continue;
      const v = num(f, "f_" + k);
      if (v !== null) fixed[k] = v;
    }
  }
  if (!swept.has("eps") && num(f, "f_eps") !== null) fixed.eps = num(f, "f_eps");
  if (!axes.some(a => SIZE_NAMES.includes(a.name)) && num(f, "f_size") !== null) {
    fixed[si ? f.elements.f_size_unit.value : "size"] = num(f, "f_size");
  }
  const body = { fixed, perturbation: f.elements.perturbation.value };
  if (scattered()) {
    const n = num(f, "n_points") || 0, r = rng(num(f, "seed") || 1);
    body.points = {};
    for (const a of axes) {
      const lo = a.start, hi = a.stop;
      body.points[a.name] = Array.from({ length: n }, () => {
        const u = r();
        return a.log ? lo * (hi / lo) ** u : lo + (hi - lo) * u;
      });
    }
  } else {
    body.axes = axes.map(a => ({ name: a.name, start: a.start, stop: a.stop, n: a.n, log: a.log }));
  }
  return body;
}
/** The form input that a problem's field names (axes[2].stop, fixed.physical.a, fixed.eps). */
function sweepInput(field) {
  const f = sweepForm();
  let m = /^axes\[(\d+)\]\.(\w+)/.exec(field);
  if (m) return f.elements[`ax${m[1]}_${m[2] === "values" ? "start" : m[2]}`];
  m = /^points\.(\w+)/.exec(field);
  if (m) {
    const k = readAxes().findIndex(a => a.name === m[1]);
    return k >= 0 ? f.elements[`ax${k}_start`] : null;
  }
  m = /^(?:fixed\.)?physical\.(\w+)/.exec(field);
  if (m) return f.elements["sp_" + m[1]];
  m = /^fixed\.(\w+)/.exec(field);
  if (m) return f.elements[SIZE_NAMES.includes(m[1]) ? "f_size" : "f_" + m[1]];
  return null;
}
async function submitSweep(ev) {
  ev.preventDefault();
  const form = sweepForm(), status = $("#sweep-status"), errBox = $("#sweep-error");
  const btn = $("#sweep-submit");
  clearProblem(errBox, form);
  btn.disabled = true;
  busy(status, "submitting\u2026");
  try {
    const res = await postJSON("/v1/sweeps", sweepBody());
    const id = res.body.id;
    busy(status, "");
    status.textContent = res.headers.get("x-cache") === "hit"
      ? `already known: ${id.slice(0, 8)}` : `submitted ${id.slice(0, 8)}`;
    select(id);
    await refreshSweeps();
  } catch (e) {
    busy(status, "");
    showProblem(errBox, null, e);
    const el = sweepInput(String((e.body || {}).field || ""));
    if (el) el.classList.add("invalid");
  } finally {
    btn.disabled = false;
  }
}

/* ------------------------------------------------------------------ the sweep list */
function describe(s) {
  // status polls carry dims (names and lengths), fixed, output, perturbation, physical
  const dims = s.dims || [];
  const fx = s.fixed || {};
  const pert = s.perturbation || "velocity-jump";
  const scatteredSweep = s.mode === "points" || (dims.length === 1 && dims[0].name === "point");
  const sizeGiven = SIZE_NAMES.some(k => fx[k] !== null && fx[k] !== undefined);
  const mode = s.output === "outcome" ? (sizeGiven ? `outcome @ ${sizeText(fx, pert)}` : "outcome")
    : "critical size";
  const grid = scatteredSweep
    ? `scattered: ${(dims[0].parameters || []).map(n => paramSymbol(n, pert)).join(", ")}`
    : dims.map(d => paramSymbol(d.name, pert)).join(" \u00d7 ");
  return { grid, scattered: scatteredSweep, si: !!s.physical,
           dims: scatteredSweep ? `${dims[0].n} pts` : dims.map(d => d.n).join("\u00d7"),
           mode: `${mode}, ${pert.replace("-", " ")}${s.physical ? ", SI" : ""}` };
}
function sizeText(fx, pert) {
  for (const k of SIZE_NAMES) {
    if (fx[k] !== null && fx[k] !== undefined) {
      return k === "size" ? `${paramSymbol("size", pert)} = ${fmt(fx[k])}`
        : `${paramSymbol(k, pert).replace(" [m/s]", "")} = ${fmt(fx[k])}${k.endsWith("_m_s") ? " m/s" : ""}`;
    }
  }
  return "";
}
/** Page-side ETA: the rate over the progress this page saw ("estimating" until two samples). */
const samples = new Map();  // id -> [{t, n}] (a sample each time n_done changed)
function noteProgress(s) {
  const now = Date.now();
  let list = samples.get(s.id);
  if (!list) { list = []; samples.set(s.id, list); }
  if (!list.length || list[list.length - 1].n !== s.n_done) list.push({ t: now, n: s.n_done });
  while (list.length > 2 && now - list[1].t > ETA_WINDOW_MS) list.shift();
}
function etaText(s) {
  if (s.status !== "queued" && s.status !== "running") return "";
  const list = samples.get(s.id) || [];
  if (list.length < 2) return "estimating\u2026";
  const a = list[0], b = list[list.length - 1];
  const rate = (b.n - a.n) / Math.max(1e-3, (Date.now() - a.t) / 1000);
  if (!(rate > 0)) return "estimating\u2026";
  return duration((s.n_total - s.n_done) / rate);
}
function row(s) {
  const d = describe(s);
  const pct = s.n_total ? Math.floor(100 * s.n_done / s.n_total) : 0;
  const active = s.status === "queued" || s.status === "running";
  return `<tr class="sweep${s.id === state.selected ? " selected" : ""}" data-id="${esc(s.id)}" data-status="${esc(s.status)}">
    <td class="sweep-name"><div><span class="mono" title="${esc(s.id)}">${esc(s.id.slice(0, 8))}</span>
      ${esc(d.grid)} <span class="hint">${esc(d.dims)}</span></div><div class="hint">${esc(d.mode)}</div></td>
    <td class="prog"><div class="prog-head"><span class="badge ${esc(s.status)}">${esc(s.status)}</span>
      ${s.n_failed ? `<span class="failed">${s.n_failed} failed</span>` : ""}</div>
      <div class="progress ${esc(s.status)}" data-done="${s.n_done}" data-total="${s.n_total}">
      <span class="bar" style="width:${pct}%"></span>
      <span class="label">${s.n_done.toLocaleString("en")} / ${s.n_total.toLocaleString("en")} (${pct}%)</span></div></td>
    <td class="eta"><div class="eta-text">${esc(etaText(s))}</div>
      ${active ? `<button type="button" class="link" data-cancel="${esc(s.id)}">cancel</button>` : ""}</td>
  </tr>`;
}
const listPoll = { timer: null, error: null };
function scheduleList(ms) {
  clearTimeout(listPoll.timer);
  listPoll.timer = setTimeout(refreshSweeps, ms);
}
async function refreshSweeps() {
  const key = "list";
  clearTimeout(listPoll.timer);
  let list;
  try {
    list = (await getJSONRetry("/v1/sweeps?limit=25")).body.sweeps;
    failures.delete(key);
    $("#sweeps-note").textContent = "";
  } catch (e) {
    const f = noteFailure(key, e);
    $("#sweeps-note").textContent = `sweep list unavailable: ${f.message}` +
      (f.final ? "" : ` (retrying in ${Math.round((f.nextAt - Date.now()) / 1000)} s)`);
    if (!f.final) scheduleList(f.nextAt - Date.now());  // a 4xx (e.g. 401) waits for the user
    if (state.polls === 0 && f.final) $("#sweeps-table tbody").innerHTML =
      `<tr class="empty"><td colspan="3">${esc(f.message)}</td></tr>`;
    return;
  }
  state.polls += 1;
  state.sweeps = new Map(list.map(s => [s.id, s]));
  list.forEach(noteProgress);
  const html = list.length ? list.map(row).join("") : `<tr class="empty"><td colspan="3">no sweeps yet</td></tr>`;
  if (html !== state.listHtml) {
    $("#sweeps-table tbody").innerHTML = html;
    state.listHtml = html;
  }
  if (state.selected === null && list.length) select(list[0].id, { history: "none" });
  else updateView();
  scheduleList(LIST_MS);
}
async function cancelSweep(id) {
  try {
    await getJSON(`/v1/sweeps/${id}`, { method: "DELETE" });
  } catch (e) {
    $("#sweeps-note").textContent = `cancel failed: ${e.message || e}`;
  }
  refreshSweeps();
}

/* ------------------------------------------------------------------ the selected sweep */
/* view: {id, token, spec, status, axes: [x, y] (names), slice: {name: index},
          params: [x, y] (scattered), data: last answer, key: what it shows} */
const specs = new Map();   // id -> spec (immutable)
function newView(id, link, auto) {
  return { id, token: Symbol(id), spec: null, status: null, axes: null, slice: {}, params: null,
           link: link || {}, shownKey: null, busy: false, askedAt: 0, auto: !!auto, statusAt: 0 };
}
function select(id, opts = {}) {
  if (state.selected !== id || !state.view) {
    state.selected = id;
    state.view = newView(id, opts.link, opts.history === "none");
    state.listHtml = "";
    document.querySelectorAll("#sweeps-table tr.sweep").forEach(tr =>
      tr.classList.toggle("selected", tr.dataset.id === id));
    placeholder(`loading sweep ${id.slice(0, 8)}\u2026`);
    $("#diagram-title").textContent = id.slice(0, 8);
    $("#view-controls").hidden = true;
    $("#diagram-links").innerHTML = "";
    $("#diagram-caption").textContent = "";
    showViewError(null);
  }
  if (opts.history !== "none") state.view.auto = false;  // the user chose it
  writeAddress(opts.history || "push");
  updateView(true);
}
function placeholder(text) {
  $("#diagram-empty").textContent = text;
  $("#diagram-empty").hidden = false;
  const c = $("#diagram-canvas");
  c.hidden = true;
  c.dataset.sweep = ""; c.dataset.key = "";
}
function showViewError(f) {
  const box = $("#diagram-error");
  if (!f) { box.hidden = true; box.textContent = ""; return; }
  box.hidden = false;
  box.textContent = f.message + (f.final ? "" : ` \u2014 retrying in ${Math.max(1, Math.round((f.nextAt - Date.now()) / 1000))} s`);
}
/** The deep link of the current view: ?sweep=ID&slice=name:value,...&axes=x,y */
function viewQuery(v) {
  const q = new URLSearchParams();
  q.set("sweep", v.id);
  if (v.badSlice) {  // what the link said, until the user picks a slice
    q.set("slice", v.badSlice);
    if (v.axes && v.axes.length === 2) q.set("axes", v.axes.join(","));
  } else if (v.spec && v.spec.mode === "grid" && v.axes) {
    const sl = Object.entries(v.slice).map(([n, k]) => `${n}:${num12(axisValues(v.spec, n)[k])}`);
    if (sl.length) q.set("slice", sl.join(","));
    if (v.spec.axes.length >= 2) q.set("axes", v.axes.join(","));
  } else if (v.params) {
    q.set("axes", v.params.join(","));
  } else {
    if (v.link.slice) q.set("slice", v.link.slice);
    if (v.link.axes) q.set("axes", v.link.axes);
  }
  return q.toString().replace(/%3A/gi, ":").replace(/%2C/gi, ",");
}
function writeAddress(mode) {
  const v = state.view;
  if (!v || v.auto || mode === "none") return;  // the page's own first choice is not a link
  const url = `${location.pathname === "/" ? "/ui" : location.pathname}?${viewQuery(v)}`;
  if (url === location.pathname + location.search) return;
  if (mode === "push") history.pushState({ sweep: v.id }, "", url);
  else history.replaceState({ sweep: v.id }, "", url);
}
function readAddress() {
  const q = new URLSearchParams(location.search);
  const id = q.get("sweep");
  if (!id) return false;
  state.selected = null;
  select(id, { history: "replace", link: { slice: q.get("slice") || "", axes: q.get("axes") || "" } });
  return true;
}

/** Values of a grid axis (as rsfapp.grid.Axis.at: end points exact, clipped). */
function axisValues(spec, name) {
  const a = spec.axes.find(x => x.name === name);
  if (!a) return [];
  if (a._values) return a._values;
  let v;
  if (a.values) v = a.values.slice();
  else if (a.n === 1) v = [a.start];
  else {
    const lo = Math.min(a.start, a.stop), hi = Math.max(a.start, a.stop);
    v = Array.from({ length: a.n }, (_, k) => {
      if (k === 0) return a.start;
      if (k === a.n - 1) return a.stop;
      const t = k / (a.n - 1);
      const x = a.log ? Math.exp(Math.log(a.start) + (Math.log(a.stop) - Math.log(a.start)) * t)
                      : a.start + (a.stop - a.start) * t;
      return Math.min(hi, Math.max(lo, x));
    });
  }
  Object.defineProperty(a, "_values", { value: v, enumerable: false });
  return v;
}
function nearest(vals, x) {
  let best = 0;
  vals.forEach((v, k) => { if (Math.abs(v - x) < Math.abs(vals[best] - x)) best = k; });
  return best;
}
/** Apply the deep link's slice and axes to a fresh view (unknown names are kept for the
    server to refuse: the page shows that 422 once). */
function initView(v) {
  const spec = v.spec;
  if (spec.mode === "grid") {
    const names = spec.axes.map(a => a.name);
    let axes = (v.link.axes || "").split(",").filter(Boolean);
    const linkSlice = {};
    v.badSlice = null;
    for (const part of (v.link.slice || "").split(",").filter(Boolean)) {
      const [n, val] = part.split(":");
      if (!names.includes(n) || val === undefined || !Number.isFinite(Number(val))) { v.badSlice = v.link.slice; continue; }
      linkSlice[n] = nearest(axisValues(spec, n), Number(val));
    }
    if (names.length >= 2) {
      if (axes.length !== 2 || !axes.every(a => names.includes(a)) || axes[0] === axes[1]) {
        const free = names.filter(n => !(n in linkSlice));
        axes = free.length >= 2 ? free.slice(0, 2) : names.slice(0, 2);
      }
      v.axes = axes;
      v.slice = {};
      for (const n of names) {
        if (axes.includes(n)) continue;
        v.slice[n] = n in linkSlice ? linkSlice[n] : 0;
      }
    } else {
      v.axes = [names[0]];
    }
  } else {
    const names = (spec.points && spec.points.names) || [];
    let p = (v.link.axes || "").split(",").filter(n => names.includes(n));
    if (p.length !== 2) p = names.length >= 2 ? names.slice(0, 2) : [names[0], names[0]];
    v.params = p;
  }
  buildControls(v);
}
function buildControls(v) {
  const spec = v.spec, pert = spec.perturbation;
  const box = $("#view-controls");
  const opt = (names, sel) => names.map(n =>
    `<option value="${esc(n)}"${n === sel ? " selected" : ""}>${esc(paramSymbol(n, pert))}</option>`).join("");
  let html = "";
  if (spec.mode === "grid" && spec.axes.length >= 2) {
    const names = spec.axes.map(a => a.name);
    html += `<div class="view-axes"><label>x <select id="view-x">${opt(names, v.axes[0])}</select></label>
      <label>y <select id="view-y">${opt(names, v.axes[1])}</select></label></div>`;
    const others = names.filter(n => !v.axes.includes(n));
    html += others.map(n => {
      const vals = axisValues(spec, n), k = v.slice[n] || 0;
      const control = vals.length <= 12
        ? `<select data-slice="${esc(n)}" aria-label="${esc(n)} slice">${vals.map((x, i) =>
            `<option value="${i}"${i === k ? " selected" : ""}>${esc(fmt(x))}</option>`).join("")}</select>`
        : `<input type="range" data-slice="${esc(n)}" min="0" max="${vals.length - 1}" step="1" value="${k}" aria-label="${esc(n)} slice">`;
      return `<label class="slice"><span class="lab">${esc(paramSymbol(n, pert))} =
        <b class="mono" data-slice-value="${esc(n)}">${esc(fmt(vals[k]))}</b>
        <span class="hint">(${k + 1} of ${vals.length})</span></span>${control}</label>`;
    }).join("");
  } else if (spec.mode === "points") {
    const names = (spec.points && spec.points.names) || [];
    html += `<div class="view-axes"><label>x <select id="view-px">${opt(names, v.params[0])}</select></label>
      <label>y <select id="view-py">${opt(names, v.params[1])}</select></label></div>`;
  }
  box.innerHTML = html;
  box.hidden = !html;
}
function onControl(ev) {
  const v = state.view;
  if (!v || !v.spec) return;
  v.auto = false;
  v.badSlice = null;
  $("#diagram-canvas").classList.add("stale");  // until the answer for the new view arrives
  const t = ev.target;
  if (t.dataset.slice) {
    const n = t.dataset.slice, k = Number(t.value), vals = axisValues(v.spec, n);
    v.slice[n] = k;
    const lab = $(`[data-slice-value="${n}"]`);
    if (lab) { lab.textContent = fmt(vals[k]); lab.nextElementSibling.textContent = `(${k + 1} of ${vals.length})`; }
    if (ev.type === "input" && t.type === "range") { writeAddress("replace"); return changeView(false); }
  } else if (t.id === "view-x" || t.id === "view-y") {
    const names = v.spec.axes.map(a => a.name);
    let [x, y] = v.axes;
    if (t.id === "view-x") { if (t.value === y) y = x; x = t.value; } else { if (t.value === x) x = y; y = t.value; }
    const slice = {};
    for (const n of names) if (n !== x && n !== y) slice[n] = n in v.slice ? v.slice[n] : 0;
    v.axes = [x, y]; v.slice = slice;
    buildControls(v);
  } else if (t.id === "view-px" || t.id === "view-py") {
    v.params = [$("#view-px").value, $("#view-py").value];
  } else return;
  writeAddress("replace");
  changeView(true);
}
let sliceTimer = null;
function changeView(now) {
  clearTimeout(sliceTimer);
  sliceTimer = setTimeout(() => updateView(true), now ? 0 : 120);  // a dragged slider asks once it rests
}

/** What the view asks the server for: {url, kind} ("diagram" JSON, or the whole "data"). */
function viewRequest(v) {
  const spec = v.spec, id = v.id;
  if (spec.mode === "grid" && spec.axes.length >= 2) {
    // the slice and, on a long shown axis, every k-th value (the server reads only those)
    const names = spec.axes.map(a => a.name);
    const parts = Object.entries(v.slice).map(([n, k]) => `${n}:${num12(axisValues(spec, n)[k])}`);
    const q = v.badSlice !== null && v.badSlice !== undefined ? v.badSlice : parts.join(",");
    const params = new URLSearchParams();
    if (q || names.length > 2) params.set("slice", q);
    const strided = (v.axes || []).map(n => spec.axes.find(a => a.name === n))
      .filter(a => a && a.n > GRID_MAX_N).map(a => `${a.name}:0:${a.n}:${Math.ceil(a.n / GRID_MAX_N)}`);
    if (strided.length) params.set("isel", strided.join(","));
    const qs = params.toString();
    return { kind: "diagram", url: `/v1/sweeps/${id}/diagram${qs ? "?" + qs : ""}` };
  }
  // a 1-D grid or scattered points: the variables drawn, every k-th point of a large sweep
  const dim = spec.mode === "grid" ? spec.axes[0].name : "point";
  const vars = ["critical_size", "kind", "outcome", "computed", "failed"];
  const si = spec.physical ? siVariable(spec.perturbation) : null;
  if (si && spec.mode === "grid") vars.push(si);
  const params = new URLSearchParams({ format: "json", variables: vars.join(",") });
  if (spec.n_total > VIEW_MAX_POINTS) params.set("isel", `${dim}:0:${spec.n_total}:${Math.ceil(spec.n_total / VIEW_MAX_POINTS)}`);
  return { kind: "data", url: `/v1/sweeps/${id}/data?${params}` };
}
/** The SI variable of an SI sweep's data (rsfapp.sweepdata.SI_VARIABLES). */
function siVariable(perturbation) {
  return perturbation === "load-point-jump" ? "critical_load_point_velocity_m_s" : "critical_slip_rate_m_s";
}

async function updateView(force = false) {
  const v = state.view;
  if (!v) return;
  if (v.busy) { v.again = v.again || force; return; }  // asked again once this answer is in
  v.busy = true;
  try {
    await stepView(v, force);
  } finally {
    v.busy = false;
  }
  if (v.again && state.view === v) { v.again = false; updateView(true); }
}
async function stepView(v, force) {
  const id = v.id;
  // 1. its status (from the list when it is there) and spec (asked once)
  let s = state.sweeps.get(id);
  const stKey = `status:${id}`;
  const known = v.status && (["done", "cancelled"].includes(v.status.status) || Date.now() - v.statusAt < VIEW_MS);
  if (!s && known) s = v.status;  // not in the list's first page: its own status, asked sparingly
  if (!s) {
    if (!mayAsk(stKey)) return;
    try {
      s = (await getJSONRetry(`/v1/sweeps/${id}`)).body;
      failures.delete(stKey);
      v.statusAt = Date.now();
    } catch (e) {
      if (state.view !== v) return;
      failed(v, stKey, e, `sweep ${id}`);
      return;
    }
  }
  if (state.view !== v) return;
  v.status = s;
  const d = describe(s);
  $("#diagram-title").textContent = `${d.grid} \u00b7 ${id.slice(0, 8)}`;
  $("#diagram-title").title = id;
  if (!v.spec) {
    const spKey = `spec:${id}`;
    if (specs.has(id)) v.spec = specs.get(id);
    else {
      if (!mayAsk(spKey)) return;
      try {
        v.spec = (await getJSONRetry(`/v1/sweeps/${id}/spec`)).body;
        specs.set(id, v.spec);
        failures.delete(spKey);
      } catch (e) {
        if (state.view !== v) return;
        failed(v, spKey, e, `no view of sweep ${id.slice(0, 8)}`);
        return;
      }
    }
    if (state.view !== v) return;
    v.spec.physical = v.spec.physical || s.physical || null;
    initView(v);
    writeAddress("replace");
  }
  links(v);
  // 2. the data of the view, asked again only when the sweep made progress
  const req = viewRequest(v);
  const final = s.status === "done" || s.status === "cancelled";
  const shape = (v.axes || v.params || []).join(",");  // a scatter's axes change no request
  const key = `${req.url}|${s.status}|${s.n_done}|${shape}`;
  if (key === v.shownKey) return;
  if (v.answer && v.answerKey === `${req.url}|${s.status}|${s.n_done}`) {
    v.shownKey = key;  // the same answer drawn over other axes
    render(v, req, v.answer);
    return;
  }
  if (!mayAsk(req.url)) return;
  if (!force && !final && Date.now() - v.askedAt < VIEW_MS) return;
  v.askedAt = Date.now();
  let ans;
  try {
    ans = (await getJSONRetry(req.url)).body;
    failures.delete(req.url);
  } catch (e) {
    if (state.view !== v) return;
    failed(v, req.url, e, `no diagram of sweep ${id.slice(0, 8)} for this view`);
    return;
  }
  if (state.view !== v || viewRequest(v).url !== req.url) return;  // the user moved on
  showViewError(null);
  v.answerKey = `${req.url}|${ans.status}|${ans.n_done}`;
  v.shownKey = `${v.answerKey}|${(v.axes || v.params || []).join(",")}`;
  v.answer = ans;
  render(v, req, ans);
}

/** A failed request of the view, shown once: a 4xx in place of the figure (not asked
    again), else above it with the time of the next try. */
function failed(v, key, err, what) {
  const f = noteFailure(key, err);
  if (f.final) {
    showViewError(null);
    placeholder(`${what}: ${f.message}`);
  } else {
    showViewError(f);
  }
}

/* ------------------------------------------------------------------ drawing */
function render(v, req, ans) {
  const spec = v.spec, s = v.status, pert = spec.perturbation;
  const outcome = spec.output === "outcome";
  const colour = outcome ? { outcome: true, label: "outcome" } : colourLabels({ perturbation: pert, physical: spec.physical });
  let fig;
  const logOf = n => { const a = spec.axes && spec.axes.find(x => x.name === n); return !!(a && a.log); };
  const stateOf = (kind, cs, oc, present) => {
    if (!present) return "missing";
    if (outcome) return oc === 1 ? "unstable" : oc === 0 ? "stable" : "missing";
    return kind === 0 ? "zero" : kind === 2 ? "infinite" : Number.isFinite(cs) ? "finite" : "missing";
  };
  if (req.kind === "diagram") {
    const [xn, yn] = v.axes, tr = ans.x_name !== xn;  // the server's x is the first free axis
    const X = tr ? ans.y : ans.x, Y = tr ? ans.x : ans.y;
    const at = (a, i, j) => (tr ? a[j][i] : a[i][j]);
    fig = { type: "grid", x: { label: paramLabel(xn, pert), values: X, log: logOf(xn) },
            y: { label: paramLabel(yn, pert), values: Y, log: logOf(yn) },
            cell: (i, j) => {
              const cs = at(ans.critical_size, i, j);
              return { state: stateOf(at(ans.kind, i, j), cs === null ? NaN : cs,
                                      ans.outcome ? at(ans.outcome, i, j) : null, at(ans.present, i, j)),
                       v: cs === null ? NaN : cs };
            } };
    v.readout = (h) => {
      const cs = at(ans.critical_size, h.i, h.j), k = at(ans.kind, h.i, h.j);
      return `${paramSymbol(xn, pert)} = ${fmt(X[h.i])}, ${paramSymbol(yn, pert)} = ${fmt(Y[h.j])}: ` +
        valueText(cs, k, ans.outcome ? at(ans.outcome, h.i, h.j) : null, at(ans.present, h.i, h.j), colour, outcome);
    };
  } else {
    const data = ans.data, n = data.kind.length;
    const pts = [];
    const coords = ans.coords;
    const [xn, yn] = spec.mode === "grid" ? [spec.axes[0].name, null] : v.params;
    for (let k = 0; k < n; k++) {
      const cs = data.critical_size[k];
      const present = !!data.computed[k] && !data.failed[k];
      const st = stateOf(data.kind[k], cs === null ? NaN : cs, data.outcome[k], present);
      pts.push({ x: coords[xn][k], y: yn ? coords[yn][k] : (st === "finite" ? cs : NaN), state: st, v: cs === null ? NaN : cs });
    }
    if (spec.mode === "grid") {  // a 1-D sweep: the critical size (or outcome) along its axis
      const fin = pts.filter(p => p.state === "finite").map(p => p.y);
      const ylog = fin.length > 0 && fin.every(y => y > 0) && extent(fin)[1] / extent(fin)[0] > 20;
      const lo = fin.length ? extent(fin)[0] : 1;
      pts.forEach(p => { if (p.state !== "finite") p.y = lo; });  // the plot puts them on an edge
      fig = { type: "line", x: { label: paramLabel(xn, pert), log: logOf(xn) },
              y: { label: outcome ? "outcome" : colour.label, log: ylog }, points: pts };
    } else {
      const auto = n2 => {  // log for positive values over two decades or more (eps: never)
        const vals = coords[n2].filter(Number.isFinite);
        return n2 !== "eps" && vals.length > 1 && vals.every(x => x > 0) && extent(vals)[1] / extent(vals)[0] >= 100;
      };
      fig = { type: "scatter", x: { label: paramLabel(xn, pert), log: auto(xn) },
              y: { label: paramLabel(yn, pert), log: auto(yn) }, points: pts };
    }
    v.readout = (h) => {
      const k = h.k, p = pts[k];
      const where = spec.mode === "grid" ? `${paramSymbol(xn, pert)} = ${fmt(p.x)}`
        : `point ${k}: ${paramSymbol(xn, pert)} = ${fmt(p.x)}, ${paramSymbol(yn, pert)} = ${fmt(coords[yn][k])}`;
      return `${where}: ` + valueText(data.critical_size[k], data.kind[k], data.outcome[k] >= 0 ? data.outcome[k] : null,
        !!data.computed[k] && !data.failed[k], colour, outcome);
    };
  }
  if (!outcome) {
    const vals = [];
    if (fig.type === "grid") {
      for (let i = 0; i < fig.x.values.length; i++) for (let j = 0; j < fig.y.values.length; j++) {
        const c = fig.cell(i, j); if (c.state === "finite") vals.push(c.v);
      }
    } else fig.points.forEach(p => { if (p.state === "finite") vals.push(p.v); });
    const [lo, hi] = vals.length ? extent(vals) : [0, 1];
    colour.lo = lo; colour.hi = hi; colour.log = lo > 0 && hi / lo > 3;
  }
  if (fig.type === "line" && colour.si) {  // SI sweeps: the curve in m/s, the server's values
    fig.y.label = colour.si.label;
    const siv = ans.data[siVariable(pert)];
    fig.points.forEach((p, k) => {
      const x = siv ? siv[k] : null;
      p.y = x !== null && x !== undefined ? x : colour.si.of(p.y);
    });
    fig.y.log = fig.points.some(p => p.state === "finite");
  }
  fig.colour = fig.type === "line" && !outcome ? { plain: true, label: colour.label, si: null } : colour;
  const canvas = $("#diagram-canvas");
  canvas.hidden = false;
  canvas.classList.remove("stale");
  $("#diagram-empty").hidden = true;
  v.hit = RsfPlot.draw(canvas, fig);
  canvas.dataset.sweep = v.id;
  canvas.dataset.status = ans.status;
  canvas.dataset.progress = `${ans.n_done}/${ans.n_total}`;
  canvas.dataset.slice = v.spec.mode === "grid" ? Object.entries(ans.slice || {}).map(([n, x]) => `${n}:${num12(x)}`).join(",") : "";
  canvas.dataset.axes = (v.axes || v.params || []).join(",");
  canvas.dataset.key = v.shownKey;
  canvas.setAttribute("aria-label", `${fig.type === "grid" ? "stability diagram" : fig.type === "line" ? "curve" : "scatter plot"} ` +
    `of sweep ${v.id}: ${$("#diagram-axes").textContent}`);
  $("#diagram-axes").textContent = `x: ${fig.x.label} \u00b7 y: ${fig.y.label}` + (fig.colour.plain ? "" : " \u00b7 colour: " +
    (outcome ? "outcome (stable / unstable)" : colour.label + (colour.si ? `; left scale ${colour.si.label}` : "")));
  caption(v, ans);
}
function valueText(cs, kind, oc, present, colour, outcome) {
  if (!present) return "not computed";
  if (outcome) return oc === 1 ? "unstable" : oc === 0 ? "stable" : "not computed";
  if (kind === 0) return "critical size zero";
  if (kind === 2) return "critical size infinite";
  if (cs === null || cs === undefined) return "not computed";
  return `critical ${fmt(cs, 6)}` + (colour.si ? ` (${fmt(colour.si.of(cs), 6)} m/s)` : "");
}
function caption(v, ans) {
  const s = v.status, spec = v.spec, pert = spec.perturbation;
  const st = ans.status || s.status;
  const fixed = Object.entries(ans.fixed || s.fixed || {})
    .filter(([k]) => !(spec.physical && ["ba", "kappa", "vo"].includes(k)) && !(ans.slice && k in ans.slice))
    .map(([k, x]) => `${paramSymbol(k, pert)} = ${fmt(x)}`);
  const slice = Object.entries(ans.slice || {}).map(([k, x]) => `${paramSymbol(k, pert)} = ${fmt(x)}`);
  // what part of a long axis or a large sweep is drawn (the server sent every k-th value)
  const thin = [];
  if (ans.x_name) {
    for (const [n, vals] of [[ans.x_name, ans.x], [ans.y_name, ans.y]]) {
      const a = spec.axes.find(x => x.name === n);
      if (a && vals.length < a.n) thin.push(`${paramSymbol(n, pert)}: ${vals.length} of ${a.n} values`);
    }
  } else if (ans.shape && ans.shape[0] < spec.n_total) {
    thin.push(`${ans.shape[0].toLocaleString("en")} of ${spec.n_total.toLocaleString("en")} points (one in ` +
      `${Math.ceil(spec.n_total / VIEW_MAX_POINTS)})`);
  }
  $("#diagram-caption").innerHTML =
    `${esc(describe(s).mode)} \u00b7 ${esc(`${ans.n_done}/${ans.n_total}`)} points \u00b7 ` +
    `<span class="badge ${esc(st)}">${esc(st)}</span> ` +
    (st === "done" || st === "cancelled" ? "" : "(blank: not computed yet) ") +
    (slice.length ? `<br>slice: <b>${esc(slice.join(", "))}</b>` : "") +
    (thin.length ? `<br>drawn: ${esc(thin.join("; "))} (the downloads have all)` : "") +
    (fixed.length ? `<br>fixed: ${esc(fixed.join(", "))}` : "") +
    (spec.physical ? `<br>machine (SI): ${esc(machineText(spec.physical))}` : "");
}
function links(v) {
  const id = v.id, spec = v.spec;
  const q = spec.mode === "grid" && spec.axes.length >= 2
    ? Object.entries(v.slice).map(([n, k]) => `${n}:${num12(axisValues(spec, n)[k])}`).join(",") : "";
  const png = `/v1/sweeps/${id}/diagram?format=png${q ? "&slice=" + encodeURIComponent(q) : ""}`;
  // the slice alone: the other axes at their slice index (the server reads only those)
  const isel = spec.mode === "grid" && spec.axes.length > 2
    ? Object.entries(v.slice).map(([n, k]) => `${n}:${k}`).join(",") : "";
  const sub = isel ? `&isel=${encodeURIComponent(isel)}` : "";
  const items = [
    ["NetCDF", `/v1/sweeps/${id}/data?format=netcdf`, "the whole result, for xarray.open_dataset"],
    ["CSV", `/v1/sweeps/${id}/data?format=csv`, "one row per point"],
    ["JSON", `/v1/sweeps/${id}/data?format=json`, "flat arrays"],
    ...(sub ? [["slice NetCDF", `/v1/sweeps/${id}/data?format=netcdf${sub}`, "this slice only"],
               ["slice CSV", `/v1/sweeps/${id}/data?format=csv${sub}`, "this slice only"]] : []),
    ...(spec.mode === "grid" && spec.axes.length >= 2 ? [["PNG", png, "this slice as the server renders it"]] : []),
    ["points", `/v1/sweeps/${id}/points`, "paged points with their errors"],
    ["Zarr (lazy)", `/v1/sweeps/${id}/zarr/.zmetadata`, "the sweep as a read-only Zarr store: xarray reads only the chunks it touches"],
    ["Python (xarray)", "#lazy", "open the sweep lazily from Python"],
  ];
  const html = items.map(([t, href, title]) =>
    `<a href="${esc(href)}" title="${esc(title)}"${href.startsWith("#") ? "" : " data-download"} target="_blank">${esc(t)}</a>`).join(" \u00b7 ");
  if ($("#diagram-links").dataset.html !== html) {
    $("#diagram-links").innerHTML = "download: " + html;
    $("#diagram-links").dataset.html = html;
  }
  const sel = sliceSel(v);
  $("#lazy-code").textContent =
    `from rsfclient import Client  # API key: RSF_API_KEY or Client(..., api_key=...)\n` +
    `ds = Client("${location.origin}").get_sweep("${id}").to_xarray(lazy=True)  # Zarr over HTTP\n` +
    (sel ? `ds.critical_size.sel(${sel}, method="nearest").load()  # reads this slice's chunks only\n`
         : `ds.critical_size.load()\n`) +
    `# or: xarray.open_zarr("${location.origin}/v1/sweeps/${id}/zarr", consolidated=True, zarr_format=2)\n` +
    `# whole file: xarray.open_dataset(<the NetCDF link>)`;
}
/** The view's slice as xarray .sel() arguments (grid sweeps), e.g. ba=1.4. */
function sliceSel(v) {
  const spec = v.spec;
  if (spec.mode !== "grid" || !v.axes) return "";
  return Object.entries(v.slice).map(([n, k]) => `${n}=${num12(axisValues(spec, n)[k])}`).join(", ");
}
/** A download link: plain when no API key is used; else fetched with the key. */
async function download(ev) {
  const a = ev.target.closest("a[data-download]");
  if (!a) {
    if (ev.target.closest('a[href="#lazy"]')) { ev.preventDefault(); $("#lazy").hidden = !$("#lazy").hidden; }
    return;
  }
  if (!apiKey()) return;
  ev.preventDefault();
  try {
    const r = await fetch(a.getAttribute("href"));
    if (!r.ok) throw await problemOf(r);
    const url = URL.createObjectURL(await r.blob());
    window.open(url, "_blank");
  } catch (e) {
    showViewError({ message: `download failed: ${e.message || e}`, final: true });
  }
}
function hover(ev) {
  const v = state.view;
  if (!v || !v.hit || !v.readout) return;
  const r = ev.currentTarget.getBoundingClientRect();
  const h = v.hit(ev.clientX - r.left, ev.clientY - r.top);
  $("#diagram-readout").textContent = h ? v.readout(h) : "";
}

/** Placeholders of the fixed fields: the API's own defaults (from its OpenAPI schema),
    so an empty field means what it means at every door (it is not sent). */
async function apiDefaults() {
  try {
    const { body } = await getJSON("/openapi.json");
    const props = ((body.components || {}).schemas || {}).SweepFixed.properties || {};
    sweepForm().querySelectorAll("[data-default]").forEach(el => {
      const p = props[el.dataset.default] || {};
      const m = /default (-?[\d.]+(?:e[-+]?\d+)?)/.exec(p.description || "");
      const d = p.default !== null && p.default !== undefined ? p.default : m ? Number(m[1]) : null;
      if (d !== null) { el.placeholder = `${fmt(d)} (default)`; el.dataset.api = d; }
    });
  } catch (e) { /* placeholders stay "default" */ }
}

/* ------------------------------------------------------------------ wiring */
document.addEventListener("DOMContentLoaded", () => {
  const f = sweepForm();
  f.addEventListener("submit", submitSweep);
  f.addEventListener("input", ev => { ev.target.classList.remove("invalid"); syncSweepForm(); });
  f.addEventListener("change", ev => {
    const n = ev.target.name || "";
    const m = /^ax(\d+)_name$/.exec(n);
    if (m) changeAxisName(Number(m[1]));
    else if (n === "sweep_units" || n === "perturbation") changeSweepUnits();
    else syncSweepForm();
  });
  f.addEventListener("click", ev => {
    const rm = ev.target.closest("[data-remove-axis]");
    if (rm) removeAxis(Number(rm.dataset.removeAxis));
  });
  $("#axis-add").addEventListener("click", addAxis);
  renderAxes([{ name: "kappa_ratio" }, { name: "eps" }]);
  apiDefaults();
  $("#sweeps-table").addEventListener("click", ev => {
    const cancel = ev.target.closest("[data-cancel]");
    if (cancel) { ev.stopPropagation(); cancelSweep(cancel.dataset.cancel); return; }
    const tr = ev.target.closest("tr.sweep");
    if (tr) select(tr.dataset.id);
  });
  $("#view-controls").addEventListener("change", onControl);
  $("#view-controls").addEventListener("input", onControl);
  $("#diagram-links").addEventListener("click", download);
  $("#diagram-canvas").addEventListener("mousemove", hover);
  window.addEventListener("popstate", () => { state.view = null; readAddress(); });
  readAddress();
  refreshSweeps();
});
Object.assign(window.rsfUi, { failures, samples, colourLabels, paramLabel, axisValues });
