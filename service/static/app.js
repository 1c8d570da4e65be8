/* rsf-stability dashboard: vanilla JS against the /v1 API (no build step, no libraries). */
"use strict";

const $ = (sel, root = document) => root.querySelector(sel);

const state = {
  selected: null,              // id of the sweep shown in the view panel (sweeps.js)
  view: null,                  // what the view panel shows (sweeps.js)
  listHtml: "",
  sweeps: new Map(),
  polls: 0,                    // answers of the sweep list so far
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
  if (typeof forgetAuthFailures === "function") forgetAuthFailures();  // sweeps.js
  health(); loadFigures(); refreshSweeps();
}

/* ------------------------------------------------------------------ helpers */
function fmt(v, digits = 4) {
  if (v === null || v === undefined) return "\u2014";
  if (typeof v !== "number") return String(v);
  if (v === 0) return "0";
  const a = Math.abs(v);
  return a >= 1e4 || a < 1e-3 ? v.toExponential(digits - 1).replace(/\.?0+e/, "e") : String(+v.toPrecision(digits));
}
function esc(s) {
  return String(s).replace(/[&<>"']/g, c => ({ "&": "&amp;", "<": "&lt;", ">": "&gt;", '"': "&quot;", "'": "&#39;" }[c]));
}
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

/* sweeps: see sweeps.js (form, list, view of the selected sweep) */

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
  $("#figure-select").addEventListener("change", () => { figureCaption(); showFigure(); });
  $("#figure-show").addEventListener("click", showFigure);
  $("#figure-svg").addEventListener("click", openSvg);
  $("#key-form").addEventListener("submit", useKey);
  kappaHint();
  health();
  loadFigures();
  setInterval(health, 15000);
});
