"""Isolated impacts have exact answers: Eq 2.5 is a normal restitution eps with frictionless contact.

Tolerances: a single circle-circle contact is solved exactly by Chipmunk's first solver
iteration, and overlap correction acts on pseudo-velocities only, so measured restitution,
tangential velocity and momentum agree with theory to round-off (we allow 1e-9 relative).
"""

import hashlib
import json
import math

import numpy as np
import pytest

import qdots
from qdots.engine import chipmunk_step as stepping
from qdots.engine.contacts import CollisionRecord, elasticity_of_impact, install_handlers
from qdots.restitution import impact_normal

TOL = 1e-9
MASK = 2**64 - 1


def splitmix(z):
    """SplitMix64's finaliser on Python integers (the oracle of the compiled `mix64`)."""
    z = (z + 0x9E3779B97F4A7C15) & MASK
    z = ((z ^ (z >> 30)) * 0xBF58476D1CE4E5B9) & MASK
    z = ((z ^ (z >> 27)) * 0x94D049BB133111EB) & MASK
    return z ^ (z >> 31)


def stream_normal(key, n):
    """Draw n of the elasticity stream ``key``: Box-Muller on two hashed 53-bit uniforms."""
    a, b = splitmix(key ^ ((2 * n) & MASK)), splitmix(key ^ ((2 * n + 1) & MASK))
    u1, u2 = ((a >> 11) + 1) / 2.0**53, (b >> 11) / 2.0**53
    return math.sqrt(-2.0 * math.log(u1)) * math.cos(2.0 * math.pi * u2)


def seed_key(seed):
    """The stream key of ``Simulation(seed=seed)``: a hash of its generator's first state."""
    state = json.dumps(np.random.default_rng(seed).bit_generator.state, sort_keys=True).encode()
    return int.from_bytes(hashlib.blake2b(state, digest_size=8).digest(), "little")


def expected_eps(seed, mean=0.8):
    """The first elasticity a simulation seeded ``seed`` draws for a dot-dot impact."""
    std = min((1 - mean) / 2, mean / 2)
    return min(max(mean + std * stream_normal(seed_key(seed), 0), 0.0), 1.0)


def collide(v1, v2, m1=1.0, m2=1.0, offset=0.0, seed=0, mean=0.8, seconds=1.2, **rule):
    """Two dots approaching along x (dot 1 displaced by `offset` in y); returns before/after velocities."""
    scene = qdots.Scene(
        box=(400, 200),
        positions=[[170, 100], [230, 100 + offset]],
        radii=[7.5, 7.5],
        masses=[m1, m2],
        velocities=[v1, v2],
    )
    sim = qdots.Simulation(scene, restitution=qdots.Restitution(mean=mean, **rule), seed=seed)
    before = sim.state()
    sim.run(seconds)
    after = sim.state()
    assert sim.collisions.dot_dot == 1
    assert sim.collisions.dot_wall == 0
    return before, after, sim


def line_of_centres_at_contact(p1, p2, v1, v2, r_sum):
    """Unit normal at first contact of two discs moving in straight lines (exact kinematics)."""
    dp, dv = p2 - p1, v2 - v1
    a, b, c = dv @ dv, 2 * dp @ dv, dp @ dp - r_sum**2
    t = (-b - np.sqrt(b * b - 4 * a * c)) / (2 * a)
    n = dp + dv * t
    return n / np.linalg.norm(n)


@pytest.mark.parametrize("seed", [0, 1, 2, 7])
@pytest.mark.parametrize("m1, m2", [(1.0, 1.0), (1.0, 3.0), (2.5, 0.4)])
def test_head_on_restitution_equals_drawn_eps(seed, m1, m2):
    before, after, _ = collide([40.0, 0.0], [-25.0, 0.0], m1, m2, seed=seed)
    v_in = before.velocities[1, 0] - before.velocities[0, 0]
    v_out = after.velocities[1, 0] - after.velocities[0, 0]
    assert -v_out / v_in == pytest.approx(expected_eps(seed), abs=TOL)
    np.testing.assert_allclose(after.momentum(), before.momentum(), atol=TOL * 100)
    np.testing.assert_allclose(after.velocities[:, 1], 0.0, atol=TOL)


