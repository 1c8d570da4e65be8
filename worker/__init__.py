"""Celery worker, SQLite/SQLAlchemy result cache and sweep bookkeeping."""
