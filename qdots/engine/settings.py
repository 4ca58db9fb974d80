"""What the settings of every engine share: the time step, plain-data form, and the switch to another engine.

Each engine has its own frozen settings class, which declares its knobs (`labrig.params.Param`), checks them
and builds the engine's `qdots.engine.Backend` for a simulation: `qdots.engine.Chipmunk` and
`qdots.engine.Event`. Their numbers (what each knob costs and changes, measured) are on the documentation's
engines page (docs/engines.md).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import TYPE_CHECKING, ClassVar

from labrig.params import Param, check_fields
from labrig.validate import InputError

from ..units import THESIS_KICK_INTERVAL

if TYPE_CHECKING:
    from .pair_scheme import PairScheme
    from .protocol import Backend

#: Time step range, s: the thesis's frame is 0.02 s; below 1e-7 s a second takes ten million steps.
DT_RANGE = (1e-7, 0.1)
#: The thesis's frame, s: its time step (the thermal kicks' interval too).
THESIS_FRAME = THESIS_KICK_INTERVAL
#: Declaration of the time step every engine takes.
DT = Param("float", *DT_RANGE, unit="s", doc="time step")
#: Declaration of ``tune_allocator``, which every engine takes.
TUNE_ALLOCATOR = Param("bool", doc="raise glibc's allocator thresholds (speed only)")


@dataclass(frozen=True)
class Settings:
    """The base of the engines' settings classes: frozen, checked when made, plain data in files.

    A subclass declares its fields in ``PARAMS`` (every field, in the order files list them), names its engine
    in ``kind`` and builds the engine in `build`.
    """

    #: The engine's name in files (``[engine] kind``) and on the command line (``--engine``).
    kind: ClassVar[str] = ""
    #: Declarations of the fields: checks and file comments (`labrig.params`).
    PARAMS: ClassVar[dict[str, Param]] = {}
    #: Settings that every version's state files of this engine hold (those added later take their defaults
    #: when an older file is loaded).
    SAVED: ClassVar[tuple[str, ...]] = ()

    #: Time step, s: every engine takes one (each subclass declares it first, with its default).
    dt: float = THESIS_FRAME

    def __post_init__(self) -> None:
        check_fields(self, self.PARAMS)

    @property
    def pairs(self) -> PairScheme:
        """How the engine evaluates pair forces in time (`qdots.engine.PairScheme`)."""
        raise NotImplementedError

    def build(self, walls, restitution, key: int, positions, velocities, radii, masses) -> Backend:
        """The engine of one simulation, holding these dots (validated by the caller, a `qdots.Scene`).

        Parameters
        ----------
        walls : ndarray, shape (M, 4)
            Static segments ``(x0, y0, x1, y1)``, px (the box edges included when the board is closed).
        restitution : qdots.Restitution
            The collision rule.
        key : int
            Key of the collision rule's draw stream (`qdots.engine.contacts.stream_key`).
        positions, velocities : ndarray, shape (N, 2)
            Centres (px) and velocities (px/s).
        radii, masses : ndarray, shape (N,)
            Radii (px) and masses (mean dot masses).
        """
        raise NotImplementedError

    def replace(self, **changes) -> Settings:
        """A copy with some settings changed, checked again.

        ``kind`` switches to another engine's settings: those the two engines share (``dt``, ``pair_skin``,
        ``tune_allocator``) carry over, the others take that engine's defaults.
        """
        kind = changes.pop("kind", self.kind)
        if kind == self.kind:
            return dataclasses.replace(self, **changes)
        cls = engine_class(kind)
        shared = {name: getattr(self, name) for name in cls.PARAMS if name in self.PARAMS}
        return cls(**{**shared, **changes})

    def to_dict(self) -> dict:
        """Plain data (JSON/TOML friendly): ``kind`` and every field; `engine_from_dict` inverts it."""
        return {"kind": self.kind, **{name: (list(value) if isinstance(value, tuple) else value)
                                      for name, value in dataclasses.asdict(self).items()}}


def engine_class(kind) -> type[Settings]:
    """The settings class of the engine ``kind``; `InputError` listing the engines otherwise."""
    from . import ENGINES

    if not isinstance(kind, str) or kind not in ENGINES:
        raise InputError(f"engine.kind must be one of {', '.join(map(repr, ENGINES))}, got {kind!r}")
    return ENGINES[kind]


def engine_from_dict(data) -> Settings:
    """The settings of a `Settings.to_dict` table (``kind`` defaults to ``"chipmunk"``); `InputError` on an unknown
    key or a bad value."""
    if not isinstance(data, dict):
        raise InputError(f"engine settings must be a table, got {data!r}")
    data = dict(data)
    cls = engine_class(data.pop("kind", "chipmunk"))
    unknown = [key for key in data if key not in cls.PARAMS]
    if unknown:
        raise InputError(f"unknown {cls.kind} engine setting {unknown[0]!r} (known: kind, {', '.join(cls.PARAMS)})")
    return cls(**data)
