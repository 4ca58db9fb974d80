"""What command lines built on labrig share: argument types, the error contract, printed tables.

Bad input never prints a usage dump or a traceback: `run_main` turns it (an argparse error, a
`labrig.validate.InputError`, a missing or unreadable file) into one line ``PROG: error: ...`` on
stderr and exit status 2 (130 when interrupted: ``PROG: interrupted``, with what had been written whole by then
when a `labrig.launch.LateInterrupt` says so). Any other exception is a bug and keeps its
traceback.

A command line answers at once: each subcommand is a `Command` whose arguments are added only when it is
the one chosen (`command_line`), so ``PROG --help``, ``PROG --version`` and a wrong command import nothing of
the simulators, and a subcommand imports only what its own arguments need.
"""

from __future__ import annotations

import argparse
import difflib
import functools
import sys
import warnings
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import TypeVar

from .launch import INTERRUPTED, interrupted_line
from .params import Param
from .validate import InputError, count, printable, real

T = TypeVar("T")


class UsageError(Exception):
    """A command-line argument was rejected by argparse."""


class Parser(argparse.ArgumentParser):
    """An ArgumentParser that raises `UsageError` instead of printing usage and exiting; ``commands`` holds its
    subcommands' parsers by name (`command_line`)."""

    commands: dict[str, argparse.ArgumentParser]

    def error(self, message: str):
        raise UsageError(f"{message} (see '{self.prog} --help')")


def _argument(check: Callable[[str], T]) -> Callable[[str], T]:
    """An argparse type from a `labrig.validate` check: the check's message, without a key (argparse names
    the option)."""
    def parse(text: str):
        try:
            return check(text)
        except InputError as exc:
            raise argparse.ArgumentTypeError(str(exc).strip()) from None
    return parse


def _number(text: str, kind: type):
    try:
        return kind(text)
    except ValueError:
        raise InputError(f"must be {'an integer' if kind is int else 'a number'}, got {text!r}") from None


def int_in(low: int, high: int | None = None) -> Callable[[str], int]:
    """Argument type: an integer in ``[low, high]`` (no upper bound when ``high`` is None)."""
    return _argument(lambda text: count("", _number(text, int), low, high))


def float_in(low: float, high: float, low_open: bool = False, high_open: bool = True) -> Callable[[str], float]:
    """Argument type: a finite number in the interval from ``low`` to ``high`` (open or closed ends)."""
    return _argument(lambda text: real("", _number(text, float), low, high, low_open=low_open,
                                       high_open=high_open))


def param_type(param: Param) -> Callable[[str], float | int]:
    """Argument type: a number its declaration accepts (a ``"float"`` or ``"int"`` `labrig.params.Param`), so that an
    option and the file key it overrides take the same values and say so in the same words."""
    if param.kind not in ("float", "int"):
        raise ValueError(f"param_type takes a float or int declaration, got kind {param.kind!r}")
    kind = float if param.kind == "float" else int
    return _argument(lambda text: param.check("", _number(text, kind)))


def param_help(param: Param, default=None) -> str:
    """An option's help from its declaration: what it is, its unit and range, and its default."""
    return param.comment() + ("" if default is None else f" (default {default:g})")


#: ``--quick F``: a fraction in (0, 1].
fraction = float_in(0.0, 1.0, low_open=True, high_open=False)


