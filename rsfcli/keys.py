"""`rsf keys`: create, list and revoke the API keys of a deployment, and the check that
keeps `rsf serve` / `rsf api` off the network without a key.

The keys live in the application database of the deployment (``--data-dir`` or the
``RSF_*`` settings, exactly as `rsf serve` finds it), stored only as SHA-256 hashes.
A new key is printed once, on stdout (alone, so ``KEY=$(rsf keys create ...)`` works).
"""

from __future__ import annotations

import ipaddress
import json
import os
import sys
import time
from pathlib import Path
from typing import Any

import typer

__all__ = ["app", "check_bind", "is_loopback"]

app = typer.Typer(
    rich_markup_mode=None,  # help texts carry units in brackets ([m], [s]), not markup
    name="keys",
    help="API keys: create (shown once), list, revoke.",
    no_args_is_help=True,
)

DATA_DIR = typer.Option(
    None,
    "--data-dir",
    help="Data directory of the deployment (default: "
    "RSF_DATA_DIR, else ./rsf-data); RSF_CACHE_URL selects another database.",
)


def _store(data_dir: Path | None) -> Any:
    if data_dir is not None:
        os.environ["RSF_DATA_DIR"] = str(Path(data_dir).expanduser().resolve())
    from rsfapp.config import get_settings
    from rsfapp.db.engine import database
    from rsfapp.store.keys import KeyStore

    return KeyStore(database(get_settings().effective_cache_url))


def _fail(msg: str) -> None:
    typer.echo(f"error: {msg}", err=True)
    raise typer.Exit(code=2)


@app.command()
def create(
    name: str = typer.Option(
        ...,
        "--name",
        help="Unique name of the key (1-64 of letters, digits, '.', '_', '-'); never reused.",
    ),
    scope: str = typer.Option(
        "read",
        "--scope",
        help="read (every single query, cached "
        "results, sweeps), submit (+ submit sweeps, batch, long jobs, "
        "cancel its own sweeps) or admin (everything).",
    ),
    quota: list[str] = typer.Option(
        [],
        "--quota",
        help="Per-key quota NAME=VALUE, repeatable: "
        "concurrent_sweeps, points_per_day, fresh_per_s, "
        "concurrent_requests, trajectory_points, step_budget.",
    ),
    from_env: str | None = typer.Option(
        None,
        "--from-env",
        help="Store the key held in "
        "this environment variable instead of a random "
        "one (replaces the key of that name; for "
        "containers).",
    ),
    data_dir: Path | None = DATA_DIR,
) -> None:
    """Create an API key and print it (once: only its hash is stored)."""
    from rsfapp.store.keys import KeyStoreError, Scope, validate_quota

    try:
        sc = Scope(scope)
    except ValueError:
        _fail(f"--scope: {scope!r} is not one of read, submit, admin")
    quotas: dict[str, Any] = {}
    for q in quota:
        k, sep, v = q.partition("=")
        if not sep:
            _fail(f"--quota: {q!r} is not NAME=VALUE")
        try:
            quotas[k.strip()] = validate_quota(k.strip(), v.strip())
        except ValueError as exc:
            _fail(f"--quota: {exc}")
    ks = _store(data_dir)
    try:
        if from_env is not None:
            key = os.environ.get(from_env, "")
            if not key:
                _fail(f"--from-env: environment variable {from_env} is empty or unset")
            changed = ks.put(name, key, sc)
            typer.echo(
                f"key {name!r} ({sc.value}) {'stored' if changed else 'unchanged'} "
                f"from ${from_env}",
                err=True,
            )
            return
        key = ks.create(name, sc, quotas)
    except KeyStoreError as exc:
        _fail(str(exc))
    typer.echo(key)
    typer.echo(
        f"key {name!r} ({sc.value}) created: shown once, keep it; send it as "
        "'Authorization: Bearer <key>' (RSF_API_KEY for the client).",
        err=True,
    )


@app.command("list")
def list_keys(
    as_json: bool = typer.Option(False, "--json", help="Print one JSON object."),
    data_dir: Path | None = DATA_DIR,
) -> None:
    """List the keys: name, scope, created, revoked, quota overrides (never the keys)."""
    keys = _store(data_dir).list_keys()
    rows = [
        {
            "name": k.name,
            "scope": k.scope.value,
            "created_at": k.created_at,
            "revoked_at": k.revoked_at,
            "active": k.active,
            "quotas": k.quotas,
        }
        for k in keys
    ]
    if as_json:
        typer.echo(json.dumps({"keys": rows}))
        return
    if not rows:
        typer.echo("no keys")
        return

    def t(x: float | None) -> str:
        return "-" if x is None else time.strftime("%Y-%m-%d %H:%M", time.gmtime(x))

    typer.echo(f"{'NAME':24} {'SCOPE':7} {'CREATED (UTC)':17} {'REVOKED':17} QUOTAS")
    for r in rows:
        q = ",".join(f"{k}={v}" for k, v in sorted(r["quotas"].items())) or "-"
        typer.echo(
            f"{r['name']:24} {r['scope']:7} {t(r['created_at']):17} {t(r['revoked_at']):17} {q}"
        )


@app.command()
def revoke(
    name: str = typer.Argument(..., help="Name of the key to revoke."),
    data_dir: Path | None = DATA_DIR,
) -> None:
    """Revoke a key: refused from the next request on."""
    from rsfapp.store.keys import KeyStoreError

    try:
        changed = _store(data_dir).revoke(name)
    except KeyStoreError as exc:
        _fail(str(exc))
    typer.echo(f"key {name!r} {'revoked' if changed else 'was already revoked'}")


def is_loopback(host: str) -> bool:
    """True for 127.0.0.0/8, ::1 and 'localhost'."""
    if host.strip("[]").lower() == "localhost":
        return True
    try:
        return ipaddress.ip_address(host.strip("[]")).is_loopback
    except ValueError:
        return False


def check_bind(host: str, what: str = "rsf serve") -> None:
    """Refuse (exit 2) to serve on a non-loopback ``host`` while no API key exists,
    unless RSF_AUTH=off (``--insecure``); print how clients authenticate."""
    from rsfapp.config import get_settings

    s = get_settings()

    def say(m: str) -> None:
        print(f"[{what}] {m}", file=sys.stderr)

    if s.auth == "off":
        say(
            "RSF_AUTH=off (--insecure): no API keys; anyone who can reach this port may "
            "submit and cancel sweeps and read every result"
        )
        return
    loop = is_loopback(host)
    n = sum(k.active for k in _store(None).list_keys())
    if n:
        say(
            f"API keys required ({n} active): send 'Authorization: Bearer <key>'; "
            "the dashboard asks for the key once per browser session"
        )
        return
    if loop:
        say(
            "no API key: serving requests without a key on loopback only "
            + (
                "(RSF_AUTH=on: every request will be refused until a key exists; "
                "'rsf keys create --name NAME')"
                if s.auth == "on"
                else "('rsf keys create --name NAME' to require keys)"
            )
        )
        return
    typer.echo(
        f"error: refusing to serve on {host}, a non-loopback interface, without an API "
        "key: anyone on the network could submit sweeps, cancel them and read every "
        "result.  Create one with 'rsf keys create --name NAME --scope admin' (same "
        "--data-dir / RSF_* settings), or pass --insecure (RSF_AUTH=off) to serve "
        "without keys.",
        err=True,
    )
    raise typer.Exit(code=2)
