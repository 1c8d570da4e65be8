"""Files served by name from one directory (the dashboard's static files, the assets of
the documentation pages), safe against any name a client can put in a URL.

A name is looked up only if it is a plain file name: ASCII letters, digits, ``.``, ``_``
and ``-``, starting with a letter or digit, at most 100 characters.  Anything else (a
null byte, a separator or dot segment however encoded, an overlong name, invalid UTF-8
decoded to U+FFFD, control characters) is "not found" without touching the file
system, so it can never raise (``ValueError: embedded null byte``, ``OSError: File name
too long``) and become a 500.
"""

from __future__ import annotations

import re
from collections.abc import Container
from pathlib import Path

__all__ = ["NAME_PATTERN", "file_in"]

#: What a servable file name looks like.
NAME_PATTERN = re.compile(r"[A-Za-z0-9][A-Za-z0-9._-]{0,99}")


def file_in(directory: Path, name: str, suffixes: Container[str]) -> Path | None:
    """The regular file ``name`` directly inside ``directory`` (an absolute, resolved
    path) with one of ``suffixes``; None if there is none or ``name`` is not a plain file
    name (module docstring)."""
    if not NAME_PATTERN.fullmatch(name):
        return None
    path = (directory / name).resolve()
    if path.parent != directory or path.suffix not in suffixes or not path.is_file():
        return None
    return path