def run_main(parser: argparse.ArgumentParser, argv: Sequence[str] | None,
             command: argparse.ArgumentParser | None = None) -> int:
    """Parse ``argv`` and run the chosen command's ``func``; returns the exit status.

    0 on success (or the command's own status), 2 on bad input (a one-line
    ``PROG: error: ...`` on stderr), 130 when interrupted. Other exceptions propagate.
    Words no argument takes are reported against ``command``'s options (the chosen subcommand's parser,
    default ``parser``), with the closest option and its ``--help``. A `FutureWarning` (a file in a spelling that
    will stop being read, say) is one line, ``PROG: note: ...``, on stderr.
    """
    try:
        with warnings.catch_warnings():
            warnings.showwarning = functools.partial(_note, parser.prog, warnings.showwarning)
            args, unknown = parser.parse_known_args(argv)
            if unknown:
                raise UsageError(unrecognized(command or parser, unknown))
            return int(args.func(args))
    except SystemExit as exc:  # --help and --version
        return exc.code if isinstance(exc.code, int) else 0
    except (UsageError, InputError, OSError) as exc:
        print(f"{parser.prog}: error: {printable(exc)}", file=sys.stderr)
        return 2
    except KeyboardInterrupt as exc:
        print(interrupted_line(parser.prog, exc), file=sys.stderr)
        return INTERRUPTED
    except Exception as exc:  # e.g. numba's SystemError "... returned a result with an exception set" on Ctrl-C
        if not interrupted(exc):
            raise
        print(interrupted_line(parser.prog), file=sys.stderr)
        return INTERRUPTED


def _note(prog: str, show, message, category, filename, lineno, file=None, line=None) -> None:
    """Show a `FutureWarning` as the line ``PROG: note: MESSAGE``, other warnings with ``show``."""
    if issubclass(category, FutureWarning):
        print(f"{prog}: note: {message}", file=sys.stderr)
    else:
        show(message, category, filename, lineno, file, line)


def did_you_mean(word: str, choices: Sequence[str]) -> str:
    """``"; did you mean 'X'?"`` for the choice closest to ``word`` (``_`` read as ``-``), or ``""``."""
    close = difflib.get_close_matches(word.replace("_", "-"), list(choices), n=1, cutoff=0.75)
    return f"; did you mean {close[0]!r}?" if close else ""


def option_strings(parser: argparse.ArgumentParser) -> dict[str, argparse.Action]:
    """``parser``'s options by each of their strings (``--scale-bar``, ``-h``, ...)."""
    return {string: action for action in parser._actions for string in action.option_strings}


def unrecognized(parser: argparse.ArgumentParser, words: Sequence[str]) -> str:
    """The error for ``words`` that no argument of ``parser`` takes: the first unknown option with the closest
    known one, or the extra words; and where help is (``PROG COMMAND --help``)."""
    options = [word.split("=", 1)[0] for word in words if word.startswith("-")]
    if options:
        hint = did_you_mean(options[0], list(option_strings(parser)))
        return f"unknown option {options[0]!r}{hint} (see '{parser.prog} --help')"
    return f"unrecognized arguments: {' '.join(words)} (see '{parser.prog} --help')"


def join_dashed_values(parser: argparse.ArgumentParser, argv: Sequence[str]) -> list[str]:
    """``argv`` with each value that starts with a dash joined to its option (``--rtol -inf`` ->
    ``--rtol=-inf``), so that the option's own check reports it instead of argparse's "expected one argument".

    Only for options of ``parser`` that take one value, and only where the next word is no option of it.
    """
    options = option_strings(parser)
    words = list(argv)
    joined: list[str] = []
    i = 0
    while i < len(words):
        word = words[i]
        action = options.get(word)
        value = words[i + 1] if i + 1 < len(words) else None
        if (action is not None and action.nargs is None and action.option_strings and action.const is None
                and value is not None and value.startswith("-") and len(value) > 1
                and value.split("=", 1)[0] not in options and not value.startswith("--")):
            joined.append(f"{word}={value}")
            i += 2
            continue
        joined.append(word)
        i += 1
    return joined


def interrupted(exc: BaseException) -> bool:
    """Whether ``exc`` is a KeyboardInterrupt or was raised while one was handled (its ``__cause__`` /
    ``__context__`` chain holds one): compiled code interrupted by Ctrl-C raises such wrappers."""
    seen: set[int] = set()
    pending: list[BaseException | None] = [exc]
    while pending:
        found = pending.pop()
        if found is None or id(found) in seen:
            continue
        if isinstance(found, KeyboardInterrupt):
            return True
        seen.add(id(found))
        pending += [found.__cause__, found.__context__]
    return False


