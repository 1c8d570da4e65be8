/* rsf-stability dashboard, lab side: SI input on the query form and the fit page.
   Loaded after app.js and uses its helpers ($, num, fmt, esc, postJSON, getJSON, settle,
   blobURL, showProblem, clearProblem, busy); every request goes through its fetch
   (API key included). */
"use strict";

/* ------------------------------------------------------------------ SI queries */
function siActive() {
  const f = $("#query-form");
  return !!f && f.elements.units && f.elements.units.value === "si";
}
function siPhysical(form) {
  const phys = {};
  for (const k of ["a", "b", "Dc_m", "sigma_Pa", "k_Pa_per_m", "V_star_m_s", "V_load_m_s"]) {
    const v = num(form, "si_" + k);
    if (v !== null) phys[k] = v;
  }
  return phys;
}
/** The query's parameters: dimensionless (ba, kappa, vo, size) or SI (physical, factor). */
function queryParams(form) {
  const common = { eps: num(form, "eps"), perturbation: form.elements.perturbation.value };
  if (!siActive()) {
    return { ba: num(form, "ba"), kappa: num(form, "kappa"), vo: num(form, "vo"),
             size: num(form, "size"), ...common };
  }
  return { physical: siPhysical(form), factor: num(form, "si_factor"), ...common };
}
/** The same query for /v1/critical (no perturbation size). */
function criticalParams(params) {
  const { size, factor, ...p } = params;
  return p;
}
function criticalText(c) {
  if (c.kind !== "finite") return c.kind;
  const si = c.si || {};
  if (si.velocity_jump) return `${fmt(c.critical_size)} (to ${fmt(si.velocity_jump.new_slip_rate_m_s)} m/s, \u00d7${fmt(si.velocity_jump.factor)})`;
  if (si.load_point_jump) return `${fmt(c.critical_size)} (to ${fmt(si.load_point_jump.new_load_point_velocity_m_s)} m/s)`;
  return fmt(c.critical_size);
}
/** Extra outcome facts in SI (empty for a dimensionless query). */
function siFacts(r) {
  const si = r && r.si;
  if (!si) return [];
  const jump = si.velocity_jump ? `\u00d7${fmt(si.velocity_jump.factor)} \u2192 ${fmt(si.velocity_jump.new_slip_rate_m_s)} m/s`
    : si.load_point_jump ? `\u2192 ${fmt(si.load_point_jump.new_load_point_velocity_m_s)} m/s` : "\u2014";
  return [
    ["\u03ba/\u03ba_crit", fmt(si.kappa / si.kappa_crit)],
    ["perturbation (SI)", jump],
    [r.outcome === "unstable" ? "blow-up time [s]" : "return time [s]",
      fmt(r.outcome === "unstable" ? si.blowup_time_s : si.return_time_s)],
    ["peak slip rate [m/s]", si.peak_slip_rate_m_s === null ? "runaway" : fmt(si.peak_slip_rate_m_s)],
    ["stress jump [Pa]", si.velocity_jump ? fmt(si.velocity_jump.shear_stress_jump_Pa) : "\u2014"],
  ];
}
function toggleUnits() {
  const si = siActive();
  $("#si-fields").hidden = !si;
  $("#dimless-fields").hidden = si;
  for (const n of ["ba", "kappa", "vo", "size"]) $("#query-form").elements[n].required = !si;
  siHint();
}
function siHint() {
  const f = $("#query-form");
  const p = siPhysical(f);
  const el = $("#si-kappa-hint");
  if (!el || !(p.a > 0 && p.b > p.a && p.Dc_m > 0 && p.sigma_Pa > 0)) return;
  const kc = p.sigma_Pa * (p.b - p.a) / p.Dc_m;
  el.textContent = `k_crit = ${fmt(kc)} Pa/m` + (p.k_Pa_per_m >= 0 ? ` \u00b7 k/k_crit = ${fmt(p.k_Pa_per_m / kc, 3)}` : "");
}

/* ------------------------------------------------------------------ fit page */
const FIT_PARAMS = [["mu0", "\u03bc0"], ["a", "a"], ["b", "b"], ["b_minus_a", "b \u2212 a"],
  ["Dc_m", "D_c [m]"], ["eps", "\u03b5"], ["k_per_m", "k [1/m]"]];

