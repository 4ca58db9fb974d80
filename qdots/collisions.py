"""The partial-elasticity collision rule (thesis Eq 2.5), run by Chipmunk as compiled callbacks.

Eq 2.5 mixes the elastic outgoing velocity with the centre-of-mass velocity along the line of
centres, ``v = eps * v_elastic + (1 - eps) * v_cm``, and keeps the tangential velocity. That is
exactly a normal coefficient of restitution ``eps`` with zero friction, so Chipmunk's contact
solver does it: dot shapes have friction 0 and a ``begin`` callback sets the arbiter's
restitution for the step in which a contact starts.

Chipmunk recomputes the restitution of a *lasting* contact every step as the product of the two
shapes' elasticities. Dot shapes therefore carry elasticity 0: a contact that persists beyond its
first step is a resting or pressed contact, and the thesis treats slow impacts (below
``sticking_speed``) as perfectly inelastic.

Speed. A film makes ~10 new contacts per Chipmunk step, most of them touching dots that part and
meet again at less than 1 px/s. A Python callback costs ~6 us per contact (a third of Chipmunk's
step on a 300-dot film), so the rule is compiled (`impact_elasticity`) and Chipmunk calls it
through a C function pointer (~0.1 us). The callback reads the two bodies' velocities and the
contact normal from Chipmunk's memory at offsets read off pymunk once (`chipmunk_layout`); if
pymunk's layout is not the one expected, the same compiled rule runs from a Python callback
(slower, same numbers).

Random draws. The n-th elasticity draw of a simulation is a hash of (key, n) turned into a
normal number (`impact_normal`), so a draw does not depend on who makes it and a run resumes bit
for bit from its key and its count of draws (`CollisionRecord`, saved in checkpoints).
"""

from __future__ import annotations

import hashlib
import json
import math
from dataclasses import dataclass

import numpy as np
import pymunk
from numba import carray
from pymunk._chipmunk import ffi, lib

from labrig.compiled import c_callback, jit, pointer
from labrig.validate import real

from .bulk import VELOCITY, body_offsets

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


# -- the collision record: one float64 array the callbacks read and write ----------------------

#: Slots of `CollisionRecord.array`. Float slots: the rule. Integer slots (the same memory read
#: as uint64): the stream key, the counts, and where Chipmunk keeps what the callbacks read.
MEAN, STD, STICKING_SPEED, WALL_ELASTICITY = 0, 1, 2, 3
KEY, DRAWS, DOT_DOT, STUCK, DOT_WALL = 4, 5, 6, 7, 8
ARBITER_WORDS, ARBITER_E, ARBITER_NORMAL, ARBITER_BODY_A, ARBITER_BODY_B, BODY_VELOCITY = 9, 10, 11, 12, 13, 14
SLOTS = 15


@jit(inline=True)
def mix64(z):
    """SplitMix64's finaliser: a bijective 64-bit hash."""
    z = z + np.uint64(0x9E3779B97F4A7C15)
    z = (z ^ (z >> np.uint64(30))) * np.uint64(0xBF58476D1CE4E5B9)
    z = (z ^ (z >> np.uint64(27))) * np.uint64(0x94D049BB133111EB)
    return z ^ (z >> np.uint64(31))


@jit
def impact_normal(key, n):
    """The ``n``-th standard normal draw of the stream ``key`` (uint64s): Box-Muller on two hashed uniforms."""
    key, n = np.uint64(key), np.uint64(n)
    a = mix64(key ^ (np.uint64(2) * n))
    b = mix64(key ^ (np.uint64(2) * n + np.uint64(1)))
    u1 = (float(a >> np.uint64(11)) + 1.0) / 9007199254740992.0  # (0, 1]
    u2 = float(b >> np.uint64(11)) / 9007199254740992.0  # [0, 1)
    return math.sqrt(-2.0 * math.log(u1)) * math.cos(2.0 * math.pi * u2)


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


