"""A simulation's run: the same seed gives the same run, one force object serves several simulations at once,
a fixed step takes its sub-steps, a step reads and writes the bodies only when it must, bad arguments are
refused, and attached writers keep one schedule over successive runs."""

from __future__ import annotations

import numpy as np
import pytest
from helpers import TimeRecorder, lone_dot

import qdots


# ---------------------------------------------------------------- the same seed, the same run
def noisy_run(seed):
    rng = np.random.default_rng(0)
    n = 150
    grid = np.array([(x, y) for x in range(20, 300, 22) for y in range(20, 300, 22)], float)[:n]
    scene = qdots.Scene(box=(300, 300), positions=grid, radii=np.full(n, 7.5), velocities=rng.normal(0, 30, (n, 2)))
    sim = qdots.Simulation(scene, [qdots.VanDerWaals(), qdots.ThermalKicks(), qdots.Drag()], seed=seed)
    sim.run(1.0)
    assert sim.collisions.dot_dot > 20  # random elasticities were drawn
    return sim.state()


def test_same_seed_is_bit_identical_and_other_seed_differs():
    a, b, c = noisy_run(42), noisy_run(42), noisy_run(43)
    assert np.array_equal(a.positions, b.positions) and np.array_equal(a.velocities, b.velocities)
    assert not np.array_equal(a.positions, c.positions)


# ---------------------------------------------------------------- one force object, several simulations
def film(n: int, seed: int) -> qdots.Scene:
    """``n`` dots of mixed sizes and masses on a square lattice at 17 px pitch, moving at ~30 px/s."""
    rng = np.random.default_rng(seed)
    side = int(np.ceil(np.sqrt(n)))
    positions = 20.0 + 17.0 * np.argwhere(np.ones((side, side)))[:n].astype(float)
    return qdots.Scene(box=(40.0 + 17.0 * side, 40.0 + 17.0 * side), positions=positions,
                       radii=rng.uniform(5.5, 8.0, n), masses=rng.uniform(0.5, 2.0, n),
                       velocities=rng.normal(0.0, 30.0, (n, 2)))


SCENES = (film(100, 1), film(4, 2))
STEPS = 200


def thermal_forces() -> list[qdots.Force]:
    return [qdots.VanDerWaals(), qdots.ThermalKicks(), qdots.Langevin(gamma=0.5)]


def simulations(forces_of) -> list[qdots.Simulation]:
    """A simulation of each of `SCENES` with the forces ``forces_of(k)`` (k: the scene's index)."""
    return [qdots.Simulation(scene, forces_of(k), seed=10 + k) for k, scene in enumerate(SCENES)]


def boards(sims) -> list[tuple]:
    return [(sim.state().positions, sim.state().velocities, sim.collisions.to_dict()) for sim in sims]


def assert_same_boards(got, expected) -> None:
    for (positions, velocities, counts), (positions0, velocities0, counts0) in zip(got, expected):
        np.testing.assert_array_equal(positions, positions0)
        np.testing.assert_array_equal(velocities, velocities0)
        assert counts == counts0


@pytest.fixture(scope="module")
def references():
    """Each scene run on its own, with its own fresh force objects."""
    sims = simulations(lambda k: thermal_forces())
    for sim in sims:
        sim.step(STEPS)
    assert sims[0].collisions.dot_dot > 20 and sims[0].force_cache(sims[0].forces[0])["pairs"].i.size
    return boards(sims)


def test_one_force_object_serves_several_simulations_at_once(references):
    """Interleaved steps of two different scenes through ONE VanDerWaals, ThermalKicks and Langevin object
    each: bit for bit the runs each scene makes with forces of its own (the force once cached the other
    scene's radii, and the run stopped with a RunawayError)."""
    shared = thermal_forces()
    sims = simulations(lambda k: shared)
    assert all(a is b for a, b in zip(sims[0].forces, sims[1].forces))
    for _ in range(STEPS):
        for sim in sims:
            sim.step()
    assert_same_boards(boards(sims), references)


def test_one_force_object_serves_several_simulations_in_turn(references):
    shared = thermal_forces()
    sims = simulations(lambda k: shared)
    for sim in sims:
        sim.step(STEPS)
    assert_same_boards(boards(sims), references)
    again = simulations(lambda k: shared)[0]  # and a later simulation of the first scene
    again.step(STEPS)
    assert_same_boards(boards([again]), references[:1])


# ---------------------------------------------------------------- sub-steps and bulk traffic
@pytest.mark.parametrize("n_forces", [0, 1, 2, 3])
def test_a_fixed_step_takes_its_sub_steps_whatever_the_number_of_forces(n_forces):
    """At a fixed sub-step (``overlap_tolerance=None``) every step takes ``substeps`` sub-steps; forces that add
    nothing leave the run as it is without them."""
    scene = qdots.Scene(box=(200.0, 100.0), positions=[[60.0, 50.0], [140.0, 50.0]], radii=[7.5, 7.5],
                        velocities=[[80.0, 3.0], [-70.0, 0.0]])
    sims = [qdots.Simulation(scene, [qdots.Drag(0.0, 0.0) for _ in range(k)], seed=1, dt=2.5e-3, substeps=3,
                             overlap_tolerance=None) for k in (0, n_forces)]
    for sim in sims:
        sim.step(400)  # one impact and a few bounces
        assert (sim.substeps_taken, sim.backend.diagnostics()["last_substeps"]) == (1200, 3)
    assert sims[1].collisions.to_dict() == sims[0].collisions.to_dict() and sims[0].collisions.dot_dot == 1
    np.testing.assert_array_equal(sims[1].state().positions, sims[0].state().positions)
    np.testing.assert_array_equal(sims[1].state().velocities, sims[0].state().velocities)


