"""Forces against exact or independently integrated answers."""

import numpy as np
import pytest
from helpers import lone_dot, worst_overlap
from scipy.integrate import solve_ivp

import qdots
from labrig.validate import InputError
from qdots.engine import PairScheme
from qdots.experiment import Experiment
from qdots.forces import StepContext, hamaker_force, thesis_offset
from qdots.units import thesis_kick_speed

BIG_BOX = (2000.0, 2000.0)
#: Every van der Waals pair pulled every step (no far pass).
EVERY_STEP = PairScheme(far_interval=None)
#: Far pairs (gap beyond near_gap) pulled once per 20 ms far interval.
FAR_PASS = PairScheme(far_interval=0.02)


# ---------------------------------------------------------------- van der Waals vs solve_ivp
def proxy_constants(force):
    """The thesis proxy's offset b (px) and the Hamaker constant ``force`` uses under the default collision rule."""
    offset = force.proxy_offset(qdots.Restitution().sticking_speed)
    return offset, force.hamaker_strength(offset)


def vdw_pair_reference(model, gap0, masses, t_end, force):
    """Separation of two dots under the dt -> 0 limit of the force law, by solve_ivp at rtol 1e-10."""
    m1, m2 = masses
    r = 7.5
    offset, strength = proxy_constants(force)

    def pull(gap):  # force magnitude between the pair (mass * px / s^2)
        if model == "thesis":
            return 0.5 * (force.r0 / (gap - offset)) ** 7
        return float(hamaker_force(np.array(gap), np.array(r), np.array(r), strength))

    def rhs(t, y):
        x1, x2, v1, v2 = y
        f = pull(max(x2 - x1 - 2 * r, force.min_gap))
        return [v1, v2, f / m1, -f / m2]

    sol = solve_ivp(rhs, (0, t_end), [0.0, 2 * r + gap0, 0.0, 0.0], rtol=1e-10, atol=1e-12,
                    dense_output=True, method="DOP853")
    return sol


def contact_time(model, gap0, masses, force):
    r = 7.5
    event = lambda t, y: y[1] - y[0] - 2 * r - 1.0  # noqa: E731 - gap of 1 px
    event.terminal = True
    m1, m2 = masses
    offset, strength = proxy_constants(force)

    def rhs(t, y):
        gap = max(y[1] - y[0] - 2 * r, force.min_gap)
        f = 0.5 * (force.r0 / (gap - offset)) ** 7 if model == "thesis" else float(
            hamaker_force(np.array(gap), np.array(r), np.array(r), strength))
        return [y[2], y[3], f / m1, -f / m2]

    sol = solve_ivp(rhs, (0, 100), [0, 2 * r + gap0, 0, 0], events=event, rtol=1e-10, atol=1e-12)
    return sol.t_events[0][0]


def pair_error(force, gap0, masses, t_end, dt, reference, **settings):
    """Largest position error (px) of two 7.5 px dots pulled together by ``force`` from ``gap0`` over ``t_end``, at
    time step ``dt`` and the engine ``settings`` (e.g. ``far_interval``)."""
    scene = qdots.Scene(box=(200, 100), positions=[[80, 50], [80 + 15 + gap0, 50]], radii=[7.5, 7.5],
                        masses=list(masses), closed=False)
    sim = qdots.Simulation(scene, [force], seed=0, dt=dt, **settings)
    sim.run(t_end)
    assert sim.collisions.dot_dot == 0
    x1, x2 = sim.state().positions[:, 0] - 80
    return max(abs(x1 - reference[0]), abs(x2 - reference[1]))