@c_callback("void(voidptr, voidptr, voidptr)")
def dot_dot_begin(arbiter, space, data):
    """Chipmunk's begin callback of a dot-dot contact (``data``: a record array)."""
    words = carray(data, SLOTS, np.uint64)
    record = carray(data, SLOTS, np.float64)
    n = np.int64(words[ARBITER_WORDS])
    arbiter_words = carray(arbiter, n, np.uint64)
    arbiter_floats = carray(arbiter, n, np.float64)
    va = carray(pointer(arbiter_words[words[ARBITER_BODY_A]] + words[BODY_VELOCITY]), 2, np.float64)
    vb = carray(pointer(arbiter_words[words[ARBITER_BODY_B]] + words[BODY_VELOCITY]), 2, np.float64)
    k = words[ARBITER_NORMAL]  # the normal from body a to body b (Chipmunk's own order, unswapped)
    approach = (va[0] - vb[0]) * arbiter_floats[k] + (va[1] - vb[1]) * arbiter_floats[k + np.uint64(1)]
    arbiter_floats[words[ARBITER_E]] = impact_elasticity(record, words, approach)


@c_callback("void(voidptr, voidptr, voidptr)")
def dot_wall_begin(arbiter, space, data):
    """Chipmunk's begin callback of a dot-wall contact: the wall's restitution."""
    words = carray(data, SLOTS, np.uint64)
    record = carray(data, SLOTS, np.float64)
    arbiter_floats = carray(arbiter, np.int64(words[ARBITER_WORDS]), np.float64)
    words[DOT_WALL] += np.uint64(1)
    arbiter_floats[words[ARBITER_E]] = record[WALL_ELASTICITY]


def chipmunk_layout() -> dict | None:
    """Where Chipmunk keeps what the callbacks read, as word indices into a ``cpArbiter`` and the byte
    offset of a body's velocity; None when pymunk's memory is not laid out as expected.

    The arbiter's fields come from pymunk's own C declarations; the body's velocity from
    `qdots.bulk.body_offsets`.
    """
    arbiter = ffi.typeof("struct cpArbiter")
    offsets = {name: ffi.offsetof(arbiter, name) for name in ("e", "n", "body_a", "body_b")}
    body = body_offsets()
    if any(offset % 8 for offset in offsets.values()) or ffi.sizeof(arbiter) % 8 or body is None:
        return None
    return {"arbiter_words": ffi.sizeof(arbiter) // 8, "e": offsets["e"] // 8, "normal": offsets["n"] // 8,
            "body_a": offsets["body_a"] // 8, "body_b": offsets["body_b"] // 8, "body_velocity": int(body[VELOCITY])}


_LAYOUT = chipmunk_layout()
_BEGIN = "void(*)(struct cpArbiter *, struct cpSpace *, void *)"


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
        if _LAYOUT is not None:
            for slot, name in ((ARBITER_WORDS, "arbiter_words"), (ARBITER_E, "e"), (ARBITER_NORMAL, "normal"),
                               (ARBITER_BODY_A, "body_a"), (ARBITER_BODY_B, "body_b"),
                               (BODY_VELOCITY, "body_velocity")):
                self._words[slot] = _LAYOUT[name]

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
        """True when Chipmunk calls the compiled callbacks directly (pymunk's layout is the one expected)."""
        return _LAYOUT is not None


def install_handlers(space: pymunk.Space, rule: Restitution, record: CollisionRecord,
                     compiled: bool | None = None) -> CollisionRecord:
    """Make ``space`` apply ``rule`` to every new dot-dot and dot-wall contact, counting in ``record``.

    ``record`` must live as long as ``space`` (Chipmunk keeps its address). ``compiled=False``
    runs the same rule from Python callbacks (the fallback; tests compare the two).
    """
    record.set_rule(rule)
    if compiled is None:
        compiled = record.compiled
    if compiled:
        address = ffi.cast("void *", record.array.ctypes.data)
        for (a, b), callback in (((DOT, DOT), dot_dot_begin), ((DOT, WALL), dot_wall_begin)):
            handler = lib.cpSpaceAddCollisionHandler(space._space, a, b)  # pymunk's C handle of the space
            handler.beginFunc = ffi.cast(_BEGIN, callback.address)
            handler.userData = address
        return record
    array = record.array

    def dot_dot(arbiter: pymunk.Arbiter, space: pymunk.Space, data: object) -> None:
        shape_a, shape_b = arbiter.shapes
        va, vb, n = shape_a.body.velocity, shape_b.body.velocity, arbiter.normal
        arbiter.restitution = elasticity_of_impact(array, (va.x - vb.x) * n.x + (va.y - vb.y) * n.y)

    def dot_wall(arbiter: pymunk.Arbiter, space: pymunk.Space, data: object) -> None:
        record.dot_wall += 1
        arbiter.restitution = rule.wall

    space.on_collision(DOT, DOT, begin=dot_dot)
    space.on_collision(DOT, WALL, begin=dot_wall)
    return record
