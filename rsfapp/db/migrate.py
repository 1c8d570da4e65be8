"""Schema migrations with Alembic: the revisions in :mod:`rsfapp.db.migrations` create
and upgrade the database (``rsf db upgrade``, ``rsf db current``; every process also
upgrades at its first use of the database, under a lock).

Legacy marker: release 0.1.0 recorded its schema as ``rsf_schema.version`` = 1 (later
hand-migrated builds 2) and refuses a database whose number is higher; a database
upgraded here has :data:`LEGACY_MARK` there, so such a process that meets it stops with
its "newer than this code" message instead of writing to a schema it does not know.
"""

from __future__ import annotations

import time
from functools import lru_cache
from pathlib import Path
from typing import Any, NamedTuple

from alembic import command
from alembic.config import Config
from alembic.runtime.migration import MigrationContext
from alembic.script import ScriptDirectory
from sqlalchemy import Connection, select
from sqlalchemy import types as sa_types

from . import ops

__all__ = [
    "LEGACY_MARK",
    "compare_type",
    "Revision",
    "SchemaTooNew",
    "config",
    "current",
    "head",
    "history",
    "too_new",
    "upgrade",
]

#: ``rsf_schema.version`` of a database managed by Alembic (0.1.0 wrote 1 and refuses > 1;
#: builds between 0.1.0 and Alembic wrote 2 and refuse > 2).
LEGACY_MARK = 3
_HERE = Path(__file__).resolve().parent / "migrations"


class SchemaTooNew(RuntimeError):
    """The database was written by a newer version of this software."""


class Revision(NamedTuple):
    """One revision: its id, the one it follows (None for the base) and its message."""

    id: str
    down: str | None
    message: str


def compare_type(
    context: Any, inspected: Any, column: Any, inspected_type: Any, metadata_type: Any
) -> bool | None:
    """Alembic's type comparison, except that INTEGER and BIGINT are one type on SQLite
    (both 64-bit there; revision 0002 widens them on PostgreSQL only)."""
    if context.dialect.name == "sqlite":
        ints = (sa_types.Integer, sa_types.BigInteger)
        if isinstance(inspected_type, ints) and isinstance(metadata_type, ints):
            return False
    return None


def config(conn: Connection | None = None) -> Config:
    """Alembic's configuration of this package (no alembic.ini), on ``conn``."""
    cfg = Config()
    cfg.set_main_option("script_location", str(_HERE))
    cfg.set_main_option("file_template", "v%%(rev)s_%%(slug)s")  # importable module names
    cfg.attributes["connection"] = conn
    return cfg


@lru_cache(maxsize=1)
def _script() -> ScriptDirectory:
    return ScriptDirectory.from_config(config())


def head() -> str:
    """The newest revision this code knows (the schema it writes)."""
    h = _script().get_current_head()
    assert h is not None
    return h


def history() -> list[Revision]:
    """Every revision, oldest first."""
    revs = list(_script().walk_revisions())
    return [
        Revision(r.revision, r.down_revision if isinstance(r.down_revision, str) else None, r.doc)
        for r in reversed(revs)
    ]


def current(conn: Connection) -> str | None:
    """The revision the database is at (None: not managed by Alembic yet)."""
    return MigrationContext.configure(conn).get_current_revision()


def upgrade(conn: Connection) -> str | None:
    """Upgrade the database on ``conn`` to :func:`head` inside the caller's transaction;
    returns the revision found before (None: new, or made by 0.1.0).

    Raises :class:`SchemaTooNew` (nothing changed) when the database is at a revision
    this code does not know."""
    before = current(conn)
    if before == head():
        return before
    if before is not None and before not in {r.revision for r in _script().walk_revisions()}:
        raise too_new(before)
    command.upgrade(config(conn), "head")
    _mark_legacy(conn)
    return before


def too_new(rev: str) -> SchemaTooNew:
    """The error for a database at an unknown (newer) revision ``rev``."""
    return SchemaTooNew(
        f"database schema revision {rev} is newer than this code's ({head()}); "
        "`rsf db current` shows both"
    )


def _mark_legacy(conn: Connection) -> None:
    t = ops.schema
    row = {"version": LEGACY_MARK, "updated_at": time.time()}
    if conn.execute(select(t.c.id).where(t.c.id == 1)).first() is None:
        conn.execute(t.insert().values(id=1, **row))
    else:
        conn.execute(t.update().where(t.c.id == 1).values(**row))
