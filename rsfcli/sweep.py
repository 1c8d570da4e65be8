"""`rsf sweep`: submit a sweep to a running service, follow it, download its result.

    rsf sweep submit spec.json [--wait]      # prints the sweep id (and waits with a bar)
    rsf sweep status ID                      # status, progress, ETA, first failures
    rsf sweep download ID -o result.nc       # NetCDF (.nc), CSV (.csv) or JSON (.json)
    rsf sweep cancel ID [--purge]

The spec file is the JSON body of ``POST /v1/sweeps`` (``axes``, ``points`` or ``x``/``y``,
with ``fixed``, ``perturbation``, ``rtol``); in lab units: the machine as
``fixed.physical`` and the perturbation size as ``factor``, ``new_slip_rate_m_s`` or
``new_load_point_velocity_m_s`` (fixed or swept; docs/lab-api.md).  A CSV download of such
a sweep has the critical size in m/s too.  ``--url`` (or RSF_URL) names the service,
``--api-key`` (or RSF_API_KEY) its key when one is required.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path
from typing import Any

import typer

__all__ = ["app"]

app = typer.Typer(
    rich_markup_mode=None,  # help texts carry units in brackets ([m], [s]), not markup
    help="Sweeps on a running service (rsf serve / rsf api): submit, follow, download.",
    no_args_is_help=True,
)

_URL = typer.Option(
    "http://127.0.0.1:8000", "--url", envvar="RSF_URL", help="Base URL of the service."
)
_KEY = typer.Option(
    None, "--api-key", envvar="RSF_API_KEY", help="API key (sent as 'Authorization: Bearer <key>')."
)


def _client(url: str, key: str | None) -> Any:
    from rsfclient import Client

    return Client(url, api_key=key)


def _fail(exc: Exception) -> None:
    typer.echo(f"error: {exc}", err=True)
    raise typer.Exit(2)


@app.command("submit")
def submit(
    spec: Path = typer.Argument(
        ..., exists=True, dir_okay=False, help="JSON file with the POST /v1/sweeps body."
    ),
    wait: bool = typer.Option(
        False, "--wait", help="Wait for the sweep to finish, with a progress bar."
    ),
    url: str = _URL,
    api_key: str | None = _KEY,
) -> None:
    """Submit the sweep in SPEC; prints its id (the same spec always gives the same id)."""
    from rsfclient import RsfError

    try:
        body = json.loads(spec.read_text())
    except (OSError, ValueError) as exc:
        _fail(exc)
    with _client(url, api_key) as c:
        try:
            s = c.sweep(body)
            what = (
                "resumed"
                if s.resumed
                else "created"
                if s.last.get("created")
                else s.last.get("status")
            )
            typer.echo(s.id)
            typer.echo(
                f"{what}: {s.last['n_total']} points in {s.last['n_chunks']} chunks", err=True
            )
            if wait:
                st = s.wait(progress=True)
                typer.echo(f"done: {st['n_done']} points, {st['n_failed']} failed", err=True)
        except (RsfError, TimeoutError) as exc:
            _fail(exc)


@app.command("status")
def status(
    sweep_id: str = typer.Argument(..., help="Sweep id (32 hex)."),
    as_json: bool = typer.Option(False, "--json", help="Print the status JSON."),
    url: str = _URL,
    api_key: str | None = _KEY,
) -> None:
    """Status, progress, ETA and the first failures of a sweep."""
    from rsfclient import RsfError

    with _client(url, api_key) as c:
        try:
            st = c.get_sweep(sweep_id).last.to_dict()
        except RsfError as exc:
            _fail(exc)
    if as_json:
        typer.echo(json.dumps(st, indent=2))
        return
    eta = st.get("eta_s")
    dims = " x ".join(f"{d['name']}[{d['n']}]" for d in st.get("dims", []))
    typer.echo(
        f"{st['id']}  {st['status']}  {st['n_done']}/{st['n_total']} points  "
        f"{st['n_failed']} failed  eta {'-' if eta is None else f'{eta:.1f} s'}"
    )
    typer.echo(f"  {dims}  output={st.get('output')}  fixed={st.get('fixed')}")
    typer.echo(
        f"  created {st.get('created_at')}  started {st.get('started_at')}  "
        f"finished {st.get('finished_at')}"
    )
    for f in st.get("failures", [])[:10]:
        typer.echo(f"  failed idx {f['idx']} {f.get('params')}: {f['error']}")


@app.command("download")
def download(
    sweep_id: str = typer.Argument(..., help="Sweep id (32 hex)."),
    output: Path = typer.Option(
        ..., "-o", "--output", help="File to write: .nc (NetCDF), .csv or .json."
    ),
    url: str = _URL,
    api_key: str | None = _KEY,
) -> None:
    """Download the whole result (also of a running sweep: missing points are NaN)."""
    from rsfclient import RsfError

    with _client(url, api_key) as c:
        try:
            p = c.get_sweep(sweep_id).download(output, progress=sys.stderr.isatty())
        except RsfError as exc:
            _fail(exc)
    typer.echo(f"wrote {p} ({p.stat().st_size} bytes)", err=True)


@app.command("cancel")
def cancel(
    sweep_id: str = typer.Argument(..., help="Sweep id (32 hex)."),
    purge: bool = typer.Option(False, "--purge", help="Delete the sweep and its data."),
    url: str = _URL,
    api_key: str | None = _KEY,
) -> None:
    """Cancel a sweep (re-submitting resumes it), or delete it with --purge."""
    from rsfclient import RsfError

    with _client(url, api_key) as c:
        try:
            s = c.get_sweep(sweep_id)
            if purge:
                s.delete()
                typer.echo("deleted", err=True)
            else:
                st = s.cancel()
                typer.echo(f"{st['status']} (changed: {str(st['changed']).lower()})", err=True)
        except RsfError as exc:
            _fail(exc)