@pytest.mark.parametrize("model, masses", [("thesis", (1.0, 1.0)), ("thesis", (1.0, 2.0)), ("hamaker", (1.0, 1.0))])
def test_vdw_pair_matches_solve_ivp_first_order(model, masses):
    """Every pair pulled every step (no far pass): first order in dt from the start's half-step lag."""
    force = qdots.VanDerWaals(model)
    gap0 = 8.0
    t_end = 0.8 * contact_time(model, gap0, masses, force)
    t_end = round(t_end / 0.004) * 0.004  # a whole number of steps for every dt below
    reference = vdw_pair_reference(model, gap0, masses, t_end, force).sol(t_end)
    errors = []
    dts = (4e-3, 2e-3, 1e-3, 5e-4)
    for dt in dts:
        errors.append(pair_error(force, gap0, masses, t_end, dt, reference, far_interval=None))
    orders = np.log2(np.array(errors[:-1]) / np.array(errors[1:]))
    # symplectic Euler (kick, then Chipmunk's drift) is first order in dt
    assert np.all((orders > 0.85) & (orders < 1.15)), (errors, orders)
    assert errors[-1] < 0.02  # px, at dt = 0.5 ms over ~0.8 of the approach


@pytest.mark.parametrize("model, masses", [("thesis", (1.0, 1.0)), ("thesis", (1.0, 2.0)), ("hamaker", (1.0, 1.0))])
def test_far_pass_is_second_order_in_its_interval(model, masses):
    """A pair beyond near_gap throughout gets its pull at the middle of each far interval (position Verlet):
    second order in the interval, and at the default interval closer to the dt -> 0 path than the every-step pass."""
    force = qdots.VanDerWaals(model)
    gap0 = 20.0
    t_end = round(0.8 * contact_time(model, gap0, masses, force) / 0.04) * 0.04
    reference = vdw_pair_reference(model, gap0, masses, t_end, force).sol(t_end)
    assert reference[1] - reference[0] - 15.0 > 2 * PairScheme().near_gap  # far all along
    intervals = (0.04, 0.02, 0.01)
    errors = [pair_error(force, gap0, masses, t_end, 5e-3, reference, far_interval=i) for i in intervals]
    orders = np.log2(np.array(errors[:-1]) / np.array(errors[1:]))
    assert np.all((orders > 1.8) & (orders < 2.2)), (errors, orders)
    every_step = pair_error(force, gap0, masses, t_end, 2.5e-3, reference, far_interval=None)
    assert errors[1] < every_step / 10  # the default 20 ms interval against every 2.5 ms step


def test_thesis_proxy_constants():
    force = qdots.VanDerWaals()
    assert force.offset is None  # derived from the collision rule's sticking speed (thesis: 1 px/s)
    assert force.proxy_offset(1.0) == pytest.approx(thesis_offset(15.0, 0.1, 1.0))
    assert force.proxy_offset(1.0) == pytest.approx(0.1 - 15.0 * (0.1 / 100.0) ** (1 / 7))
    assert force.proxy_offset(2.0) == pytest.approx(thesis_offset(15.0, 0.1, 2.0))
    assert qdots.VanDerWaals(offset=-3.0).proxy_offset(1.0) == -3.0
    assert force.max_gap == 30.0


def test_the_proxy_offset_follows_the_simulations_sticking_speed():
    """The sticking speed is the collision rule's: the same force pulls harder under a rule with a faster one."""
    force = qdots.VanDerWaals()
    slow, fast = (kick_speed(force, 2.0, restitution=qdots.Restitution(sticking_speed=v)) for v in (1.0, 3.0))
    a = (15.0 / (2.0 - thesis_offset(15.0, 0.1, 3.0))) ** 7
    assert fast == pytest.approx(a / 2 * 1e-3, rel=1e-12) and fast > slow


