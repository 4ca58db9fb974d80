"""The event-driven engine (the thesis's algorithm): exact impacts in time order, energy, buffers, the frame's
cap, resume, and the same experiments as the Chipmunk engine."""

import math

import numpy as np
import pytest

import qdots
from qdots.engine import Event
from qdots.engine.event_backend import EventBackend
from qdots.engine.event_loop import pair_time, wall_time
from qdots.experiment import Board, Deposition, Experiment, run_experiment

EVENT = Event(dt=0.02)
ELASTIC = qdots.Restitution(mean=1.0, sticking_speed=0.0)


def two_dots(m1, m2, speed, angle, offset):
    """Dot 0 at rest at the centre, dot 1 coming at it along ``angle`` at ``speed`` px/s, ``offset`` px off the
    line of centres, meeting it after about 0.5 s, in a big box (no walls reached)."""
    c, s = math.cos(angle), math.sin(angle)
    start = np.array([500.0, 500.0]) - (12.5 + 0.5 * speed) * np.array([c, s]) + offset * np.array([-s, c])
    return qdots.Scene(box=(1000.0, 1000.0), positions=[[500.0, 500.0], start], radii=[7.5, 5.0],
                       masses=[m1, m2], velocities=[[0.0, 0.0], speed * np.array([c, s])])


@pytest.mark.parametrize("m1, m2", [(1.0, 1.0), (1.0, 3.0), (0.2, 5.0)])
@pytest.mark.parametrize("speed, angle, offset", [(10.0, 0.0, 0.0), (300.0, 0.7, 4.0), (0.5, -2.0, -9.0)])
def test_one_impact_is_eq_2_5_to_round_off(m1, m2, speed, angle, offset):
    """The velocities after one impact are Eq 2.5 with the drawn restitution, along the line of centres at
    contact; the tangential velocities are unchanged."""
    scene = two_dots(m1, m2, speed, angle, offset)
    rule = qdots.Restitution(mean=0.8, sticking_speed=1.0)
    sim = qdots.Simulation(scene, [], restitution=rule, seed=3, engine=EVENT)
    eps = sim.collisions.next_elasticity(np.inf)  # what the next draw will be (nothing is counted)
    # the contact: where dot 1's path first comes within r0 + r1 + 2 buffers of dot 0
    buffer = EVENT.buffer * 6.25
    v1 = scene.velocities[1]
    t = pair_time(*(scene.positions[0] - scene.positions[1]), *(-v1), 12.5 + 2 * buffer)
    sim.run(t + 0.3)
    assert sim.collisions.dot_dot == 1
    after = sim.state()
    n = scene.positions[0] - (scene.positions[1] + v1 * t)
    n /= np.linalg.norm(n)
    approach = v1 @ n
    eps = 0.0 if approach < rule.sticking_speed else eps
    share = (1 + eps) * approach / (1 / m1 + 1 / m2)
    expected = np.array([share / m1 * n, v1 - share / m2 * n])
    assert np.abs(after.velocities - expected).max() <= 1e-12 * max(speed, 1.0)
    momentum = m1 * after.velocities[0] + m2 * after.velocities[1]
    assert np.abs(momentum - m2 * v1).max() <= 1e-12 * m2 * speed


def test_an_elastic_gas_keeps_its_energy():
    rng = np.random.default_rng(4)
    grid = np.array([(x, y) for x in range(20, 400, 25) for y in range(20, 400, 25)], float)
    scene = qdots.Scene(box=(420.0, 420.0), positions=grid + rng.uniform(-3, 3, grid.shape),
                        radii=rng.uniform(5, 9, len(grid)), masses=rng.uniform(0.3, 3.0, len(grid)),
                        velocities=rng.normal(0, 80, grid.shape))
    sim = qdots.Simulation(scene, [], restitution=ELASTIC, seed=1, engine=EVENT)
    before = sim.state().kinetic_energy()
    sim.run(5.0)
    assert sim.collisions.dot_dot > 2000 and sim.collisions.dot_wall > 200
    assert abs(sim.state().kinetic_energy() / before - 1) < 1e-12


def test_a_chain_resolves_its_impacts_in_time_order():
    """Dot 0 hits dot 1, which then hits dot 2: equal masses and elastic impacts pass the speed down the line."""
    scene = qdots.Scene(box=(400.0, 100.0), positions=[[50.0, 50.0], [100.0, 50.0], [116.0, 50.0]],
                        radii=[7.5, 7.5, 7.5], velocities=[[40.0, 0.0], [0.0, 0.0], [0.0, 0.0]])
    sim = qdots.Simulation(scene, [], restitution=ELASTIC, seed=1, engine=EVENT)
    sim.run(1.2)  # 35 px at 40 px/s, then 1 px: the second impact 0.025 s after the first
    assert sim.collisions.dot_dot == 2
    v = sim.state().velocities
    assert np.allclose(v[:2], 0.0, atol=1e-12) and v[2, 0] == pytest.approx(40.0, rel=1e-12)


