"""Alembic migrations (issue 25, item 6), on SQLite and PostgreSQL.

* a database made by release 0.1.0's code path (tests/data/legacy_db_010.py, its tables
  and schema creation frozen) upgrades to head and keeps every row, and 0.1.0 would then
  refuse it (``rsf_schema.version`` > 1);
* the revisions at head build exactly the tables of the code (Alembic's own comparison),
  so a change of rsfapp/db/tables.py without a revision fails here;
* a database at a revision newer than the code is refused, unchanged, naming the command;
* ``rsf db current`` / ``rsf db upgrade`` say and do the same.
"""

from __future__ import annotations

import importlib.util
import json
from collections.abc import Iterator
from pathlib import Path

import pytest
from alembic.autogenerate import compare_metadata
from alembic.runtime.migration import MigrationContext
from sqlalchemy import select, text
from typer.testing import CliRunner

from rsfapp.db import migrate, ops
from rsfapp.db.engine import Database, SchemaTooNew, diagnose
from rsfapp.db.tables import metadata
from rsfapp.store.results import ResultStore

_LEGACY = Path(__file__).resolve().parents[1] / "data" / "legacy_db_010.py"


def _legacy() -> object:
    spec = importlib.util.spec_from_file_location("legacy_db_010", _LEGACY)
    assert spec and spec.loader
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


@pytest.fixture(
    params=["sqlite", pytest.param("postgresql", marks=pytest.mark.e2e)],
)
def url(request: pytest.FixtureRequest, tmp_path: Path) -> Iterator[str]:
    if request.param == "sqlite":
        yield f"sqlite:///{tmp_path / 'rsf.db'}"
    else:
        pg = request.getfixturevalue("postgres")
        yield pg.url


def test_a_010_database_upgrades_and_keeps_its_rows(url: str) -> None:
    old: object = _legacy()
    db = Database(url)
    with db.writer.begin() as conn:
        old.create_010(conn)  # type: ignore[attr-defined]
        conn.execute(
            old.results.insert().values(  # type: ignore[attr-defined]
                key="k" * 64,
                kind="critical",
                numerics_version="4",
                request="{}",
                result='{"critical_size": 2.5}',
                created_at=1.0,
            )
        )
        conn.execute(
            old.sweeps.insert().values(  # type: ignore[attr-defined]
                id="s1",
                spec="{}",
                status="done",
                n_total=4,
                n_chunks=1,
                numerics_version="4",
                created_at=2.0,
            )
        )
        conn.execute(
            old.sweep_blocks.insert().values(  # type: ignore[attr-defined]
                sweep_id="s1", idx=0, i0=0, i1=4, n_failed=1, data=b"\x00npz", created_at=3.0
            )
        )
        conn.execute(
            old.chunks.insert().values(  # type: ignore[attr-defined]
                sweep_id="s1", idx=0, i0=0, i1=4, status="done", attempts=1
            )
        )
        conn.execute(
            old.api_keys.insert().values(  # type: ignore[attr-defined]
                name="lab", key_hash="h" * 64, scope="admin", quotas="{}", created_at=4.0
            )
        )
    assert db.schema_version() is None  # 0.1.0 kept no Alembic revision

    assert db.ensure_schema() is None
    assert db.schema_version() == migrate.head()
    with db.read() as conn:
        assert conn.execute(select(ops.schema.c.version)).scalar() == migrate.LEGACY_MARK > 1
        assert conn.execute(text("SELECT result FROM results")).scalar() == (
            '{"critical_size": 2.5}'
        )
        assert conn.execute(text("SELECT status, n_total FROM sweeps")).one() == ("done", 4)
        # revision 0004 filled the progress counters from the rows already stored
        assert conn.execute(
            text("SELECT chunks_done, points_done, points_failed FROM sweeps")
        ).one() == (1, 4, 1)
        assert conn.execute(text("SELECT data FROM sweep_blocks")).scalar() == b"\x00npz"
        assert conn.execute(text("SELECT scope FROM api_keys")).scalar() == "admin"
    with db.reader.connect() as conn:  # the upgraded tables are those of the code
        ctx = MigrationContext.configure(conn, opts={"compare_type": migrate.compare_type})
        assert compare_metadata(ctx, metadata) == []
    # the application reads the upgraded rows through its stores
    assert ResultStore(db).get("k" * 64) is not None
    # and starting again changes nothing
    assert db.ensure_schema() == migrate.head()
    db.dispose()


def test_revisions_at_head_build_the_tables_of_the_code(url: str) -> None:
    db = Database(url)
    assert db.ensure_schema() is None
    with db.reader.connect() as conn:
        diff = compare_metadata(
            MigrationContext.configure(conn, opts={"compare_type": migrate.compare_type}), metadata
        )
    db.dispose()
    assert diff == [], (
        "rsfapp/db/tables.py (or ops.py) differs from the Alembic revisions; write one with "
        f"`rsf db revision -m '...'` and review it: {diff}"
    )


def test_a_newer_database_is_refused_unchanged(url: str) -> None:
    db = Database(url)
    db.ensure_schema()
    with db.writer.begin() as conn:
        conn.execute(text("UPDATE alembic_version SET version_num = '9999'"))
    fresh = Database(url)  # another process, newer database
    with pytest.raises(SchemaTooNew, match="9999 is newer than this code's"):
        fresh.ensure_schema()
    assert fresh.schema_version() == "9999"
    try:
        fresh.ensure_schema()
    except SchemaTooNew as exc:
        p = diagnose(exc, url)
    assert p is not None and p.kind == "schema"
    assert "pip install -U" in p.hint and "rsf db current" in p.reason
    db.dispose()
    fresh.dispose()


def test_rsf_db_commands(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    from rsfcli.main import app

    monkeypatch.delenv("RSF_CACHE_URL", raising=False)
    runner = CliRunner()
    d = str(tmp_path / "data")
    r = runner.invoke(app, ["db", "current", "--data-dir", d, "--json"])
    assert r.exit_code == 1, r.output
    assert json.loads(r.stdout) == {"current": None, "head": migrate.head(), "state": "not created"}
    r = runner.invoke(app, ["db", "upgrade", "--data-dir", d])
    assert r.exit_code == 0 and f"-> {migrate.head()}" in r.stdout, r.output
    r = runner.invoke(app, ["db", "current", "--data-dir", d])
    assert r.exit_code == 0 and "up to date" in r.stdout, r.output
    r = runner.invoke(app, ["db", "history", "--json"])
    assert [x["id"] for x in json.loads(r.stdout)][0] == "0001"


def test_key_usage_holds_more_than_2_31_points(url: str) -> None:
    """``key_usage.points`` is BIGINT at head (revision 0003): a day's usage beyond 2^31
    points is counted exactly (PostgreSQL's INTEGER fails with 'integer out of range')."""
    from rsfapp.store.keys import KeyStore

    db = Database(url)
    db.ensure_schema()
    keys = KeyStore(db)
    big = 3 * 10**9
    assert keys.reserve_points("lab", big, 10 * big, day=1) == 9 * big
    assert keys.reserve_points("lab", big, 10 * big, day=1) == 8 * big
    assert keys.points_used("lab", day=1) == 2 * big > 2**31
    keys.refund_points("lab", big, day=1)
    assert keys.points_used("lab", day=1) == big
    db.dispose()
