"""The per-frame kinetic-energy budget (`qdots.diagnostics.energy_budget`) closes and changes nothing, on both
engines; the Chipmunk prototype that resolves impacts at contact (``qdots.Chipmunk(impacts="contact")``) leaves a pair where
the exact collision does."""

import numpy as np
import pytest

import qdots
from labrig.validate import InputError
from qdots.diagnostics.energy_budget import EnergyBudget
from qdots.engine.contacts import install_handlers

ENGINES = ("event", "chipmunk")
EDGES = (0.9, 1.1)


def small_board(seed=3) -> qdots.Scene:
    """36 dots of diameters ~ N(15, 1.5) px, masses ~ d^3, on a jittered 17.5 px lattice, moving at ~N(0, 8) px/s."""
    rng = np.random.default_rng(seed)
    ij = np.argwhere(np.ones((6, 6))).astype(float)
    positions = 20.0 + 17.5 * ij + rng.uniform(-0.5, 0.5, ij.shape)
    diameters = np.clip(rng.normal(15.0, 1.5, len(ij)), 12.0, 16.5)
    return qdots.Scene(box=(140.0, 140.0), positions=positions, radii=diameters / 2, masses=(diameters / 15.0) ** 3,
                       velocities=rng.normal(0.0, 8.0, ij.shape))


def energies(state, budget) -> np.ndarray:
    classes = budget.classes_of(state.masses)
    ke = 0.5 * state.masses * (state.velocities ** 2).sum(axis=1)
    return np.bincount(classes, weights=ke, minlength=budget.n_classes)


@pytest.mark.parametrize("kind", ENGINES)
def test_the_budget_closes_frame_by_frame(kind):
    """start = the energy before the frame, end = after it, and injected - removed = end - start, by class, to round-off."""
    sim = qdots.Simulation(small_board(), [qdots.VanDerWaals(), qdots.ThermalKicks()], seed=5,
                           engine=qdots.engine.ENGINES[kind]())
    budget = EnergyBudget(EDGES, ("light", "middle", "heavy")).attach(sim)
    before, after = [], []
    for _ in range(40):
        before.append(energies(sim.state(), budget))
        sim.step(1)
        after.append(energies(sim.state(), budget))
    budget.finish(sim)
    f = budget.frames()
    assert f.start.shape == (40, 3) and f.forces == ("VanDerWaals", "ThermalKicks")
    assert np.all(f.dots.sum(axis=1) == 36) and np.all(f.dots > 0)
    scale = np.max(before)
    np.testing.assert_allclose(f.start, before, rtol=0, atol=1e-12 * scale)
    np.testing.assert_allclose(f.end, after, rtol=0, atol=1e-12 * scale)
    np.testing.assert_allclose(f.injected - f.removed, np.array(after) - np.array(before), rtol=0, atol=1e-11 * scale)
    np.testing.assert_allclose(f.injected_by(0) + f.injected_by(1), f.injected, rtol=0, atol=1e-11 * scale)
    assert f.impacts.sum() == sim.collisions.dot_dot > 0
    # the kicks give each dot 0.5 m |dv|^2 = 1.76 a frame whatever its mass, plus a cross term averaging to zero
    assert 0.5 < f.injected_by(1).sum() / f.dots.sum() < 3.0


@pytest.mark.parametrize("kind", ENGINES)
def test_a_run_with_the_budget_is_bit_identical(kind):
    def run(with_budget):
        sim = qdots.Simulation(small_board(), [qdots.VanDerWaals(), qdots.ThermalKicks()], seed=11,
                               engine=qdots.engine.ENGINES[kind]())
        if with_budget:
            EnergyBudget(EDGES).attach(sim)
        sim.run(0.4)
        sim.add_dots([(130.0, 130.0)], [4.0])  # a dot added between frames starts at rest
        sim.run(0.2)
        return sim.state(), sim.collisions.to_dict()

    (plain, plain_record), (probed, probed_record) = run(False), run(True)
    assert np.array_equal(plain.positions, probed.positions)
    assert np.array_equal(plain.velocities, probed.velocities)
    assert plain_record == probed_record


