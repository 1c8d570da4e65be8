/* rsf-stability dashboard: vanilla JS against the /v1 API (no build step, no libraries). */
"use strict";

const $ = (sel, root = document) => root.querySelector(sel);
const POLL_MS = 1000;          // sweep list refresh
const DIAGRAM_MS = 2000;       // partial diagram refresh while a sweep runs

const state = {
  selected: null,              // id of the sweep shown in the diagram panel
  diagramKey: null,            // "<id>:<status>:<n_done>" of the image shown
  diagramBusy: false,
  diagramAt: 0,
  listHtml: "",
  sweeps: new Map(),
  polls: 0,
};
window.rsfUi = state;          // for debugging (and the browser test)

/* ------------------------------------------------------------------ API key */
/* A server with API keys answers 401 without one.  The key is asked for once, kept in
   this tab's sessionStorage (gone when the tab closes, never sent to another origin) and
   sent as "Authorization: Bearer <key>" by every request of the page. */
const KEY_ITEM = "rsf-api-key";
const plainFetch = window.fetch.bind(window);
function apiKey() { try { return sessionStorage.getItem(KEY_ITEM) || ""; } catch (e) { return ""; } }
function askKey(message) {
  const form = $("#key-form");
  if (!form) return;
  $("#key-message").textContent = message || "This server needs an API key.";
  form.hidden = false;
}
window.fetch = async (url, opts = {}) => {
  const sameOrigin = new URL(String(url), location.href).origin === location.origin;
  const headers = new Headers(opts.headers || {});
  const key = apiKey();
  if (sameOrigin && key && !headers.has("authorization")) headers.set("authorization", "Bearer " + key);
  const r = await plainFetch(url, { ...opts, headers });
  // A 401 to a request sent before the key changed (e.g. a poll in flight while the key
  // was being entered) says nothing about the current key: only the current key's refusal asks.
  if (sameOrigin && r.status === 401 && key === apiKey()) {
    askKey(key ? "The API key was refused (unknown or revoked)." : "");
  }
  return r;
};
function useKey(ev) {
  ev.preventDefault();
  const v = $("#key-input").value.trim();
  try { if (v) sessionStorage.setItem(KEY_ITEM, v); else sessionStorage.removeItem(KEY_ITEM); } catch (e) { /* private mode */ }
  $("#key-input").value = "";
  $("#key-form").hidden = true;
  health(); loadFigures(); refreshSweeps();
}