async function runFit(ev) {
  ev.preventDefault();
  const form = $("#fit-form"), status = $("#fit-status"), errBox = $("#fit-error");
  clearProblem(errBox, form);
  const file = form.elements.record.files[0];
  if (!file) return;
  // fit_stiffness only when ticked: unticked with no stiffness means "fitted" (the API default)
  const body = { record: await file.text() };
  if (form.elements.fit_stiffness.checked) body.fit_stiffness = true;
  const law = form.elements.law.value;
  if (law) body.law = law;
  const k = num(form, "k_friction_per_m");
  if (k !== null) body.k_friction_per_m = k;
  $("#fit-submit").disabled = true;
  busy(status, "queued for fitting\u2026");
  const t0 = performance.now();
  try {
    let res = await postJSON("/v1/fits", body);
    for (let n = 0; res.status === 202 && n < 1200; n++) {  // queued: poll, show the stage
      busy(status, res.body.progress ? `fitting: ${res.body.progress}\u2026` : "queued for a worker\u2026");
      await new Promise(ok => setTimeout(ok, 500));
      res = await getJSON(res.headers.get("location") || res.body.location);
    }
    showFit(res.body);
    busy(status, "plotting\u2026");
    const key = res.body.cache_key;
    const img = await blobURL(`/v1/fits/${key}?format=png`);
    const el = $("#fit-img");
    if (el.src.startsWith("blob:")) URL.revokeObjectURL(el.src);
    el.src = img.url;
    $("#fit-csv").dataset.key = key;
    $("#fit-figure").hidden = false;
    busy(status, "");
    status.textContent = `done in ${((performance.now() - t0) / 1000).toFixed(2)} s` + (res.body.cached ? " (cached)" : "");
  } catch (e) {
    busy(status, "");
    showProblem(errBox, form, e);
  } finally {
    $("#fit-submit").disabled = false;
  }
}

function showFit(r) {
  $("#fit-result").hidden = false;
  const badge = $("#fit-badge");
  badge.textContent = `${r.law}: ${r.status}`;
  badge.className = "badge " + (r.ok ? "stable" : "unstable");
  $("#fit-message").textContent = r.message || "";
  const rows = FIT_PARAMS.filter(([k]) => k in (r.params || {})).map(([k, label]) => {
    const se = (r.stderr || {})[k];
    const fixed = !(r.fitted || []).includes(k) && k !== "b_minus_a";
    return `<tr><td>${esc(label)}</td><td class="mono">${esc(fmt(r.params[k], 6))}</td>` +
      `<td class="mono">${fixed ? "fixed" : esc(fmt(se, 3))}</td></tr>`;
  });
  $("#fit-params tbody").innerHTML = rows.join("");
  const comp = r.law_comparison;
  $("#fit-laws tbody").innerHTML = comp ? comp.scores.map(s =>
    `<tr${s.law === comp.best ? ' class="best"' : ""}><td>${esc(s.law)}${s.law === comp.best ? " \u2605" : ""}</td>` +
    `<td class="mono">${esc(fmt(s.rms, 3))}</td><td class="mono">${esc(fmt(s.delta_aic, 3))}</td>` +
    `<td class="mono">${esc(fmt(s.delta_bic, 3))}</td><td class="mono">${esc(fmt(s.akaike_weight, 3))}</td>` +
    `<td>${esc(s.status)}</td></tr>`).join("") : '<tr class="empty"><td colspan="6">not compared</td></tr>';
  const st = r.stability || {};
  const crit = j => !j ? "\u2014" : j.kind !== "finite" ? (j.kind || "outside range")
    : `${fmt(j.critical_m_s && j.critical_m_s.median)} m/s (95%: ${fmt(j.critical_m_s && j.critical_m_s.p2_5)} \u2013 ${fmt(j.critical_m_s && j.critical_m_s.p97_5)})`;
  const facts = r.stability ? [
    ["regime", st.regime],
    ["\u03ba/\u03ba_crit", fmt(st.kappa_ratio)],
    ["critical stiffness [1/m]", fmt(st.critical_stiffness_per_m)],
    ["P(linearly unstable)", fmt(st.prob_linearly_unstable, 3)],
    ["critical velocity jump", crit(st.velocity_jump)],
    ["critical load-point velocity", crit(st.load_point_jump)],
    ["note", st.message || "\u2014"],
  ] : [["stability", "not answered (the fit is not determined)"]];
  $("#fit-stability").innerHTML = facts.map(([k, v]) =>
    `<div><dt>${esc(k)}</dt><dd>${esc(v === undefined || v === null ? "\u2014" : v)}</dd></div>`).join("");
}

async function fitCsv(ev) {  // through fetch, so that the API key is sent
  ev.preventDefault();
  const key = ev.currentTarget.dataset.key;
  if (!key) return;
  const r = await fetch(`/v1/fits/${key}?format=csv`);
  if (r.status !== 200) return;
  const a = document.createElement("a");
  a.href = URL.createObjectURL(await r.blob());
  a.download = "fit.csv";
  a.click();
}

document.addEventListener("DOMContentLoaded", () => {
  const q = $("#query-form");
  if (q) {
    q.addEventListener("change", ev => { if (ev.target.name === "units") toggleUnits(); });
    q.addEventListener("input", siHint);
    toggleUnits();
  }
  const f = $("#fit-form");
  if (f) f.addEventListener("submit", runFit);
  const c = $("#fit-csv");
  if (c) c.addEventListener("click", fitCsv);
});
