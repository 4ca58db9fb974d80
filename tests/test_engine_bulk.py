"""Bulk access to Chipmunk's bodies and direct stepping: the same numbers as pymunk's own paths."""

from __future__ import annotations

import math

import numpy as np
import pymunk
import pytest

import qdots
from qdots.engine import bodies as body_io
from qdots.engine.bodies import BodyArrays
from qdots.engine.chipmunk import advance, internals


def dots_space(n=40, seed=0):
    """A space with ``n`` free discs at random places and speeds (no walls), and their bodies."""
    rng = np.random.default_rng(seed)
    space = pymunk.Space()
    bodies = []
    for _ in range(n):
        body = pymunk.Body(float(rng.uniform(0.5, 2.0)), math.inf)
        body.position = tuple(rng.uniform(0.0, 200.0, 2))
        body.velocity = tuple(rng.normal(0.0, 30.0, 2))
        space.add(body, pymunk.Circle(body, float(rng.uniform(2.0, 6.0))))
        bodies.append(body)
    return space, bodies


def test_the_body_fields_are_found_in_chipmunks_memory():
    found = internals()
    assert found is not None, "pymunk's body layout changed: the step falls back to pymunk.batch"
    offsets = found.body_offsets
    assert len(set(offsets.tolist())) == 3 and all(offset % 8 == 0 for offset in offsets.tolist())


@pytest.mark.parametrize("direct", [True, False], ids=["direct", "pymunk.batch"])
def test_reads_and_force_writes_equal_pymunks_own_accessors(direct, monkeypatch):
    if not direct:
        monkeypatch.setattr(body_io, "internals", lambda: None)
    space, bodies = dots_space()
    io = BodyArrays(space, bodies)
    assert io.direct is direct
    space.step(0.01)  # positions and velocities as Chipmunk's integrator leaves them
    expected = np.array([(*b.position, *b.velocity) for b in bodies])
    rows = io.read_rows()
    assert np.array_equal(rows, expected) and not rows.flags.writeable
    forces = np.random.default_rng(1).normal(0.0, 100.0, (len(bodies), 2))
    io.write_forces(forces)
    assert np.array_equal([tuple(b.force) for b in bodies], forces)


def test_direct_force_writes_step_like_pymunks_force_setter():
    forces = np.random.default_rng(2).normal(0.0, 1e3, (40, 2))
    boards = []
    for direct in (True, False):
        space, bodies = dots_space(seed=3)
        if direct:
            BodyArrays(space, bodies).write_forces(forces)
        else:
            for body, force in zip(bodies, forces):
                body.force = tuple(force)
        space.step(0.01)
        boards.append(np.array([(*b.position, *b.velocity) for b in bodies]))
    assert np.array_equal(*boards)


def test_direct_chipmunk_steps_equal_pymunks_step():
    boards = []
    for direct in (True, False):
        space, bodies = dots_space(seed=4)
        space.step(1e-3)  # clears what pymunk checks on new bodies
        if direct:
            advance(space, 1e-3, 50)
        else:
            for _ in range(50):
                space.step(1e-3)
        boards.append(np.array([(*b.position, *b.velocity) for b in bodies]))
    assert np.array_equal(*boards)


def test_a_space_with_pending_python_work_steps_through_pymunk():
    space, bodies = dots_space(n=3, seed=5)
    ran = []
    space.add_post_step_callback(lambda s, key: ran.append(key), "probe")
    advance(space, 1e-3, 2)
    assert ran == ["probe"]


def test_a_run_is_the_same_through_pymunk_batch(monkeypatch):
    def film(direct):
        rng = np.random.default_rng(6)
        grid = np.array([(x, y) for x in range(20, 200, 20) for y in range(20, 200, 20)], float)
        scene = qdots.Scene(box=(220, 220), positions=grid, radii=np.full(len(grid), 7.5),
                            velocities=rng.normal(0, 20, grid.shape))
        sim = qdots.Simulation(scene, [qdots.VanDerWaals(), qdots.ThermalKicks()], seed=6)
        assert sim.engine.io.direct is direct
        sim.run(0.5)
        return sim.state()

    direct = film(True)
    monkeypatch.setattr(body_io, "internals", lambda: None)  # the bulk reads and writes alone fall back
    fallback = film(False)
    assert np.array_equal(direct.positions, fallback.positions)
    assert np.array_equal(direct.velocities, fallback.velocities)
