"""The revisions (one module each; Alembic reads them by file, not by import)."""

__all__: list[str] = []