def test_pair_and_wall_times_are_exact():
    assert pair_time(20.0, 0.0, -10.0, 0.0, 15.0) == pytest.approx(0.5, rel=1e-15)
    assert pair_time(20.0, 0.0, 10.0, 0.0, 15.0) == math.inf  # parting
    assert pair_time(10.0, 0.0, -1.0, 0.0, 15.0) == 0.0  # already within reach and approaching
    t, nx, ny, bx, by = wall_time(50.0, 20.0, 0.0, -10.0, 5.0, 0.0, 0.0, 100.0, 0.0)
    assert t == pytest.approx(1.5) and (nx, ny) == (0.0, 1.0) and math.isnan(bx)
    t, *_, bx, by = wall_time(-10.0, 20.0, 0.0, -10.0, 5.0, 0.0, 0.0, 100.0, 0.0)  # misses the line, not its end
    assert t == math.inf
    t, *_, bx, by = wall_time(-3.0, 20.0, 0.0, -10.0, 5.0, 0.0, 0.0, 100.0, 0.0)  # meets its end (0, 0)
    assert (bx, by) == (0.0, 0.0) and t == pytest.approx((20 - 4.0) / 10.0)


SMALL = Experiment(name="small", board=Board(150.0, 150.0), engine=EVENT,
                   deposition=Deposition(n_dots=25, interval=0.2, settle=3.0, sigma=0.15, mass_model="volume"))


@pytest.mark.parametrize("exp", [SMALL, SMALL.replace(grating=40.0, deposition=SMALL.deposition),
                                 SMALL.replace(deposition=Deposition(n_dots=25, interval=0.2, settle=3.0,
                                                                     mass_model="bimodal"))],
                         ids=["free", "grating", "bimodal"])
def test_no_two_discs_ever_overlap(exp):
    """Hard discs: the true radii never overlap (the buffer keeps them apart), on the figures' kinds of board."""
    sim = run_experiment(exp)
    s = sim.state()
    d = np.linalg.norm(s.positions[:, None] - s.positions[None], axis=2)
    gap = d - s.radii[:, None] - s.radii[None]
    np.fill_diagonal(gap, np.inf)
    assert gap.min() >= 0.0 and sim.collisions.dot_dot > 100
    walls = s.walls
    from qdots.geometry import segment_distances

    assert (segment_distances(s.positions, walls) - s.radii[:, None]).min() >= 0.0


def test_a_frame_that_reaches_its_cap_leaves_the_rest_unmoved_and_is_counted():
    """The thesis's loop stopped after 2,500 impacts in a frame (our default cap is 1,000,000); the rest of the
    frame was not moved."""
    scene = two_dots(1.0, 1.0, 10.0, 0.0, 0.0)
    capped = Event(dt=0.02, max_events=1)
    sim = qdots.Simulation(scene, [], restitution=ELASTIC, seed=1, engine=capped)
    free = qdots.Simulation(scene, [], restitution=ELASTIC, seed=1, engine=EVENT)
    for s in (sim, free):
        s.run(3.0)
    assert sim.backend.diagnostics()["capped_frames"] == 0  # one impact: the cap is never exceeded
    many = qdots.Scene(box=(60.0, 20.0), positions=[[10.0, 10.0], [50.0, 10.0]], radii=[5.0, 5.0],
                       velocities=[[3000.0, 0.0], [-3000.0, 0.0]])
    sim = qdots.Simulation(many, [], restitution=ELASTIC, seed=1, engine=capped)
    sim.run(0.02)
    assert sim.backend.diagnostics() == {"capped_frames": 1, "events": 1}
    x = sim.state().positions[:, 0]
    assert x[1] - x[0] == pytest.approx(10.0, abs=1e-3)  # stopped at the first impact, 0.005 s into the frame


def test_a_resumed_run_continues_bit_for_bit(tmp_path):
    exp = SMALL.replace(forces=(qdots.VanDerWaals(contact="zero").to_dict(), qdots.ThermalKicks().to_dict()))
    sim = run_experiment(exp)
    qdots.save(sim, tmp_path / "x.npz")
    back = qdots.load(tmp_path / "x.npz")
    assert isinstance(back.backend, EventBackend) and back.engine == sim.engine
    sim.run(1.0)
    back.run(1.0)
    assert sim.state().positions.tobytes() == back.state().positions.tobytes()
    assert sim.collisions.to_dict() == back.collisions.to_dict()


def test_the_engine_can_change_between_runs():
    sim = qdots.Simulation(two_dots(1.0, 1.0, 10.0, 0.0, 0.0), [], seed=1)
    sim.run(0.1)
    counts = sim.collisions.to_dict()
    sim.engine = EVENT
    assert isinstance(sim.backend, EventBackend) and sim.collisions.to_dict() == counts
    sim.run(4.0)
    assert sim.collisions.dot_dot == counts["dot_dot"] + 1


@pytest.mark.slow
@pytest.mark.timeout(600)
def test_the_javas_event_cap_lets_a_collapse_heat_a_film_and_the_default_does_not():
    """The fig2-2 film at sigma 0, seed 159: near t = 392 s a cluster collapses inelastically, 195,311 collisions in
    one frame. At the Java's cap of 2,500 the frames stop short, keep what the collisions would have damped, and the
    film heats (measured: mean speed 14 -> 128 px/s, 35.5 at the end, 82 single dots); at the default cap the frame
    resolves and the film stays near 12 px/s."""
    from qdots.engine.event import THESIS_EVENTS
    from qdots.presets import get_preset

    base = get_preset("fig2-2")[0]
    films = {}
    for cap in (THESIS_EVENTS, Event().max_events):
        sim = run_experiment(base.replace(seed=159, engine=base.engine.replace(kind="event", max_events=cap)))
        films[cap] = (sim.backend.diagnostics()["capped_frames"], float(np.hypot(*sim.state().velocities.T).mean()))
    (capped, hot), (none, calm) = films[THESIS_EVENTS], films[Event().max_events]
    assert capped > 10 and hot > 25.0, films
    assert none == 0 and calm < 16.0, films
