"""Alembic revisions of the application database (run by :mod:`rsfapp.db.migrate`).

``env.py`` is Alembic's environment script, ``versions/`` the revisions, oldest first:
``0001`` is the schema of release 0.1.0 (the last one migrated by hand), created table by
table where missing, so a database made by that release upgrades in place.  A change of
:mod:`rsfapp.db.tables` or :mod:`rsfapp.db.ops` needs a new revision:
``rsf db revision -m "what"`` writes one by comparing the tables with a database at head
(review it); ``tests/app/test_migrations.py`` fails while the two differ.
"""

__all__: list[str] = []
