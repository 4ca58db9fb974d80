"""A package's public names, imported when first used, and modules that moved, still importable by their old names.

A package's ``__init__`` states its public names and the module each lives in; `exports` gives it the module
``__getattr__`` and ``__dir__`` (PEP 562) that import a name's module on first use, as scikit-image's lazy loader
does, so that importing the package, and a command line's ``--help``, loads nothing heavy.

`moved_module` keeps a module that moved importable by its old name for a deprecation period: the old name is a
file of one line, whose import warns (a `DeprecationWarning` naming the new module and the release the old name
goes in) and whose names are the new module's. `moved_names` does the same for some names of a module that stays.

>>> getattr_, dir_ = exports("json", {"JSONDecoder": "decoder"})   # json.JSONDecoder lives in json.decoder
>>> getattr_("JSONDecoder").__module__
'json.decoder'
>>> "JSONDecoder" in dir_()
True
"""

from __future__ import annotations

import importlib
import sys
import warnings
from collections.abc import Callable, Iterable, Mapping

__all__ = ["exports", "moved_module", "moved_names"]


def exports(package: str, names: Mapping[str, str], modules: Iterable[str] = ()) -> tuple[Callable, Callable]:
    """The ``__getattr__`` and ``__dir__`` of a package that exports ``names`` lazily.

    Parameters
    ----------
    package : str
        The package's ``__name__``.
    names : mapping of str to str
        Each public name and the module, relative to the package, that defines it (``{"Scene": "scene"}``).
    modules : iterable of str
        Subpackages or modules reachable as attributes (``qdots.forces``), imported when first used.

    Returns
    -------
    (__getattr__, __dir__)
        Assign them in the package's ``__init__``. A name, once imported, is stored in the package's namespace,
        so that the next lookup does not call ``__getattr__``.
    """
    names, modules = dict(names), tuple(modules)

    def __getattr__(name: str):
        if name in names:
            value = getattr(importlib.import_module(f".{names[name]}", package), name)
        elif name in modules:
            value = importlib.import_module(f".{name}", package)
        else:
            raise AttributeError(f"module {package!r} has no attribute {name!r}")
        vars(sys.modules[package])[name] = value
        return value

    def __dir__() -> list[str]:
        return sorted({*vars(sys.modules[package]), *names, *modules})

    return __getattr__, __dir__


def moved_module(old: str, new: str, since: str, goes_in: str) -> tuple[Callable, Callable]:
    """The ``__getattr__`` and ``__dir__`` of module ``old``, which moved to ``new``; warns once, when ``old`` is
    imported.

    The old module is a file of one line, ``__getattr__, __dir__ = moved_module(__name__, "pkg.new", "0.3",
    "0.4")``: importing it warns with a `DeprecationWarning` that names ``new`` and the release ``goes_in`` that
    removes ``old``, and every name is looked up in ``new``. No import hook is installed.
    """
    warnings.warn(f"{old} is {new} since {since} (the same names); the old name goes in {goes_in}",
                  DeprecationWarning, stacklevel=3)
    target = importlib.import_module(new)

    def __getattr__(name: str):
        return getattr(target, name)

    def __dir__() -> list[str]:
        return dir(target)

    return __getattr__, __dir__


def moved_names(old: str, homes: Mapping[str, str], since: str, goes_in: str) -> Callable:
    """The ``__getattr__`` of module ``old``, some of whose names moved: ``homes`` maps each to the module that now
    holds it. Each, when asked of ``old``, warns with a `DeprecationWarning` that names its new home and the release
    ``goes_in`` that removes it from ``old``, and is its new home's; any other missing name raises AttributeError as
    usual.

    >>> getattr_ = moved_names("mine", {"JSONDecoder": "json.decoder"}, "0.3", "0.4")
    >>> import warnings
    >>> with warnings.catch_warnings(record=True) as caught:
    ...     warnings.simplefilter("always")
    ...     getattr_("JSONDecoder").__module__, str(caught[0].message)
    ('json.decoder', 'mine.JSONDecoder is json.decoder.JSONDecoder since 0.3; the old name goes in 0.4')
    """
    homes = dict(homes)

    def __getattr__(name: str):
        if name in homes:
            warnings.warn(f"{old}.{name} is {homes[name]}.{name} since {since}; the old name goes in {goes_in}",
                          DeprecationWarning, stacklevel=2)
            return getattr(importlib.import_module(homes[name]), name)
        raise AttributeError(f"module {old!r} has no attribute {name!r}")

    return __getattr__
