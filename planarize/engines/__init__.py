"""The planarization engines: one model (`planarize.model.Model`), three ways to compute it.

Choose one with its settings object, ``anodize(..., engine=Fast(tolerance=0.05))``, or by name
(``engine="reference"``):

* `Continuum` -- the limit of the thesis's rule as grid and step shrink, with its discretization
  error estimated (`planarize.engines.continuum`, `planarize.resolution`); the default;
* `Fast` -- batched sweeps with incremental updates, compiled (`planarize.engines.fast`);
* `Reference` -- the thesis's sequential algorithm (`planarize.engines.reference`);
* `Matlab` -- the reference with the Matlab listings' shortcuts, to measure them.

The parts: `planarize.engines.base` (surfaces, Eq 3.9, volume accounting), `features` (the slot
layout), `kernels` (the compiled distance kernel), `sets` (the fast engine's oxide sets),
`pyramid` (ball searches), `closer` (where raised oxide can come closer); the continuum engine's
`flow` (the metal's motion) and `offset` (its conformal oxide, surface integrals).
"""

from __future__ import annotations

from labrig.validate import InputError

from .continuum import Continuum
from .fast import Fast
from .reference import Matlab, Reference

#: The engines by name, each as its settings class (default settings: ``ENGINES[name]()``); the first is
#: the default.
ENGINES = {"continuum": Continuum, "fast": Fast, "reference": Reference, "matlab": Matlab}


def engine_settings(engine) -> Continuum | Fast | Reference | Matlab:
    """An engine's settings object from a name of `ENGINES` or a settings object (returned as it is)."""
    if isinstance(engine, tuple(ENGINES.values())):
        return engine
    if isinstance(engine, str) and engine in ENGINES:
        return ENGINES[engine]()
    raise InputError(f"engine must be one of {', '.join(map(repr, ENGINES))} or a settings object "
                     f"(planarize.engines.Fast(...)), got {engine!r}")


__all__ = ["ENGINES", "Continuum", "Fast", "Reference", "Matlab", "engine_settings"]
