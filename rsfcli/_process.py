"""A short-lived `rsf` process: the garbage collector paused while it starts, OpenBLAS's
idle threads asleep at once, no teardown.

An `rsf` command creates about 10^5 long-lived objects while it imports typer, pydantic,
numpy and numba and loads the cached kernels.  Meanwhile Python's cyclic garbage
collector runs about 200 times and frees nothing (0.06 s of CPU), and at exit the
interpreter's teardown (every module, numba's LLVM objects, pydantic's validators) takes
0.15 s more with nothing left to write (measured: `rsf classify`, 2-core machine, warm
kernel cache: 0.78 -> 0.57 s CPU for both together).

* :func:`pause_collector`: no automatic collection for the first :data:`COLLECTOR_PAUSE_S`
  seconds of the process; a command that runs longer (a large diagram, a long fit, a
  server) gets the collector back then, so its memory stays bounded as before; so does
  a child forked meanwhile (none is, today).
* :func:`quiet_blas`: OpenBLAS's worker threads (numpy's linear algebra) sleep as soon
  as they have no work instead of spinning ~2^28 cycles each time (``OPENBLAS_THREAD_TIMEOUT``
  = :data:`BLAS_THREAD_TIMEOUT`, read when numpy loads; a value already set is kept).
  The same threads split the same work, so every result keeps its bits (checked: the
  eigenvalues and modes of `rsf stiffness` cases B and E); on the shared 2-core machine
  the first 256 x 256 ``eigh`` of `rsf stiffness` took 1.05 s CPU / 3.7 s wall spinning,
  0.045 s / 0.16 s with it.  (Fewer threads would change the bits: ``OPENBLAS_NUM_THREADS
  =1`` changes the eigenvectors in the last place.)
* :func:`exit_now`: ends the process as ``sys.exit(code)`` would (same status, same
  message for a non-integer code), after the ``atexit`` handlers and with stdout and
  stderr flushed (a failed flush of stdout exits 120, as Python's own shutdown does), but
  without the teardown.  Every file a command writes is closed before it returns
  (``Path.write_*``, ``with open(...)``, numpy's savez), so nothing is lost.

Only the console entry point (:func:`rsfcli.main.main`) uses these, and not for the
long-running server commands; importing rsfcli (the tests, ``typer.testing.CliRunner``)
changes nothing of the process.
"""

from __future__ import annotations

import atexit
import contextlib
import gc
import os
import sys
import threading
from typing import NoReturn

__all__ = [
    "BLAS_THREAD_TIMEOUT",
    "COLLECTOR_PAUSE_S",
    "exit_now",
    "pause_collector",
    "quiet_blas",
]

#: Seconds after start-up without automatic garbage collection [s]: longer than any
#: warm `rsf` command that answers one question (<= 1.5 s, issue 20 item 7).
COLLECTOR_PAUSE_S = 2.0


#: OpenBLAS's idle-thread spin, log2 of CPU cycles (its smallest accepted value; default 28).
BLAS_THREAD_TIMEOUT = 4


def quiet_blas() -> None:
    """OpenBLAS threads sleep at once when idle (before numpy is imported; else nothing)."""
    if "numpy" not in sys.modules:
        os.environ.setdefault("OPENBLAS_THREAD_TIMEOUT", str(BLAS_THREAD_TIMEOUT))


def _resume_collector() -> None:
    gc.enable()


def pause_collector(seconds: float = COLLECTOR_PAUSE_S) -> None:
    """Disable automatic garbage collection now and enable it again after ``seconds``
    (a daemon timer thread; nothing happens if the process has ended before)."""
    if not gc.isenabled():
        return
    gc.disable()
    os.register_at_fork(after_in_child=_resume_collector)  # a forked child: as usual
    timer = threading.Timer(seconds, _resume_collector)
    timer.daemon = True
    timer.name = "rsf-gc-resume"
    timer.start()


def _status(code: object) -> int:
    """The exit status of ``sys.exit(code)`` (a non-integer code is printed on stderr)."""
    if code is None:
        return 0
    if isinstance(code, int):
        return code
    with contextlib.suppress(OSError, ValueError):
        print(code, file=sys.stderr)
    return 1


def exit_now(code: object = 0) -> NoReturn:
    """End the process as ``sys.exit(code)`` would, without the interpreter's teardown."""
    status = _status(code)
    run_exit_handlers = getattr(atexit, "_run_exitfuncs", None)
    if run_exit_handlers is None:  # another Python: the ordinary exit (slower, same result)
        sys.exit(status)
    run_exit_handlers()
    for stream in (sys.stdout, sys.stderr):
        try:
            if stream is not None:
                stream.flush()
        except (OSError, ValueError):
            if stream is sys.stdout and status == 0:
                status = 120
    os._exit(status)
