"""Key verification: the lean paths (:meth:`KeyStore.verify` on a pooled driver
connection, :meth:`KeyStore.verify_inline` on the event loop's own SQLite connection)
give the same answers as the SQLAlchemy path, and a revocation committed through
another database handle (another process's connections) is seen by the next call of
either, even with their connections already open."""

from __future__ import annotations

import sqlite3
from pathlib import Path

import pytest

from rsfapp.db.engine import Database
from rsfapp.store.keys import KeyStore, Scope, WouldBlock


def _stores(tmp_path: Path) -> tuple[KeyStore, KeyStore, Path]:
    """Two key stores on one SQLite file through separate engines (two 'processes')."""
    f = tmp_path / "k.sqlite3"
    return KeyStore(Database(f"sqlite:///{f}")), KeyStore(Database(f"sqlite:///{f}")), f


def test_lean_paths_agree_with_the_orm_path(tmp_path: Path) -> None:
    api, admin, _ = _stores(tmp_path)
    active = admin.create("a", Scope.submit, {"fresh_per_s": 2.5})
    revoked = admin.create("r", Scope.read)
    assert admin.revoke("r")
    for key, expect in (
        (active, ("a", Scope.submit, {"fresh_per_s": 2.5})),
        (revoked, None),
        ("rsf_" + "A" * 43, None),  # unknown
        ("", None),
        ("x" * 513, None),  # too long to be a key
        (active[:-1], None),  # one character short
    ):
        got = [api.verify(key), api.verify_inline(key)]
        for k in got:
            assert (None if k is None else (k.name, k.scope, k.quotas)) == expect, key
        assert got[0] == got[1]


def test_revocation_by_another_handle_is_seen_at_once(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    api, admin, _ = _stores(tmp_path)
    key = admin.create("short", Scope.read)
    assert api.verify(key) is not None  # the schema is known to exist from here

    def no_orm() -> None:
        raise AssertionError("the lean query should have answered")

    monkeypatch.setattr(api.db, "read", no_orm)  # the lean paths alone from here
    # both paths have their connections open and have answered before the revocation
    assert api.verify_inline(key) is not None and api.verify(key) is not None
    assert admin.revoke("short")
    assert api.verify_inline(key) is None
    assert api.verify(key) is None
    # and a key put back under that name (new hash) is seen at once too
    new = "rsf_" + "n" * 43
    assert admin.put("short", new, Scope.admin)
    v = api.verify_inline(new)
    assert v is not None and v.scope is Scope.admin
    assert api.verify_inline(key) is None


def test_inline_never_waits_for_a_locked_database(tmp_path: Path) -> None:
    """Another connection holding an exclusive lock makes the inline read give up at once
    (WouldBlock: the caller asks in a thread) instead of blocking the event loop.  (In WAL
    mode readers are never locked out, so the file is put in rollback-journal mode,
    where an exclusive write lock keeps every reader out.)"""
    api, admin, f = _stores(tmp_path)
    key = admin.create("k", Scope.read)
    admin.db.dispose()  # no other connection: the journal mode can be changed
    holder = sqlite3.connect(f, isolation_level=None)
    try:
        assert holder.execute("PRAGMA journal_mode=DELETE").fetchone()[0] == "delete"
        holder.execute("BEGIN EXCLUSIVE")
        holder.execute("UPDATE api_keys SET scope = scope")
        with pytest.raises(WouldBlock):
            api.verify_inline(key)
        holder.execute("ROLLBACK")
    finally:
        holder.close()
    k = api.verify_inline(key)  # a new connection once the lock is gone
    assert k is not None and k.name == "k"
    # what makes it give up at once rather than after a timeout
    assert api._inline_conn().execute("PRAGMA busy_timeout").fetchone()[0] == 0


def test_inline_defers_when_it_cannot_answer(tmp_path: Path) -> None:
    # no file yet: never created by the inline path; verify creates the schema
    missing = tmp_path / "new.sqlite3"
    ks = KeyStore(Database(f"sqlite:///{missing}"))
    with pytest.raises(WouldBlock):
        ks.verify_inline("rsf_" + "A" * 43)
    assert not missing.exists()
    assert ks.verify("rsf_" + "A" * 43) is None
    key = ks.create("k")
    assert ks.verify_inline(key) is not None
    # the connection in use by another thread: defer rather than wait for it
    assert ks._inline_lock.acquire()
    try:
        with pytest.raises(WouldBlock):
            ks.verify_inline(key)
    finally:
        ks._inline_lock.release()
    # a server database (network I/O): always deferred, without connecting (port 1)
    pytest.importorskip("psycopg")
    server = KeyStore(Database("postgresql+psycopg://rsf@127.0.0.1:1/rsf"))
    with pytest.raises(WouldBlock):
        server.verify_inline(key)


def test_inline_follows_a_disposed_engine(tmp_path: Path) -> None:
    """After ``Database.dispose`` (e.g. the file was replaced) the inline path opens a
    new connection, like the pool does: it reads the current file."""
    api, admin, f = _stores(tmp_path)
    key = admin.create("k", Scope.read)
    assert api.verify_inline(key) is not None
    f.unlink()
    for suffix in ("-wal", "-shm"):
        Path(f"{f}{suffix}").unlink(missing_ok=True)
    fresh = KeyStore(Database(f"sqlite:///{f}"))
    other = fresh.create("other", Scope.read)
    api.db.dispose()
    assert api.verify_inline(key) is None
    assert api.verify_inline(other) is not None
