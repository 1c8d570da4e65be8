"""kombu's filesystem transport made safe for concurrent producers and consumers.

The single-machine default (``rsf serve``) queues Celery messages as files: one
``<stamp>_<uuid>.<queue>.msg`` file per message in the queue folder.  Stock kombu
(``kombu.transport.filesystem``) has two races that lose workers under load:

1. **Torn reads.**  ``Channel._put`` *creates* the ``.msg`` file under its final name
   and only then writes the JSON into it.  A consumer listing the folder in between
   sees the name, moves the file away and reads an empty or half-written payload:
   ``JSONDecodeError`` escapes ``_get`` and Celery stops the worker ("Unrecoverable
   error"), so the sweep never finishes.  (The producer's ``flock`` does not help: the
   consumer never takes the lock.)
2. **Double claims.**  With ``store_processed=False`` the consumer ``shutil.move``\\ s the
   file to the system temporary folder, which is often another file system: the move
   is then copy + unlink, two consumers may both copy the same message to the same
   temporary name and one of them reads the other's partial copy.

This module fixes both at the source:

* the producer writes the payload to ``<name>.msg.part`` (a name the consumer's
  ``<queue>.msg`` filter ignores) in the same folder, then ``os.replace``\\ s it to
  ``<name>.msg``: a rename inside one directory is atomic on POSIX, so a consumer sees
  either no file or the complete one;
* the consumer claims a message with one ``os.rename`` into the processed folder (same
  file system as the queue folder under ``RSF_DATA_DIR/broker``): exactly one consumer's
  rename succeeds, the others get ``FileNotFoundError`` and look at the next file;
* a file that still does not decode (written by an older, unfixed producer, or damaged
  on disk) is moved to the quarantine folder with a warning, never raised.

Select it with ``broker_url="filesystem://"`` and ``broker_transport=TRANSPORT_PATH``
(see :func:`rsfapp.queue.make_app`).
"""

from __future__ import annotations

import contextlib
import errno
import logging
import os
import uuid
from pathlib import Path
from queue import Empty
from time import monotonic
from typing import Any

from kombu.exceptions import ChannelError
from kombu.transport import filesystem as _kombu_fs
from kombu.utils.encoding import bytes_to_str, str_to_bytes
from kombu.utils.json import dumps, loads

__all__ = ["Channel", "Transport", "TRANSPORT_PATH", "MESSAGE_SUFFIX", "PARTIAL_SUFFIX"]

log = logging.getLogger(__name__)

#: The class path Celery's ``broker_transport`` setting takes.
TRANSPORT_PATH = "rsfapp.fsqueue:Transport"
#: Suffix of a complete message file (kombu's naming: ``<stamp>_<uuid>.<queue>.msg``).
MESSAGE_SUFFIX = ".msg"
#: Suffix of a message still being written; consumers never match it.
PARTIAL_SUFFIX = ".part"
#: Transport option naming the folder undecodable message files are moved to
#: (default: ``<processed_folder>/quarantine``).
QUARANTINE_OPTION = "quarantine_folder"


class Channel(_kombu_fs.Channel):  # type: ignore[misc]
    """Filesystem channel with atomic publish, atomic claim and quarantine."""

    def _put(self, queue: str, message: Any, **kwargs: Any) -> None:  # type: ignore[override]
        """Write ``message`` to a partial file, then rename it into the queue folder."""
        name = f"{int(round(monotonic() * 1000))}_{uuid.uuid4()}.{queue}{MESSAGE_SUFFIX}"
        final = os.path.join(self.data_folder_out, name)
        partial = final + PARTIAL_SUFFIX
        try:
            with open(partial, "wb") as f:
                f.write(str_to_bytes(dumps(message)))  # type: ignore[no-untyped-call]
            # Atomic on POSIX: a consumer listing the folder sees no file or the whole one.
            os.replace(partial, final)
        except OSError as exc:
            with contextlib.suppress(OSError):
                os.unlink(partial)
            raise ChannelError(f"Cannot add file {final!r} to directory") from exc

    def _claim(self, filename: str) -> str | None:
        """Move queue file ``filename`` out of the queue folder; its new path, or None
        when another consumer took it first."""
        src = os.path.join(self.data_folder_in, filename)
        folder = self.processed_folder
        os.makedirs(folder, exist_ok=True)
        dst = os.path.join(folder, filename)
        try:
            os.rename(src, dst)
            return dst
        except FileNotFoundError:
            return None
        except OSError as exc:
            if exc.errno != errno.EXDEV:
                return None
        # processed folder on another file system: claim by a rename inside the queue
        # folder instead (still atomic; the claimed name no longer ends in ".msg").
        dst = f"{src}.claimed-{uuid.uuid4().hex}"
        try:
            os.rename(src, dst)
            return dst
        except OSError:
            return None

    def _quarantine(self, path: str, reason: str) -> None:
        """Move an undecodable message file aside and log it (never raise)."""
        folder = self.transport_options.get(QUARANTINE_OPTION) or os.path.join(
            self.processed_folder, "quarantine"
        )
        try:
            os.makedirs(folder, exist_ok=True)
            dst = os.path.join(folder, os.path.basename(path))
            os.replace(path, dst)
        except OSError:
            dst = path
        log.warning(
            "broker: skipped undecodable message file %s (%s); kept at %s", path, reason, dst
        )

    def _get(self, queue: str, timeout: float | None = None) -> Any:
        """The next complete message of ``queue``; undecodable files are quarantined."""
        wanted = f"{queue}{MESSAGE_SUFFIX}"
        for filename in sorted(os.listdir(self.data_folder_in)):
            if filename.partition(".")[2] != wanted:
                continue
            path = self._claim(filename)
            if path is None:
                continue
            try:
                payload = Path(path).read_bytes()
            except OSError as exc:
                raise ChannelError(f"Cannot read file {path!r} from queue.") from exc
            try:
                message = loads(bytes_to_str(payload))  # type: ignore[no-untyped-call]
            except (ValueError, UnicodeDecodeError) as exc:
                self._quarantine(path, f"{type(exc).__name__}: {exc}")
                continue
            if not isinstance(message, dict):
                self._quarantine(path, f"payload is {type(message).__name__}, not an object")
                continue
            if not self.store_processed:
                with contextlib.suppress(OSError):
                    os.remove(path)
            return message
        raise Empty()


class Transport(_kombu_fs.Transport):  # type: ignore[misc]
    """kombu's filesystem transport using :class:`Channel`."""

    Channel = Channel
