"""Fits of lab records (POST /v1/fits, worker.tasks.fit_record; rsfcore.fit, imported
lazily: it pulls in scipy.optimize)."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from rsfcore.jsonsafe import jsonsafe
from rsfcore.params import ParameterError

from ..metrics import timed_fit
from ..requests.fits import FIT_LAWS, FitRequest
from ._common import ComputeError, guard, json_dict

__all__ = ["FIT_COLUMNS", "fit", "fit_key_request", "fit_record_of", "fit_table"]


def fit_record_of(req: FitRequest) -> Any:
    """The request's record parsed by rsfcore.fit.read_record (ParameterError naming
    ``record`` and what is wrong)."""
    from rsfcore import fit as _fit

    try:
        return guard(
            _fit.read_record,
            req.record,
            columns=req.columns,
            decimal=req.decimal,
            smooth=req.smooth,
        )
    except ParameterError as exc:
        if exc.field.startswith("record"):
            raise
        raise ParameterError(f"record.{exc.field}", exc.value, exc.valid) from None


def fit_key_request(req: FitRequest) -> dict[str, Any]:
    """What identifies a fit: the record's content hash and the options (cache key)."""
    return {"record_sha256": fit_record_of(req).digest(), **req.options()}


def fit(req: FitRequest, progress: Callable[[str], None] | None = None) -> dict[str, Any]:
    """Fit the record (rsfcore.fit): the reported law's FitResult.to_dict() (params,
    stderr, residuals and series, misfit, stability answer in SI with uncertainty), plus
    ``law_comparison`` (misfit and information criteria per law; laws other than the
    requested or best one stop once their rejection is certain: ``stopped_early``, see
    rsfcore.fit.compare_laws ``complete``) when ``compare`` and
    ``posterior`` (emcee) when asked.  ``progress`` is told each stage as it starts.
    Counted and timed in ``rsf_fits_total`` / ``rsf_fit_duration_seconds``."""
    with timed_fit():
        return _fit(req, progress)


def _fit(req: FitRequest, progress: Callable[[str], None] | None) -> dict[str, Any]:
    from rsfcore import fit as _fit

    def stage(text: str) -> None:
        if progress is not None:
            progress(text)

    stage("reading the record")
    rec = fit_record_of(req)
    opts: dict[str, Any] = {
        **req.stiffness_options(),
        "trend": req.trend,
        "windows": req.windows,
        "steps": req.steps,
        "time_budget_s": req.time_budget_s,
        "nagata_c": req.nagata_c,
        "rtol": req.rtol,
        "uncertainty_samples": req.uncertainty_samples,
        "seed": req.seed,
    }
    comparison: dict[str, Any] | None = None
    if req.compare:
        stage(f"fitting {rec.n} samples with each law ({', '.join(FIT_LAWS)})")
        # the requested law is fitted completely; the others (apart from the best, which
        # is never rejected) stop once the comparison's rejection is certain
        complete = (req.law,) if req.law else ()
        cmp = guard(_fit.compare_laws, rec, laws=FIT_LAWS, complete=complete, **opts)
        law = req.law or cmp.best or (req.law or "aging")
        res = cmp.fits[law]
        if res.status in _fit.STABILITY_STATUSES and res.stability is None:
            stage("stability answer with uncertainty")
            guard(
                _fit.attach_stability,
                res,
                uncertainty_samples=req.uncertainty_samples,
                seed=req.seed,
            )
        comparison = {
            "best": cmp.best,
            "misfit_floor": cmp.misfit_floor,
            "scores": [s.to_dict() for s in cmp.scores],
            "params": {k: f.params for k, f in cmp.fits.items()},
            "stderr": {k: f.stderr for k, f in cmp.fits.items()},
            "status": {k: f.status.value for k, f in cmp.fits.items()},
            "stopped_early": {k: f.stopped_early for k, f in cmp.fits.items()},
        }
    else:
        assert req.law is not None
        stage(f"fitting {rec.n} samples ({req.law} law) and the stability answer")
        res = guard(_fit.fit_record, rec, req.law, **opts)
    out = res.to_dict(series=True)
    out["posterior"] = None
    if req.posterior is not None:
        po = req.posterior
        stage(f"posterior: {po.n_walkers} walkers x {po.n_steps} steps (emcee)")
        try:
            post = guard(
                _fit.sample_posterior,
                res,
                n_walkers=po.n_walkers,
                n_steps=po.n_steps,
                burn=po.burn,
                thin=po.thin,
                seed=req.seed,
                stability_samples=req.uncertainty_samples,
            )
            out["posterior"] = post.to_dict()
        except (ParameterError, ComputeError, ImportError) as exc:
            out["posterior"] = {"error": str(exc)}
    out["law_comparison"] = jsonsafe(comparison)
    out["options"] = req.options()
    return json_dict(out)


#: Columns of a fit's CSV (data, model, residuals, the sample's step and whether it was used).
FIT_COLUMNS = ("t_s", "v_lp_m_s", "mu", "model", "residuals", "step", "used")


def fit_table(result: dict[str, Any]) -> dict[str, list[Any]]:
    """The series of a fit answer as columns (FIT_COLUMNS)."""
    s = result.get("series") or {}
    return {k: s[k] for k in FIT_COLUMNS if k in s and s[k] is not None}