def test_substeps_and_spatial_hash_give_the_same_free_flight():
    a = qdots.Simulation(lone_dot(velocity=(10.0, 5.0)), seed=0, substeps=3, spatial_hash=(20.0, 1000))
    a.run(0.1)
    np.testing.assert_allclose(a.state().positions[0], 1000.0 + np.array([10.0, 5.0]) * a.time, rtol=1e-12)


def bulk_traffic(forces, **settings):
    """The bulk reads (`BodyArrays.read_rows`, the read a step makes) and velocity changes of 10 steps of a lone dot
    moving at 10 px/s, and its x after them."""
    sim = qdots.Simulation(lone_dot(velocity=(10.0, 0.0)), forces, seed=0, **settings)
    io = sim.backend.io
    calls = {"read_rows": 0, "add_velocities": 0}
    for name in calls:
        method = getattr(io, name)

        def counted(*args, name=name, method=method):
            calls[name] += 1
            return method(*args)

        setattr(io, name, counted)
    sim.step(10)
    stepped = dict(calls)  # before the state is read
    return stepped, sim.state().positions[0, 0]


def test_no_forces_means_no_bulk_traffic():
    """With no forces and a fixed sub-step a step neither reads nor writes the bodies in bulk; with the sub-step
    plan (which reads the velocities) every step reads, and with a force every step also writes."""
    calls, x = bulk_traffic([], overlap_tolerance=None)
    assert calls == {"read_rows": 0, "add_velocities": 0}
    assert x == pytest.approx(1000.0 + 10.0 * 10 * qdots.Chipmunk().dt, rel=1e-15)  # it did move
    assert bulk_traffic([])[0] == {"read_rows": 10, "add_velocities": 0}  # the plan reads; nothing to write
    assert bulk_traffic([qdots.Drag(0.0, 0.0)])[0] == {"read_rows": 10, "add_velocities": 10}


# ---------------------------------------------------------------- arguments
@pytest.mark.parametrize(
    "kwargs, message",
    [
        (dict(dt=0), r"dt must be (a number )?in \[1e-7, 0.1\] s"),
        (dict(substeps=0), r"substeps must be an integer in \[1, 1,000\]"),
        (dict(iterations=2.5), r"iterations must be an integer in \[1, 1,000\]"),
        (dict(collision_slop=-1), r"collision_slop must be in \[0, 100\] px"),
        (dict(collision_bias=1.5), r"collision_bias must be in \[0, 1\)"),
        (dict(threads=3), "threads must be one of 1, 2"),
        (dict(threads=True), "threads must be one of 1, 2"),
        (dict(dt=True), r"dt must be (a number )?in \[1e-7, 0.1\] s"),
        (dict(spatial_hash=(10.0, 2.5)), "spatial_hash"),
        (dict(spatial_hash="big"), "spatial_hash"),
        (dict(pair_skin=-1), r"pair_skin must be in \[0, 1000\] px"),
        (dict(near_gap=0), r"near_gap must be in \(0, 2,?000\] px"),
        (dict(far_interval=0), r"far_interval must be in \(0, "),
        (dict(tune_allocator="yes"), "tune_allocator"),
        (dict(restitution=0.8), "restitution must be a qdots.Restitution"),
    ],
)
def test_simulation_validation(kwargs, message):
    with pytest.raises(ValueError, match=message):
        qdots.Simulation(lone_dot(), **kwargs)


def test_run_rejects_negative_time_and_bad_writer():
    sim = qdots.Simulation(lone_dot(), seed=0)
    with pytest.raises(ValueError, match="seconds must be >= 0"):
        sim.run(-1)

    class Bad:
        every = 0

        def write(self, state):
            pass

    with pytest.raises(ValueError, match="every must be an integer >= 1"):
        sim.attach(Bad())
    with pytest.raises(ValueError, match="write"):
        sim.attach(object(), every=3)
    with pytest.raises(ValueError, match="every .* or seconds"):
        sim.attach(Bad(), every=3, seconds=0.1)


# ---------------------------------------------------------------- writers
def test_attached_writers_see_one_schedule_over_successive_runs():
    writer = TimeRecorder(every=7)
    sim = qdots.Simulation(lone_dot(), seed=0, dt=1e-3)
    assert sim.attach(writer) is writer and sim.writers == (writer,)
    with pytest.raises(ValueError, match="attached already"):
        sim.attach(writer)
    sim.run(0.03)
    np.testing.assert_allclose(writer.times, [0.0, 0.007, 0.014, 0.021, 0.028])
    sim.run(0.004)  # successive runs keep the schedule: 0.035 at step 35 is next
    sim.run(0.001)
    sim.run(0.01)
    np.testing.assert_allclose(writer.times, [0.0, 0.007, 0.014, 0.021, 0.028, 0.035, 0.042])
    sim.detach(writer)
    sim.run(0.01)
    assert len(writer.times) == 7
    with pytest.raises(ValueError, match="not attached"):
        sim.detach(writer)


def test_writer_in_seconds_keeps_its_interval_when_dt_changes():
    writer = TimeRecorder(every=7)
    sim = qdots.Simulation(lone_dot(), seed=0, dt=1e-3)
    sim.attach(writer, seconds=0.01)
    sim.run(0.02)
    sim.engine = sim.engine.replace(dt=2e-3)  # the time so far is kept
    assert sim.time == pytest.approx(0.02)
    sim.run(0.02)
    np.testing.assert_allclose(writer.times, [0.0, 0.01, 0.02, 0.03, 0.04])
