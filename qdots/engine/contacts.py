"""The collision rule (`qdots.restitution`) run by Chipmunk: compiled pre-solve callbacks and their memory.

Chipmunk's contact solver applies a coefficient of restitution with zero friction, which is Eq 2.5: dot
shapes have friction 0, and a callback sets each contact's restitution. The thesis draws one restitution
per impact, and an impact is any moment two dots approach at contact, whether their contact is new or has
lasted (a kick drives a dot into a neighbour it already touches). The callback therefore runs in every
step a contact lasts (Chipmunk's ``preSolve``, before it solves the contact from the velocities the
step began with): when the dots approach, the rule gives the restitution (a draw, or 0 below the
sticking speed) and counts an impact; a resting or parting contact gets 0. (Until 0.3 the rule ran
only in a contact's first step, and a lasting contact was perfectly inelastic: every kick into a
touching neighbour was absorbed, one reason why films of unequal masses came out colder and more
cohesive than the thesis's model; see `qdots.engine.stepping` for the other.)

Speed. A film makes hundreds of contacts per Chipmunk step. A Python callback costs ~6 us per contact,
so the rule is compiled (`impact_elasticity`) and Chipmunk calls it through a C function pointer
(~0.1 us). The callback reads the two bodies' velocities and the contact normal from Chipmunk's memory
(`qdots.engine.chipmunk.internals`); without them (an untested pymunk), the same compiled rule runs from
a Python callback (slower, same numbers).
"""

from __future__ import annotations

import hashlib
import json
import math

import numpy as np
import pymunk
from numba import carray

from labrig.compiled import c_callback, jit, pointer

from ..restitution import Restitution, impact_normal
from .allocator import tune_allocator
from .chipmunk import DOT, VELOCITY, WALL, add_pre_solve_callback, internals


# -- the collision record: one float64 array the callbacks read and write ----------------------

#: Slots of `CollisionRecord.array`. Float slots: the rule. Integer slots (the same memory read
#: as uint64): the stream key, the counts, and where Chipmunk keeps what the callbacks read.
MEAN, STD, STICKING_SPEED, WALL_ELASTICITY = 0, 1, 2, 3
KEY, DRAWS, DOT_DOT, STUCK, DOT_WALL = 4, 5, 6, 7, 8
ARBITER_WORDS, ARBITER_E, ARBITER_NORMAL, ARBITER_BODY_A, ARBITER_BODY_B, BODY_VELOCITY = 9, 10, 11, 12, 13, 14
SLOTS = 15
#: Slowest approach, px/s, that is an impact: a lasting contact whose solve left the dots closing more slowly
#: (round-off) is resting, not a new impact.
RESTING = 1e-9


@jit(inline=True)
def impact_elasticity(record, words, approach):
    """The restitution of a new dot-dot contact with normal approach speed ``approach`` (px/s): 0 below
    the sticking speed, else a draw from Normal(mean, std) clipped to [0, 1]; counts the impact."""
    words[DOT_DOT] += np.uint64(1)
    if approach < record[STICKING_SPEED]:
        words[STUCK] += np.uint64(1)
        return 0.0
    eps = record[MEAN]
    if record[STD] > 0.0:
        eps += record[STD] * impact_normal(words[KEY], words[DRAWS])
        words[DRAWS] += np.uint64(1)
    return min(max(eps, 0.0), 1.0)


@jit
def elasticity_of_impact(record, approach):
    """`impact_elasticity` on a record array, callable from Python (the fallback callback, tests)."""
    return impact_elasticity(record, record.view(np.uint64), approach)


@jit(inline=True)
def contact_approach(arbiter, words):
    """``(floats, approach)``: the arbiter's memory as float64 words and the speed (px/s) at which its two
    bodies approach along its normal (a wall's static body has velocity 0, on either side)."""
    n = np.int64(words[ARBITER_WORDS])
    arbiter_words = carray(arbiter, n, np.uint64)
    arbiter_floats = carray(arbiter, n, np.float64)
    va = carray(pointer(arbiter_words[words[ARBITER_BODY_A]] + words[BODY_VELOCITY]), 2, np.float64)
    vb = carray(pointer(arbiter_words[words[ARBITER_BODY_B]] + words[BODY_VELOCITY]), 2, np.float64)
    k = words[ARBITER_NORMAL]
    return arbiter_floats, (va[0] - vb[0]) * arbiter_floats[k] + (va[1] - vb[1]) * arbiter_floats[k + np.uint64(1)]


@c_callback("void(voidptr, voidptr, voidptr)")
def dot_dot_pre_solve(arbiter, space, data):
    """Chipmunk's pre-solve callback of a dot-dot contact, every step it lasts: an impact (the dots approach)
    gets the rule's restitution (a draw, or 0 below the sticking speed); a resting or parting contact 0."""
    words = carray(data, SLOTS, np.uint64)
    record = carray(data, SLOTS, np.float64)
    arbiter_floats, approach = contact_approach(arbiter, words)
    arbiter_floats[words[ARBITER_E]] = impact_elasticity(record, words, approach) if approach > RESTING else 0.0


