"""CLI hook for ``rsf figure NAME --out FILE.png|.svg`` and ``rsf figure --list``.

The typer command in rsfcli.main calls :func:`figure_command`; it returns the exit code.
"""

from __future__ import annotations

import sys
import textwrap
from pathlib import Path

from rsfcore import ParameterError

__all__ = ["figure_command"]


def figure_command(name: str | None, out: Path | None, list_: bool, quality: str = "paper") -> int:
    """Print the figure list (``list_``) or render ``name`` to ``out`` (default NAME.png).

    Exit codes: 0 done, 2 usage error (no/unknown name, bad extension).
    """
    from . import FIGURES, render

    if list_:
        width = max(len(n) for n in FIGURES)
        for spec in FIGURES.values():
            cap = f"{spec.label}: {spec.caption}"
            lines = textwrap.wrap(cap, width=100 - width - 2) or [""]
            print(f"{spec.name.ljust(width)}  {lines[0]}")
            for ln in lines[1:]:
                print(" " * (width + 2) + ln)
            if spec.note:
                for ln in textwrap.wrap("note: " + spec.note, width=100 - width - 2):
                    print(" " * (width + 2) + ln)
        return 0
    if not name:
        print(
            "error: give a figure NAME or --list (names: " + ", ".join(FIGURES) + ")",
            file=sys.stderr,
        )
        return 2
    if name not in FIGURES:
        print(
            f"error: unknown figure {name!r}; valid names: " + ", ".join(FIGURES), file=sys.stderr
        )
        return 2
    target = Path(out) if out is not None else Path(f"{name}.png")
    if target.suffix.lower() not in (".png", ".svg"):
        print(f"error: --out must end in .png or .svg, got {str(target)!r}", file=sys.stderr)
        return 2
    try:
        render(name, target, quality=quality)
    except ParameterError as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    print(f"wrote {target} ({FIGURES[name].label})")
    return 0
