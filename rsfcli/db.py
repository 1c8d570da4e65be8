"""`rsf db`: the schema of the application database (Alembic revisions).

Every rsf process upgrades the database to its own revision at first use; `rsf db
upgrade` does it by hand (e.g. before starting a new release on several hosts), `rsf db
current` says where a database is, and `rsf db revision` writes a new revision after a
change of the tables (developers).  The database is the deployment's (``--data-dir`` or
the ``RSF_*`` settings, as `rsf serve` finds it).
"""

from __future__ import annotations

import json
import os
import tempfile
from pathlib import Path
from typing import Any

import typer

__all__ = ["app"]

app = typer.Typer(
    rich_markup_mode=None,
    name="db",
    help="Database schema: upgrade, current revision, history, new revision.",
    no_args_is_help=True,
)

DATA_DIR = typer.Option(
    None,
    "--data-dir",
    help="Data directory of the deployment (default: RSF_DATA_DIR, else ./rsf-data); "
    "RSF_CACHE_URL selects another database.",
)
JSON = typer.Option(False, "--json", help="Print one JSON object.")


def _database(data_dir: Path | None) -> Any:
    if data_dir is not None:
        os.environ["RSF_DATA_DIR"] = str(Path(data_dir).expanduser().resolve())
    from rsfapp.config import get_settings
    from rsfapp.db.engine import database

    return database(get_settings().effective_cache_url)


def _fail(exc: BaseException, url: str) -> None:
    from rsfapp.db.engine import diagnose

    p = diagnose(exc, url)
    if p is None:
        raise exc
    typer.echo(f"error: {p.reason}\nhow to recover: {p.hint}", err=True)
    raise typer.Exit(code=1)


@app.command()
def current(data_dir: Path | None = DATA_DIR, as_json: bool = JSON) -> None:
    """The database's schema revision and this code's (exit 1 if they differ)."""
    from rsfapp.db import migrate

    db = _database(data_dir)
    try:
        rev = db.schema_version()
    except Exception as exc:  # noqa: BLE001 - a message, not a traceback
        _fail(exc, db.url)
    head = migrate.head()
    state = "up to date" if rev == head else ("not created" if rev is None else "differs")
    if as_json:
        typer.echo(json.dumps({"current": rev, "head": head, "state": state}))
    else:
        typer.echo(f"database: {rev or '-'}  code: {head}  ({state})")
        if rev != head:
            typer.echo("run `rsf db upgrade` (or start any rsf process) to upgrade", err=True)
    if rev != head:
        raise typer.Exit(code=1)


@app.command()
def upgrade(data_dir: Path | None = DATA_DIR) -> None:
    """Create or upgrade the schema to this code's revision (keeps every row)."""
    from rsfapp.db import migrate

    db = _database(data_dir)
    try:
        before = db.ensure_schema()
    except Exception as exc:  # noqa: BLE001
        _fail(exc, db.url)
    head = migrate.head()
    if before == head:
        typer.echo(f"already at {head}")
    else:
        typer.echo(f"upgraded {before or '(new or 0.1.0)'} -> {head}")


@app.command()
def history(as_json: bool = JSON) -> None:
    """The revisions this code knows, oldest first."""
    from rsfapp.db import migrate

    revs = migrate.history()
    if as_json:
        typer.echo(json.dumps([r._asdict() for r in revs]))
        return
    for r in revs:
        typer.echo(f"{r.id}  {r.message}")


@app.command()
def revision(
    message: str = typer.Option(..., "-m", "--message", help="What the revision changes."),
) -> None:
    """Write a new revision from the difference between the tables (rsfapp/db/tables.py,
    ops.py) and a database at head (developers; review the file before committing)."""
    from alembic import command

    from rsfapp.db import migrate
    from rsfapp.db.engine import Database

    nxt = f"{int(migrate.head()) + 1:04d}"
    with tempfile.TemporaryDirectory() as d:
        db = Database(f"sqlite:///{d}/head.db")
        db.ensure_schema()
        with db.writer.begin() as conn:
            command.revision(migrate.config(conn), message=message, autogenerate=True, rev_id=nxt)
        db.dispose()
    typer.echo(f"wrote revision {nxt}: rsfapp/db/migrations/versions/ (review it)")