def test_a_rule_that_never_sticks_and_the_thesis_proxy():
    """The proxy's offset b derives from the rule's sticking speed, which may be 0 (an elastic gas); 0.2's force
    had its own, above 0. A van der Waals run under such a rule is refused in one line before it starts, or
    runs: it does not die inside a step. An offset given to the force does not depend on the rule."""
    scene = qdots.Scene(box=(100.0, 100.0), positions=[[30.0, 50.0], [60.0, 50.0]], radii=[7.5, 7.5])
    rule = qdots.Restitution(sticking_speed=0.0)
    with pytest.raises(InputError, match=r"^VanDerWaals derives the thesis proxy's offset b from "
                                         r"restitution.sticking_speed, which is 0"):
        qdots.Simulation(scene, [qdots.VanDerWaals()], restitution=rule, seed=0)
    sim = qdots.Simulation(scene, [qdots.VanDerWaals()], seed=0)
    with pytest.raises(InputError, match="restitution.sticking_speed"):
        sim.restitution = rule
    assert sim.restitution.sticking_speed == 1.0  # the refused rule did not replace the old one
    with pytest.raises(InputError, match=r"^forces\[0\]: VanDerWaals derives"):
        Experiment(restitution=rule)
    given = qdots.Simulation(scene, [qdots.VanDerWaals(offset=-5.0)], restitution=rule, seed=0)
    given.run(0.05)
    assert given.state().velocities[0, 0] > 0.0  # pulled toward the other dot


@pytest.mark.parametrize("speed", [1e-300, 1e-160])
def test_a_sticking_speed_too_small_for_the_proxy_is_refused(speed):
    """A sticking speed so small that the proxy's offset b overflows to -inf (found by the random test of
    experiment files: 1e-300 ended in a ZeroDivisionError inside the first step) is refused in one line naming
    the least one, as 0 is; the least one runs."""
    scene = qdots.Scene(box=(100.0, 100.0), positions=[[30.0, 50.0], [60.0, 50.0]], radii=[7.5, 7.5])
    with pytest.raises(InputError, match=r"which is 1e-[0-9]+ \(b would be -inf, no pull\): give a sticking "
                                         r"speed of at least 1e-150 px/s"):
        qdots.Simulation(scene, [qdots.VanDerWaals()], restitution=qdots.Restitution(sticking_speed=speed), seed=0)
    least = qdots.Simulation(scene, [qdots.VanDerWaals()], restitution=qdots.Restitution(sticking_speed=1e-150),
                             seed=0)
    least.run(0.05)
    assert np.isfinite(least.state().velocities).all()


def kick_speed(force, gap, dt=1e-3, masses=(1.0, 1.0), time=0.0, pairs=None, restitution=None):
    """Speed change of dot 0 toward dot 1 in one step from ``time``, two 7.5 px dots at surface gap `gap`, under the
    pair scheme ``pairs`` (default `qdots.engine.PairScheme`) and collision rule ``restitution`` (default the thesis's)."""
    radii, masses = np.array([7.5, 7.5]), np.array(masses)
    x = np.array([0.0, 15.0 + gap])
    ctx = StepContext(time=time, dt=dt, x=x, y=np.zeros(2), velocity=np.zeros((2, 2)), radii=radii,
                      masses=masses, rng=np.random.default_rng(0), dv=np.zeros((2, 2)),
                      pairs=pairs or PairScheme(), restitution=restitution or qdots.Restitution(),
                      cache={})
    force.kick(ctx)
    assert ctx.dv[0, 1] == 0 and ctx.dv[1, 1] == 0
    assert ctx.dv[0, 0] * masses[0] == pytest.approx(-ctx.dv[1, 0] * masses[1])  # equal and opposite
    return ctx.dv[0, 0]


@pytest.mark.parametrize("gap, dt", [(0.5, 1e-3), (0.5, 0.2), (5.0, 1e-3), (29.0, 1e-2)])
def test_thesis_proxy_one_step(gap, dt):
    """min(a dt/2, sqrt(g a)/2) with a = (R0/(g - b))^7 / m; the cap binds at large dt."""
    force = qdots.VanDerWaals()
    a = (15.0 / (gap - force.proxy_offset(1.0))) ** 7
    expected = min(a * dt / 2, np.sqrt(gap * a) / 2)
    assert kick_speed(force, gap, dt, pairs=EVERY_STEP) == pytest.approx(expected, rel=1e-12)


