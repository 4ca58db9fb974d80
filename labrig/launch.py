"""The console commands ``qdots`` and ``planarize``: a Ctrl-C while they start is one line, not a traceback.

Importing a command line imports its whole package (numba kernels, pymunk, matplotlib: about a
second). The entry points here import nothing heavy themselves; they import the real ``main``
inside a ``try``, so an interrupt during those imports, or before `labrig.cli.run_main` takes over,
ends with ``PROG: interrupted`` on stderr and exit status 130, as an interrupt during a run does.
"""

from __future__ import annotations

import importlib
import sys
from typing import Sequence

#: Exit status of an interrupted command (128 + SIGINT), as shells report it.
INTERRUPTED = 130


def launch(prog: str, module: str, argv: Sequence[str] | None = None) -> int:
    """Import ``module`` and run its ``main(argv)``; returns the exit status (130 on Ctrl-C at any point)."""
    try:
        main = importlib.import_module(module).main
        return main(argv)
    except KeyboardInterrupt:
        print(f"{prog}: interrupted", file=sys.stderr)
        return INTERRUPTED


def qdots(argv: Sequence[str] | None = None) -> int:
    """The ``qdots`` command (`qdots.cli.main`)."""
    return launch("qdots", "qdots.cli", argv)


def planarize(argv: Sequence[str] | None = None) -> int:
    """The ``planarize`` command (`planarize.cli.main`)."""
    return launch("planarize", "planarize.cli", argv)
