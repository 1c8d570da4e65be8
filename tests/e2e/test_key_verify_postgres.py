"""Key verification on PostgreSQL: the lean query (plain SQL on a pooled driver
connection, ``%s`` parameters) gives the answers of the SQLAlchemy path, sees a
revocation made through another engine (another process or host) at once, never runs
on the event loop (network I/O), and still reports an unreachable server as the
database error the API answers 503.  SQLite version: tests/api/test_key_verify.py."""

from __future__ import annotations

import pytest
from sqlalchemy.exc import SQLAlchemyError

from rsfapp.db.engine import Database
from rsfapp.store.keys import KeyStore, Scope, WouldBlock
from tests.conftest import PgDatabase

pytestmark = [pytest.mark.e2e, pytest.mark.timeout(120)]


def test_lean_verify_on_postgres(postgres: PgDatabase, monkeypatch: pytest.MonkeyPatch) -> None:
    api, admin = KeyStore(Database(postgres.url)), KeyStore(Database(postgres.url))
    try:
        assert api.verify("rsf_" + "A" * 43) is None  # the lean query creates nothing:
        # it failed on the missing table and the SQLAlchemy path made the schema
        key = admin.create("pg", Scope.submit, {"points_per_day": 7})
        k = api.verify(key)
        assert k is not None and (k.name, k.scope, k.quotas) == (
            "pg",
            Scope.submit,
            {"points_per_day": 7},
        )
        with pytest.raises(WouldBlock):
            api.verify_inline(key)

        def no_orm() -> None:
            raise AssertionError("the lean query should have answered")

        monkeypatch.setattr(api.db, "read", no_orm)  # the lean path alone from here
        assert admin.revoke("pg")
        assert api.verify(key) is None  # the next call, same pooled connections
        assert api.verify(key[:-1]) is None
    finally:
        api.db.dispose()
        admin.db.dispose()


def test_unreachable_postgres_is_a_database_error() -> None:
    ks = KeyStore(Database("postgresql+psycopg://rsf@127.0.0.1:1/rsf", retry_s=0.1))
    with pytest.raises(SQLAlchemyError):
        ks.verify("rsf_" + "A" * 43)