@c_callback("void(voidptr, voidptr, voidptr)")
def dot_wall_pre_solve(arbiter, space, data):
    """Chipmunk's pre-solve callback of a dot-wall contact, every step it lasts: an impact gets the wall's
    restitution (counted), a resting or parting contact 0."""
    words = carray(data, SLOTS, np.uint64)
    record = carray(data, SLOTS, np.float64)
    arbiter_floats, approach = contact_approach(arbiter, words)
    if approach > RESTING:
        words[DOT_WALL] += np.uint64(1)
        arbiter_floats[words[ARBITER_E]] = record[WALL_ELASTICITY]
    else:
        arbiter_floats[words[ARBITER_E]] = 0.0


def stream_key(rng: np.random.Generator) -> int:
    """A 64-bit key for the elasticity draws, derived from (and not advancing) ``rng``'s state."""
    state = json.dumps(rng.bit_generator.state, sort_keys=True).encode()
    return int.from_bytes(hashlib.blake2b(state, digest_size=8).digest(), "little")


class CollisionRecord:
    """The collision rule's memory: its parameters, the draw stream and the impact counts.

    Chipmunk's callbacks read and write `array` directly; the counts and the stream position
    (``key``, ``draws``) are what a checkpoint saves to resume bit for bit.

    Parameters
    ----------
    key : int
        Key of the elasticity stream (0 <= key < 2**64), e.g. `stream_key` of the simulation's generator.
    """

    def __init__(self, key: int = 0) -> None:
        self.array = np.zeros(SLOTS)
        self._words = self.array.view(np.uint64)
        self.key = key
        found = internals()
        if found is not None:
            for slot, name in ((ARBITER_WORDS, "words"), (ARBITER_E, "e"), (ARBITER_NORMAL, "normal"),
                               (ARBITER_BODY_A, "body_a"), (ARBITER_BODY_B, "body_b")):
                self._words[slot] = found.arbiter[name]
            self._words[BODY_VELOCITY] = found.body_offsets[VELOCITY]

    def _get(slot):
        return property(lambda self: int(self._words[slot]),
                        lambda self, value: self._words.__setitem__(slot, int(value)))

    key = _get(KEY)
    draws = _get(DRAWS)
    dot_dot = _get(DOT_DOT)
    sticking = _get(STUCK)
    dot_wall = _get(DOT_WALL)
    del _get

    #: What a checkpoint saves.
    SAVED = ("dot_dot", "dot_wall", "sticking", "draws", "key")

    def to_dict(self) -> dict:
        return {name: getattr(self, name) for name in self.SAVED}

    def copy_from(self, other: "CollisionRecord") -> None:
        """Take ``other``'s counts and stream position (a simulation that goes on from another)."""
        for name in self.SAVED:
            setattr(self, name, getattr(other, name))

    def set_rule(self, rule: Restitution) -> None:
        self.array[[MEAN, STD, STICKING_SPEED, WALL_ELASTICITY]] = (rule.mean, rule.std, rule.sticking_speed,
                                                                    rule.wall)

    def next_elasticity(self, approach: float = math.inf) -> float:
        """The restitution the next dot-dot impact at ``approach`` px/s will get (nothing is counted or drawn)."""
        return float(elasticity_of_impact(self.array.copy(), float(approach)))

    @property
    def compiled(self) -> bool:
        """True when Chipmunk calls the compiled callbacks directly (`qdots.engine.chipmunk.internals`)."""
        return internals() is not None


def install_handlers(space: pymunk.Space, rule: Restitution, record: CollisionRecord,
                     compiled: bool | None = None) -> CollisionRecord:
    """Make ``space`` apply ``rule`` to every dot-dot and dot-wall impact, counting them in ``record``.

    ``record`` must live as long as ``space`` (Chipmunk keeps its address). ``compiled=False``
    runs the same rule from Python callbacks (the fallback; tests compare the two).
    """
    record.set_rule(rule)
    if compiled is None:
        compiled = record.compiled
    if compiled:
        for (a, b), callback in (((DOT, DOT), dot_dot_pre_solve), ((DOT, WALL), dot_wall_pre_solve)):
            add_pre_solve_callback(space, a, b, callback.address, record.array.ctypes.data)
        return record
    array = record.array

    def approach(arbiter: pymunk.Arbiter) -> float:
        shape_a, shape_b = arbiter.shapes
        va, vb, n = shape_a.body.velocity, shape_b.body.velocity, arbiter.normal
        return (va.x - vb.x) * n.x + (va.y - vb.y) * n.y

    def dot_dot(arbiter: pymunk.Arbiter, space: pymunk.Space, data: object) -> None:
        speed = approach(arbiter)
        arbiter.restitution = elasticity_of_impact(array, speed) if speed > RESTING else 0.0

    def dot_wall(arbiter: pymunk.Arbiter, space: pymunk.Space, data: object) -> None:
        impact = approach(arbiter) > RESTING
        record.dot_wall += impact
        arbiter.restitution = rule.wall if impact else 0.0

    space.on_collision(DOT, DOT, pre_solve=dot_dot)
    space.on_collision(DOT, WALL, pre_solve=dot_wall)
    return record


def start_run(walls: np.ndarray, settings, key: int) -> tuple[np.ndarray, CollisionRecord]:
    """What every engine does first: the allocator tuning when ``settings.tune_allocator`` asks for it
    (`qdots.engine.allocator`), the walls as a contiguous (M, 4) array (px), and a fresh collision record whose
    draws follow ``key``."""
    if settings.tune_allocator:
        tune_allocator()
    return np.ascontiguousarray(walls, dtype=float).reshape(-1, 4), CollisionRecord(key)
