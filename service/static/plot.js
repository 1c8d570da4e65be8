/* rsf-stability dashboard: small canvas plots (no libraries, works offline).

   RsfPlot.draw(canvas, fig) draws one figure:
     fig.type   "grid" (a 2-D map of cells), "scatter" (points) or "line" (a 1-D grid)
     fig.x, fig.y   {label, log}  and for "grid" also {values}  (cell centres)
     fig.cell(i, j) -> {state, v}  ("grid": the cell at x[i], y[j])
     fig.points      [{x, y, state, v}]  ("scatter", "line"; "line" ignores y for states
                     other than "finite")
     fig.colour  {label, log, lo, hi, si: {label, of: v => SI value} | null}, {outcome: true}
                 (stable / unstable) or {plain: true} (one colour: a curve whose y says it all)
   state: "finite" (coloured by v), "zero", "infinite", "stable", "unstable", "missing".
   Returns a hit-test function (x px, y px) -> {i, j} | {k} | null for hover read-outs.
*/
"use strict";

const RsfPlot = (() => {
  const COLOURS = {
    // zero: unstable to any jump (red); infinite: stable to any jump (the light blue of
    // "stable"), both apart from viridis's hues
    zero: "#d62728", infinite: "#9ecae1", stable: "#9ecae1", unstable: "#de2d26",
    missing: "#eef0f4",
  };
  // viridis, 9 anchors (matplotlib's table at 0, 1/8, ..., 1), interpolated linearly
  const VIRIDIS = [[68, 1, 84], [71, 44, 122], [59, 81, 139], [44, 113, 142], [33, 144, 141],
    [39, 173, 129], [92, 200, 99], [170, 220, 50], [253, 231, 37]];
  function viridis(t) {
    t = Math.min(1, Math.max(0, t)) * (VIRIDIS.length - 1);
    const k = Math.min(VIRIDIS.length - 2, Math.floor(t)), f = t - k;
    const c = VIRIDIS[k].map((a, n) => Math.round(a + (VIRIDIS[k + 1][n] - a) * f));
    return `rgb(${c[0]},${c[1]},${c[2]})`;
  }
  function tickText(v) {
    if (v === 0) return "0";
    const a = Math.abs(v);
    if (a >= 1e4 || a < 1e-3) {
      const [m, e] = v.toExponential(2).split("e");
      return `${+m}e${+e}`;
    }
    return String(+v.toPrecision(4));
  }
  /** Tick values of [lo, hi]: decades (log) or 1-2-5 steps (linear). */
  function ticks(lo, hi, log, want = 6) {
    if (!(hi > lo)) return [lo];
    if (log) {
      const a = Math.floor(Math.log10(lo)), b = Math.ceil(Math.log10(hi));
      const step = Math.max(1, Math.ceil((b - a) / want));
      const out = [];
      for (let e = a; e <= b; e += step) {
        const v = 10 ** e;
        if (v >= lo * (1 - 1e-9) && v <= hi * (1 + 1e-9)) out.push(v);
      }
      if (out.length < 2) {
        for (const m of [2, 5]) for (let e = a; e <= b; e++) {
          const v = m * 10 ** e;
          if (v >= lo && v <= hi) out.push(v);
        }
        out.sort((p, q) => p - q);
      }
      return out.length ? out : [lo, hi];
    }
    const raw = (hi - lo) / want, mag = 10 ** Math.floor(Math.log10(raw));
    const step = [1, 2, 5, 10].map(m => m * mag).find(s => s >= raw) || 10 * mag;
    const out = [];
    for (let v = Math.ceil(lo / step) * step; v <= hi + step * 1e-9; v += step) {
      out.push(Math.abs(v) < step * 1e-9 ? 0 : v);
    }
    return out;
  }
  /** A scale [lo, hi] -> [p0, p1] pixels, linear or log10. */
  function scale(lo, hi, p0, p1, log) {
    const f = log ? Math.log10 : (v => v);
    const a = f(lo), b = f(hi), d = b - a || 1;
    const s = v => p0 + (f(v) - a) / d * (p1 - p0);
    s.lo = lo; s.hi = hi; s.log = log;
    return s;
  }
  /** Cell edges around centres (midpoints, in log space for a log axis). */
  function edges(vals, log) {
    const f = log ? Math.log10 : (v => v), g = log ? (v => 10 ** v) : (v => v);
    const t = vals.map(f), n = t.length, out = new Array(n + 1);
    if (n === 1) {
      const h = log ? 0.5 : (Math.abs(t[0]) * 0.1 || 0.5);
      return [g(t[0] - h), g(t[0] + h)];
    }
    for (let k = 1; k < n; k++) out[k] = (t[k - 1] + t[k]) / 2;
    out[0] = t[0] - (t[1] - t[0]) / 2;
    out[n] = t[n - 1] + (t[n - 1] - t[n - 2]) / 2;
    return out.map(g);
  }
  function range(vals, log) {
    const v = vals.filter(x => Number.isFinite(x) && (!log || x > 0));
    if (!v.length) return [log ? 1 : 0, log ? 10 : 1];
    let lo = Infinity, hi = -Infinity;
    for (const x of v) { if (x < lo) lo = x; if (x > hi) hi = x; }
    if (lo === hi) { lo = log ? lo / 2 : lo - (Math.abs(lo) || 1) * 0.5; hi = log ? hi * 2 : hi + (Math.abs(hi) || 1) * 0.5; }
    return [lo, hi];
  }
  function colourOf(c, state, v) {
    if (state !== "finite") return COLOURS[state] || COLOURS.missing;
    if (c.plain) return "#1d2433";
    if (!Number.isFinite(v)) return COLOURS.missing;
    if (c.log && v <= 0) return COLOURS.zero;
    const s = scale(c.lo, c.hi, 0, 1, c.log);
    return viridis(c.hi > c.lo ? s(v) : 0.5);
  }

  function axes(ctx, sx, sy, box, fig) {
    ctx.strokeStyle = "#1d2433"; ctx.lineWidth = 1;
    ctx.strokeRect(box.l + 0.5, box.t + 0.5, box.w, box.h);
    ctx.fillStyle = "#1d2433"; ctx.font = "11px system-ui, sans-serif";
    ctx.textAlign = "center"; ctx.textBaseline = "top";
    for (const v of ticks(sx.lo, sx.hi, sx.log)) {
      const p = Math.round(sx(v)) + 0.5;
      if (p < box.l - 1 || p > box.l + box.w + 1) continue;
      ctx.beginPath(); ctx.moveTo(p, box.t + box.h); ctx.lineTo(p, box.t + box.h + 4); ctx.stroke();
      ctx.fillText(tickText(v), p, box.t + box.h + 6);
    }
    ctx.textAlign = "right"; ctx.textBaseline = "middle";
    for (const v of ticks(sy.lo, sy.hi, sy.log)) {
      const p = Math.round(sy(v)) + 0.5;
      if (p < box.t - 1 || p > box.t + box.h + 1) continue;
      ctx.beginPath(); ctx.moveTo(box.l - 4, p); ctx.lineTo(box.l, p); ctx.stroke();
      ctx.fillText(tickText(v), box.l - 6, p);
    }
    ctx.font = "13px system-ui, sans-serif"; ctx.textAlign = "center"; ctx.textBaseline = "bottom";
    ctx.fillText(fig.x.label, box.l + box.w / 2, box.t + box.h + 40);
    ctx.save();
    ctx.translate(box.l - 52, box.t + box.h / 2); ctx.rotate(-Math.PI / 2);
    ctx.textBaseline = "bottom"; ctx.fillText(fig.y.label, 0, 0);
    ctx.restore();
  }

  function colourBar(ctx, c, box, present) {
    const x0 = box.l + box.w + 22, w = 14;
    ctx.font = "11px system-ui, sans-serif"; ctx.fillStyle = "#1d2433"; ctx.strokeStyle = "#1d2433";
    let y = box.t;
    if (c.outcome) {
      for (const st of ["unstable", "stable"]) {
        ctx.fillStyle = COLOURS[st]; ctx.fillRect(x0, y, w, 28);
        ctx.fillStyle = "#1d2433"; ctx.textAlign = "left"; ctx.textBaseline = "middle";
        ctx.fillText(st, x0 + w + 6, y + 14); y += 34;
      }
    } else if (present.finite && !c.plain) {
      const nLegend = ["zero", "infinite", "missing"].filter(k => present[k]).length;
      const h = Math.max(60, box.h - 18 * nLegend - 12), s = scale(c.lo, c.hi, y + h, y, c.log);
      for (let k = 0; k < h; k++) {
        ctx.fillStyle = viridis(1 - k / h); ctx.fillRect(x0, y + k, w, 1);
      }
      ctx.strokeRect(x0 + 0.5, y + 0.5, w, h);
      const tv = c.hi > c.lo ? ticks(c.lo, c.hi, c.log, 5) : [c.lo];
      ctx.textBaseline = "middle";
      for (const v of tv) {
        const p = c.hi > c.lo ? Math.round(s(v)) + 0.5 : y + h / 2;
        ctx.fillStyle = "#1d2433"; ctx.textAlign = "left";
        ctx.beginPath(); ctx.moveTo(x0 + w, p); ctx.lineTo(x0 + w + 3, p); ctx.stroke();
        ctx.fillText(tickText(v), x0 + w + 5, p);
        if (c.si) {  // the same tick in SI, on the left of the bar
          ctx.textAlign = "right";
          ctx.fillText(tickText(c.si.of(v)), x0 - 4, p);
        }
      }
      // what the colour measures, written along the bar
      ctx.save(); ctx.translate(x0 + w + 62, y + h / 2); ctx.rotate(Math.PI / 2);
      ctx.textAlign = "center"; ctx.textBaseline = "bottom"; ctx.font = "12px system-ui, sans-serif";
      ctx.fillText(c.label, 0, 0); ctx.restore();
      if (c.si) {
        ctx.save(); ctx.translate(x0 - 44, y + h / 2); ctx.rotate(-Math.PI / 2);
        ctx.textAlign = "center"; ctx.textBaseline = "bottom"; ctx.font = "12px system-ui, sans-serif";
        ctx.fillText(c.si.label, 0, 0); ctx.restore();
      }
      y += h + 10;
    }
    const line = c.plain;
  const legend = [["zero", line ? "zero (bottom edge)" : "zero: unstable"],
    ["infinite", line ? "infinite (top edge)" : "infinite: stable"], ["missing", "not computed"]];
    ctx.textAlign = "left"; ctx.textBaseline = "middle";
    for (const [st, text] of legend) {
      if (!present[st]) continue;
      ctx.fillStyle = COLOURS[st]; ctx.fillRect(x0, y, w, 12);
      ctx.strokeStyle = "#9aa3b2"; ctx.strokeRect(x0 + 0.5, y + 0.5, w, 12);
      ctx.fillStyle = "#1d2433"; ctx.fillText(text, x0 + w + 6, y + 6); y += 18;
    }
  }

  function draw(canvas, fig) {
    const W = canvas.clientWidth || 680, H = canvas.clientHeight || 500;
    const dpr = window.devicePixelRatio || 1;
    canvas.width = Math.round(W * dpr); canvas.height = Math.round(H * dpr);
    const ctx = canvas.getContext("2d");
    ctx.setTransform(dpr, 0, 0, dpr, 0, 0);
    ctx.fillStyle = "#fff"; ctx.fillRect(0, 0, W, H);
    const box = { l: 78, t: 14, w: W - 78 - (fig.colour.si ? 190 : 150), h: H - 14 - 56 };
    if (fig.colour.si) box.l += 0;
    const present = {};
    let sx, sy, hit;
    if (fig.type === "grid") {
      const ex = edges(fig.x.values, fig.x.log), ey = edges(fig.y.values, fig.y.log);
      sx = scale(Math.min(ex[0], ex[ex.length - 1]), Math.max(ex[0], ex[ex.length - 1]), box.l, box.l + box.w, fig.x.log);
      sy = scale(Math.min(ey[0], ey[ey.length - 1]), Math.max(ey[0], ey[ey.length - 1]), box.t + box.h, box.t, fig.y.log);
      for (let i = 0; i < fig.x.values.length; i++) {
        for (let j = 0; j < fig.y.values.length; j++) {
          const c = fig.cell(i, j);
          present[c.state] = true;
          ctx.fillStyle = colourOf(fig.colour, c.state, c.v);
          const x0 = sx(ex[i]), x1 = sx(ex[i + 1]), y0 = sy(ey[j]), y1 = sy(ey[j + 1]);
          // whole device pixels: no seams between neighbouring cells
          const l = Math.floor(Math.min(x0, x1) * dpr) / dpr, r = Math.ceil(Math.max(x0, x1) * dpr) / dpr;
          const t = Math.floor(Math.min(y0, y1) * dpr) / dpr, b = Math.ceil(Math.max(y0, y1) * dpr) / dpr;
          ctx.fillRect(l, t, r - l, b - t);
        }
      }
      hit = (px, py) => {
        const i = ex.findIndex((e, k) => k < ex.length - 1 && (px - sx(e)) * (px - sx(ex[k + 1])) <= 0);
        const j = ey.findIndex((e, k) => k < ey.length - 1 && (py - sy(e)) * (py - sy(ey[k + 1])) <= 0);
        return i >= 0 && j >= 0 ? { i, j } : null;
      };
    } else {
      const pts = fig.points;
      const xr = range(pts.map(p => p.x), fig.x.log);
      const yr = range(pts.map(p => p.y), fig.y.log);
      const pad = (r, log) => log ? [r[0] / 1.15, r[1] * 1.15] : [r[0] - (r[1] - r[0]) * 0.04, r[1] + (r[1] - r[0]) * 0.04];
      const [x0, x1] = pad(xr, fig.x.log), [y0, y1] = pad(yr, fig.y.log);
      sx = scale(x0, x1, box.l, box.l + box.w, fig.x.log);
      sy = scale(y0, y1, box.t + box.h, box.t, fig.y.log);
      ctx.save();
      ctx.beginPath(); ctx.rect(box.l, box.t, box.w, box.h); ctx.clip();
      if (fig.type === "line") {
        ctx.strokeStyle = "#6b7488"; ctx.lineWidth = 1; ctx.beginPath();
        let on = false;
        for (const p of pts) {
          if (p.state !== "finite" || !Number.isFinite(p.y)) { on = false; continue; }
          if (on) ctx.lineTo(sx(p.x), sy(p.y)); else ctx.moveTo(sx(p.x), sy(p.y));
          on = true;
        }
        ctx.stroke();
      }
      const r = pts.length > 5000 ? 1.5 : pts.length > 500 ? 2.5 : 4;
      for (const p of pts) {
        present[p.state] = true;
        if (fig.type === "line" && p.state !== "finite" && Number.isFinite(p.x)) {
          // no value to plot: a square on the top edge (infinite) or the bottom edge
          const py = p.state === "infinite" ? box.t + r + 1 : box.t + box.h - r - 1;
          ctx.fillStyle = COLOURS[p.state] || COLOURS.missing;
          ctx.fillRect(sx(p.x) - r, py - r, 2 * r, 2 * r);
          ctx.strokeStyle = "#1d2433"; ctx.strokeRect(sx(p.x) - r, py - r, 2 * r, 2 * r);
          continue;
        }
        if (!Number.isFinite(p.x) || !Number.isFinite(p.y)) continue;
        ctx.fillStyle = colourOf(fig.colour, p.state, p.v);
        ctx.beginPath(); ctx.arc(sx(p.x), sy(p.y), r, 0, 2 * Math.PI); ctx.fill();
        if (p.state === "missing") { ctx.strokeStyle = "#9aa3b2"; ctx.stroke(); }
      }
      ctx.restore();
      hit = (px, py) => {
        let best = null, bd = 64;
        pts.forEach((p, k) => {
          const d = (sx(p.x) - px) ** 2 + (sy(p.y) - py) ** 2;
          if (d < bd) { bd = d; best = { k }; }
        });
        return best;
      };
    }
    axes(ctx, sx, sy, box, fig);
    colourBar(ctx, fig.colour, box, present);
    return hit;
  }

  return { draw, ticks, viridis, COLOURS };
})();
window.RsfPlot = RsfPlot;
