"""The compiled van der Waals pass against a numpy oracle (the vectorized code it replaced)."""

import numpy as np
import pytest

import qdots
from qdots.engine import PairScheme
from qdots.forces.base import StepContext
from qdots.forces.vdw import hamaker_force
from qdots.geometry import VerletPairs

#: The collision rule of every context here (its sticking speed sets the proxy's offset).
RULE = qdots.Restitution()


def context(x, y, radii, masses, dt, time=0.0, pairs=None, cache=None, rng=None):
    """The step context a simulation would give a force: the pair scheme ``pairs`` (default `qdots.engine.PairScheme`),
    `RULE`, and ``cache`` (a fresh one by default: one per simulation)."""
    n = len(x)
    return StepContext(time=time, dt=dt, x=x, y=y, velocity=np.zeros((n, 2)), radii=radii, masses=masses,
                       rng=rng or np.random.default_rng(0), dv=np.zeros((n, 2)),
                       pairs=pairs or PairScheme(), restitution=RULE,
                       cache={} if cache is None else cache)


def numpy_kicks(force: qdots.VanDerWaals, pairs, x, y, radii, masses, dt, time=0.0):
    """Velocity changes of one step from ``time`` under the pair scheme ``pairs``, written array-wise (bincount over
    the pair list): with the split, the pull of each pair for ``dt`` times ``w(g)`` (1 below ``near_gap / 2``,
    smoothstep down to 0 at ``near_gap``) plus, in the step after a far interval's middle, its pull over that
    interval times ``1 - w(g)``."""
    offset = force.proxy_offset(RULE.sticking_speed)
    strength = force.hamaker_strength(offset)
    verlet = VerletPairs(pairs.pair_skin)
    verlet.update(x, y, force.max_gap + 2.0 * radii.max())
    i, j = verlet.i, verlet.j
    ri, rj, inv_mi, inv_mj = radii[i], radii[j], 1.0 / masses[i], 1.0 / masses[j]
    dx, dy = x[j] - x[i], y[j] - y[i]
    d = np.sqrt(dx * dx + dy * dy)
    gap = d - ri - rj
    active = gap < force.max_gap
    if force.contact == "zero":
        active &= gap >= force.min_gap
    weight = np.divide(active, d, out=np.zeros_like(d), where=d > 0)
    g = np.maximum(gap, force.min_gap)

    def speeds(seconds):
        if force.model == "hamaker":
            impulse = hamaker_force(g, ri, rj, strength) * seconds
            return impulse * inv_mi, impulse * inv_mj
        pull = (force.r0 / (g - offset)) ** 7
        capped = 0.5 * np.sqrt(g * pull)
        return (np.minimum(0.5 * seconds * pull * inv_mi, capped * np.sqrt(inv_mi)),
                np.minimum(0.5 * seconds * pull * inv_mj, capped * np.sqrt(inv_mj)))

    speed_i, speed_j = speeds(dt)
    if pairs.splits(force.max_gap):
        interval, near_gap = pairs.far_interval, pairs.near_gap
        # the far pass runs at the start of the step after each middle: the middles in (time - dt, time]
        middles = np.floor(time / interval + 0.5 + 1e-9) - np.floor((time - dt) / interval + 0.5 + 1e-9)
        s = np.clip((gap - near_gap / 2) / (near_gap / 2), 0.0, 1.0)
        near = 1.0 - s * s * (3.0 - 2.0 * s)
        far_i, far_j = speeds(middles * interval)
        speed_i, speed_j = near * speed_i + (1 - near) * far_i, near * speed_j + (1 - near) * far_j
    n = len(x)
    dv = np.zeros((n, 2))
    dv[:, 0] = np.bincount(i, speed_i * weight * dx, n) - np.bincount(j, speed_j * weight * dx, n)
    dv[:, 1] = np.bincount(i, speed_i * weight * dy, n) - np.bincount(j, speed_j * weight * dy, n)
    return dv


