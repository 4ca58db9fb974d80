"""The partial-elasticity collision rule (thesis Eq 2.5) as pymunk handlers.

Eq 2.5 mixes the elastic outgoing velocity with the centre-of-mass velocity
along the line of centres, ``v = eps * v_elastic + (1 - eps) * v_cm``, and
keeps the tangential velocity. That is exactly a normal coefficient of
restitution ``eps`` with zero friction, so we let Chipmunk's contact solver
do it: dot shapes have friction 0 and a ``begin`` handler sets
``arbiter.restitution`` for the step in which a contact starts.

Chipmunk recomputes the restitution of a *lasting* contact every step as the
product of the two shapes' elasticities. Dot shapes therefore carry
elasticity 0: a contact that persists beyond its first step is a resting or
pressed contact, and the thesis treats slow impacts (below
``sticking_speed``) as perfectly inelastic. Per-step ``pre_solve`` callbacks
would keep the drawn value but cost ~1.5 us per contact per step.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pymunk

from labrig.validate import real

#: Largest sticking speed, px/s.
MAX_STICKING_SPEED = 1e6
#: pymunk collision types of the two kinds of shape.
DOT = 1
WALL = 2


@dataclass(frozen=True)
class Restitution:
    """Coefficients of restitution of the thesis's collision model.

    Parameters
    ----------
    mean : float
        Mean elasticity ``e`` of dot-dot collisions, in [0, 1] (thesis 0.8).
        Each impact draws ``eps ~ Normal(e, min((1 - e)/2, e/2))`` clipped
        to [0, 1], so that complete inelasticity is two standard deviations
        from the mean (thesis ``setElasticity``).
    wall : float
        Restitution of dot-wall impacts, in [0, 1]. The thesis's walls are
        elastic (1.0).
    sticking_speed : float
        Normal approach speed (px/s) below which a dot-dot impact is
        perfectly inelastic (thesis ``completelyInelasticThresh = 1``).
    """

    mean: float = 0.8
    wall: float = 1.0
    sticking_speed: float = 1.0

    def __post_init__(self) -> None:
        for name in ("mean", "wall"):
            object.__setattr__(self, name, real(f"Restitution.{name}", getattr(self, name), 0.0, 1.0))
        object.__setattr__(self, "sticking_speed", real("Restitution.sticking_speed", self.sticking_speed, 0.0,
                                                        MAX_STICKING_SPEED, unit="px/s"))

    @property
    def std(self) -> float:
        """Standard deviation of the per-impact elasticity draw."""
        return min((1.0 - self.mean) / 2.0, self.mean / 2.0)

    def draw(self, rng: np.random.Generator, approach_speed: float) -> float:
        """Elasticity of one dot-dot impact with the given normal approach speed (px/s): the rule the
        collision handlers apply (`install_handlers`), one normal draw from ``rng`` per impact that does
        not stick."""
        if approach_speed < self.sticking_speed:
            return 0.0
        if self.std == 0.0:
            return self.mean
        eps = self.mean + self.std * rng.standard_normal()
        return min(max(eps, 0.0), 1.0)


class CollisionCounter:
    """Counts of impacts seen by the handlers (diagnostics for benchmarks)."""

    __slots__ = ("dot_dot", "dot_wall", "sticking")

    def __init__(self) -> None:
        self.dot_dot = 0
        self.dot_wall = 0
        self.sticking = 0


def install_handlers(space: pymunk.Space, rule: Restitution, rng: np.random.Generator,
                     counter: CollisionCounter | None = None) -> CollisionCounter:
    """Install the dot-dot and dot-wall ``begin`` handlers on ``space``.

    Random draws come from ``rng`` in the order Chipmunk reports new
    contacts, which is deterministic for a given space, so runs repeat
    bit for bit from the same seed.

    Returns
    -------
    CollisionCounter
        Live counts of the impacts handled (``counter`` when given, so counts
        survive a rebuilt space).
    """
    counter = CollisionCounter() if counter is None else counter

    sticking_speed, draw = rule.sticking_speed, rule.draw

    # This runs for every new contact (hundreds per step in a film), so it avoids
    # pymunk's slower accessors (arbiter.bodies, Vec2d arithmetic): ~3 us instead of ~7 us.
    def dot_dot_begin(arbiter: pymunk.Arbiter, space: pymunk.Space, data: object) -> None:
        shape_a, shape_b = arbiter.shapes
        va, vb = shape_a.body.velocity, shape_b.body.velocity
        n = arbiter.normal  # from shape a to shape b
        approach = (va.x - vb.x) * n.x + (va.y - vb.y) * n.y
        counter.dot_dot += 1
        if approach < sticking_speed:
            counter.sticking += 1
            arbiter.restitution = 0.0  # Restitution.draw's sticking case, without the call (most impacts)
        else:
            arbiter.restitution = draw(rng, approach)

    def dot_wall_begin(arbiter: pymunk.Arbiter, space: pymunk.Space, data: object) -> None:
        counter.dot_wall += 1
        arbiter.restitution = rule.wall

    space.on_collision(DOT, DOT, begin=dot_dot_begin)
    space.on_collision(DOT, WALL, begin=dot_wall_begin)
    return counter
