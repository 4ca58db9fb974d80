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
cohesive than the thesis's model; see `qdots.engine.chipmunk_step` for the other.)

Speed. A film makes hundreds of contacts per Chipmunk step, too many for a Python callback each, so the rule
is compiled (`impact_elasticity`) and Chipmunk calls it through a C function pointer (docs/performance.md,
"Design measurements"). The callback reads the two bodies' velocities and the contact normal from Chipmunk's memory
(`qdots.engine.pymunk_adapter.internals`); without them (an untested pymunk), the same compiled rule runs from
a Python callback (slower, same numbers).

Impacts at the instant of contact (``Chipmunk(impacts="contact")``, the default).
Chipmunk sees a contact only once two discs overlap: positions move first in each sub-step, then the
contacts are found, then the velocities solved. An impact at approach speed ``u`` is therefore found
late, when the sub-step's motion has pushed the discs ``delta = min(overlap, u h)`` into each other
(``h`` the sub-step, which the sub-step plan keeps ``u h`` below ``overlap_tolerance`` radii), and the
bounce would start from there. The thesis's model resolves it at contact (its steps 4-11): by the end of
the sub-step the pair would have separated again by ``e delta``. So every impact would leave the pair
``(1 + e) delta`` closer than the model, and with the thesis's van der Waals proxy that is not a small
error: the proxy acts only at gaps >= 0.1 px and is steepest just above that, so pairs that bounce from
too close are pulled too hard in the next frame, which injected more energy than the model and left the
films hotter and, with masses ~ d^3, more fragmented (the numbers: docs/engines.md, "Energy budget"). The
callback therefore moves the two bodies of every impact apart along the normal by ``(1 + e) delta``,
shared in inverse proportion to their masses (all of it on the dot at a wall), where the impact at
contact would have left them; velocities are not touched. A lasting contact that a kick drives together
again is moved by what this sub-step's approach made (``u h``), not by its older overlap, which Chipmunk's
position correction handles. Each impact is moved from the positions at which Chipmunk found it: a dot
with two impacts in one sub-step gets both moves. ``impacts = "overlap"`` keeps Chipmunk's own late
resolution (the earlier default).
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
from .pymunk_adapter import DOT, POSITION, VELOCITY, WALL, add_pre_solve_callback, impact_layout, internals

# -- the collision record: one float64 array the callbacks read and write ----------------------