def test_thesis_proxy_mass_dependence():
    force = qdots.VanDerWaals()
    a = (15.0 / (2.0 - force.proxy_offset(1.0))) ** 7
    assert kick_speed(force, 2.0, 1e-3, masses=(2.0, 1.0)) == pytest.approx(a / 2 * 1e-3 / 2, rel=1e-12)


@pytest.mark.parametrize("model", ["thesis", "hamaker"])
def test_the_pulls_scale_multiplies_it_cap_included(model):
    """``scale`` multiplies the pull of either model; the thesis proxy's cap sqrt(g a)/2 scales as the pull does;
    a scale of 1 is the force as it was, and stays out of its parameters (old scene files unchanged)."""
    force, double = qdots.VanDerWaals(model), qdots.VanDerWaals(model, scale=2.0)
    assert kick_speed(double, 2.0, 1e-3) == pytest.approx(2.0 * kick_speed(force, 2.0, 1e-3), rel=1e-12)
    if model == "thesis":
        a = (15.0 / (2.0 - force.proxy_offset(1.0))) ** 7
        assert kick_speed(double, 2.0, 10.0, pairs=EVERY_STEP) == pytest.approx(np.sqrt(2.0 * 2.0 * a) / 2, rel=1e-12)
    assert "scale" not in force.params() and double.params()["scale"] == 2.0
    assert qdots.forces.force_from_dict(double.to_dict()).scale == 2.0
    with pytest.raises(InputError, match=r"VanDerWaals.scale"):
        qdots.VanDerWaals(scale=-1.0)


def test_vdw_range_and_contact_rules():
    hold, zero = qdots.VanDerWaals(contact="hold"), qdots.VanDerWaals(contact="zero")

    def kick(force, gap):
        return kick_speed(force, gap, pairs=EVERY_STEP)

    assert kick(hold, 31.0) == 0.0  # beyond 2 R0
    assert kick(hold, 29.0) > 0.0
    at_min_gap = kick(hold, 0.1)
    assert kick(hold, -0.05) == pytest.approx(at_min_gap)  # pressed pairs keep the contact force
    assert kick(hold, 0.02) == pytest.approx(at_min_gap)
    assert kick(zero, 0.02) == 0.0 and kick(zero, -0.05) == 0.0
    assert kick(hold, 0.2) > 0
    assert kick(zero, 0.2) == pytest.approx(kick(hold, 0.2))


@pytest.mark.parametrize("model", ["thesis", "hamaker"])
def test_far_pairs_get_the_pull_of_their_interval_at_its_middle(model):
    force = qdots.VanDerWaals(model)

    def split(gap, dt, time=0.0):
        return kick_speed(force, gap, dt, time=time, pairs=FAR_PASS)

    def every(gap, dt):
        return kick_speed(force, gap, dt, pairs=EVERY_STEP)

    far, near = 10.0, 2.0  # surface gaps, px, beyond and within near_gap
    assert FAR_PASS.near_gap == 4.0 and FAR_PASS.far_interval == 0.02
    # the far pass runs at the start of the step after each middle (the middles in (time - dt, time])
    assert split(far, 1e-3) == 0.0  # no interval's middle in (-1 ms, 0]
    assert split(far, 1e-3, time=0.0105) == pytest.approx(every(far, 0.02), rel=1e-12)
    assert split(far, 0.05, time=0.05) == pytest.approx(every(far, 0.06), rel=1e-12)  # 3 middles
    assert split(near, 1e-3) == every(near, 1e-3)
    assert split(31.0, 1e-3, time=0.0105) == 0.0  # beyond max_gap either way
    wide = PairScheme(near_gap=40.0, far_interval=0.02)
    assert kick_speed(force, far, 1e-3, pairs=wide) == every(far, 1e-3)


