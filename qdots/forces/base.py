"""The interface every force implements, and the per-step data it sees."""

from __future__ import annotations

import inspect
import math
from dataclasses import dataclass, field

import numpy as np

from ..engine.pair_scheme import PairScheme
from ..restitution import Restitution


@dataclass
class StepContext:
    """What a force sees at the start of one time step.

    The simulation fills one context again at every step (its arrays are the step's own buffers):
    a force reads it within `Force.kick` and keeps nothing of it.

    Attributes
    ----------
    time : float
        Simulation time at the start of the step, s.
    dt : float
        Length of the step, s.
    x, y : ndarray, shape (N,)
        Dot centres, px (contiguous copies: fast to fancy-index).
    velocity : ndarray, shape (N, 2)
        Dot velocities, px/s. Read-only for forces.
    radii, masses : ndarray, shape (N,)
        Dot radii (px) and masses (mean dot mass = 1).
    rng : numpy.random.Generator
        The simulation's generator; draw from it only, so runs repeat.
    dv : ndarray, shape (N, 2)
        Accumulator: each force *adds* its velocity change, px/s.
    pairs : qdots.engine.PairScheme
        How the engine evaluates pair forces in time (its pair list and multiple time stepping): a pair force
        states its law and leaves which pairs are pulled when to it (`PairScheme.pull`).
    restitution : qdots.Restitution
        The collision rule of the simulation (its sticking speed enters the thesis's van der Waals proxy).
    cache : dict
        This force's cache in this simulation, owned by the engine: what a force derives from the dots
        (per-dot constants, pair lists) it keeps here, never on itself, so one force object serves any
        number of simulations. The engine empties it when the dots or the forces change.
    """

    time: float
    dt: float
    x: np.ndarray
    y: np.ndarray
    velocity: np.ndarray
    radii: np.ndarray
    masses: np.ndarray
    rng: np.random.Generator | None  # (None only in an engine's context between steps)
    dv: np.ndarray
    pairs: PairScheme = field(default_factory=PairScheme)
    restitution: Restitution | None = None
    cache: dict = field(default_factory=dict)


def instants_in_step(time: float, dt: float, interval: float) -> int:
    """How many of the instants ``interval, 2 interval, ...`` (s) fall in the step ``(time, time + dt]``.

    A schedule on the clock, not on a step counter: it does not depend on ``dt`` and needs no state to
    resume. The tolerance absorbs the round-off of a time that is a sum of steps.
    """
    tol = 1e-9
    return math.floor((time + dt) / interval + tol) - math.floor(time / interval + tol)


class Force:
    """A velocity update applied to the dots once per time step: physics only.

    Forces are evaluated on the same start-of-step state and their velocity
    changes summed (first-order operator splitting, as the thesis adds
    "acceleration ... only at the beginning of each time step as a change in
    velocity"); the engine then moves the dots and resolves contacts.

    A force holds its physical parameters and nothing of any run: what it derives from the dots it
    keeps in ``ctx.cache``, which the engine owns. One force object can serve any number of
    simulations, at once or in turn. Subclasses implement `kick`.
    """

    def kick(self, ctx: StepContext) -> None:
        """Add this force's velocity change for one step to ``ctx.dv``."""
        raise NotImplementedError

    def check_rule(self, restitution) -> None:
        """`InputError` when this force cannot act beside the collision rule ``restitution``; called whenever
        either is set. Most forces do not depend on the rule."""

    def check_run(self, dt: float, steps: int | None = None) -> None:
        """`InputError` when a step of ``dt`` s (or a run of ``steps`` such steps) would make this force do
        more work than a run may; called before a run starts. A force that acts once per step has
        nothing to check; a force on its own clock (`instants_in_step`) bounds how often it acts."""

    def params(self) -> dict:
        """The constructor arguments that rebuild this force (plain data, JSON/TOML friendly).

        Subclasses store each constructor argument as an attribute of the same name.
        """
        names = [n for n in inspect.signature(type(self).__init__).parameters if n != "self"]
        return {name: _plain(getattr(self, name)) for name in names}

    def to_dict(self) -> dict:
        """``{"type": class name, **params()}``; `qdots.forces.force_from_dict` inverts it."""
        return {"type": type(self).__name__, **self.params()}

    def __repr__(self) -> str:
        params = ", ".join(f"{k}={v!r}" for k, v in self.params().items())
        return f"{type(self).__name__}({params})"


def _plain(value: object) -> object:
    if isinstance(value, tuple):
        return [_plain(v) for v in value]
    if isinstance(value, np.generic):
        return value.item()
    return value