def test_dots_added_between_frames_keep_the_books_closed():
    sim = qdots.Simulation(small_board(), [qdots.VanDerWaals(), qdots.ThermalKicks()], seed=2)
    budget = EnergyBudget().attach(sim)
    sim.run(0.1)
    sim.add_dots([(130.0, 130.0)], [4.0])
    sim.run(0.1)
    budget.finish(sim)
    f = budget.frames()
    assert list(f.dots[:, 0]) == [36] * 5 + [37] * 5
    np.testing.assert_allclose(f.end[:-1], f.start[1:], rtol=1e-14)
    with pytest.raises(ValueError, match="already carries"):
        budget.attach(sim)
    budget.detach(sim)
    assert len(sim.forces) == 2


@pytest.mark.parametrize("compiled", [True, False])
@pytest.mark.parametrize("e", [1.0, 0.8])
@pytest.mark.parametrize("masses", [(1.0, 1.0), (0.5, 2.0)])
def test_impacts_at_contact_leave_a_bounced_pair_where_the_exact_collision_does(e, masses, compiled):
    """Chipmunk resolving an impact where it finds it (``impacts = "overlap"``) leaves the pair (1 + e) overlap
    closer; at contact (the default) moves it to where the impact at contact leaves it (the event engine's, to
    its buffer), with the compiled callbacks and with the Python fallback."""
    def gaps(kind, impacts):
        scene = qdots.Scene(box=(200.0, 200.0), positions=[(92.49, 100.0), (107.51, 100.0)], radii=[7.5, 7.5],
                            masses=masses, velocities=[(6.0, 0.0), (-4.0, 0.0)])
        sim = qdots.Simulation(scene, [], restitution=qdots.Restitution(mean=e), seed=1,
                               engine=qdots.Chipmunk(impacts=impacts) if kind == "chipmunk" else qdots.Event())
        if kind == "chipmunk" and not compiled:
            install_handlers(sim.backend.space, sim.restitution, sim.collisions, impacts == "contact", compiled=False)
        out = []
        for _ in range(2):
            sim.step(1)
            p = sim.state().positions
            out.append(p[1, 0] - p[0, 0] - 15.0)
        assert sim.collisions.dot_dot == 1
        return np.array(out)

    exact, overlapped, at_contact = gaps("event", "contact"), gaps("chipmunk", "overlap"), gaps("chipmunk", "contact")
    assert np.all(exact - overlapped > 0.02)  # the deficit: (1 + e) times the overlap, less its correction
    np.testing.assert_allclose(at_contact, exact, atol=1e-4)


def test_a_wall_impact_at_contact_moves_the_dot_only():
    """At a wall the whole move is the dot's: it leaves the wall where the exact collision leaves it."""
    def gap(kind):
        scene = qdots.Scene(box=(100.0, 100.0), positions=[(7.51, 50.0)], radii=[7.5], velocities=[(-8.0, 0.0)])
        sim = qdots.Simulation(scene, [], seed=1, engine=qdots.engine.ENGINES[kind]())
        sim.step(2)
        assert sim.collisions.dot_wall == 1
        return sim.state().positions[0, 0] - 7.5

    np.testing.assert_allclose(gap("chipmunk"), gap("event"), atol=1e-4)


def test_the_impacts_setting_is_checked_and_changes_a_live_engine():
    with pytest.raises(InputError, match="impacts"):
        qdots.Chipmunk(impacts="late")
    scene = qdots.Scene(box=(200.0, 200.0), positions=[(92.49, 100.0), (107.51, 100.0)], radii=[7.5, 7.5],
                        velocities=[(6.0, 0.0), (-4.0, 0.0)])
    ends = []
    for switch in (False, True):
        sim = qdots.Simulation(scene, [], seed=1, engine=qdots.Chipmunk(impacts="overlap"))
        if switch:
            sim.engine = sim.engine.replace(impacts="contact")
        sim.step(2)
        ends.append(sim.state().positions[1, 0] - sim.state().positions[0, 0])
    assert ends[1] - ends[0] > 0.02
