"""The planarization engines: one model (`planarize.model.Model`), three ways to compute it.

Choose one with its settings object, ``anodize(..., engine=Fast(tolerance=0.05))``, or by name
(``engine="reference"``):

* `Continuum` -- the limit of the thesis's rule as grid and step shrink, with its discretization
  error estimated (`planarize.engines.continuum`, `planarize.engines.resolution`); the default;
* `Fast` -- batched sweeps with incremental updates, compiled (`planarize.engines.fast`);
* `Reference` -- the thesis's sequential algorithm (`planarize.engines.reference`);
* `Matlab` -- the reference with the Matlab listings' shortcuts, to measure them.

Each settings class builds its engine and runs it (the contracts: `planarize.engines.protocol`); `anodize`
checks a run's arguments and calls the settings' ``run``. The parts: `planarize.engines.base` (surfaces, Eq 3.9,
volume accounting, `run_sweeps`: the thesis's engines' run), `features` (the slot
layout), `kernels` (the compiled distance kernel), `sets` (the fast engine's oxide sets),
`pyramid` (ball searches), `closer` (where raised oxide can come closer); the continuum engine's
`flow` (the metal's motion), `offset` (its conformal oxide, surface integrals) and `resolution` (its driver:
the grid a tolerance asks for, and the error estimate).
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any, cast

from labrig.params import Param
from labrig.tomlfile import as_table, check_keys
from labrig.validate import InputError

if TYPE_CHECKING:
    from .continuum import Continuum
    from .fast import Fast
    from .reference import Matlab, Reference

#: Each engine's name (the first is the default) with the module and name of its settings class. The engines
#: are imported when first used (``ENGINES``, ``Fast``, ...), so that the command line lists their names at once.
HOMES = {"continuum": (".continuum", "Continuum"), "fast": (".fast", "Fast"), "reference": (".reference", "Reference"),
         "matlab": (".reference", "Matlab")}
#: The engines' names, the default first.
NAMES = tuple(HOMES)
#: Declaration of ``kind``, the key of a scene file's ``[engine]`` table that names the engine its other keys set.
KIND = Param("str", choices=NAMES, doc='the engine ("continuum": the thesis rule\'s converged limit, with its error; '
                                      '"fast": the thesis algorithm batched; "reference": the thesis algorithm, slow)')

#: The continuum engine's default tolerance: the relative discretization error of RMS and z-range a run aims at.
RTOL = 0.02
#: Interacting candidates of a fast engine's batch: wait for the next batch, or go together (faster, within the
#: tolerance).
INTERACTING = ("wait", "together")
#: The settings each engine's ``[engine]`` table takes, declared once: its settings class checks its fields with
#: them (``Continuum.PARAMS`` is ``PARAMS["continuum"]``), and the command line's options and help come from them
#: without importing an engine.
PARAMS: dict[str, dict[str, Param]] = {
    "continuum": {"rtol": Param("float", 1e-4, 1.0, doc="relative discretization error of RMS and z-range aimed "
                                                         "at (continuum engine)")},
    "fast": {"tolerance": Param("float", 0.0, 1e6, unit="nm", optional=True, doc="batch tolerance (fast engine)",
                                unset="step / 10"),
             "interacting": Param("str", choices=INTERACTING, doc='interacting candidates of a batch (fast engine; '
                                                                  '"together" is faster, within the tolerance)')},
    "reference": {},
    "matlab": {},
}


def __getattr__(name: str) -> Any:
    """``ENGINES`` (the engines by name, each as its settings class; default settings: ``ENGINES[name]()``) and
    the settings classes, imported when first asked for."""
    if name == "ENGINES":
        return {engine: __getattr__(cls) for engine, (_, cls) in HOMES.items()}
    for module, cls in HOMES.values():
        if name == cls:
            return getattr(importlib.import_module(module, __name__), cls)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def engine_settings(engine) -> Continuum | Fast | Reference | Matlab:
    """An engine's settings object from a name of `ENGINES` or a settings object (returned as it is)."""
    engines = __getattr__("ENGINES")
    if isinstance(engine, tuple(engines.values())):  # the classes are imported lazily: mypy cannot narrow
        return cast("Continuum | Fast | Reference | Matlab", engine)
    if isinstance(engine, str) and engine in engines:
        return engines[engine]()
    raise InputError(f"engine must be one of {', '.join(map(repr, engines))} or a settings object "
                     f"(planarize.engines.Fast(...)), got {engine!r}")


def engine_params(engine) -> dict[str, Param]:
    """The declarations of an ``[engine]`` table holding ``engine`` (a name or settings): `KIND`, then the fields
    its settings class declares (``PARAMS``)."""
    return {"kind": KIND, **type(engine_settings(engine)).PARAMS}


def engine_to_dict(engine) -> dict:
    """An engine's settings as a scene file's ``[engine]`` table: ``kind`` and every declared field (unset ones,
    None, left out)."""
    settings = engine_settings(engine)
    values = {key: getattr(settings, key) for key in type(settings).PARAMS}
    return {"kind": settings.name, **{key: value for key, value in values.items() if value is not None}}


def engine_from_dict(table: dict, where: str = "engine") -> Continuum | Fast | Reference | Matlab:
    """The settings an ``[engine]`` table states: its ``kind`` (default the first of `NAMES`) and that engine's
    declared settings. A key of another engine is refused with the engine it belongs to; errors name the key as
    ``where.KEY``."""
    table = as_table(where, table)
    kind = KIND.check(f"{where}.kind", table.get("kind", NAMES[0]))
    engines = __getattr__("ENGINES")
    declared = engines[kind].PARAMS
    for key in table:
        if key == "kind" or key in declared:
            continue
        owners = [name for name, cls in engines.items() if key in cls.PARAMS]
        if owners:
            raise InputError(f"{where}.{key} is a setting of the {owners[0]} engine, not of engine {kind!r}: leave it "
                             "out")
        check_keys(where, [key], ["kind", *declared])
    values = {key: declared[key].check(f"{where}.{key}", value) for key, value in table.items() if key != "kind"}
    return engines[kind](**values)


__all__ = ["ENGINES", "NAMES", "KIND", "engine_params", "engine_to_dict", "engine_from_dict", "Continuum", "Fast", "Reference", "Matlab", "engine_settings"]
