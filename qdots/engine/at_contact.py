"""A prototype, off by default: the Chipmunk engine's impacts resolved at the instant of contact, not where
Chipmunk finds them.

Chipmunk sees a contact only once two discs overlap: positions are moved first in each sub-step, then the
contacts found, then the velocities solved. An impact at approach speed ``u`` is therefore resolved late,
when the discs already overlap by some ``delta`` (up to ``u h`` in a sub-step ``h``, which the sub-step plan
keeps below ``overlap_tolerance`` radii), and the bounce starts from there. The thesis's model resolves it at
contact (its steps 4-11): by the time Chipmunk resolves it the pair would have separated again by
``e delta``. So every impact leaves the pair ``(1 + e) delta`` closer than the model does; Chipmunk's overlap
correction gives back only part of it (30 % of the overlap beyond the slop per sub-step, while the discs
still overlap). For most purposes that is a small position error; with the thesis's van der Waals proxy it
is not, because the proxy acts only at gaps >= 0.1 px and is steepest just above that: pairs that have just
bounced sit closer, fewer of them are back above 0.1 px when the next frame pulls them, and the pull, which
slows a separating pair and speeds an approaching one, adds more energy than it does in the model
(`benchmarks.qdots_energy_budget` measures it).

`resolve_at_contact` installs collision callbacks that do what `qdots.engine.contacts` does (the same rule,
draws and counts, the same record) and, at the first step of a contact that is an impact, move the two
bodies apart along the normal by ``(1 + e) delta``, shared in inverse proportion to their masses (all of it
on the dot at a wall): where the impact at contact would have left them. Velocities are not touched.
A contact that lasts is not moved (its overlap is older than the sub-step). It needs Chipmunk's internals
(`qdots.engine.chipmunk.impact_layout`) and is undone by anything that installs the default callbacks again
(`ChipmunkEngine.build`, `ChipmunkEngine.set_restitution`).
"""

from __future__ import annotations

import numpy as np
from numba import carray

from labrig.compiled import c_callback, jit, pointer

from .chipmunk import (
    DOT,
    POSITION,
    VELOCITY,
    WALL,
    add_pre_solve_callback,
    impact_layout,
    internals,
)
from .contacts import DOT_WALL, RESTING, SLOTS, WALL_ELASTICITY, impact_elasticity

#: Slots of the callbacks' data (uint64 words): the collision record's address, then where Chipmunk keeps
#: what they read.
RECORD, WORDS, E, NORMAL, BODY_A, BODY_B, CONTACTS, STATE, R1, R2, BODY_POSITION, BODY_VELOCITY, INVERSE_MASS = range(13)
DATA_SLOTS = 13


@jit(inline=True)
def _impact(arbiter, data, wall):
    """The rule on one contact (as `qdots.engine.contacts` applies it), and the move back to contact."""
    record = carray(pointer(data[RECORD]), SLOTS, np.float64)
    words = record.view(np.uint64)
    n = np.int64(data[WORDS])
    arbiter_words = carray(arbiter, n, np.uint64)
    arbiter_floats = carray(arbiter, n, np.float64)
    body_a = arbiter_words[data[BODY_A]]
    body_b = arbiter_words[data[BODY_B]]
    va = carray(pointer(body_a + data[BODY_VELOCITY]), 2, np.float64)
    vb = carray(pointer(body_b + data[BODY_VELOCITY]), 2, np.float64)
    k = data[NORMAL]
    nx = arbiter_floats[k]
    ny = arbiter_floats[k + np.uint64(1)]
    approach = (va[0] - vb[0]) * nx + (va[1] - vb[1]) * ny
    if not approach > RESTING:
        arbiter_floats[data[E]] = 0.0
        return
    if wall:
        words[DOT_WALL] += np.uint64(1)
        e = record[WALL_ELASTICITY]
    else:
        e = impact_elasticity(record, words, approach)
    arbiter_floats[data[E]] = e
    if (arbiter_words[data[STATE]] & np.uint64(0xFFFFFFFF)) != np.uint64(0):  # not the contact's first step
        return
    contact = carray(pointer(arbiter_words[data[CONTACTS]]), 4, np.float64)
    pa = carray(pointer(body_a + data[BODY_POSITION]), 2, np.float64)
    pb = carray(pointer(body_b + data[BODY_POSITION]), 2, np.float64)
    r1 = data[R1]
    r2 = data[R2]
    gap = ((pb[0] + contact[r2]) - (pa[0] + contact[r1])) * nx \
        + ((pb[1] + contact[r2 + np.uint64(1)]) - (pa[1] + contact[r1 + np.uint64(1)])) * ny
    if gap >= 0.0:
        return
    ia = carray(pointer(body_a + data[INVERSE_MASS]), 1, np.float64)[0]
    ib = carray(pointer(body_b + data[INVERSE_MASS]), 1, np.float64)[0]
    shift = -(1.0 + e) * gap / (ia + ib)
    pa[0] -= ia * shift * nx
    pa[1] -= ia * shift * ny
    pb[0] += ib * shift * nx
    pb[1] += ib * shift * ny


@c_callback("void(voidptr, voidptr, voidptr)")
def dot_dot_at_contact(arbiter, space, data):
    """Chipmunk's pre-solve callback of a dot-dot contact: the rule, and a first-step impact moved back to contact."""
    _impact(arbiter, carray(data, DATA_SLOTS, np.uint64), False)


@c_callback("void(voidptr, voidptr, voidptr)")
def dot_wall_at_contact(arbiter, space, data):
    """Chipmunk's pre-solve callback of a dot-wall contact: the wall's restitution, and a first-step impact moved
    back to contact."""
    _impact(arbiter, carray(data, DATA_SLOTS, np.uint64), True)


def resolve_at_contact(engine) -> None:
    """Make a `qdots.engine.ChipmunkEngine` resolve every impact at the instant of contact (the module's docstring).

    Install it before the first step for a run that uses it throughout; a `build` or a `set_restitution` of the
    engine puts the default callbacks back. `RuntimeError` without Chipmunk's internals.
    """
    found, layout = internals(), impact_layout()
    if found is None or layout is None:
        raise RuntimeError("resolving impacts at contact needs pymunk's internals (a tested pymunk)")
    data = np.zeros(DATA_SLOTS, dtype=np.uint64)
    data[RECORD] = engine.collisions.array.ctypes.data
    data[WORDS], data[E], data[NORMAL] = found.arbiter["words"], found.arbiter["e"], found.arbiter["normal"]
    data[BODY_A], data[BODY_B] = found.arbiter["body_a"], found.arbiter["body_b"]
    data[CONTACTS], data[STATE], data[R1], data[R2] = layout["contacts"], layout["state"], layout["r1"], layout["r2"]
    data[BODY_POSITION], data[BODY_VELOCITY] = found.body_offsets[POSITION], found.body_offsets[VELOCITY]
    data[INVERSE_MASS] = layout["inverse_mass"]
    engine._at_contact_data = data  # Chipmunk keeps its address: it lives as long as the engine
    for (a, b), callback in (((DOT, DOT), dot_dot_at_contact), ((DOT, WALL), dot_wall_at_contact)):
        add_pre_solve_callback(engine.space, a, b, callback.address, data.ctypes.data)
