"""The Chipmunk adapter: building a `pymunk.Space` for a scene, and the one place that reaches into pymunk.

pymunk's public API (``Space``, ``Body``, ``Circle``, ``Segment``, ``pymunk.batch``, ``Space.on_collision``,
``Space.step``) does everything a simulation needs. Four of pymunk's internals make it several times
faster, and they are written for the pymunk versions in `TESTED_PYMUNK` (7.3, Chipmunk 2.0.1):

* where Chipmunk keeps a body's position and velocity (`Internals.body_offsets`), so compiled code
  reads and writes them directly (`qdots.engine.bodies`);
* where it keeps an arbiter's restitution, normal and bodies (`Internals.arbiter`), so the collision rule
  runs as a compiled C callback (`qdots.engine.contacts`, `add_pre_solve_callback`);
* its C step without pymunk's Python bookkeeping (`advance`);
* ``cpSpaceSetCurrentTimeStep``, which tells Chipmunk the length of the last sub-step when the sub-step
  changes (`set_last_substep`).

`internals` finds them once, when the first simulation is built (nothing is probed at import). On a
pymunk outside `TESTED_PYMUNK`, or when the memory is not laid out as expected, it returns None and
warns once: every engine module then runs on the public API alone, with the same numbers at a fixed
sub-step and slower; when the sub-step changes between steps, Chipmunk re-applies its warm-start
impulses scaled by the ratio of the sub-steps (an elastic gas then gains or loses a few per cent of
its energy over many impacts).
"""

from __future__ import annotations

import functools
import math
import warnings
from dataclasses import dataclass

import numpy as np
import pymunk

from .chipmunk import Chipmunk

#: (major, minor) versions of pymunk whose internals this module was written for and tested with.
TESTED_PYMUNK = ((7, 3),)
#: pymunk collision types of the two kinds of shape.
DOT = 1
WALL = 2
#: pymunk's records of work its ``Space.step`` does in Python after the C step (pymunk 7.3).
_PYMUNK_PENDING = ("_bodies_to_check", "_add_later", "_remove_later", "_post_step_callbacks")
#: The C type of a collision callback.
_CALLBACK = "void(*)(struct cpArbiter *, struct cpSpace *, void *)"


@dataclass(frozen=True)
class Internals:
    """Where Chipmunk keeps what compiled code reads and writes.

    Attributes
    ----------
    body_offsets : ndarray of uint64, shape (2,)
        Byte offsets of a body's position and velocity vectors (`POSITION`, `VELOCITY`).
    arbiter : dict
        Word (8-byte) indices into a ``cpArbiter``: its size in words (``"words"``), the restitution
        ``"e"``, the normal ``"normal"``, the two body pointers ``"body_a"``, ``"body_b"``.
    """

    body_offsets: np.ndarray
    arbiter: dict


#: Index of each field's byte offset in `Internals.body_offsets`.
POSITION, VELOCITY = 0, 1


def pymunk_tested(version: str | None = None) -> bool:
    """Whether ``version`` (default: the installed pymunk's) is one of `TESTED_PYMUNK`."""
    parts = (version or pymunk.version).split(".")
    try:
        return (int(parts[0]), int(parts[1])) in TESTED_PYMUNK
    except (IndexError, ValueError):
        return False


@functools.cache
def internals() -> Internals | None:
    """pymunk's internals the engine uses, found once per process; None (with one warning) when they cannot
    be used: an untested pymunk, or memory not laid out as expected."""
    why = None
    found = None
    if not pymunk_tested():
        why = f"pymunk {pymunk.version} is not a tested version ({_tested_text()})"
    else:
        offsets = _body_offsets()
        arbiter = _arbiter_layout() if offsets is not None else None
        if offsets is None or arbiter is None:
            why = f"pymunk {pymunk.version} does not lay out its bodies and arbiters as expected"
        else:
            found = Internals(offsets, arbiter)
    if found is None:
        warnings.warn(f"{why}: qdots runs on pymunk's public API alone (same results at a fixed sub-step, "
                      "slower; sub-step changes are not rescaled). Install a tested pymunk for speed: "
                      f"{_tested_text()}", RuntimeWarning, stacklevel=3)
    return found


def _tested_text() -> str:
    return ", ".join(f"{major}.{minor}.x" for major, minor in TESTED_PYMUNK)


def _ffi():
    from pymunk._chipmunk import ffi

    return ffi


def _lib():
    from pymunk._chipmunk import lib

    return lib


