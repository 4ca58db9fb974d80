"""The console commands ``qdots`` and ``planarize``: a Ctrl-C is one line at any moment, not a traceback.

Importing a command line imports its whole package (numba kernels, pymunk, matplotlib: about a
second). The entry points here import nothing heavy themselves; they import the real ``main``
inside a ``try``, so an interrupt during those imports, or before `labrig.cli.run_main` takes over,
ends with ``PROG: interrupted`` on stderr and exit status 130, as an interrupt during a run does.

After the command has returned, Python would still tear its modules down (half a second, measured
after a sweep), a time in which it no longer runs a handler of Ctrl-C: the process would die of the
signal (status -2) and say nothing. The entry points therefore end the process themselves once every
``atexit`` handler has run, and a Ctrl-C after the command returned says so
(``PROG: interrupted after it had finished``), with status 130. An exception that is a bug keeps its
traceback and exits with status 1.
"""

from __future__ import annotations

import atexit
import importlib
import os
import signal
import sys
import threading
from collections.abc import Sequence

#: Exit status of an interrupted command (128 + SIGINT), as shells report it.
INTERRUPTED = 130
#: Exit status of a command that crashed (an exception that is a bug; its traceback is printed).
CRASHED = 1


class LateInterrupt(KeyboardInterrupt):
    """A Ctrl-C held until something was written whole; its message says what (``"the table was written"``)."""


def interrupted_line(prog: str, exc: BaseException | None = None) -> str:
    """What an interrupted command prints on its own line: ``PROG: interrupted``, with what had been written by
    then for a `LateInterrupt`."""
    late = f" after {exc}" if isinstance(exc, LateInterrupt) and str(exc) else ""
    return f"{prog}: interrupted{late}"


def launch(prog: str, module: str, argv: Sequence[str] | None = None, *, console: bool = False) -> int:
    """Import ``module`` and run its ``main(argv)``; returns the exit status (130 on Ctrl-C at any point).

    With ``console`` (a console command), the process ends as soon as the ``atexit`` handlers have run
    (`end_after_exit_handlers`), and a Ctrl-C after ``main`` returned prints a line and exits 130. A crash (any
    other exception) keeps its traceback and exits 1, so that a script tells it from a Ctrl-C.
    """
    status = [CRASHED]
    if console:
        end_after_exit_handlers(status)
    finished = False
    try:
        try:
            main = importlib.import_module(module).main
            status[0] = main(argv)
            finished = True
        finally:
            if console and threading.current_thread() is threading.main_thread():
                signal.signal(signal.SIGINT, lambda signum, frame: _late_interrupt(prog))
    except KeyboardInterrupt as exc:  # during the command, or in the instant after it returned
        late = LateInterrupt("it had finished (its results are written)") if finished else exc
        print(interrupted_line(prog, late), file=sys.stderr)
        status[0] = INTERRUPTED
    except SystemExit as exc:
        status[0] = exc.code if isinstance(exc.code, int) else (0 if exc.code is None else 1)
        raise
    return status[0]


def end_after_exit_handlers(status: list) -> None:
    """End the process with the exit status ``status[0]`` right after the ``atexit`` handlers registered later
    (every one a command's imports register) have run, skipping the teardown of the modules.

    Registered first, the handler runs last (``atexit`` runs its handlers in reverse order).
    """
    def end() -> None:
        for stream in (sys.stdout, sys.stderr):
            try:
                stream.flush()
            except (AttributeError, OSError, ValueError):
                pass
        code = status[0]
        os._exit(code if isinstance(code, int) and 0 <= code <= 255 else 1)

    atexit.register(end)


def _late_interrupt(prog: str) -> None:
    """What a Ctrl-C after the command returned does: one line, exit status 130 (its results are all written)."""
    os.write(2, (interrupted_line(prog, LateInterrupt("it had finished (its results are written)")) + "\n").encode())
    os._exit(INTERRUPTED)


def qdots(argv: Sequence[str] | None = None) -> int:
    """The ``qdots`` command (`qdots.cli.main`)."""
    return launch("qdots", "qdots.cli", argv, console=True)


def planarize(argv: Sequence[str] | None = None) -> int:
    """The ``planarize`` command (`planarize.cli.main`)."""
    return launch("planarize", "planarize.cli", argv, console=True)
