"""The ``planarize`` command line: `planarize.cli.main` parses, `planarize.cli.commands` does the work,
`planarize.cli.sweep` runs sweeps of scenes."""

from .main import build_parser, main

__all__ = ["main", "build_parser"]
