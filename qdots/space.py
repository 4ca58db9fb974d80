"""Chipmunk's side of a simulation: a `pymunk.Space` holding a scene's walls and dots.

One place builds the space, so a new simulation and one re-seated from a checkpoint have the
same Chipmunk history (body order, shape ids, spatial index) and step identically.
"""

from __future__ import annotations

import math

import pymunk
from pymunk._chipmunk import lib

from .collisions import DOT, WALL
from .scene import Scene
from .settings import EngineSettings


def tune_space(space: pymunk.Space, settings: EngineSettings) -> None:
    """Apply the solver knobs that can change on a live space (iterations, slop, bias)."""
    space.iterations = int(settings.iterations)
    space.collision_slop = float(settings.collision_slop)
    space.collision_bias = settings.bias


def new_space(scene: Scene, settings: EngineSettings) -> pymunk.Space:
    """A space with ``settings``' solver, threads and spatial index, holding ``scene``'s wall segments.

    Walls are static, frictionless, perfectly elastic segments of zero thickness.
    """
    space = pymunk.Space(threaded=settings.threads > 1)
    if settings.threads > 1:
        space.threads = settings.threads
    tune_space(space, settings)
    if settings.spatial_hash is not None:
        cell, cells = settings.spatial_hash
        space.use_spatial_hash(float(cell), int(cells))
    for x0, y0, x1, y1 in scene.wall_segments():
        wall = pymunk.Segment(space.static_body, (x0, y0), (x1, y1), 0.0)
        wall.friction = 0.0
        wall.elasticity = 1.0
        wall.collision_type = WALL
        space.add(wall)
    return space


def add_discs(space: pymunk.Space, positions, velocities, radii, masses) -> list[pymunk.Body]:
    """Add one frictionless, non-rotating disc per dot (px, px/s, px, mean mass = 1); returns their bodies.

    A disc's own elasticity is 0, so lasting contacts are inelastic; the restitution of each impact
    is set by the collision handler (`qdots.collisions`).
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


#: pymunk's records of work its ``Space.step`` does in Python after the C step (pymunk 7.3).
_PYMUNK_PENDING = ("_bodies_to_check", "_add_later", "_remove_later", "_post_step_callbacks")


def advance(space: pymunk.Space, h: float, k: int) -> None:
    """Advance ``space`` by ``k`` Chipmunk steps of ``h`` s.

    pymunk's ``Space.step`` wraps each C step in Python bookkeeping for what Python callbacks may
    have asked during it (bodies to check, additions and removals, post-step callbacks): about
    20 us a step, against ~60 us for the C step of a settled 300-dot film without forces and
    ~500 us with van der Waals pressing its ~700 contacts (measured on this 2-core machine). The
    steps go straight to Chipmunk unless some of that is pending; the C step is the same either
    way (and pymunk's own step is used when it keeps that bookkeeping elsewhere).
    """
    if any(getattr(space, name, True) for name in _PYMUNK_PENDING):
        for _ in range(k):
            space.step(h)
        return
    step = lib.cpHastySpaceStep if space.threaded else lib.cpSpaceStep
    handle = space._space
    for _ in range(k):
        step(handle, h)
