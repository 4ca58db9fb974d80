"""The engine settings the qdots benchmarks measure, every knob written out.

A benchmark measures the settings it names, not whatever the library's defaults are on the day it runs: a
change of a default can then neither stretch a benchmark (the 20 ms frame made one run for minutes in quick
mode) nor change what its report says it measured. `CHIPMUNK` and `EVENT` are the defaults of release 0.3.0,
written out knob by knob (`every_knob` refuses a settings class with a knob left out); a benchmark varies them
with `chipmunk` and `event`, checked like any settings. `moved_defaults` names the knobs whose library default
now differs from these, so that a knob table can say which of its settings is the library's default.
"""

from __future__ import annotations

import dataclasses

import qdots


def every_knob(cls: type, **values):
    """``cls(**values)``, the settings class ``cls`` (`qdots.Chipmunk`, `qdots.Event`) with every knob given.

    Raises
    ------
    ValueError
        Naming the knobs not given.
    """
    missing = [f.name for f in dataclasses.fields(cls) if f.name not in values]
    if missing:
        raise ValueError(f"{cls.__name__} settings of a benchmark must give every knob; missing: {', '.join(missing)}")
    return cls(**values)


#: The Chipmunk engine as the benchmarks run it: the defaults of 0.3.0 (the thesis's 20 ms frame).
CHIPMUNK = every_knob(qdots.Chipmunk, dt=0.02, substeps=1, overlap_tolerance=0.005, max_substeps=512, iterations=5,
                      impacts="contact", collision_slop=0.01, collision_bias=None, spatial_hash=None, threads=1,
                      pair_skin=6.0, near_gap=4.0, far_interval=None, tune_allocator=True)
#: The event engine as the benchmarks run it: the defaults of 0.3.0.
EVENT = every_knob(qdots.Event, dt=0.02, max_events=1_000_000, buffer=1e-6, pair_skin=6.0, tune_allocator=True)
#: Both, by engine name.
PINNED = {"chipmunk": CHIPMUNK, "event": EVENT}


def chipmunk(**changes) -> qdots.Chipmunk:
    """`CHIPMUNK` with some knobs changed."""
    return CHIPMUNK.replace(**changes)


def event(**changes) -> qdots.Event:
    """`EVENT` with some knobs changed."""
    return EVENT.replace(**changes)


def engine(kind: str, **changes):
    """The pinned settings of the engine ``kind`` with some knobs changed."""
    return PINNED[kind].replace(**changes)


def moved_defaults() -> list[str]:
    """``"kind.knob = library default (pinned value)"`` for every knob whose library default differs from the
    pinned one (empty while the library keeps the defaults the benchmarks measure)."""
    moved = []
    for kind, pinned in PINNED.items():
        library = type(pinned)()
        for f in dataclasses.fields(pinned):
            if getattr(library, f.name) != getattr(pinned, f.name):
                moved.append(f"{kind}.{f.name} = {getattr(library, f.name)!r} ({getattr(pinned, f.name)!r} measured)")
    return moved


def is_library_default(settings) -> bool:
    """True when ``settings`` are the library's defaults of their engine (what a user gets unasked)."""
    return settings == type(settings)()