/* ------------------------------------------------------------------ helpers */
function fmt(v, digits = 4) {
  if (v === null || v === undefined) return "\u2014";
  if (typeof v !== "number") return String(v);
  if (v === 0) return "0";
  const a = Math.abs(v);
  return a >= 1e4 || a < 1e-3 ? v.toExponential(digits - 1) : String(+v.toPrecision(digits));
}
function esc(s) {
  return String(s).replace(/[&<>"']/g, c => ({ "&": "&amp;", "<": "&lt;", ">": "&gt;", '"': "&quot;", "'": "&#39;" }[c]));
}
const NAMES = { kappa_ratio: "\u03ba/\u03ba_crit", eps: "\u03b5", ba: "b/a", size: "size" };
function duration(s) {
  if (s === null || s === undefined) return "\u2014";
  if (s < 1) return "<1 s";
  if (s < 90) return Math.round(s) + " s";
  if (s < 5400) return Math.round(s / 60) + " min";
  return (s / 3600).toFixed(1) + " h";
}
function num(form, name) {
  const el = form.elements[name];
  const v = el.value.trim();
  return v === "" ? null : Number(v);
}

/** Error carrying an RFC 9457 problem body. */
class Problem extends Error {
  constructor(status, body) {
    super((body && (body.detail || body.title)) || `HTTP ${status}`);
    this.status = status; this.body = body || {};
  }
}
async function problemOf(r) {
  let body = null;
  try { body = await r.json(); } catch (e) { /* not JSON */ }
  return new Problem(r.status, body);
}
async function getJSON(url, opts = {}) {
  const r = await fetch(url, opts);
  if (!r.ok && r.status !== 202) throw await problemOf(r);
  return { status: r.status, body: await r.json(), headers: r.headers };
}
function postJSON(url, body) {
  return getJSON(url, { method: "POST", headers: { "content-type": "application/json" }, body: JSON.stringify(body) });
}
async function blobURL(url, opts = {}) {
  const r = await fetch(url, opts);
  if (r.status !== 200) throw await problemOf(r);
  const type = r.headers.get("content-type") || "";
  if (!type.startsWith("image/")) throw new Problem(r.status, { detail: "still computing, retry" });
  return { url: URL.createObjectURL(await r.blob()), headers: r.headers };
}
/** A computation deferred with 202 + Location: poll it until it is done. */
async function settle(res) {
  let n = 0;
  while (res.status === 202 && n++ < 600) {
    await new Promise(ok => setTimeout(ok, 500));
    res = await getJSON(res.headers.get("location") || res.body.location);
  }
  return res;
}
function showProblem(box, form, err) {
  box.hidden = false;
  const b = err.body || {};
  box.textContent = b.detail || err.message || String(err);
  if (form) {
    form.querySelectorAll(".invalid").forEach(el => el.classList.remove("invalid"));
    const field = String(b.field || "");
    const guess = [field, "f_" + field, field.replace(/\./g, "_"), field.split(".")[0]];
    for (const g of guess) {
      if (form.elements[g]) { form.elements[g].classList.add("invalid"); break; }
    }
  }
}
function clearProblem(box, form) {
  box.hidden = true; box.textContent = "";
  if (form) form.querySelectorAll(".invalid").forEach(el => el.classList.remove("invalid"));
}
function busy(el, text) { el.textContent = text || ""; el.classList.toggle("busy", !!text); }

/* ------------------------------------------------------------------ health */
async function health() {
  const pill = $("#health");
  try {
    const { body } = await getJSON("/health");
    pill.className = "pill ok";
    pill.textContent = `service ok \u00b7 ${body.cache_entries} cached`;
    $("#numerics").textContent = "numerics " + body.numerics_version;
  } catch (e) {
    pill.className = "pill bad";
    pill.textContent = "service unreachable";
  }
}

/* ------------------------------------------------------------------ single query */
function kappaHint() {
  const f = $("#query-form");
  const ba = num(f, "ba"), k = num(f, "kappa");
  const kc = ba !== null ? ba - 1 : null;
  $("#kappa-hint").textContent = kc !== null && kc > 0
    ? `\u03ba_crit = ${fmt(kc)}` + (k !== null ? ` \u00b7 \u03ba/\u03ba_crit = ${fmt(k / kc, 3)}` : "")
    : "\u03ba_crit = b/a \u2212 1";
}

async function runQuery(ev) {
  ev.preventDefault();
  const form = $("#query-form"), status = $("#query-status"), errBox = $("#query-error");
  const btn = $("#query-submit");
  clearProblem(errBox, form);
  const params = queryParams(form);  // lab.js: dimensionless, or SI ("physical" + factor)
  const body = { ...params, n_points: 800 };
  btn.disabled = true;
  busy(status, "integrating\u2026");
  const t0 = performance.now();
  try {
    const res = await settle(await postJSON("/v1/trajectory", body));
    showOutcome(res.body, (performance.now() - t0) / 1000);
    busy(status, "plotting\u2026");
    const img = await blobURL("/v1/trajectory?format=png", {
      method: "POST", headers: { "content-type": "application/json" }, body: JSON.stringify(body) });
    const el = $("#phase-img");
    if (el.src.startsWith("blob:")) URL.revokeObjectURL(el.src);
    el.src = img.url;
    $("#phase-figure").hidden = false;
    busy(status, "");
    status.textContent = `done in ${((performance.now() - t0) / 1000).toFixed(2)} s`;
    criticalSize(params).then(health);
  } catch (e) {
    busy(status, "");
    showProblem(errBox, form, e);
  } finally {
    btn.disabled = false;
  }
}

function showOutcome(r, seconds) {
  $("#outcome").hidden = false;
  const badge = $("#outcome-badge");
  badge.textContent = r.outcome;
  badge.className = "badge " + r.outcome;
  $("#outcome-cert").textContent = r.certificate;
  const facts = [
    ["peak \u03c6", r.peak_phi === null ? "runaway" : fmt(r.peak_phi)],
    ["peak time T", fmt(r.peak_time)],
    [r.outcome === "unstable" ? "blow-up time T" : "return time T",
      fmt(r.outcome === "unstable" ? r.blowup_time : r.return_time)],
    ["rel. accuracy", fmt(r.rel_accuracy, 2)],
    ["start (\u03c6, \u03c8)", r.start ? `(${fmt(r.start.phi)}, ${fmt(r.start.psi)})` : "\u2014"],
    ["steps / RHS", `${r.n_steps} / ${r.n_rhs}`],
    ["critical size", "<span id='critical-size'>\u2026</span>"],
    ["cache", r.cached ? "hit" : "computed"],
    ["wall time", `${seconds.toFixed(2)} s`],
    ...siFacts(r),  // lab.js: the answer in SI when the query was in SI
  ];
  $("#outcome-facts").innerHTML = facts.map(([k, v]) =>
    `<div><dt>${esc(k)}</dt><dd>${k === "critical size" ? v : esc(v)}</dd></div>`).join("");
}

async function criticalSize(params) {
  const p = criticalParams(params);  // lab.js: the query without its perturbation size
  const el = () => $("#critical-size");
  try {
    const res = await settle(await postJSON("/v1/critical", p));
    const c = res.body;
    if (el()) el().textContent = criticalText(c);  // lab.js (SI: critical slip rate too)
  } catch (e) {
    if (el()) el().textContent = "n/a";
  }
}

/* ------------------------------------------------------------------ sweeps */
function sweepBody() {
  const f = $("#sweep-form");
  const axis = w => ({ name: f.elements[w + "_name"].value, start: num(f, w + "_start"),
                       stop: num(f, w + "_stop"), n: num(f, w + "_n") });
  const x = axis("x"), y = axis("y");
  const fixed = {};
  for (const k of ["ba", "kappa_ratio", "eps", "vo", "size"]) {
    if (k === x.name || k === y.name) continue;
    const v = num(f, "f_" + k);
    if (v !== null) fixed[k] = v;
  }
  return { x, y, fixed, perturbation: f.elements.perturbation.value };
}

function syncFixed() {
  const f = $("#sweep-form");
  const swept = [f.elements.x_name.value, f.elements.y_name.value];
  for (const k of ["ba", "kappa_ratio", "eps", "vo", "size"]) {
    const el = f.elements["f_" + k];
    el.disabled = swept.includes(k);
    el.title = el.disabled ? "swept" : (k === "size" ? "empty: critical size per point; a value: stable/unstable" : "");
  }
  const nx = num(f, "x_n") || 0, ny = num(f, "y_n") || 0;
  $("#sweep-npoints").textContent = `${nx} \u00d7 ${ny} = ${nx * ny} points`;
}

async function submitSweep(ev) {
  ev.preventDefault();
  const form = $("#sweep-form"), status = $("#sweep-status"), errBox = $("#sweep-error");
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
    showProblem(errBox, form, e);
  } finally {
    btn.disabled = false;
  }
}

function describe(s) {
  // status polls carry dims (names and lengths), fixed, output, perturbation
  const dims = s.dims || [];
  const fx = s.fixed || {};
  const scattered = dims.length === 1 && dims[0].name === "point";
  const mode = s.output === "outcome"
    ? (fx.size !== null && fx.size !== undefined ? `outcome @ size ${fmt(fx.size)}` : "outcome")
    : "critical size";
  return { grid: scattered ? "scattered points" : dims.map(d => NAMES[d.name] || d.name).join(" \u00d7 "),
           dims: dims.map(d => d.n).join("\u00d7"),
           mode: `${mode}, ${(s.perturbation || "").replace("-", " ")}` };
}

function row(s) {
  const d = describe(s);
  const pct = s.n_total ? Math.floor(100 * s.n_done / s.n_total) : 0;
  const active = s.status === "queued" || s.status === "running";
  return `<tr class="sweep${s.id === state.selected ? " selected" : ""}" data-id="${esc(s.id)}" data-status="${esc(s.status)}">
    <td class="mono" title="${esc(s.id)}">${esc(s.id.slice(0, 8))}</td>
    <td><div>${esc(d.grid)} <span class="hint">${esc(d.dims)}</span></div><div class="hint">${esc(d.mode)}</div></td>
    <td><span class="badge ${esc(s.status)}">${esc(s.status)}</span></td>
    <td class="wide"><div class="progress ${esc(s.status)}" data-done="${s.n_done}" data-total="${s.n_total}">
      <span class="bar" style="width:${pct}%"></span>
      <span class="label">${s.n_done} / ${s.n_total} (${pct}%)</span></div>
      ${s.n_failed ? `<span class="failed">${s.n_failed} failed</span>` : ""}</td>
    <td>${active ? esc(duration(s.eta_s)) : ""}</td>
    <td>${active ? `<button type="button" class="link" data-cancel="${esc(s.id)}">cancel</button>` : ""}</td>
  </tr>`;
}

async function refreshSweeps() {
  let list;
  try {
    list = (await getJSON("/v1/sweeps?limit=25")).body.sweeps;
  } catch (e) {
    return;
  }
  state.polls += 1;
  state.sweeps = new Map(list.map(s => [s.id, s]));
  const html = list.length ? list.map(row).join("") : `<tr class="empty"><td colspan="6">no sweeps yet</td></tr>`;
  if (html !== state.listHtml) {
    $("#sweeps-table tbody").innerHTML = html;
    state.listHtml = html;
  }
  if (state.selected === null && list.length) select(list[0].id);
  else updateDiagram();
}

async function cancelSweep(id) {
  try {
    await getJSON(`/v1/sweeps/${id}`, { method: "DELETE" });
  } catch (e) { /* shown by the next refresh */ }
  refreshSweeps();
}

function select(id) {
  if (state.selected !== id) {
    state.selected = id;
    state.diagramKey = null;
    state.listHtml = "";  // re-render the selection highlight
    document.querySelectorAll("#sweeps-table tr.sweep").forEach(tr =>
      tr.classList.toggle("selected", tr.dataset.id === id));
  }
  updateDiagram(true);
}

/* ------------------------------------------------------------------ diagram */
async function updateDiagram(force = false) {
  const id = state.selected;
  if (!id || state.diagramBusy) return;
  let s = state.sweeps.get(id);
  if (!s) {
    try { s = (await getJSON(`/v1/sweeps/${id}`)).body; } catch (e) { return; }
  }
  const key = `${id}:${s.status}:${s.n_done}`;
  const final = s.status === "done" || s.status === "cancelled";
  const now = Date.now();
  if (key === state.diagramKey) return;
  if (!final && !force && now - state.diagramAt < DIAGRAM_MS) return;
  state.diagramBusy = true;
  state.diagramAt = now;
  try {
    const img = await blobURL(`/v1/sweeps/${id}/diagram?format=png`);
    const el = $("#diagram-img");
    const old = el.src;
    el.src = img.url;
    if (old.startsWith("blob:")) URL.revokeObjectURL(old);
    const st = img.headers.get("x-sweep-status") || s.status;
    const prog = img.headers.get("x-sweep-progress") || `${s.n_done}/${s.n_total}`;
    el.dataset.sweep = id;
    el.dataset.status = st;
    el.dataset.progress = prog;
    el.hidden = false;
    $("#diagram-empty").hidden = true;
    state.diagramKey = `${id}:${st}:${prog.split("/")[0]}`;
    const d = describe(s);
    $("#diagram-title").textContent = `${d.grid} \u00b7 ${id.slice(0, 8)}`;
    $("#diagram-caption").innerHTML =
      `${esc(d.mode)} \u00b7 ${esc(prog)} points \u00b7 <span class="badge ${esc(st)}">${esc(st)}</span> ` +
      `${st === "done" || st === "cancelled" ? "" : "(blank cells: not computed yet) "}\u00b7 ` +
      `<a href="/v1/sweeps/${esc(id)}/diagram?format=png" target="_blank">PNG</a> \u00b7 ` +
      `<a href="/v1/sweeps/${esc(id)}/diagram" target="_blank">JSON</a> \u00b7 ` +
      `<a href="/v1/sweeps/${esc(id)}/points" target="_blank">points</a>`;
  } catch (e) {
    $("#diagram-caption").textContent = "diagram unavailable: " + (e.message || e);
  } finally {
    state.diagramBusy = false;
  }
}

/* ------------------------------------------------------------------ paper figures */
async function loadFigures() {
  const sel = $("#figure-select");
  try {
    const { body } = await getJSON("/v1/figures");
    state.figures = new Map(body.figures.map(f => [f.name, f]));
    sel.innerHTML = body.figures.map(f => `<option value="${esc(f.name)}">${esc(f.name)}</option>`).join("");
    figureCaption();
  } catch (e) {
    $("#figure-caption").textContent = "figures unavailable: " + (e.message || e);
  }
}
function figureCaption() {
  const f = state.figures && state.figures.get($("#figure-select").value);
  if (!f) return;
  $("#figure-caption").textContent = f.caption + (f.note ? ` \u2014 note: ${f.note}` : "");
  $("#figure-svg").href = `/v1/figures/${encodeURIComponent(f.name)}?format=svg`;
}
function showFigure() {
  const name = $("#figure-select").value;
  if (!name) return;
  const img = $("#figure-img"), status = $("#figure-status");
  busy(status, "rendering (first time takes a few seconds)\u2026");
  img.onload = () => { busy(status, ""); $("#figure-figure").hidden = false; };
  img.onerror = () => { busy(status, ""); status.textContent = "could not render"; };
  blobURL(`/v1/figures/${encodeURIComponent(name)}?format=png`)
    .then(res => { img.src = res.url; })
    .catch(() => { busy(status, ""); status.textContent = "could not render"; });
}
async function openSvg(ev) {  // through fetch, so that the API key is sent
  ev.preventDefault();
  try { window.open((await blobURL(ev.currentTarget.href)).url, "_blank"); }
  catch (e) { $("#figure-status").textContent = "could not render: " + (e.message || e); }
}

/* ------------------------------------------------------------------ wiring */
document.addEventListener("DOMContentLoaded", () => {
  $("#query-form").addEventListener("submit", runQuery);
  $("#query-form").addEventListener("input", kappaHint);
  $("#sweep-form").addEventListener("submit", submitSweep);
  $("#sweep-form").addEventListener("input", syncFixed);
  $("#sweep-form").addEventListener("change", syncFixed);
  $("#sweeps-table").addEventListener("click", ev => {
    const cancel = ev.target.closest("[data-cancel]");
    if (cancel) { ev.stopPropagation(); cancelSweep(cancel.dataset.cancel); return; }
    const tr = ev.target.closest("tr.sweep");
    if (tr) select(tr.dataset.id);
  });
  $("#figure-select").addEventListener("change", () => { figureCaption(); showFigure(); });
  $("#figure-show").addEventListener("click", showFigure);
  $("#figure-svg").addEventListener("click", openSvg);
  $("#key-form").addEventListener("submit", useKey);
  kappaHint();
  syncFixed();
  health();
  loadFigures();
  refreshSweeps();
  setInterval(refreshSweeps, POLL_MS);
  setInterval(health, 15000);
});