@dataclass(frozen=True)
class Command:
    """One subcommand of a command line (`command_line`).

    Parameters
    ----------
    name : str
        The subcommand's name.
    help : str
        Its line in the list of commands.
    run : callable
        ``run(args)`` runs it and returns the exit status.
    arguments : callable, optional
        ``arguments(parser)`` adds its arguments to its parser; called only when the command is the one chosen
        (or the whole parser is built), so it may import what they need (choices, bounds).
    description : str, optional
        What its ``--help`` says first; default ``run``'s docstring.
    """

    name: str
    help: str
    run: Callable[[argparse.Namespace], int]
    arguments: Callable[[argparse.ArgumentParser], None] | None = None
    description: str | None = None


#: `command_line`'s ``build_parser(command=EVERY)``: the arguments of every command (for documentation and tests).
EVERY = "\0every"


def command_line(prog: str, description: str, commands: Sequence[Command]) -> tuple[Callable, Callable]:
    """The ``build_parser`` and ``main`` of a command line of subcommands, ``PROG [--version] COMMAND ...``.

    Parameters
    ----------
    prog : str
        The command's name.
    description : str
        What ``PROG --help`` says first.
    commands : sequence of Command
        The subcommands, in the order ``--help`` lists them.

    Returns
    -------
    build_parser : callable
        ``build_parser(command=EVERY)``: a `Parser` with ``--version`` and one subparser per command; only
        ``command``'s gets its arguments (every command's by default, none for None).
    main : callable
        ``main(argv=None)``: runs the command line (`run_main`) with only the chosen command's arguments built,
        and returns the exit status: 0 on success, 2 on bad input (a one-line ``PROG: error: ...`` on stderr).
    """
    def build_parser(command: str | None = EVERY) -> Parser:
        """The argument parser: ``--version`` and one subparser per command (arguments: see `command_line`);
        each subparser is in its ``commands`` by name."""
        from . import __version__

        parser = Parser(prog=prog, description=description)
        parser.add_argument("--version", action="version", version=f"{prog} {__version__}")
        subparsers = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)
        parser.commands = {}
        for entry in commands:
            p = subparsers.add_parser(entry.name, help=entry.help, description=entry.description or entry.run.__doc__)
            p.set_defaults(func=entry.run)
            if entry.arguments is not None and command in (EVERY, entry.name):
                entry.arguments(p)
            parser.commands[entry.name] = p
        return parser

    def main(argv: Sequence[str] | None = None) -> int:
        """Run the command line; returns the exit status (0 on success, 2 on bad input: one line on stderr)."""
        argv = sys.argv[1:] if argv is None else list(argv)
        # the top level takes options without values only (--help, --version): its first other word is the command
        chosen = next((word for word in argv if not word.startswith("-")), None)
        names = [entry.name for entry in commands]
        if chosen is not None and chosen not in names:
            print(f"{prog}: error: unknown command {printable(chosen)!r}{did_you_mean(chosen, names)} "
                  f"(see '{prog} --help')", file=sys.stderr)
            return 2
        parser = build_parser(chosen)
        command = parser.commands.get(chosen) if chosen is not None else None
        if chosen is not None and command is not None:
            at = argv.index(chosen) + 1
            argv = argv[:at] + join_dashed_values(command, argv[at:])
        return run_main(parser, argv, command)

    return build_parser, main


def print_table(title: str, rows: Sequence[tuple[str, str]]) -> None:
    """Print ``title`` and aligned ``key  value`` lines, control characters escaped (`labrig.validate.printable`)."""
    rows = [(printable(key), printable(value)) for key, value in rows]
    width = max(len(key) for key, _ in rows)
    print(printable(title))
    print("\n".join(f"  {key:<{width}}  {value}" for key, value in rows))
