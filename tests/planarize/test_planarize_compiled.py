"""The compiled parts of the engines against plain, independent oracles: the kernel's sets, the ball searches,
the fast engine's set bookkeeping, threads and kept searches."""

import numpy as np
import pytest

from planarize import Fast, Model, Surface, anodize, surfaces
from planarize.engines import fast
from planarize.engines.fast import FastEngine
from planarize.engines.features import (
    METAL_HALF_DIAGONALS,
    METAL_SEGMENTS,
    OXIDE_HALF_DIAGONALS,
    OXIDE_SEGMENTS,
    OXIDE_TRIANGLES,
    feature_tables,
)
from planarize.engines.kernels import closest_sets, max_feature_length, pair_slots, star_reach
from planarize.engines.pyramid import BallCache, HeightPyramid
from planarize.engines.sets import OxideSets
from planarize.grid import EDGE_DIRECTIONS, QUADRANTS, Grid

CASES = [(boundary, distance) for boundary in ("open", "periodic") for distance in ("thesis", "exact")]


def rough_pair(grid, rng):
    """Metal and oxide heights with steep and flat parts (flat parts make exact ties)."""
    zm = rng.normal(scale=0.4, size=grid.n)
    zm[: grid.n // 4] = 0.0
    zo = zm + rng.uniform(0.0, 1.0, grid.n)
    zo[: grid.n // 4] = 0.5
    return zm, zo


def slot_points(grid, v, slot):
    """The oxide points of one slot at anchor v, from the slot layout's meaning (the module docstring)."""
    if OXIDE_SEGMENTS <= slot < METAL_SEGMENTS:
        other = grid.edge_neighbours[v, slot - OXIDE_SEGMENTS]
        return {v} | ({int(other)} if other >= 0 else set())
    if OXIDE_HALF_DIAGONALS <= slot < METAL_HALF_DIAGONALS:
        q = slot - OXIDE_HALF_DIAGONALS if slot < OXIDE_TRIANGLES else (slot - OXIDE_TRIANGLES) // 2
        return {v} | {int(u) for u in grid.quadrant_corners[v, q] if u >= 0}
    return {v}  # the anchor point, and metal features against it


def sets_oracle(grid, slots, m, v, tie):
    """Each metal point's smallest slot and the union of the oxide points of its slots within tie of it."""
    out = {}
    for p in np.unique(m):
        rows = np.flatnonzero(m == p)
        best = slots[rows].min()
        points = set()
        for r in rows:
            for s in np.flatnonzero(slots[r] <= best + tie):
                points |= slot_points(grid, int(v[r]), int(s))
        out[int(p)] = (best, sorted(points))
    return out


@pytest.mark.parametrize("boundary,distance", CASES)
def test_closest_sets_take_the_smallest_slot_and_its_oxide_points(boundary, distance, rng):
    grid = Grid((9, 8), (0.5, 0.35), boundary == "periodic")
    tables = feature_tables(grid, distance)
    zm, zo = rough_pair(grid, rng)
    # a few nearby anchors per metal point, so that every kind of feature is sometimes the closest
    m = np.sort(rng.integers(0, grid.n, 3000))
    v = grid.shift(m, rng.integers(-2, 3, len(m)), rng.integers(-2, 3, len(m)))
    keep = v >= 0
    m, v = m[keep], v[keep]
    oxide, metal = rng.random(len(m)) < 0.8, rng.random(len(m)) < 0.8
    for masks in ((None, None), (oxide, metal)):
        points, best, owner, oxide_points = closest_sets(tables, zm, zo, m, v, 1e-9, *masks)
        expected = sets_oracle(grid, pair_slots(tables, zm, zo, m, v, *masks), m, v, 1e-9)
        assert points.tolist() == sorted(expected)
        for k, p in enumerate(points.tolist()):
            assert best[k] == expected[p][0]
            assert oxide_points[owner == k].tolist() == expected[p][1]
    # unsorted input gives the same answer
    order = rng.permutation(len(m))
    for a, b in zip(closest_sets(tables, zm, zo, m, v, 1e-9), closest_sets(tables, zm, zo, m[order], v[order], 1e-9)):
        np.testing.assert_array_equal(a, b)


@pytest.mark.parametrize("boundary,distance", CASES)
def test_star_reach_is_the_farthest_feature_end(boundary, distance, rng):
    grid = Grid((9, 8), (0.5, 0.35), boundary == "periodic")
    tables = feature_tables(grid, distance)
    z = rng.normal(scale=0.8, size=grid.n)
    for k in rng.permutation(grid.n)[:30]:
        ends = [((di * grid.dx, dj * grid.dy), z[u]) for (di, dj), u in zip(EDGE_DIRECTIONS, grid.edge_neighbours[k])
                if u >= 0]
        if distance == "exact":
            for (sx, sy), cell in zip(QUADRANTS, grid.quadrant_cell[k]):
                if cell >= 0:
                    ends.append(((sx * grid.dx / 2, sy * grid.dy / 2), z[grid.cell_corners[cell]].mean()))
        expected = max(np.sqrt(x * x + y * y + (h - z[k]) ** 2) for (x, y), h in ends)
        assert star_reach(tables, z, [k])[0] == pytest.approx(expected, rel=1e-14)


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
    kept = FastEngine(surface, model=Model(step=0.05))
    fresh = FastEngine(surface, model=Model(step=0.05))
    fresh._cache = None  # every search from scratch
    while kept.thickness < 1.0:
        kept.advance()
        fresh.advance()
    np.testing.assert_array_equal(kept.zm, fresh.zm)
    np.testing.assert_array_equal(kept.zo, fresh.zo)
    np.testing.assert_array_equal(kept.D, fresh.D)
    assert kept.zm.max() < kept.zo.min()  # every search was kept for a while
    assert np.any(kept._cache.count >= 0)


@pytest.mark.parametrize("distance", ["thesis", "exact"])
def test_longest_edge_bounds_hold_between_measurements(distance):
    engine = FastEngine(surfaces.hill(), model=Model(step=0.05, distance=distance))
    for _ in range(30):
        engine.advance()
        assert engine._metal_longest >= max_feature_length(engine.tables, engine.zm)
        assert engine._oxide_longest >= max_feature_length(engine.tables, engine.zo)


# -- the oxide sets' bookkeeping against plain oracles -----------------------------------------

def batch_oracle(engine):
    """The batch by its definition, point by point: candidates within the tolerance, each waiting (if asked) for a
    strictly closer interacting candidate (a neighbour, or a sharer of one of its oxide points)."""
    d, sets = engine.D, engine.sets
    members = [set(sets.oxide[sets.start[p]:sets.start[p + 1]].tolist()) for p in range(engine.grid.n)]
    candidates = np.flatnonzero(d <= d.min() + engine.tolerance)
    key = {p: (d[p] if engine.interacting == "wait" else 0.0) for p in candidates}
    taken = np.zeros(engine.grid.n, dtype=bool)
    for p in candidates:
        rivals = [key[u] for u in engine.neighbours[p] if u in key]
        rivals += [key[q] for q in candidates if members[p] & members[q]]
        taken[p] = not min(rivals, default=np.inf) < key[p] - engine.tie
    rows = np.flatnonzero(taken[sets.metal])
    sharers = np.bincount(sets.oxide, minlength=engine.grid.n)
    return taken, rows, np.diff(sets.start)[sets.metal[rows]], sharers[sets.oxide[rows]]


def stale_oracle(engine, in_batch, raised):
    stale = in_batch.copy()
    for p in np.flatnonzero(in_batch):
        stale[engine.neighbours[p][engine.neighbours[p] >= 0]] = True
    stale[engine.sets.metal[np.isin(engine.sets.oxide, raised)]] = True
    return stale


@pytest.mark.parametrize("interacting", ["wait", "together"])
@pytest.mark.parametrize("boundary,distance", CASES)
def test_batch_stale_and_bound_follow_their_definitions(boundary, distance, interacting, rng):
    surface = Surface(rng.normal(scale=0.4, size=(12, 9)), (0.5, 0.35), boundary)
    engine = FastEngine(surface, model=Model(distance=distance), settings=Fast(tolerance=0.05, interacting=interacting))
    for _ in range(5):
        saved = engine.D.copy()
        engine.D[:] = np.round(rng.uniform(0.0, 0.2, surface.z.size), 2)  # exact ties and a spread around the tolerance
        got = engine.sets.batch(engine.D, engine.tolerance, engine.tie, interacting == "wait", engine.neighbours)
        for a, b in zip(got, batch_oracle(engine)):
            np.testing.assert_array_equal(a, b)
        raised = rng.choice(surface.z.size, 7, replace=False)
        np.testing.assert_array_equal(engine.sets.stale(got[0], raised, engine.neighbours),
                                      stale_oracle(engine, got[0], raised))
        points = np.sort(rng.choice(surface.z.size, 30, replace=False))
        nearest = engine.sets.nearest[points]
        di, dj = engine.grid.offsets(points, nearest)
        expected = np.sqrt((di * engine.grid.dx) ** 2 + (dj * engine.grid.dy) ** 2
                           + (engine.zo[nearest] - engine.zm[points]) ** 2)
        np.testing.assert_allclose(engine.sets.bound(engine.tables, engine.zm, engine.zo, points), expected, rtol=1e-15)
        engine.D[:] = saved
        engine.advance()


def test_replacing_sets_keeps_rows_sorted_and_sharers_counted(rng):
    n = 30
    sets = OxideSets(n)
    truth = {p: set() for p in range(n)}
    for _ in range(20):
        points = np.sort(rng.choice(n, rng.integers(1, 8), replace=False))
        new = {int(p): sorted(set(rng.integers(0, n, rng.integers(1, 5)).tolist())) for p in points}
        owner = np.array([p for p in points for _ in new[int(p)]], dtype=np.intp)
        oxide = np.array([o for p in points for o in new[int(p)]], dtype=np.intp)
        sets.replace(points, owner, oxide)
        truth.update({p: set(v) for p, v in new.items()})
        assert np.all(np.diff(sets.metal) >= 0)
        for p in range(n):
            assert sets.oxide[sets.start[p]:sets.start[p + 1]].tolist() == sorted(truth[p])
        np.testing.assert_array_equal(sets.sharers, np.bincount(sets.oxide, minlength=n))


# -- threads ------------------------------------------------------------------------------------

@pytest.mark.parametrize("distance", ["thesis", "exact"])
def test_threads_do_not_change_results(distance, monkeypatch):
    monkeypatch.setattr(fast, "POINTS_PER_THREAD", 4)  # split even the hill's few updated points
    model = Model(step=0.02, distance=distance)
    one = anodize(surfaces.hill(), 0.4, model, Fast(threads=1), record=5)
    three = anodize(surfaces.hill(), 0.4, model, Fast(threads=3), record=5)
    np.testing.assert_array_equal(one.metal.z, three.metal.z)
    np.testing.assert_array_equal(one.oxide.z, three.oxide.z)
    np.testing.assert_array_equal(one.distances, three.distances)


@pytest.mark.parametrize("threads", [0, -1, 1.5, True, "2", 10**6])
def test_bad_thread_counts_are_refused(threads):
    with pytest.raises(ValueError, match="threads"):
        Fast(threads=threads)


def _oxide_after_hill_run():
    return anodize(surfaces.hill(), 0.1, Model(step=0.02), Fast(threads=2)).oxide.z


@pytest.mark.skipif(not hasattr(__import__("os"), "fork"), reason="needs fork")
def test_a_forked_process_runs_its_own_threads(monkeypatch):
    import multiprocessing

    monkeypatch.setattr(fast, "POINTS_PER_THREAD", 4)
    here = _oxide_after_hill_run()  # this process now has a thread pool; a forked child must not wait on it
    with multiprocessing.get_context("fork").Pool(1) as pool:
        there = pool.apply_async(_oxide_after_hill_run).get(timeout=60)
    np.testing.assert_array_equal(here, there)