def step_until_impact(sim, max_steps=5000):
    """Step until velocities change; return (velocities before, state after the impact step)."""
    v_prev = sim.state().velocities
    for _ in range(max_steps):
        sim.step()
        state = sim.state()
        if not np.array_equal(state.velocities, v_prev):
            return v_prev, state
        v_prev = state.velocities
    raise AssertionError("no impact")


@pytest.mark.parametrize("m1, m2", [(1.0, 1.0), (1.0, 3.0)])
def test_oblique_impact_keeps_tangential_velocity(m1, m2):
    """Frictionless: both velocity changes lie on one line, the contact normal; along it the
    restitution is the drawn one, exactly. The normal is the line of centres when Chipmunk saw the
    overlap, within a degree of the line of centres after a 2.5 ms step."""
    seed = 4
    scene = qdots.Scene(box=(400, 200), positions=[[170, 100], [230, 109]], radii=[7.5, 7.5],
                        masses=[m1, m2], velocities=[[60.0, 0.0], [-10.0, 0.0]])
    sim = qdots.Simulation(scene, seed=seed, dt=2.5e-3)
    p_before = sim.state().momentum()
    v0, after = step_until_impact(sim)
    v1 = after.velocities
    n = (v1[0] - v0[0]) / np.linalg.norm(v1[0] - v0[0])
    t = np.array([-n[1], n[0]])
    np.testing.assert_allclose(v1 @ t, v0 @ t, atol=TOL * 100)  # no tangential impulse on either dot
    eps = -((v1[1] - v1[0]) @ n) / ((v0[1] - v0[0]) @ n)
    assert eps == pytest.approx(expected_eps(seed), abs=TOL)
    np.testing.assert_allclose(after.momentum(), p_before, atol=TOL * 100)
    centres = after.positions[1] - after.positions[0]
    assert np.degrees(np.arccos(-n @ centres / np.linalg.norm(centres))) < 1.0


def test_contact_normal_error_shrinks_with_dt():
    """Detecting an impact up to one step late tilts the normal by O(v dt / r): first order in dt.

    The delay depends on where contact falls on the step grid, so average over start offsets.
    """
    mean_errors = []
    for dt in (2e-3, 5e-4):
        errors = []
        for shift in np.linspace(0.0, 1.0, 12):
            scene = qdots.Scene(box=(400, 200), positions=[[170 + shift, 100], [230, 109]], radii=[7.5, 7.5],
                                velocities=[[60.0, 0.0], [-10.0, 0.0]])
            sim = qdots.Simulation(scene, seed=4, dt=dt)
            start = sim.state()
            exact = line_of_centres_at_contact(start.positions[0], start.positions[1],
                                               start.velocities[0], start.velocities[1], 15.0)
            _, after = step_until_impact(sim, max_steps=int(2.0 / dt))
            n = after.positions[1] - after.positions[0]
            errors.append(np.degrees(np.arccos(min(1.0, n @ exact / np.linalg.norm(n)))))
        mean_errors.append(np.mean(errors))
    assert mean_errors[1] < 0.1  # degrees, at dt = 0.5 ms and a 70 px/s approach
    assert 2.5 < mean_errors[0] / mean_errors[1] < 6.5  # 4x smaller dt -> ~4x smaller error


