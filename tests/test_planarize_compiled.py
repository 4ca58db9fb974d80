"""The numba kernels against their numpy originals: same sets and distances bit for bit, same runs."""

import numpy as np
import pytest

from planarize import Surface, anodize, compiled, surfaces
from planarize.engines.features import FeatureKernel, closest_sets
from planarize.grid import Grid
from planarize.engines.pyramid import BallCache, HeightPyramid

pytestmark = pytest.mark.skipif(not compiled.AVAILABLE, reason="numba is not installed")

CASES = [(boundary, distance) for boundary in ("open", "periodic") for distance in ("thesis", "exact")]


def rough_pair(grid, rng):
    """Metal and oxide heights with steep and flat parts (flat parts make exact ties)."""
    zm = rng.normal(scale=0.4, size=grid.n)
    zm[: grid.n // 4] = 0.0
    zo = zm + rng.uniform(0.0, 1.0, grid.n)
    zo[: grid.n // 4] = 0.5
    return zm, zo


@pytest.mark.parametrize("boundary,distance", CASES)
def test_closest_sets_match_the_numpy_kernel_bit_for_bit(boundary, distance, rng):
    grid = Grid((9, 8), (0.5, 0.35), boundary == "periodic")
    kernel = FeatureKernel(grid, distance)
    zm, zo = rough_pair(grid, rng)
    # a few nearby anchors per metal point, so that every kind of feature is sometimes the closest
    m = np.sort(rng.integers(0, grid.n, 3000))
    v = grid.shift(m, rng.integers(-2, 3, len(m)), rng.integers(-2, 3, len(m)))
    keep = v >= 0
    m, v = m[keep], v[keep]
    oxide, metal = rng.random(len(m)) < 0.8, rng.random(len(m)) < 0.8
    for masks in ((None, None), (oxide, metal), (np.zeros(len(m), bool), metal)):
        expected = closest_sets(kernel, zm, zo, m, v, 1e-9, *masks)
        got = compiled.closest_sets(kernel, zm, zo, m, v, 1e-9, *masks)
        for a, b in zip(expected, got):
            np.testing.assert_array_equal(a, b)
    # unsorted input is sorted the same way
    order = rng.permutation(len(m))
    for a, b in zip(closest_sets(kernel, zm, zo, m[order], v[order], 1e-9),
                    compiled.closest_sets(kernel, zm, zo, m[order], v[order], 1e-9)):
        np.testing.assert_array_equal(a, b)


def brute_ball(grid, z, points, zq, radius):
    """Every (query, grid point, distance) within the radius, at the nearest periodic image."""
    di = grid.i[None, :] - grid.i[points][:, None]
    dj = grid.j[None, :] - grid.j[points][:, None]
    if grid.periodic:
        di = di - grid.nx * np.floor_divide(di + grid.nx // 2, grid.nx)
        dj = dj - grid.ny * np.floor_divide(dj + grid.ny // 2, grid.ny)
    d = np.sqrt((di * grid.dx) ** 2 + (dj * grid.dy) ** 2 + (z[None, :] - zq[:, None]) ** 2)
    q, p = np.nonzero(d <= radius[:, None])
    return q, p, d[q, p]


@pytest.mark.parametrize("shape", [(2, 2), (5, 7), (17, 17), (70, 33)])
@pytest.mark.parametrize("periodic", [False, True])
def test_pyramid_ball_finds_exactly_the_points_within_reach(shape, periodic, rng):
    grid = Grid(shape, (0.7, 0.4), periodic)
    z = rng.normal(scale=2.0, size=grid.n)
    pyramid = HeightPyramid(grid, z)
    points = rng.integers(0, grid.n, 300)
    zq = z[points] + rng.uniform(-3, 3, len(points))
    radius = rng.choice([0.1, 0.8, 2.5, 9.0, 60.0], len(points))  # inside one cell .. beyond the grid
    q, p, d = pyramid.ball(z, points, zq, radius)
    assert np.all(np.diff(q) >= 0)  # grouped by query
    got = sorted(zip(q.tolist(), p.tolist()))
    eq, ep, ed = brute_ball(grid, z, points, zq, radius)
    assert got == sorted(zip(eq.tolist(), ep.tolist()))
    np.testing.assert_allclose(d[np.lexsort((p, q))], ed[np.lexsort((ep, eq))], rtol=1e-13)
    # heights that changed are seen after a rebuild
    z = z + rng.uniform(0, 1, grid.n)
    pyramid.rebuild(z)
    q, p, _ = pyramid.ball(z, points, zq, radius)
    eq, ep, _ = brute_ball(grid, z, points, zq, radius)
    assert sorted(zip(q.tolist(), p.tolist())) == sorted(zip(eq.tolist(), ep.tolist()))


@pytest.mark.parametrize("periodic", [False, True])
def test_kept_searches_answer_like_fresh_ones_while_distances_grow(periodic, rng):
    grid = Grid((23, 19), (2.0, 1.5), periodic)
    z = rng.normal(scale=0.5, size=grid.n) + 5.0  # the searched surface lies above every query point
    pyramid = HeightPyramid(grid, z)
    cache = BallCache(grid.n, margin=0.5, capacity=12)  # small: some queries overflow and are not kept
    points = rng.permutation(grid.n)[:150]
    zq = rng.normal(scale=0.5, size=len(points))
    zq[:10] = 6.0  # above the lowest grid point: never kept
    radius = rng.uniform(5.0, 6.0, len(points))
    for sweep in range(6):
        kept = pyramid.ball(z, points, zq, radius, cache=cache)
        fresh = pyramid.ball(z, points, zq, radius)
        assert sorted(zip(*(a.tolist() for a in kept))) == sorted(zip(*(a.tolist() for a in fresh)))
        assert np.all(cache.count[points[:10]] < 0)
        if sweep == 0:
            assert np.any(cache.count >= 0) and np.any(cache.count[points[10:]] < 0)
        # the surface rises and the query points sink: every distance grows; radii grow, some past the margin
        z = z + rng.uniform(0.0, 0.3, grid.n)
        pyramid.rebuild(z)
        zq = zq - rng.uniform(0.0, 0.2, len(points))
        radius = radius + rng.uniform(0.0, 0.4, len(points))


def test_kept_searches_leave_a_thick_oxide_run_unchanged():
    surface = Surface(np.random.default_rng(3).normal(scale=0.1, size=(12, 12)), 0.5, "periodic")
    kwargs = dict(step=0.05, record=5)
    compiled_run = anodize(surface, 1.0, jit=True, **kwargs)
    numpy_run = anodize(surface, 1.0, jit=False, **kwargs)
    np.testing.assert_array_equal(compiled_run.metal.z, numpy_run.metal.z)
    np.testing.assert_array_equal(compiled_run.oxide.z, numpy_run.oxide.z)
    np.testing.assert_array_equal(compiled_run.distances, numpy_run.distances)
    assert compiled_run.metal.z.max() < compiled_run.oxide.z.min()  # every search was kept for a while


@pytest.mark.parametrize("interacting", ["wait", "together"])
@pytest.mark.parametrize("boundary,distance", CASES)
def test_fast_engine_runs_identically_with_and_without_jit(boundary, distance, interacting):
    surface = Surface(surfaces.hill().z, 0.25, boundary)
    kwargs = dict(step=0.02, distance=distance, record=5, interacting=interacting, tolerance=0.02)
    compiled_run = anodize(surface, 0.4, jit=True, **kwargs)
    numpy_run = anodize(surface, 0.4, jit=False, **kwargs)
    np.testing.assert_array_equal(compiled_run.metal.z, numpy_run.metal.z)
    np.testing.assert_array_equal(compiled_run.oxide.z, numpy_run.oxide.z)
    np.testing.assert_array_equal(compiled_run.distances, numpy_run.distances)
    assert compiled_run.history["iterations"][-1] == numpy_run.history["iterations"][-1]


def test_jit_without_numba_is_a_clear_error(monkeypatch):
    monkeypatch.setattr(compiled, "AVAILABLE", False)
    with pytest.raises(ImportError, match="numba"):
        anodize(surfaces.hill(), 0.1, jit=True)


@pytest.mark.parametrize("boundary,distance", CASES)
def test_star_reach_matches_the_numpy_reach_bit_for_bit(boundary, distance, rng):
    from planarize.engines.fast import FastEngine

    surface = Surface(rng.normal(scale=0.4, size=(9, 8)), (0.5, 0.35), boundary)
    kernel = FastEngine(surface, distance=distance).kernel
    z = surface.z.ravel().copy()
    moved = rng.choice(z.size, 12, replace=False)
    z[moved] -= rng.uniform(0.0, 2.0, len(moved))  # steep edges at and around the moved points
    points = rng.permutation(z.size)[:40]
    np.testing.assert_array_equal(compiled.star_reach(kernel, z, points), kernel.star_reach(z, points))


@pytest.mark.parametrize("distance", ["thesis", "exact"])
def test_longest_edge_bounds_hold_between_measurements(distance):
    from planarize.engines.fast import FastEngine

    engine = FastEngine(surfaces.hill(), step=0.05, distance=distance)
    for _ in range(30):
        engine.advance()
        assert engine._metal_longest >= engine.kernel.max_feature_length(engine.zm)
        assert engine._oxide_longest >= engine.kernel.max_feature_length(engine.zo)


@pytest.mark.parametrize("distance", ["thesis", "exact"])
def test_threads_do_not_change_results(distance, monkeypatch):
    from planarize import fast

    monkeypatch.setattr(fast, "POINTS_PER_THREAD", 4)  # split even the hill's few updated points
    kwargs = dict(step=0.02, distance=distance, record=5)
    one = anodize(surfaces.hill(), 0.4, threads=1, **kwargs)
    three = anodize(surfaces.hill(), 0.4, threads=3, **kwargs)
    np.testing.assert_array_equal(one.metal.z, three.metal.z)
    np.testing.assert_array_equal(one.oxide.z, three.oxide.z)
    np.testing.assert_array_equal(one.distances, three.distances)


@pytest.mark.parametrize("threads", [0, -1, 1.5, True, "2"])
def test_bad_thread_counts_are_refused(threads):
    with pytest.raises(ValueError, match="threads"):
        anodize(surfaces.hill(), 0.1, threads=threads)


def _oxide_after_hill_run():
    return anodize(surfaces.hill(), 0.1, step=0.02, threads=2).oxide.z


@pytest.mark.skipif(not hasattr(__import__("os"), "fork"), reason="needs fork")
def test_a_forked_process_runs_its_own_threads(monkeypatch):
    import multiprocessing

    from planarize import fast

    monkeypatch.setattr(fast, "POINTS_PER_THREAD", 4)
    here = _oxide_after_hill_run()  # this process now has a thread pool; a forked child must not wait on it
    with multiprocessing.get_context("fork").Pool(1) as pool:
        there = pool.apply_async(_oxide_after_hill_run).get(timeout=60)
    np.testing.assert_array_equal(here, there)


@pytest.mark.parametrize("interacting", ["wait", "together"])
@pytest.mark.parametrize("boundary,distance", CASES)
def test_compiled_batch_and_bound_match_numpy(boundary, distance, interacting, rng):
    from planarize.engines.fast import FastEngine

    surface = Surface(rng.normal(scale=0.4, size=(12, 9)), (0.5, 0.35), boundary)
    jit = FastEngine(surface, distance=distance, tolerance=0.05, interacting=interacting)
    plain = FastEngine(surface, distance=distance, tolerance=0.05, interacting=interacting, jit=False)
    for _ in range(5):
        # distances with exact ties and a spread around the tolerance
        distance_now = np.round(rng.uniform(0.0, 0.2, surface.z.size), 2)
        jit.D[:], plain.D[:] = distance_now, distance_now
        for got, expected in zip(jit._batch(), plain._batch()):
            np.testing.assert_array_equal(got, expected)
        raised = rng.choice(surface.z.size, 7, replace=False)
        np.testing.assert_array_equal(jit._stale(jit._batch()[0], raised), plain._stale(plain._batch()[0], raised))
        points = np.sort(rng.choice(surface.z.size, 30, replace=False))
        np.testing.assert_array_equal(jit._bound(points), plain._bound(points))
        jit.advance()
        plain.advance()
