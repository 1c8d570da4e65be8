"""Celery workers: run sweep chunks and long single queries (imports rsfapp, never service)."""
