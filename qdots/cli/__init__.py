"""The ``qdots`` command line: `qdots.cli.main` parses, `qdots.cli.commands` does the work,
`qdots.cli.sweep` runs sweeps of experiments."""

from .main import build_parser, main

__all__ = ["main", "build_parser"]
