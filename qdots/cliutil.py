"""What the ``qdots`` and ``planarize`` command lines share: argument types and the error contract.

Bad input never prints a usage dump or a traceback: `run_main` turns it into
one line ``PROG: error: ...`` on stderr and exit status 2 (130 when interrupted).
"""

from __future__ import annotations

import argparse
import math
import sys
from typing import Callable, Sequence


class UsageError(Exception):
    """A command-line argument was rejected by argparse."""


class Parser(argparse.ArgumentParser):
    """An ArgumentParser that raises `UsageError` instead of printing usage and exiting."""

    def error(self, message: str):
        raise UsageError(f"{message} (see '{self.prog} --help')")


def int_at_least(low: int) -> Callable[[str], int]:
    """Argument type: an integer >= ``low``."""
    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"must be an integer, got {text!r}") from None
        if value < low:
            raise argparse.ArgumentTypeError(f"must be an integer >= {low}, got {value}")
        return value
    return parse


def float_in(low: float, high: float, low_open: bool = False, high_open: bool = True) -> Callable[[str], float]:
    """Argument type: a finite number in the interval from ``low`` to ``high`` (open or closed ends)."""
    def parse(text: str) -> float:
        try:
            value = float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"must be a number, got {text!r}") from None
        ok = math.isfinite(value) and (value > low if low_open else value >= low) and \
            (value < high if high_open else value <= high)
        if not ok:
            interval = f"{'(' if low_open else '['}{low:g}, {high:g}{')' if high_open else ']'}"
            raise argparse.ArgumentTypeError(f"must be in {interval}, got {text}")
        return value
    return parse


#: ``--quick F``: a fraction in (0, 1].
fraction = float_in(0.0, 1.0, low_open=True, high_open=False)


def run_main(parser: argparse.ArgumentParser, argv: Sequence[str] | None) -> int:
    """Parse ``argv`` and run the chosen command's ``func``; returns the exit status.

    0 on success (or the command's own status), 2 on bad input (a one-line
    ``PROG: error: ...`` on stderr), 130 when interrupted.
    """
    try:
        args = parser.parse_args(argv)
        return int(args.func(args))
    except SystemExit as exc:  # --help and --version
        return exc.code if isinstance(exc.code, int) else 0
    except (UsageError, ValueError, OSError) as exc:
        print(f"{parser.prog}: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"{parser.prog}: interrupted", file=sys.stderr)
        return 130