def body_address(body: pymunk.Body) -> int:
    """The address of a body's Chipmunk struct (valid while the body lives)."""
    return int(_ffi().cast("uintptr_t", body._body))


def _body_offsets() -> np.ndarray | None:
    """Byte offsets of a Chipmunk body's position and velocity vectors, or None when pymunk's memory is
    not laid out as expected.

    The body struct is opaque to pymunk's declarations, so each field is found by writing two
    different known values through pymunk (a disc body: no rotation, centre of gravity at its
    position) and reading them back from memory. The velocity must be found at exactly one
    offset; the position is also the translation of the body's transform, further on, so the first
    of its offsets (Chipmunk's ``cpBody.p``, which its integrator moves) is taken.
    """
    ffi = _ffi()
    found = []
    for field in ("position", "velocity"):
        offsets = set()
        for value in ((1.25e-3, -7.5e4), (-3.5e2, 6.0625)):
            body = pymunk.Body(1.0, math.inf)
            setattr(body, field, value)
            memory = np.frombuffer(ffi.buffer(ffi.cast("char *", body._body), 256), dtype=np.float64)
            offsets.add(tuple(8 * k for k in range(len(memory) - 1) if (memory[k], memory[k + 1]) == value))
        if len(offsets) != 1 or not (at := offsets.pop()) or (len(at) > 1 and field != "position"):
            return None
        found.append(at[0])
    return np.array(found, dtype=np.uint64)