#: Slots of `CollisionRecord.array`. Float slots: the rule and the current sub-step (s). Integer slots (the
#: same memory read as uint64): the stream key, the counts, whether impacts are moved to contact, and where
#: Chipmunk keeps what the callbacks read.
MEAN, STD, STICKING_SPEED, WALL_ELASTICITY, SUBSTEP = 0, 1, 2, 3, 4
KEY, DRAWS, DOT_DOT, STUCK, DOT_WALL, AT_CONTACT = 5, 6, 7, 8, 9, 10
ARBITER_WORDS, ARBITER_E, ARBITER_NORMAL, ARBITER_BODY_A, ARBITER_BODY_B, BODY_VELOCITY = 11, 12, 13, 14, 15, 16
ARBITER_CONTACTS, CONTACT_R1, CONTACT_R2, BODY_POSITION, BODY_INVERSE_MASS, BODY_TRANSLATION = 17, 18, 19, 20, 21, 22
SLOTS = 23
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
def resolve_contact(arbiter, data, wall):
    """The rule on one contact, every step it lasts: an impact (the bodies approach along the normal) gets the
    rule's restitution (a dot-dot draw or 0 below the sticking speed; the wall's) and is counted, and, with
    `AT_CONTACT`, its bodies are moved to where the impact at contact leaves them (the module's docstring); a
    resting or parting contact gets 0."""
    words = carray(data, SLOTS, np.uint64)
    record = carray(data, SLOTS, np.float64)
    n = np.int64(words[ARBITER_WORDS])
    arbiter_words = carray(arbiter, n, np.uint64)
    arbiter_floats = carray(arbiter, n, np.float64)
    body_a = arbiter_words[words[ARBITER_BODY_A]]
    body_b = arbiter_words[words[ARBITER_BODY_B]]
    va = carray(pointer(body_a + words[BODY_VELOCITY]), 2, np.float64)
    vb = carray(pointer(body_b + words[BODY_VELOCITY]), 2, np.float64)
    k = words[ARBITER_NORMAL]
    nx = arbiter_floats[k]
    ny = arbiter_floats[k + np.uint64(1)]
    approach = (va[0] - vb[0]) * nx + (va[1] - vb[1]) * ny
    if not approach > RESTING:
        arbiter_floats[words[ARBITER_E]] = 0.0
        return
    if wall:
        words[DOT_WALL] += np.uint64(1)
        e = record[WALL_ELASTICITY]
    else:
        e = impact_elasticity(record, words, approach)
    arbiter_floats[words[ARBITER_E]] = e
    if words[AT_CONTACT] == np.uint64(0):
        return
    contact = carray(pointer(arbiter_words[words[ARBITER_CONTACTS]]), 4, np.float64)
    pa = carray(pointer(body_a + words[BODY_POSITION]), 2, np.float64)
    pb = carray(pointer(body_b + words[BODY_POSITION]), 2, np.float64)
    r1 = words[CONTACT_R1]
    r2 = words[CONTACT_R2]
    gap = ((pb[0] + contact[r2]) - (pa[0] + contact[r1])) * nx \
        + ((pb[1] + contact[r2 + np.uint64(1)]) - (pa[1] + contact[r1 + np.uint64(1)])) * ny
    made = min(-gap, approach * record[SUBSTEP])
    if not made > 0.0:
        return
    ia = carray(pointer(body_a + words[BODY_INVERSE_MASS]), 1, np.float64)[0]
    ib = carray(pointer(body_b + words[BODY_INVERSE_MASS]), 1, np.float64)[0]
    shift = (1.0 + e) * made / (ia + ib)
    pa[0] -= ia * shift * nx
    pa[1] -= ia * shift * ny
    pb[0] += ib * shift * nx
    pb[1] += ib * shift * ny
    for body, p in ((body_a, pa), (body_b, pb)):  # Body.position reads it until the next step sets it from p (a disc)
        t = carray(pointer(body + words[BODY_TRANSLATION]), 2, np.float64)
        t[0] = p[0]
        t[1] = p[1]


@c_callback("void(voidptr, voidptr, voidptr)")
def dot_dot_pre_solve(arbiter, space, data):
    """Chipmunk's pre-solve callback of a dot-dot contact, every step it lasts (`resolve_contact`)."""
    resolve_contact(arbiter, data, False)


@c_callback("void(voidptr, voidptr, voidptr)")
def dot_wall_pre_solve(arbiter, space, data):
    """Chipmunk's pre-solve callback of a dot-wall contact, every step it lasts (`resolve_contact`)."""
    resolve_contact(arbiter, data, True)


def stream_key(rng: np.random.Generator) -> int:
    """A 64-bit key for the elasticity draws, derived from (and not advancing) ``rng``'s state."""
    state = json.dumps(rng.bit_generator.state, sort_keys=True).encode()
    return int.from_bytes(hashlib.blake2b(state, digest_size=8).digest(), "little")


