"""`rsf`: command-line interface to rsfcore and the service.

Every command prints human-readable text by default and one JSON object with --json.
Invalid input exits with status 2 and a message naming the field and its valid range.
Dimensionless parameters follow the paper: --ba = b/a (> 1), --kappa = k Dc/(a sigma)
(absolute, kappa_crit = b/a - 1), --eps in [0, 1] (0 slip law, 1 aging law),
--vo = V_o/V_* (0 = stationary load point).

Every computing command builds the HTTP endpoint's request model (:mod:`rsfapp.requests`)
from the options given and answers through :mod:`rsfapp.adapter`, so ``--json`` prints the
endpoint's answer; an option not given takes the model's default (eps = 0.25 at every
door) and the text output ends with the parameters used (rsfcli.common).

Start-up: each command lives in the module of its question (:data:`COMMANDS`) and is
built, with the request models it declares its options from, only when it is asked for:
`rsf classify` imports neither the lab commands, the batch models, the sweep client nor
the database (`rsf --help` builds them all).  The console entry point :func:`main` ends
the process without the interpreter's teardown (:mod:`rsfcli._process`).
"""

from __future__ import annotations

import importlib
from collections.abc import Iterator, Mapping, MutableMapping
from typing import Any, NamedTuple

import typer
from typer.core import TyperGroup

__all__ = ["COMMANDS", "LONG_RUNNING", "Mount", "app", "main"]


class Mount(NamedTuple):
    """Where a command of `rsf` is declared: ``module.attr`` is a :class:`typer.Typer`
    that holds the command (``group=False``) or is the command group itself (``True``)."""

    module: str
    attr: str
    group: bool = False


_SINGLE = Mount("rsfcli.single", "app")
_SERVE = Mount("rsfcli.serve", "app")
_QUESTIONS = Mount("rsfcli.questions", "app")

#: `rsf`'s commands, in the order of `rsf --help`.
COMMANDS: dict[str, Mount] = {
    "classify": _SINGLE,
    "trajectory": _SINGLE,
    "critical": _SINGLE,
    "diagram": Mount("rsfcli.diagram", "app"),
    "stiffness": _SINGLE,
    "figure": Mount("rsfcli.figures", "app"),
    "serve": _SERVE,
    "api": _SERVE,
    "worker": _SERVE,
    "fit": Mount("rsfcli.lab", "fit_app"),
    "boundaries": _QUESTIONS,
    "analytic-u": _QUESTIONS,
    "classify-points": _QUESTIONS,
    "critical-batch": _QUESTIONS,
    "classify-batch": _QUESTIONS,
    "keys": Mount("rsfcli.keys", "app", group=True),
    "si": Mount("rsfcli.lab", "si_app", group=True),
    "protocol": Mount("rsfcli.lab", "protocol_app", group=True),
    "sweep": Mount("rsfcli.sweep", "app", group=True),
    "db": Mount("rsfcli.db", "app", group=True),
}


def _build(name: str) -> Any:
    """The click command ``name`` of `rsf` (typer's vendored click), built from its
    module as ``app.add_typer`` would mount it on the root."""
    where = COMMANDS[name]
    sub = getattr(importlib.import_module(where.module), where.attr)
    holder = typer.Typer(rich_markup_mode=None, add_completion=False)
    holder.add_typer(sub, name=name if where.group else None)
    return typer.main.get_command(holder).commands[name]  # type: ignore[attr-defined]


class _Commands(MutableMapping[str, Any]):
    """The root group's commands by name: every name of :data:`COMMANDS` is listed, and a
    command is built the first time it is looked up."""

    def __init__(self, built: Mapping[str, Any]) -> None:
        self._built: dict[str, Any] = dict(built)

    def __getitem__(self, name: str) -> Any:
        if name not in self._built:
            if name not in COMMANDS:
                raise KeyError(name)
            self._built[name] = _build(name)
        return self._built[name]

    def __setitem__(self, name: str, command: Any) -> None:
        self._built[name] = command

    def __delitem__(self, name: str) -> None:
        del self._built[name]

    def __iter__(self) -> Iterator[str]:
        yield from COMMANDS
        yield from (n for n in self._built if n not in COMMANDS)

    def __len__(self) -> int:
        return len(COMMANDS) + sum(n not in COMMANDS for n in self._built)


class _LazyGroup(TyperGroup):
    """`rsf` itself: a typer group whose commands are built when asked for."""

    def __init__(self, **attrs: Any) -> None:
        super().__init__(**attrs)
        self.commands = _Commands(self.commands)

    def list_commands(self, ctx: Any) -> list[str]:
        return list(self.commands)


app = typer.Typer(
    cls=_LazyGroup,
    rich_markup_mode=None,  # help texts carry units in brackets ([m], [s]), not markup
    name="rsf",
    help="Non-linear slip-stability analysis of rate-and-state friction (spring-slider, "
    "aging-to-slip evolution laws; Ciardo & Viesca).",
    no_args_is_help=True,
    add_completion=False,
    context_settings={"help_option_names": ["-h", "--help"]},
)


@app.callback()
def _root() -> None:
    # no options of its own; the help is the Typer's (the commands are in COMMANDS)
    return None


#: The commands that run a server: they keep the collector and OpenBLAS as they are.
LONG_RUNNING = frozenset({"serve", "api", "worker"})


def main() -> None:
    """Console entry point: the command, then the process ends at once, without the
    interpreter's teardown (:mod:`rsfcli._process`)."""
    import sys

    from ._process import exit_now, pause_collector, quiet_blas

    if not LONG_RUNNING.intersection(sys.argv[1:2]):
        pause_collector()
        quiet_blas()
    try:
        app()
    except SystemExit as exc:
        exit_now(exc.code)
    exit_now(0)


if __name__ == "__main__":  # pragma: no cover
    main()