def random_film(n=400, seed=0):
    rng = np.random.default_rng(seed)
    radii = 7.5 * (1 + 0.15 * rng.standard_normal(n)).clip(0.5)
    side = np.sqrt(n) * 18.0
    xy = rng.uniform(0, side, (n, 2))
    xy[:5] = xy[5:10] + [[0.3, 0.0]] * 5  # overlapping and nearly touching pairs
    xy[10] = xy[11]  # coincident centres
    return xy[:, 0].copy(), xy[:, 1].copy(), radii


@pytest.mark.parametrize("model", ["thesis", "hamaker"])
@pytest.mark.parametrize("contact", ["hold", "zero"])
@pytest.mark.parametrize("dt", [1e-3, 2e-2])  # at 20 ms the thesis proxy's cap binds for close pairs
@pytest.mark.parametrize("masses", ["equal", "bimodal"])
@pytest.mark.parametrize("far", [None, "no middle", "a middle"])
def test_compiled_pass_matches_the_numpy_oracle(model, contact, dt, masses, far):
    x, y, radii = random_film()
    m = np.ones(len(x)) if masses == "equal" else np.where(np.arange(len(x)) % 2, 2.0, 1.0)
    force = qdots.VanDerWaals(model, contact=contact)
    pairs = PairScheme(far_interval=None if far is None else 0.05)
    time = 0.025 + dt / 2 if far == "a middle" else 0.0  # the middle of the first far interval is 25 ms
    ctx = context(x, y, radii, m, dt, time, pairs)
    force.kick(ctx)
    expected = numpy_kicks(force, pairs, x, y, radii, m, dt, time)
    assert np.abs(expected).max() > 0
    np.testing.assert_allclose(ctx.dv, expected, rtol=1e-12, atol=1e-12 * np.abs(expected).max())


def test_the_cap_binds_where_the_numpy_oracle_says():
    """At 20 ms the proxy's sqrt(g a)/2 cap is smaller than a dt/2 for a close pair: the kernel uses it."""
    force = qdots.VanDerWaals()
    radii, m = np.array([7.5, 7.5]), np.ones(2)
    x, y = np.array([0.0, 15.2]), np.zeros(2)
    ctx = context(x, y, radii, m, 0.02, pairs=PairScheme(far_interval=None))
    force.kick(ctx)
    dv = ctx.dv
    pull = (force.r0 / (0.2 - force.proxy_offset(RULE.sticking_speed))) ** 7
    assert 0.5 * 0.02 * pull > 0.5 * np.sqrt(0.2 * pull)
    assert dv[0, 0] == pytest.approx(0.5 * np.sqrt(0.2 * pull), rel=1e-14) and dv[1, 0] == -dv[0, 0]


def test_coincident_centres_get_no_force():
    force = qdots.VanDerWaals()
    radii, m = np.array([7.5, 7.5, 7.5]), np.ones(3)
    x, y = np.array([10.0, 10.0, 200.0]), np.array([10.0, 10.0, 10.0])
    ctx = context(x, y, radii, m, 1e-3)
    force.kick(ctx)
    assert np.all(ctx.dv == 0.0)


def test_the_split_force_matches_the_oracle_while_the_dots_move():
    """The every-step list is a sub-list of the Verlet list, rebuilt with it: no pair that comes within
    near_gap between rebuilds is missed, and the far pass runs at each interval's middle."""
    x, y, radii = random_film(n=200, seed=3)
    m = np.ones(len(x))
    force = qdots.VanDerWaals()
    pairs = PairScheme(far_interval=0.01)
    cache = {}  # one simulation's: the pair lists live on from step to step
    rng, dt = np.random.default_rng(4), 2e-3
    for step in range(60):
        x, y = x + rng.normal(0, 0.4, x.size), y + rng.normal(0, 0.4, y.size)
        ctx = context(x, y, radii, m, dt, step * dt, pairs, cache, rng)
        force.kick(ctx)
        expected = numpy_kicks(force, pairs, x, y, radii, m, dt, step * dt)
        np.testing.assert_allclose(ctx.dv, expected, rtol=1e-12, atol=1e-12 * np.abs(expected).max(), err_msg=step)
    assert 3 < cache["pairs"].rebuilds < 60
