"""A progress bar over status dicts on stderr (rich if installed, else a text line)."""

from __future__ import annotations

import sys
from typing import Any

__all__ = ["Progress"]


class Progress:
    """A progress bar: :meth:`update` with ``{n_done, n_total, status}``, then :meth:`close`."""

    def __init__(self, label: str, unit: str = "points") -> None:
        self.label, self.unit = label, unit
        self._rich: Any = None
        self._task: Any = None
        try:
            from rich.console import Console
            from rich.progress import (
                BarColumn,
                MofNCompleteColumn,
                TextColumn,
                TimeRemainingColumn,
            )
            from rich.progress import Progress as RichProgress
        except ImportError:
            return
        self._rich = RichProgress(
            TextColumn("{task.description}"),
            BarColumn(),
            MofNCompleteColumn(),
            TextColumn("{task.fields[status]}"),
            TimeRemainingColumn(),
            transient=False,
            console=Console(stderr=True),
        )
        self._rich.start()
        self._task = self._rich.add_task(label, total=None, status="")

    def update(self, st: Any) -> None:
        """Show ``st`` (a mapping with n_done, n_total, status)."""
        done, total, status = st.get("n_done", 0), st.get("n_total"), st.get("status", "")
        if self._rich is not None:
            self._rich.update(self._task, completed=done, total=total, status=status)
        else:
            print(
                f"\r{self.label}: {done}/{total or '?'} {self.unit} {status}   ",
                end="",
                file=sys.stderr,
                flush=True,
            )

    def close(self) -> None:
        """End the bar (a newline on stderr)."""
        if self._rich is not None:
            self._rich.stop()
        else:
            print(file=sys.stderr)