def test_eq_2_5_form_matches_restitution():
    """Eq 2.5: v_f = eps v_elastic + (1 - eps) v_cm, per dot, along the line of centres."""
    seed, m1, m2 = 3, 1.0, 2.0
    before, after, _ = collide([30.0, 0.0], [-30.0, 0.0], m1, m2, seed=seed, mean=0.5)
    eps = expected_eps(seed, mean=0.5)
    u1, u2 = before.velocities[:, 0]
    v_cm = (m1 * u1 + m2 * u2) / (m1 + m2)
    elastic1 = 2 * v_cm - u1
    elastic2 = 2 * v_cm - u2
    np.testing.assert_allclose(after.velocities[:, 0],
                               [eps * elastic1 + (1 - eps) * v_cm, eps * elastic2 + (1 - eps) * v_cm],
                               atol=1e-9)


def test_slow_impact_is_perfectly_inelastic():
    before, after, sim = collide([0.4, 0.0], [-0.3, 0.0], seconds=80.0)  # approach 0.7 px/s < 1 px/s
    np.testing.assert_allclose(after.velocities[0], after.velocities[1], atol=TOL)
    np.testing.assert_allclose(after.momentum(), before.momentum(), atol=TOL)
    assert sim.collisions.sticking == 1


def test_zero_mean_elasticity_sticks_and_unit_mean_is_elastic():
    _, after, _ = collide([40.0, 0.0], [-40.0, 0.0], mean=0.0)
    np.testing.assert_allclose(after.velocities, 0.0, atol=TOL)
    _, after, _ = collide([40.0, 0.0], [-40.0, 0.0], mean=1.0)
    np.testing.assert_allclose(after.velocities[:, 0], [-40.0, 40.0], atol=TOL)


@pytest.mark.parametrize("angle_deg", [0.0, 30.0, 75.0])
def test_wall_impacts_are_elastic_by_default(angle_deg):
    a = np.radians(angle_deg)
    v = 50.0 * np.array([np.sin(a), -np.cos(a)])  # toward the bottom wall
    scene = qdots.Scene(box=(300, 100), positions=[[100, 30]], radii=[7.5], velocities=[v])
    sim = qdots.Simulation(scene, seed=0)
    sim.run(2.0)
    assert sim.collisions.dot_wall >= 1
    after = sim.state().velocities[0]
    assert np.linalg.norm(after) == pytest.approx(50.0, abs=TOL)
    assert after[0] == pytest.approx(v[0], abs=TOL)


def test_wall_restitution_is_configurable():
    scene = qdots.Scene(box=(300, 100), positions=[[100, 50]], radii=[7.5], velocities=[[0.0, -50.0]])
    sim = qdots.Simulation(scene, restitution=qdots.Restitution(wall=0.5), seed=0)
    sim.run(0.9)  # one bounce off the floor, not yet the ceiling
    assert sim.state().velocities[0, 1] == pytest.approx(25.0, abs=TOL)


@pytest.mark.parametrize("iterations, bound", [(5, 5e-3), (10, 2e-4), (30, 1e-12)])
def test_elastic_gas_conserves_energy(rng, iterations, bound):
    """e = 1, no forces, 10^4 steps, ~2,000 impacts.

    A two-body impact conserves energy to round-off. A simultaneous impact of
    three dots is solved iteratively (Gauss-Seidel) and can lose a little when
    the solver stops early: over this gas and four other velocity draws
    (seeds 0-3), the default 5 iterations lost at most 1.7e-3 of the energy
    (one draw; the others 7e-11 or less), 10 iterations round-off; at 30 the
    solver converges and the drift is round-off.
    """
    n, side = 100, 400
    grid = np.array([(x, y) for x in range(20, side, 38) for y in range(20, side, 38)], float)[:n]
    scene = qdots.Scene(box=(side, side), positions=grid, radii=np.full(n, 7.5),
                        velocities=rng.normal(0, 100, (n, 2)))
    sim = qdots.Simulation(scene, restitution=qdots.Restitution(mean=1.0, sticking_speed=0.0), seed=1, dt=1e-3,
                           iterations=iterations)
    e0 = sim.state().kinetic_energy()
    energies = []
    for _ in range(20):
        sim.step(500)
        energies.append(sim.state().kinetic_energy())
    drift = np.abs(np.array(energies) / e0 - 1).max()
    assert sim.steps_taken == 10_000
    assert sim.collisions.dot_dot > 1000  # the test means something only if dots collide a lot
    assert drift < bound