def _arbiter_layout() -> dict | None:
    """Word indices of a ``cpArbiter``'s fields, from pymunk's own C declarations; None when not 8-byte aligned."""
    ffi = _ffi()
    arbiter = ffi.typeof("struct cpArbiter")
    offsets = {name: ffi.offsetof(arbiter, name) for name in ("e", "n", "body_a", "body_b")}
    if any(offset % 8 for offset in offsets.values()) or ffi.sizeof(arbiter) % 8:
        return None
    return {"words": ffi.sizeof(arbiter) // 8, "e": offsets["e"] // 8, "normal": offsets["n"] // 8,
            "body_a": offsets["body_a"] // 8, "body_b": offsets["body_b"] // 8}


@functools.cache
def impact_layout() -> dict | None:
    """Where Chipmunk keeps what a callback needs to move an impact's bodies to the instant of contact
    (`qdots.engine.contacts`); None without `internals` or when the layout is not as expected.

    Returns ``{"contacts": word index of the arbiter's contact array pointer, "r1", "r2": word indices of a
    contact's two offsets from its bodies' centres, "inverse_mass": byte offset of a body's 1/m, "translation":
    byte offset of the translation of a body's transform}``. Chipmunk's ``cpBodyGetPosition`` (pymunk's
    ``Body.position``, ``pymunk.batch``) reads that translation, which its integrator sets from ``cpBody.p``
    at the next step: a callback that moves ``p`` writes both.
    """
    known = internals()
    if known is None:
        return None
    ffi = _ffi()
    arbiter, contact = ffi.typeof("struct cpArbiter"), ffi.typeof("struct cpContact")
    offsets = {"contacts": ffi.offsetof(arbiter, "contacts"), "r1": ffi.offsetof(contact, "r1"),
               "r2": ffi.offsetof(contact, "r2")}
    if any(offset % 8 for offset in offsets.values()):
        return None
    found = set()
    for mass in (2.0, 8.0):  # 1/m written by pymunk, found in memory as the mass's inverse next to the mass
        body = pymunk.Body(mass, math.inf)
        memory = np.frombuffer(ffi.buffer(ffi.cast("char *", body._body), 256), dtype=np.float64)
        found.add(tuple(8 * k for k in range(1, len(memory)) if (memory[k - 1], memory[k]) == (mass, 1.0 / mass)))
    if len(found) != 1 or len(at := found.pop()) != 1:
        return None
    translation = _translation_offset(int(known.body_offsets[POSITION]))
    if translation is None:
        return None
    return {**{name: offset // 8 for name, offset in offsets.items()}, "inverse_mass": at[0], "translation": translation}


def _translation_offset(position: int) -> int | None:
    """Byte offset of the translation of a body's transform: the one other place a disc body's position is
    found, after ``cpBody.p``, and the one ``Body.position`` reads (checked by writing there); None if not so."""
    ffi = _ffi()
    body = pymunk.Body(1.0, math.inf)
    body.position = (3.25, -1.5e3)
    memory = np.frombuffer(ffi.buffer(ffi.cast("char *", body._body), 256), dtype=np.float64)
    at = [8 * k for k in range(len(memory) - 1) if (memory[k], memory[k + 1]) == (3.25, -1.5e3)]
    if len(at) != 2 or at[0] != position:
        return None
    memory[at[1] // 8: at[1] // 8 + 2] = (7.75, 2.5)
    return at[1] if tuple(body.position) == (7.75, 2.5) else None


# -- the space -----------------------------------------------------------------------------------

def tune_space(space: pymunk.Space, settings: Chipmunk) -> None:
    """Apply the solver knobs that can change on a live space (iterations, slop, bias)."""
    space.iterations = int(settings.iterations)
    space.collision_slop = float(settings.collision_slop)
    space.collision_bias = settings.bias


def new_space(walls: np.ndarray, settings: Chipmunk) -> pymunk.Space:
    """A space with ``settings``' solver, threads and spatial index, holding the static segments ``walls`` (M, 4).

    Walls are static, frictionless, perfectly elastic segments of zero thickness.
    """
    space = pymunk.Space(threaded=settings.threads > 1)
    if settings.threads > 1:
        space.threads = settings.threads
    tune_space(space, settings)
    if settings.spatial_hash is not None:
        cell, cells = settings.spatial_hash
        space.use_spatial_hash(float(cell), int(cells))
    for x0, y0, x1, y1 in walls:
        wall = pymunk.Segment(space.static_body, (x0, y0), (x1, y1), 0.0)
        wall.friction = 0.0
        wall.elasticity = 1.0
        wall.collision_type = WALL
        space.add(wall)
    return space


def add_discs(space: pymunk.Space, positions, velocities, radii, masses) -> list[pymunk.Body]:
    """Add one frictionless, non-rotating disc per dot (px, px/s, px, mean mass = 1); returns their bodies.

    A disc's own elasticity is 0, so lasting contacts are inelastic; the restitution of each impact
    is set by the collision callbacks (`qdots.engine.contacts`).
    """
    bodies = []
    for (x, y), (vx, vy), r, m in zip(positions, velocities, radii, masses):
        body = pymunk.Body(float(m), math.inf)
        body.position = (float(x), float(y))
        body.velocity = (float(vx), float(vy))
        circle = pymunk.Circle(body, float(r))
        circle.friction = 0.0
        circle.elasticity = 0.0
        circle.collision_type = DOT
        space.add(body, circle)
        bodies.append(body)
    return bodies


def advance(space: pymunk.Space, h: float, k: int) -> None:
    """Advance ``space`` by ``k`` Chipmunk steps of ``h`` s.

    pymunk's ``Space.step`` wraps each C step in Python bookkeeping for what Python callbacks may
    have asked during it (bodies to check, additions and removals, post-step callbacks), a cost of the
    order of the C step itself on a small film (docs/performance.md, "Design measurements"). With
    `internals`, the steps go straight to Chipmunk unless some of that is pending; the C step is the
    same either way.
    """
    if internals() is None or any(getattr(space, name, True) for name in _PYMUNK_PENDING):
        for _ in range(k):
            space.step(h)
        return
    lib = _lib()
    step = lib.cpHastySpaceStep if space.threaded else lib.cpSpaceStep
    handle = space._space
    for _ in range(k):
        step(handle, h)


def set_last_substep(space: pymunk.Space, h: float) -> None:
    """Tell Chipmunk that its last step was ``h`` s long (nothing without `internals`).

    Chipmunk re-applies the last sub-step's contact impulses scaled by ``h / (its h)`` but keeps
    them unscaled as the total the solver may take back: a ratio other than 1 leaves an impact's
    impulse partly applied twice or reversed (an elastic gas gained or lost 2-5 % of its energy).
    Telling it the last sub-step was ``h`` makes the ratio 1, as at a fixed step.
    """
    if internals() is not None:
        _lib().cpSpaceSetCurrentTimeStep(space._space, h)


def add_pre_solve_callback(space: pymunk.Space, type_a: int, type_b: int, address: int, data_address: int) -> None:
    """Make Chipmunk call the C function at ``address`` in every step a contact of shapes of collision types
    ``type_a`` and ``type_b`` lasts (before it solves the contact), with ``data_address`` as its data. Needs
    `internals`."""
    ffi = _ffi()
    handler = _lib().cpSpaceAddCollisionHandler(space._space, type_a, type_b)
    handler.preSolveFunc = ffi.cast(_CALLBACK, address)
    handler.userData = ffi.cast("void *", data_address)