def _word(slot: int) -> property:
    """A `CollisionRecord` count kept as an integer in the word ``slot`` of its array."""
    return property(lambda self: int(self._words[slot]),
                    lambda self, value: self._words.__setitem__(slot, int(value)))


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
        found, layout = internals(), impact_layout()
        if found is not None and layout is not None:
            for slot, name in ((ARBITER_WORDS, "words"), (ARBITER_E, "e"), (ARBITER_NORMAL, "normal"),
                               (ARBITER_BODY_A, "body_a"), (ARBITER_BODY_B, "body_b")):
                self._words[slot] = found.arbiter[name]
            self._words[[BODY_VELOCITY, BODY_POSITION]] = found.body_offsets[[VELOCITY, POSITION]]
            for slot, name in ((ARBITER_CONTACTS, "contacts"), (CONTACT_R1, "r1"), (CONTACT_R2, "r2"),
                               (BODY_INVERSE_MASS, "inverse_mass"), (BODY_TRANSLATION, "translation")):
                self._words[slot] = layout[name]

    key = _word(KEY)
    draws = _word(DRAWS)
    dot_dot = _word(DOT_DOT)
    sticking = _word(STUCK)
    dot_wall = _word(DOT_WALL)

    #: What a checkpoint saves.
    SAVED = ("dot_dot", "dot_wall", "sticking", "draws", "key")

    def to_dict(self) -> dict:
        return {name: getattr(self, name) for name in self.SAVED}

    def copy_from(self, other: CollisionRecord) -> None:
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
    def substep(self) -> float:
        """The current Chipmunk sub-step, s (set by the stepper before it steps: impacts at contact read it)."""
        return float(self.array[SUBSTEP])

    @substep.setter
    def substep(self, h: float) -> None:
        self.array[SUBSTEP] = h

    @property
    def compiled(self) -> bool:
        """True when Chipmunk calls the compiled callbacks directly (`qdots.engine.pymunk_adapter.internals` and
        `qdots.engine.pymunk_adapter.impact_layout`)."""
        return internals() is not None and impact_layout() is not None


def install_handlers(space: pymunk.Space, rule: Restitution, record: CollisionRecord, at_contact: bool = True,
                     compiled: bool | None = None) -> CollisionRecord:
    """Make ``space`` apply ``rule`` to every dot-dot and dot-wall impact, counting them in ``record``.

    ``at_contact``: move each impact's bodies to where the impact at contact leaves them (the module's
    docstring; `qdots.engine.Chipmunk.impacts`). ``record`` must live as long as ``space`` (Chipmunk keeps its
    address) and its `CollisionRecord.substep` must be the sub-step Chipmunk takes. ``compiled=False`` runs the
    same rule from Python callbacks (the fallback; tests compare the two).
    """
    record.set_rule(rule)
    record._words[AT_CONTACT] = bool(at_contact)
    if compiled is None:
        compiled = record.compiled
    if compiled:
        for (a, b), callback in (((DOT, DOT), dot_dot_pre_solve), ((DOT, WALL), dot_wall_pre_solve)):
            add_pre_solve_callback(space, a, b, callback.address, record.array.ctypes.data)
        return record
    array = record.array

    def resolve(arbiter: pymunk.Arbiter, wall: bool) -> None:
        shape_a, shape_b = arbiter.shapes
        a, b, n = shape_a.body, shape_b.body, arbiter.normal
        assert a is not None and b is not None  # a colliding shape is attached to a body
        speed = (a.velocity.x - b.velocity.x) * n.x + (a.velocity.y - b.velocity.y) * n.y
        if not speed > RESTING:
            arbiter.restitution = 0.0
            return
        if wall:
            record.dot_wall += 1
            e = rule.wall
        else:
            e = elasticity_of_impact(array, speed)
        arbiter.restitution = e
        made = min(-min(point.distance for point in arbiter.contact_point_set.points), speed * record.substep)
        if at_contact and made > 0.0:
            ia, ib = (1.0 / body.mass if body.body_type == pymunk.Body.DYNAMIC else 0.0 for body in (a, b))
            shift = (1.0 + e) * made / (ia + ib)
            a.position -= n * (ia * shift)
            b.position += n * (ib * shift)

    space.on_collision(DOT, DOT, pre_solve=lambda arbiter, space, data: resolve(arbiter, False))
    space.on_collision(DOT, WALL, pre_solve=lambda arbiter, space, data: resolve(arbiter, True))
    return record


def start_run(walls: np.ndarray, settings, key: int) -> tuple[np.ndarray, CollisionRecord]:
    """What every engine does first: the allocator tuning when ``settings.tune_allocator`` asks for it
    (`qdots.engine.allocator`), the walls as a contiguous (M, 4) array (px), and a fresh collision record whose
    draws follow ``key``."""
    if settings.tune_allocator:
        tune_allocator()
    return np.ascontiguousarray(walls, dtype=float).reshape(-1, 4), CollisionRecord(key)