def test_too_fast_for_the_time_step_warns_once_and_a_normal_run_does_not(recwarn):
    fast = qdots.Scene(box=(400, 200), positions=[[100, 100]], radii=[7.5], velocities=[[4500.0, 0.0]])
    sim = qdots.Simulation(fast, seed=0, dt=1e-3, overlap_tolerance=None)  # 4.5 px per 1 ms step = 0.6 r
    with pytest.warns(RuntimeWarning, match=r"moves 0\.60 radii per sub-step \(> 0\.5\)"):
        sim.run(0.5)
    recwarn.clear()
    sim.run(0.5)
    assert not [w for w in recwarn if issubclass(w.category, RuntimeWarning)]  # once per simulation
    qdots.Simulation(fast, seed=0, dt=1e-3, substeps=2, overlap_tolerance=None).run(0.5)  # 0.3 r per sub-step
    assert not [w for w in recwarn if issubclass(w.category, RuntimeWarning)]


def test_sub_steps_adapt_to_a_fast_dot_and_warn_only_when_capped(recwarn):
    fast = qdots.Scene(box=(400, 200), positions=[[100, 100]], radii=[7.5], velocities=[[4500.0, 0.0]])
    sim = qdots.Simulation(fast, seed=0)  # default: sub-steps short enough near the walls
    sim.run(0.5)
    assert not [w for w in recwarn if issubclass(w.category, RuntimeWarning)]
    assert sim.substeps_taken > sim.steps_taken  # split where the dot meets a wall (6 times) ...
    # ... and only there: per bounce at most one step at max_substeps, then halving back to 1
    assert sim.substeps_taken < sim.steps_taken + 6 * 2 * sim.engine.max_substeps
    assert 7.5 <= sim.state().positions[0, 0] <= 392.5
    assert sim.state().velocities[0] == pytest.approx([4500.0, 0.0], abs=TOL)  # elastic walls, 6 bounces
    capped = qdots.Scene(box=(4000, 200), positions=[[3000, 100]], radii=[7.5], velocities=[[2e5, 0.0]])
    with pytest.warns(RuntimeWarning, match=r"radii per sub-step"):
        qdots.Simulation(capped, seed=0, dt=2e-3, max_substeps=8).run(0.01)  # 2e5 px/s * 0.25 ms = 6.7 r


class _Blowup(qdots.forces.base.Force):
    def kick(self, ctx):
        ctx.dv[:] = np.nan


def test_a_non_finite_state_stops_the_run_with_its_time():
    scene = qdots.Scene(box=(400, 200), positions=[[100, 100], [200, 100]], radii=[7.5, 7.5])
    sim = qdots.Simulation(scene, [_Blowup()], seed=0)
    with pytest.raises(FloatingPointError, match=r"the dots left the model's range at t = 0 s \(step 0\)"):
        sim.run(1.0)  # the sub-step plan of the first step meets the non-finite velocities its forces gave
    sim = qdots.Simulation(scene, [_Blowup()], seed=0, overlap_tolerance=None)
    with pytest.raises(FloatingPointError, match=r"the dots left the model's range at t = \S+ s \(step 50\)"):
        sim.run(1.0)  # without a plan: checked every max(CHECK_EVERY, 400 / 200) = 50 steps
    assert sim.steps_taken == qdots.simulation.CHECK_EVERY == 50


@pytest.mark.parametrize("key, n", [(0, 0), (1, 5), (2**64 - 1, 2**63 + 7), (seed_key(3), 123456)])
def test_compiled_stream_equals_its_oracle(key, n):
    assert impact_normal(np.uint64(key), np.uint64(n)) == stream_normal(key, n)


