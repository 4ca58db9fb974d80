"""Old names that keep working for one release, with a `DeprecationWarning` that gives the new one.

Two kinds of old name:

* a moved module (``qdots.structure`` is now ``qdots.analysis.structure``): `alias_modules` makes
  ``import qdots.structure`` give the new module;
* a renamed attribute (``qdots.CenterGravity`` is now ``qdots.CentreGravity``): `renamed_attributes`
  gives a module ``__getattr__`` that returns the new object.

Either way the first use warns, naming the new spelling; nothing else changes.
"""

from __future__ import annotations

import importlib
import importlib.abc
import importlib.util
import sys
import warnings
from typing import Callable, Mapping


def warn(old: str, new: str, stacklevel: int = 3) -> None:
    """Warn that ``old`` is now spelled ``new`` and will go in the next release."""
    warnings.warn(f"{old} is now {new}; the old name will be removed in the next release", DeprecationWarning,
                  stacklevel=stacklevel)


class _ModuleAliases(importlib.abc.MetaPathFinder, importlib.abc.Loader):
    """Finds an old module name and loads it as the new module itself (one module object, two names)."""

    def __init__(self, aliases: Mapping[str, str]):
        self.aliases = dict(aliases)

    def find_spec(self, fullname, path=None, target=None):
        if fullname in self.aliases:
            return importlib.util.spec_from_loader(fullname, self)
        return None

    def create_module(self, spec):
        new = self.aliases[spec.name]
        warn(spec.name, new, stacklevel=7)
        return importlib.import_module(new)

    def exec_module(self, module) -> None:
        pass  # the new module is already executed


def alias_modules(aliases: Mapping[str, str]) -> None:
    """Let ``import OLD`` load the module ``NEW`` for each ``{OLD: NEW}``, warning once per old name."""
    sys.meta_path.append(_ModuleAliases(aliases))


def renamed_attributes(module_name: str, renames: Mapping[str, str]) -> Callable[[str], object]:
    """A module ``__getattr__`` that serves each old attribute name of ``renames`` ({old: new}) with a warning."""
    def __getattr__(name: str):
        if name in renames:
            warn(f"{module_name}.{name}", f"{module_name}.{renames[name]}")
            return getattr(sys.modules[module_name], renames[name])
        raise AttributeError(f"module {module_name!r} has no attribute {name!r}")
    return __getattr__
