"""Plots of lab answers for the service's ``?format=png`` responses and the CLI.

* :func:`plot_protocol` -- a protocol answer (velocity step, slide-hold-slide, load
  history; the JSON dict of rsfapp.adapter.protocol_*): friction and slip rate against
  time, with the true per-segment peaks marked.
* :func:`plot_fit` -- a fit answer (rsfcore.fit FitResult.to_dict() or the service's
  fit JSON): data and fitted friction, residuals per step with each step's rms.

Each returns the encoded image (PNG by default, or SVG) as bytes.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from rsfcore import ParameterError

from ._common import figure_bytes, new_figure

__all__ = ["plot_protocol", "plot_fit"]


def _arr(v: Any) -> np.ndarray:
    """List (None for non-finite) -> float array with nan."""
    if v is None:
        return np.array([], dtype=float)
    return np.array([np.nan if x is None else x for x in v], dtype=float)


def plot_protocol(result: dict[str, Any], fmt: str = "png", *, dpi: int = 100) -> bytes:
    """Friction f(t) (top) and slip rate V(t) on a log axis (bottom) of a protocol answer,
    load-point velocity dashed, true peak friction of every segment marked."""
    prot = result.get("protocol", result)
    if "t_s" not in prot or "friction" not in prot:
        raise ParameterError("result", None, "a protocol answer with t_s and friction")
    t, f, v = _arr(prot["t_s"]), _arr(prot["friction"]), _arr(prot.get("V_m_s"))
    vo = _arr(prot.get("Vo_m_s"))
    fig = new_figure(8.0, 5.5)
    ax1, ax2 = fig.subplots(2, 1, sharex=True)
    ax1.plot(t, f, "k-", lw=1.1, label="friction")
    for s in prot.get("segments", []):
        if s.get("peak_friction") is not None and s.get("peak_friction_time_s") is not None:
            ax1.plot([s["peak_friction_time_s"]], [s["peak_friction"]], "rv", ms=5)
    ax1.set_ylabel("friction f (-)")
    ax1.plot([], [], "rv", ms=5, label="true peak per segment")
    ax1.legend(fontsize=7)
    pos = v > 0
    ax2.semilogy(t[pos], v[pos], "k-", lw=1.1, label="slip rate V")
    if vo.size == t.size and np.any(vo > 0):
        ax2.semilogy(
            t,
            np.where(vo > 0, vo, np.nan),
            "--",
            color="tab:blue",
            lw=0.9,
            label="load-point velocity (gap: hold)",
        )
    ax2.set_xlabel("t (s)")
    ax2.set_ylabel("V (m/s)")
    ax2.legend(fontsize=7)
    kind = result.get("kind", "protocol")
    fc = result.get("friction_changes") or {}
    extra = ""
    if fc.get("steady_state_delta_f") is not None:
        extra = (
            f"; df_ss = {fc['steady_state_delta_f']:.4g}, df_peak = {fc['peak_delta_f']:.4g}"
            if fc.get("peak_delta_f") is not None
            else f"; df_ss = {fc['steady_state_delta_f']:.4g}"
        )
    elif fc.get("healing_delta_f") is not None:
        extra = f"; healing df = {fc['healing_delta_f']:.4g}"
    if result.get("protocol", result).get("unstable"):
        extra += "; UNSTABLE (runaway)"
    fig.suptitle(f"{kind}{extra}", fontsize=9)
    return figure_bytes(fig, fmt, dpi)


def plot_fit(result: dict[str, Any], fmt: str = "png", *, dpi: int = 100) -> bytes:
    """Data and fitted friction against time (top) and the residuals (bottom) of a fit
    answer (rsfcore.fit FitResult.to_dict() with ``series`` {t_s, mu, model, residuals,
    [step, used]}): residuals coloured per step (constant-velocity segment) with each
    step's rms written at its start; samples outside the fitted windows / steps grey."""
    s = result.get("series") or {}
    t, mu, model = _arr(s.get("t_s")), _arr(s.get("mu")), _arr(s.get("model"))
    res = _arr(s.get("residuals")) if s.get("residuals") is not None else model - mu
    if not t.size or t.size != mu.size or mu.size != model.size:
        raise ParameterError("result", None, "a fit answer with series {t_s, mu, model}")
    step = np.asarray(s.get("step") or np.zeros(t.size), dtype=int)
    used = np.asarray(s["used"], dtype=bool) if s.get("used") is not None else np.ones(t.size, bool)
    if step.size != t.size or used.size != t.size:
        raise ParameterError("result", None, "series step/used of the length of t_s")
    fig = new_figure(8.0, 5.5)
    ax1, ax2 = fig.subplots(2, 1, sharex=True, gridspec_kw={"height_ratios": [3, 1.4]})
    ax1.plot(t, mu, ".", color="0.5", ms=2, label="data")
    ax1.plot(t, model, "r-", lw=1.1, label="fit")
    ax1.set_ylabel("friction mu (-)")
    ax1.legend(fontsize=7)
    colors = ("tab:blue", "tab:orange", "tab:green", "tab:purple", "tab:brown", "tab:cyan")
    if (~used).any():
        ax2.plot(t[~used], res[~used], ".", color="0.8", ms=2, label="not fitted")
    rms_by_step = {int(d["index"]): d.get("rms") for d in result.get("steps") or []}
    for j in np.unique(step):
        sel = (step == j) & used
        if not sel.any():
            continue
        ax2.plot(t[sel], res[sel], ".", color=colors[int(j) % len(colors)], ms=2)
        rms = rms_by_step.get(int(j))
        if rms is None:
            r = res[sel][np.isfinite(res[sel])]
            rms = float(np.sqrt(np.mean(r**2))) if r.size else None
        if rms is not None:
            ax2.annotate(
                f"#{int(j)} rms {rms:.2g}",
                (float(t[sel][0]), 1.0),
                xycoords=("data", "axes fraction"),
                va="top",
                fontsize=6,
                color=colors[int(j) % len(colors)],
            )
    ax2.axhline(0.0, color="r", lw=0.8)
    ax2.set_ylabel("model - data")
    ax2.set_xlabel("t (s)")
    p = result.get("params", {})
    txt = ", ".join(
        f"{k}={v:.4g}"
        for k, v in p.items()
        if k in ("mu0", "a", "b", "Dc_m", "eps", "k_per_m", "trend_per_m")
        and isinstance(v, (int, float))
        and (k != "trend_per_m" or k in (result.get("fitted") or ()))
    )
    fig.suptitle(f"{result.get('law', '')} law ({result.get('status', '')}): {txt}", fontsize=9)
    return figure_bytes(fig, fmt, dpi)
