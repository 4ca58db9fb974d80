"""The ``cli-help`` directive: a command line's ``--help``, generated from its argument parser.

In a MyST page::

    ```{cli-help} qdots.cli.main:build_parser
    ```

shows what ``--help`` prints for the command, then a section per subcommand with its own
``--help``. The argument names a callable of the package: either one that returns the parser
(``build_parser()``), or, with the ``:argv:`` option, a ``main(argv)`` / ``parse(argv)`` that
builds its parser and parses ``argv`` at once: the directive calls it with ``[]`` and stops it at
``parse_args``, so nothing runs. The text is argparse's own at a fixed width; a default that is a
path inside the checkout is shown relative to the repository root.
"""

from __future__ import annotations

import argparse
import importlib
import os
import sys
from contextlib import contextmanager
from pathlib import Path

from docutils import nodes
from docutils.parsers.rst import directives
from sphinx.util.docutils import SphinxDirective

#: Width of the help text, characters.
WIDTH = 88
ROOT = Path(__file__).resolve().parents[2]


class _Captured(Exception):
    def __init__(self, parser: argparse.ArgumentParser):
        super().__init__(parser.prog)
        self.parser = parser


@contextmanager
def _fixed_width():
    """argparse wraps at ``$COLUMNS``: fix it while the help is formatted."""
    saved = os.environ.get("COLUMNS")
    os.environ["COLUMNS"] = str(WIDTH)
    try:
        yield
    finally:
        if saved is None:
            del os.environ["COLUMNS"]
        else:
            os.environ["COLUMNS"] = saved


def parser_of(target: str, argv: bool = False) -> argparse.ArgumentParser:
    """The parser named by ``"module:function"``: what the function returns, or, with ``argv``, the
    parser the function builds and asks to parse (``function([])`` stopped at ``parse_args``)."""
    module_name, _, name = target.partition(":")
    function = getattr(importlib.import_module(module_name), name)
    if not argv:
        return function()

    def capture(self, *args, **kwargs):
        raise _Captured(self)

    original = argparse.ArgumentParser.parse_args
    argparse.ArgumentParser.parse_args = capture
    try:
        function([])
    except _Captured as captured:
        return captured.parser
    finally:
        argparse.ArgumentParser.parse_args = original
    raise RuntimeError(f"{target}([]) returned without parsing its arguments")


def help_text(parser: argparse.ArgumentParser) -> str:
    """``parser.format_help()`` at `WIDTH` columns, paths of this checkout relative to it."""
    with _fixed_width():
        text = parser.format_help()
    return text.replace(str(ROOT) + os.sep, "").replace(str(ROOT), ".").rstrip()


def subcommands(parser: argparse.ArgumentParser) -> dict[str, argparse.ArgumentParser]:
    """The parser's subcommands by name, in the order ``--help`` lists them (none: empty)."""
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            return dict(action.choices)
    return {}


class CliHelp(SphinxDirective):
    """``cli-help MODULE:FUNCTION``: the command's ``--help`` and one section per subcommand."""

    required_arguments = 1
    option_spec = {"argv": directives.flag}

    def run(self) -> list[nodes.Node]:
        target = self.arguments[0]
        parser = parser_of(target, argv="argv" in self.options)
        module = sys.modules[target.partition(":")[0]]
        if getattr(module, "__file__", None):
            self.env.note_dependency(module.__file__)
        result: list[nodes.Node] = [self._block(parser)]
        std = self.env.get_domain("std")
        for name, sub in subcommands(parser).items():
            node_id = nodes.make_id(f"{parser.prog} {name}")
            section = nodes.section(ids=[node_id])
            section += nodes.title(text=sub.prog)
            # a label ``cli-qdots-measure``, so that links to ``cli.md#qdots-measure`` are checked
            std.note_hyperlink_target(f"cli-{node_id}", self.env.docname, node_id, sub.prog)
            section += self._block(sub)
            result.append(section)
        return result

    @staticmethod
    def _block(parser: argparse.ArgumentParser) -> nodes.literal_block:
        text = help_text(parser)
        block = nodes.literal_block(text, text)
        block["language"] = "text"
        return block


def setup(app):
    app.add_directive("cli-help", CliHelp)
    return {"version": "1", "parallel_read_safe": True, "parallel_write_safe": True}