@pytest.mark.parametrize("model", ["thesis", "hamaker"])
def test_fade_between_the_passes_keeps_each_pairs_whole_pull(model):
    """Between near_gap / 2 and near_gap the every-step part falls smoothly from the whole pull to none, and
    the far pass carries the rest: in a step of one far interval the two parts sum to the whole pull."""
    force = qdots.VanDerWaals(model)
    near_gap = FAR_PASS.near_gap
    gaps = np.linspace(0.5 * near_gap, near_gap, 9)
    # no far pass in a step of 1 ms from 0 (no middle in (-1 ms, 0])
    weights = [kick_speed(force, g, 1e-3, pairs=FAR_PASS) / kick_speed(force, g, 1e-3, pairs=EVERY_STEP)
               for g in gaps]
    assert weights[0] == 1.0 and weights[-1] == 0.0
    assert np.all(np.diff(weights) < 0) and weights[4] == pytest.approx(0.5, abs=1e-12)  # smoothstep's middle
    for g in gaps:
        whole = kick_speed(force, g, 0.02, pairs=EVERY_STEP)
        assert kick_speed(force, g, 0.02, pairs=FAR_PASS) == pytest.approx(whole, rel=1e-12)


def test_pair_crossing_near_gap_is_neither_pulled_twice_nor_missed():
    """Two dots approaching from exactly near_gap cross from the far pass into the every-step pass. With a
    hard cut at near_gap they were 6.5x farther from the dt -> 0 path than with every pair every step
    (measured: 4.9e-2 against 7.6e-3 px); with the fade they are closer than every pair every step."""
    force = qdots.VanDerWaals()
    gap0, masses = FAR_PASS.near_gap, (1.0, 1.0)
    t_end = round(0.8 * contact_time("thesis", gap0, masses, force) / 0.02) * 0.02
    reference = vdw_pair_reference("thesis", gap0, masses, t_end, force).sol(t_end)
    split = pair_error(force, gap0, masses, t_end, 2.5e-3, reference, far_interval=FAR_PASS.far_interval)
    every_step = pair_error(force, gap0, masses, t_end, 2.5e-3, reference, far_interval=None)
    assert split < every_step / 3, (split, every_step)


def test_default_hamaker_strength_matches_proxy_at_one_px():
    thesis, hamaker = qdots.VanDerWaals("thesis"), qdots.VanDerWaals("hamaker")
    offset = thesis.proxy_offset(1.0)
    proxy = 0.5 * (15.0 / (1.0 - offset)) ** 7
    assert hamaker.strength is None  # unset: derived per run from the proxy's offset
    strength = hamaker.hamaker_strength(offset)
    assert float(hamaker_force(np.array(1.0), np.array(7.5), np.array(7.5), strength)) == pytest.approx(proxy)
    assert kick_speed(hamaker, 1.0, pairs=EVERY_STEP) == pytest.approx(kick_speed(thesis, 1.0, pairs=EVERY_STEP))


def test_hamaker_force_limits():
    """Eq 2.2 tends to Ha R_eff / (6 h^2) at small gaps (Derjaguin limit for spheres)."""
    r, h = 7.5, 1e-3
    f = float(hamaker_force(np.array(h), np.array(r), np.array(r), 6.0))
    assert f == pytest.approx((r / 2) / h**2, rel=2e-3)


# ---------------------------------------------------------------- thermal motion
def test_thesis_kick_speed_value():
    assert float(thesis_kick_speed(1.0)) == pytest.approx(1.5 * np.sqrt(2 * 1.38e-20 * 297 / 5.24e-18))
    assert float(thesis_kick_speed(1.0)) == pytest.approx(1.876, abs=1e-3)


def test_each_kick_has_the_thesis_magnitude():
    masses = np.array([0.5, 1.0, 2.0, 4.0])
    scene = qdots.Scene(box=BIG_BOX, positions=[[200 * (k + 1), 500] for k in range(4)], radii=[5.0] * 4,
                        masses=masses)
    sim = qdots.Simulation(scene, [qdots.ThermalKicks()], seed=3, dt=0.02)
    sim.step()  # the interval (0, 0.02] holds exactly one kick
    speeds = np.linalg.norm(sim.state().velocities, axis=1)
    np.testing.assert_allclose(speeds, thesis_kick_speed(masses), rtol=1e-12)