def test_stream_is_standard_normal():
    z = np.array([impact_normal(np.uint64(seed_key(1)), np.uint64(n)) for n in range(40_000)])
    assert abs(z.mean()) < 4 / math.sqrt(len(z))  # 4 standard errors
    assert abs(z.std() - 1) < 4 / math.sqrt(2 * len(z))
    assert abs(np.mean(z**3)) < 4 * math.sqrt(15 / len(z))  # symmetric
    assert np.mean(z**4) == pytest.approx(3.0, abs=4 * math.sqrt(96 / len(z)))


def test_rule_counts_sticks_and_clips():
    record = CollisionRecord(key=seed_key(2))
    record.set_rule(qdots.Restitution(mean=0.9, sticking_speed=1.0))
    assert elasticity_of_impact(record.array, 0.99) == 0.0
    draws = [elasticity_of_impact(record.array, 50.0) for _ in range(2000)]
    assert 0.0 <= min(draws) and max(draws) == 1.0  # mean 0.9, std 0.05: some draws clip at 1
    assert (record.dot_dot, record.sticking, record.draws) == (2001, 1, 2000)
    assert draws[0] == min(0.9 + 0.05 * stream_normal(seed_key(2), 0), 1.0)


def busy_film(seed, compiled):
    rng = np.random.default_rng(5)
    grid = np.array([(x, y) for x in range(20, 200, 18) for y in range(20, 200, 18)], float)
    scene = qdots.Scene(box=(220, 220), positions=grid, radii=rng.uniform(6.5, 8.5, len(grid)),
                        velocities=rng.normal(0, 40, (len(grid), 2)), segments=[[0, 110, 80, 110]])
    sim = qdots.Simulation(scene, [qdots.VanDerWaals(contact="hold"), qdots.ThermalKicks()], seed=seed, dt=2.5e-3)
    install_handlers(sim.backend.space, sim.restitution, sim.collisions, compiled=compiled)
    sim.run(1.0)
    return sim


def test_compiled_callbacks_equal_the_python_fallback_bit_for_bit():
    if not CollisionRecord().compiled:
        pytest.skip("pymunk's memory layout is not the expected one: only the Python callbacks run")
    fast, slow = busy_film(11, True), busy_film(11, False)
    assert fast.collisions.to_dict() == slow.collisions.to_dict()
    assert fast.collisions.draws > 50 and fast.collisions.sticking > 10 and fast.collisions.dot_wall > 5
    np.testing.assert_array_equal(fast.state().positions, slow.state().positions)
    np.testing.assert_array_equal(fast.state().velocities, slow.state().velocities)


def test_a_still_board_skips_the_pair_plan_and_keeps_the_same_sub_steps(monkeypatch):
    # a settling lattice: the pairs' closing travel is evaluated only while some dot is fast enough to matter
    rng = np.random.default_rng(3)
    ij = np.argwhere(np.ones((8, 8))).astype(float)
    scene = qdots.Scene(box=(200.0, 200.0), positions=40.0 + 15.2 * ij + rng.uniform(-0.05, 0.05, (64, 2)),
                        radii=np.full(64, 7.5), velocities=rng.normal(0.0, 30.0, (64, 2)))
    calls = []
    travel = stepping.closing_travel
    monkeypatch.setattr(stepping, "closing_travel", lambda *a: calls.append(1) or travel(*a))
    boards = []
    for shortcut in (True, False):
        calls.clear()
        sim = qdots.Simulation(scene, [qdots.Drag(linear=5.0)], seed=0)
        sim.step(1)
        if not shortcut:
            sim.backend._stepper.smallest = 0.0  # no dot is ever slow enough: the plan always reads the pairs
        sim.step(800)
        boards.append((sim.state(), sim.substeps_taken, len(calls)))
    (fast, k_fast, planned), (full, k_full, every) = boards
    assert every == 801 and 0 < planned < every  # the shortcut was taken, and not always
    assert k_fast == k_full > 801  # some steps were split, the same ones
    np.testing.assert_array_equal(fast.positions, full.positions)
    np.testing.assert_array_equal(fast.velocities, full.velocities)