@pytest.mark.parametrize("dt", [1e-3, 3e-3, 7e-3, 0.05])
def test_kick_schedule_does_not_depend_on_dt(dt):
    kicks = qdots.ThermalKicks()
    n_steps = int(round(1.0 / dt))
    t, total = 0.0, 0
    for _ in range(n_steps):
        total += kicks.kicks_in_step(t, dt)
        t += dt
    assert total == int(np.floor(n_steps * dt / kicks.interval + 1e-9))


def test_kicks_random_walk_variance(rng):
    """After k independent kicks of size s, E|v|^2 = k s^2; 400 free dots, 3 standard errors."""
    n = 400
    grid = np.array([(x, y) for x in range(50, 2000, 95) for y in range(50, 2000, 95)], float)[:n]
    scene = qdots.Scene(box=BIG_BOX, positions=grid, radii=np.full(n, 2.0))
    sim = qdots.Simulation(scene, [qdots.ThermalKicks()], seed=5, dt=2e-3)
    sim.run(0.5)
    assert sim.collisions.dot_dot == 0
    v2 = np.sum(sim.state().velocities ** 2, axis=1)
    expected = 25 * thesis_kick_speed(1.0) ** 2
    assert abs(v2.mean() - expected) < 3 * v2.std(ddof=1) / np.sqrt(n)


def test_langevin_equipartition():
    """Dilute elastic gas with mixed masses: <m v_x^2> = kT per degree of freedom, within 3 SE."""
    n = 200
    rng = np.random.default_rng(0)
    grid = np.array([(x, y) for x in range(40, 1000, 68) for y in range(40, 1000, 68)], float)[:n]
    masses = rng.choice([0.5, 1.0, 2.0], n)
    scene = qdots.Scene(box=(1000, 1000), positions=grid, radii=np.full(n, 3.0), masses=masses)
    kT = 5.0
    sim = qdots.Simulation(scene, [qdots.Langevin(gamma=2.0, kT=kT)],
                           restitution=qdots.Restitution(mean=1.0, sticking_speed=0.0), seed=11, dt=2e-3)
    sim.run(3.0)  # kinetic energy relaxes as exp(-2 gamma t)
    samples = []
    for _ in range(30):
        sim.run(1.0)  # velocity autocorrelation exp(-gamma * 1 s) = 0.14
        s = sim.state()
        samples.append(s.masses[:, None] * s.velocities**2)
    samples = np.array(samples)  # (time, dot, dof)
    per_snapshot = samples.mean(axis=(1, 2))
    se = per_snapshot.std(ddof=1) / np.sqrt(len(per_snapshot))
    assert abs(per_snapshot.mean() - kT) < 3 * se
    assert se < 0.03 * kT  # the test has the power to see a 10 % error
    for m in (0.5, 2.0):  # equipartition holds for each mass separately
        assert abs(samples[:, masses == m].mean() - kT) < 0.1 * kT


def test_langevin_default_temperature_matches_a_thesis_kick():
    assert qdots.Langevin().kT == pytest.approx(float(thesis_kick_speed(1.0)) ** 2 / 2)


# ---------------------------------------------------------------- drag and gravity (exact)
def test_drag_one_step_exact():
    sim = qdots.Simulation(lone_dot(velocity=(100.0, 0.0)), [qdots.Drag(0.025, 0.025 / 30)], seed=0, dt=1e-3)
    sim.step()
    assert sim.state().velocities[0, 0] == pytest.approx(100.0 * (1 - 0.025e-3 - (0.025 / 30) * 100 * 1e-3), rel=1e-14)


def test_drag_never_reverses_velocity():
    sim = qdots.Simulation(lone_dot(velocity=(100.0, 0.0)), [qdots.Drag(2000.0, 0.0)], seed=0, dt=1e-3)
    sim.step()
    assert sim.state().velocities[0, 0] == 0.0


def test_uniform_gravity_exact():
    sim = qdots.Simulation(lone_dot(), [qdots.Gravity((0.0, -750.0))], seed=0, dt=1e-3)
    sim.step(100)
    np.testing.assert_allclose(sim.state().velocities[0], [0.0, -75.0], rtol=1e-12)


def test_center_gravity_points_at_centre():
    sim = qdots.Simulation(lone_dot(position=(1300.0, 1400.0)), [qdots.CentreGravity((1000.0, 1000.0), 500.0)],
                           seed=0, dt=1e-3)
    sim.step()
    v = sim.state().velocities[0]
    np.testing.assert_allclose(v, 0.5 * np.array([-0.6, -0.8]), rtol=1e-12)


# ---------------------------------------------------------------- dense pack: the overlap bound
OVERLAP_TOLERANCE = {1.0: 0.015, 10.0: 0.03}  # fraction of a radius, settled, at default settings (measured 0.41 %, 1.7 %)


@pytest.mark.parametrize("gravity", [1.0, 10.0])
def test_dense_pack_under_centre_gravity_overlap_bounded(gravity):
    rng = np.random.default_rng(0)
    n, side = 400, 600
    grid = np.array([(x, y) for x in range(20, side - 15, 25) for y in range(20, side - 15, 25)], float)
    grid = grid[rng.permutation(len(grid))[:n]]
    radii = rng.normal(7.5, 0.75, n).clip(5, 9.5)
    scene = qdots.Scene(box=(side, side), positions=grid, radii=radii)
    forces = [qdots.CentreGravity((300, 300), 750.0 * gravity), qdots.VanDerWaals(), qdots.ThermalKicks(),
              qdots.Drag(1.0, 0.01)]
    sim = qdots.Simulation(scene, forces, seed=1)
    sim.run(3.0)
    worst = []
    for _ in range(3):
        sim.run(0.2)
        s = sim.state()
        worst.append(worst_overlap(s.positions, s.radii))
        assert np.isfinite(s.positions).all()
    # the pack really is compressed: most dots touch several others
    s = sim.state()
    d = np.linalg.norm(s.positions - [300, 300], axis=1)
    assert np.median(d) < 160
    assert 0 < max(worst) < OVERLAP_TOLERANCE[gravity]


# ---------------------------------------------------------------- the forces' parameters
@pytest.mark.parametrize(
    "make, message",
    [
        (lambda: qdots.VanDerWaals("lennard-jones"), "model must be one of"),
        (lambda: qdots.VanDerWaals(contact="sticky"), "contact must be"),
        (lambda: qdots.VanDerWaals(r0=-1), r"r0 must be in \(0, 1000\] px"),
        (lambda: qdots.VanDerWaals(max_gap=0.05), "max_gap"),
        (lambda: qdots.ThermalKicks(interval=0), r"interval must be in \(0, "),
        (lambda: qdots.Langevin(gamma=-1), r"gamma must be in \[0, "),
        (lambda: qdots.Drag(-0.1), r"linear must be in \[0, "),
        (lambda: qdots.Gravity((0, np.nan)), "Gravity.acceleration"),
        (lambda: qdots.CentreGravity((1, 2), -5), r"magnitude must be in \[0, "),
    ],
)
def test_force_validation(make, message):
    with pytest.raises(ValueError, match=message):
        make()


@pytest.mark.parametrize("knob", ["skin", "near_gap", "far_interval", "sticking_speed"])
def test_vdw_holds_no_numerics_of_the_engine(knob):
    """The pair list's skin and the near/far split are engine settings, the sticking speed the collision rule's."""
    with pytest.raises(TypeError, match=knob):
        qdots.VanDerWaals(**{knob: 1.0})
