"""The planarization engines: exact bookkeeping, invariants, the fast engine against the reference."""

import functools

import numpy as np
import pytest

import planarize
from planarize import Fast, Model, Surface, surfaces
from planarize.engines.fast import FastEngine
from planarize.engines.kernels import closest_sets
from planarize.engines.reference import ReferenceEngine
from planarize.metrics import history_difference

#: The thesis's algorithm: these tests are the discrete engines' (the continuum engine has its own file).
anodize = functools.partial(planarize.anodize, engine="fast")


def brute_force(engine):
    """Every metal point's distance and oxide set from all (metal, anchor) pairs of the grid."""
    n = engine.grid.n
    m, v = np.repeat(np.arange(n), n), np.tile(np.arange(n), n)
    _, best, owner, oxide = closest_sets(engine.tables, engine.zm, engine.zo, m, v, engine.tie)
    sets = [set() for _ in range(n)]
    for p, o in zip(owner.tolist(), oxide.tolist()):
        sets[p].add(o)
    return best, sets


def engine_sets(engine):
    if isinstance(engine, ReferenceEngine):
        return engine.ox
    sets = [set() for _ in range(engine.grid.n)]
    for p, o in zip(engine.sets.metal.tolist(), engine.sets.oxide.tolist()):
        sets[p].add(o)
    return sets


def small_surfaces():
    rng = np.random.default_rng(7)
    return {
        "hill": surfaces.hill(points=5, refine=2),
        "periodic": Surface(rng.uniform(0, 0.6, (8, 9)), 0.25, "periodic"),
        "anisotropic": Surface(rng.uniform(0, 0.8, (7, 9)), (0.2, 0.35)),
    }


@pytest.mark.parametrize("engine_class", [ReferenceEngine, FastEngine])
@pytest.mark.parametrize("distance", ["thesis", "exact"])
@pytest.mark.parametrize("name", list(small_surfaces()))
def test_distances_and_sets_stay_exact(engine_class, distance, name):
    """After every update the incremental searches agree with a search over all pairs."""
    options = {"settings": Fast(tolerance=0.01)} if engine_class is FastEngine else {}
    engine = engine_class(small_surfaces()[name], model=Model(step=0.01, k_exp=2.3, distance=distance), **options)
    for k in range(60):
        if k % 15 == 0:
            best, sets = brute_force(engine)
            np.testing.assert_array_equal(engine.D, best)
            assert engine_sets(engine) == sets
        engine.advance()
    assert engine.thickness > 0


@pytest.mark.parametrize("name", list(small_surfaces()))
def test_interacting_together_at_zero_tolerance_is_the_default(name):
    """At tolerance 0 no candidate is closer than another by more than round-off: nothing waits."""
    runs = [anodize(small_surfaces()[name], 0.3, record=5, model=Model(step=0.01), engine=Fast(tolerance=0.0, interacting=mode))
            for mode in ("wait", "together")]
    np.testing.assert_array_equal(runs[0].metal.z, runs[1].metal.z)
    np.testing.assert_array_equal(runs[0].oxide.z, runs[1].oxide.z)


@pytest.mark.parametrize("distance", ["thesis", "exact"])
def test_interacting_together_keeps_distances_and_volume_exact(distance):
    """With every candidate of a wide batch oxidized, sets and distances stay exact, volume balances, and
    the batches are larger than when interacting candidates wait."""
    surface = small_surfaces()["periodic"]
    engines = {mode: FastEngine(surface, model=Model(step=0.01, distance=distance), settings=Fast(tolerance=0.03, interacting=mode))
               for mode in ("wait", "together")}
    together = engines["together"]
    for k in range(40):
        if k % 10 == 0:
            best, sets = brute_force(together)
            np.testing.assert_array_equal(together.D, best)
            assert engine_sets(together) == sets
        for engine in engines.values():
            engine.advance()
    assert together.point_updates > engines["wait"].point_updates
    assert abs(together.oxide_gained() / ((together.k_exp - 1) * together.metal_lost()) - 1) < 1e-12


def test_fast_engine_counts_its_distance_recomputations():
    """Every point is searched once at the start, and each oxidized point at least once per update."""
    engine = FastEngine(small_surfaces()["hill"], model=Model(step=0.01))
    assert engine.recomputed == engine.grid.n
    for _ in range(20):
        before, updates = engine.recomputed, engine.point_updates
        engine.advance()
        assert engine.recomputed - before >= engine.point_updates - updates > 0


@pytest.mark.parametrize("distance", ["thesis", "exact"])
@pytest.mark.parametrize("name", list(small_surfaces()))
def test_fast_engine_at_zero_tolerance_is_the_reference(distance, name):
    surface = small_surfaces()[name]
    ref = ReferenceEngine(surface, model=Model(step=0.01, k_exp=1.8, distance=distance))
    fast = FastEngine(surface, model=Model(step=0.01, k_exp=1.8, distance=distance), settings=Fast(tolerance=0))
    for _ in range(80):
        ref.advance()
        fast.advance()
    np.testing.assert_array_equal(fast.zm, ref.zm)
    np.testing.assert_array_equal(fast.zo, ref.zo)
    np.testing.assert_array_equal(fast.D, ref.D)
    assert engine_sets(fast) == ref.ox


@pytest.mark.parametrize("engine", ["reference", "fast"])
@pytest.mark.parametrize("boundary", ["open", "periodic"])
@pytest.mark.parametrize("distance", ["thesis", "exact"])
def test_volume_balance_is_exact_at_every_row(engine, boundary, distance):
    """Oxide gained above the original surface = (k_exp - 1) x metal lost, with the exact volume."""
    surface = surfaces.bump(4.6, points=3, refine=3, boundary=boundary)
    run = anodize(surface, 0.3, record=6, model=Model(step=0.02, k_exp=2.3, distance=distance), engine=engine)
    h = run.history
    assert np.all(np.abs(h["volume_error"][1:]) < 1e-12)
    lost = run.initial.volume() - run.metal.volume()
    gained = run.oxide.volume() - run.initial.volume()
    assert gained == pytest.approx(1.3 * lost, rel=1e-12)


def test_thesis_volume_rule_is_off_on_open_grids_only():
    hill = surfaces.hill(points=5, refine=2)
    open_run = anodize(hill, 0.3, record=2, model=Model(step=0.01, volume="thesis"))
    periodic = anodize(surfaces.bump(4.5, points=5, refine=2, boundary="periodic"), 0.3, record=2, model=Model(step=0.01, volume="thesis"))
    assert abs(open_run.history["volume_error"][-1]) > 1e-4
    assert abs(periodic.history["volume_error"][-1]) < 1e-12


@pytest.mark.parametrize("engine", ["reference", "fast"])
@pytest.mark.parametrize("boundary", ["open", "periodic"])
def test_flat_film_grows_exactly_and_stays_flat(engine, boundary):
    step, k_exp, target = 0.01, 2.3, 0.2
    flat = Surface(np.full((6, 7), 4.0), 0.25, boundary)
    run = anodize(flat, target, record=4, model=Model(step=step, k_exp=k_exp), engine=engine)
    layers = int(np.ceil(target / (k_exp * step) - 1e-9))  # the thesis's termination: first layer past target
    assert run.thickness == pytest.approx(layers * k_exp * step, rel=1e-12)
    assert np.ptp(run.metal.z) == 0.0 and np.ptp(run.oxide.z) == 0.0
    assert run.metal.z[0, 0] == pytest.approx(4.0 - layers * step, rel=1e-13)
    assert run.oxide.z[0, 0] == pytest.approx(4.0 + layers * (k_exp - 1) * step, rel=1e-13)
    assert run.history["iterations"][-1] == layers  # every point at once: they are exact ties


@pytest.mark.parametrize("engine", ["reference", "fast"])
def test_transposing_the_grid_transposes_the_result(engine):
    surface = Surface(np.random.default_rng(2).uniform(3.5, 4.5, (5, 5)), 1.0).refine(2)
    a = anodize(surface, 0.4, record=3, model=Model(step=0.01), engine=engine)
    b = anodize(surface.transposed(), 0.4, record=3, model=Model(step=0.01), engine=engine)
    np.testing.assert_allclose(b.metal.z.T, a.metal.z, atol=1e-12)
    np.testing.assert_allclose(b.oxide.z.T, a.oxide.z, atol=1e-12)
    np.testing.assert_allclose(b.history["oxide_rms_nm"], a.history["oxide_rms_nm"], atol=1e-12)


def test_periodic_translation_gives_the_translated_result():
    z = np.random.default_rng(4).uniform(0, 0.5, (10, 12))
    a = anodize(Surface(z, 0.25, "periodic"), 0.4, record=3, model=Model(step=0.01))
    b = anodize(Surface(np.roll(z, (3, 5), axis=(0, 1)), 0.25, "periodic"), 0.4, record=3, model=Model(step=0.01))
    np.testing.assert_allclose(np.roll(a.oxide.z, (3, 5), axis=(0, 1)), b.oxide.z, atol=1e-12)
    np.testing.assert_allclose(np.roll(a.metal.z, (3, 5), axis=(0, 1)), b.metal.z, atol=1e-12)


def test_hill_and_depression_planarize_by_the_same_amount():
    """Thesis Fig 3-9: the total planarization is the same for the hill and the depression."""
    drop = {}
    for name in ("hill", "depression"):
        run = anodize(getattr(surfaces, name)(), 1.0, record=2, model=Model(step=0.01))
        drop[name] = {c: run.history[c][0] - run.history[c][-1] for c in ("metal_rms_nm", "oxide_rms_nm")}
    total = {name: sum(d.values()) for name, d in drop.items()}
    assert total["hill"] == pytest.approx(total["depression"], rel=0.04)
    for c in ("metal_rms_nm", "oxide_rms_nm"):
        assert drop["hill"][c] == pytest.approx(drop["depression"][c], rel=0.15)
        assert drop["hill"][c] > 0.4 * run.history[c][0]  # and both planarize substantially


RMS = ("metal_rms_nm", "oxide_rms_nm")
ZRANGE = ("metal_zrange_nm", "oxide_zrange_nm")
RANDOM = Surface(4 + np.random.default_rng(5).uniform(-0.25, 0.25, (4, 4)), 1.0).refine(4)


# Allowed RMS / z-range differences at every 0.1 nm: the fast engine at its default tolerance (a tenth
# of a step) measured (RMS, z-range) hill 1.5 / 6.2 %, depression 1.7 / 5.9 %, tilted 0.5 / 1.7 %,
# random 0.8 / 2.9 %: the RMS goal of 2 % is met. The z-range (a difference of two extremes) is noisier:
# the reference itself moves by 15.6 % (hill), 10.9, 2.1 and 2.6 % when its exact ties are broken by
# 1e-9 nm of height noise (docs/performance.md).
@pytest.mark.parametrize("surface, rms_allowed, zrange_allowed", [
    pytest.param(surfaces.hill(), 0.02, 0.07, id="hill"),
    pytest.param(surfaces.depression(), 0.02, 0.07, id="depression"),
    pytest.param(surfaces.tilted_plane(), 0.01, 0.03, id="tilted"),
    pytest.param(RANDOM, 0.01, 0.04, id="random", marks=pytest.mark.slow),
])
def test_fast_engine_matches_the_reference(surface, rms_allowed, zrange_allowed):
    targets = np.arange(1, 11) * 0.1
    ref = anodize(surface, 1.0, record=200, model=Model(step=0.01), engine=Fast(tolerance=0))  # = reference, faster
    run = anodize(surface, 1.0, record=200, model=Model(step=0.01), engine="fast")
    assert history_difference(run, ref, targets, RMS) < rms_allowed
    assert history_difference(run, ref, targets, ZRANGE) < zrange_allowed
    np.testing.assert_allclose(run.history["volume_error"], 0.0, atol=1e-12)
    assert run.history["iterations"][-1] < 0.75 * ref.history["iterations"][-1]  # batches do form


def test_no_expansion_and_large_expansion_are_sane():
    hill = surfaces.hill(points=5, refine=2)
    still = anodize(hill, 0.2, record=2, model=Model(step=0.01, k_exp=1.0))
    np.testing.assert_array_equal(still.oxide.z, hill.z)  # k_exp = 1: the oxide just replaces the metal
    assert np.all(still.metal.z < hill.z) and still.thickness >= 0.2
    big = anodize(hill, 0.5, record=2, model=Model(step=0.01, k_exp=5.0))  # the largest allowed
    assert np.all(np.isfinite(big.oxide.z)) and big.thickness >= 0.5
    assert big.history["volume_error"][-1] == pytest.approx(0.0, abs=1e-12)


@pytest.mark.parametrize("distance", ["thesis", "exact"])
@pytest.mark.parametrize("kind", ["cliff", "spike", "pit"])
def test_cliffs_and_spikes_stay_finite(kind, distance):
    z = np.full((7, 7), 4.0)
    if kind == "cliff":
        z[:, 4:] = 6.0  # a 2 nm step between two grid columns 0.25 nm apart
    elif kind == "spike":
        z[3, 3] = 8.0
    else:
        z[3, 3] = 0.0
    run = anodize(Surface(z, 0.25), 0.4, record=3, model=Model(step=0.02, k_exp=1.8, distance=distance))
    for s in run.snapshots:
        assert np.all(np.isfinite(s.metal.z)) and np.all(np.isfinite(s.oxide.z))
        assert np.all(s.oxide.z >= s.metal.z)
        assert np.all(np.isfinite(s.distances)) and np.all(s.distances >= 0)
    assert abs(run.history["volume_error"][-1]) < 1e-12


@pytest.mark.parametrize("call, message", [
    (lambda hill: anodize(hill, -1), r"thickness must be in \[0, "),
    (lambda hill: anodize(hill, np.nan), "thickness"),
    (lambda hill: anodize(hill, 1e300), "thickness"),
    (lambda hill: anodize(hill, 0.1, Model(step=0)), "step"),
    (lambda hill: anodize(hill, 0.1, Model(step=5.0)), r"step \(5 nm\) must not exceed thickness"),
    (lambda hill: anodize(hill, 100.0, Model(step=1e-5)), r"thickness / step = 1e\+07 steps"),
    (lambda hill: anodize(hill, 0.1, Model(k_exp=0.5)), r"k_exp must be in \[1, 5\]"),
    (lambda hill: anodize(hill, 0.1, Model(k_exp=1e100)), "k_exp"),
    (lambda hill: anodize(hill, 0.1, engine="gpu"), "engine"),
    (lambda hill: anodize(hill, 0.1, Model(distance="manhattan")), "distance"),
    (lambda hill: anodize(hill, 0.1, Model(volume="mean")), "volume"),
    (lambda hill: anodize(hill, 0.1, record=0), "record"),
    (lambda hill: anodize(hill, 0.1, record=[]), "record"),
    (lambda hill: anodize(hill, 0.1, record=10**9), "record"),
    (lambda hill: anodize(hill, 0.1, snapshots=[2.0]), "snapshots"),
    (lambda hill: anodize(hill, 0.1, snapshots="all"), "snapshots"),
    (lambda hill: anodize(hill, 0.1, engine=Fast(tolerance=-1)), "tolerance"),
    (lambda hill: anodize(hill, 0.1, engine=Fast(interacting="first")), "interacting"),
    (lambda hill: anodize(hill.z, 0.1), "Surface"),
])
def test_bad_run_parameters(call, message):
    with pytest.raises(ValueError, match=message):
        call(surfaces.hill(points=3, refine=1))


@pytest.mark.parametrize("keyword", ["step", "k_exp", "distance", "volume", "tolerance", "interacting", "threads",
                                     "jit"])
def test_flat_keywords_of_0_1_are_not_taken(keyword):
    # the physics is model=Model(...), the engine's settings engine=Fast(...): no second spelling
    with pytest.raises(TypeError, match=f"unexpected keyword argument '{keyword}'"):
        anodize(surfaces.hill(points=3, refine=1), 0.1, **{keyword: 0.01})


def test_observer_sees_every_sweep_and_a_budget_stops_the_run():
    hill = surfaces.hill(points=5, refine=2)
    seen = []
    run = anodize(hill, 0.3, Model(step=0.01), observer=lambda engine: seen.append(engine.thickness))
    assert len(seen) == run.history["iterations"][-1] + 1 and seen == sorted(seen) and run.complete
    cut = anodize(hill, 0.3, Model(step=0.01), max_seconds=1e-9)
    assert not cut.complete and cut.thickness < 0.3
    assert cut.history["target_nm"][-1] == cut.thickness == cut.snapshots[-1].thickness


def test_oxide_must_fit_the_metal():
    hill = surfaces.hill(points=3, refine=1)
    with pytest.raises(ValueError, match="below the metal"):
        anodize(hill, 0.1, oxide=hill.shifted(-0.1))
    with pytest.raises(ValueError, match="grid"):
        anodize(hill, 0.1, oxide=surfaces.hill(points=3, refine=2))


def test_a_run_continues_from_its_oxide():
    hill = surfaces.hill(points=5, refine=2)
    first = anodize(hill, 0.2, record=2, model=Model(step=0.01))
    second = anodize(first.metal, 0.4, oxide=first.oxide, record=2, model=Model(step=0.01))
    assert second.thickness >= 0.4
    assert second.history["thickness_nm"][0] == pytest.approx(first.thickness)


# -- the engines' contract (planarize.engines.protocol) ---------------------------------------------------------

@pytest.mark.parametrize("name", ["continuum", "fast", "reference", "matlab"])
def test_every_engine_satisfies_the_two_contracts(name):
    from planarize.engines import ENGINES
    from planarize.engines.protocol import EngineSettings, RunningEngine

    settings = ENGINES[name]()
    assert isinstance(settings, EngineSettings) and settings.name == name
    engine = settings.build(surfaces.hill(points=5, refine=2), None, Model(step=0.05))
    assert isinstance(engine, RunningEngine)


def test_anodize_knows_no_engine_by_its_type():
    """anodize hands a run to its settings (EngineSettings.run): a settings object of a new kind runs."""
    import inspect

    import planarize.anodize as module
    from planarize.engines import Fast

    assert "isinstance(settings" not in inspect.getsource(module)

    class Counting(Fast):
        calls = []

        def run(self, *args, **kwargs):
            Counting.calls.append(args[2])
            return super().run(*args, **kwargs)

    run = planarize.anodize(surfaces.hill(points=5, refine=2), 0.5, engine=Counting())
    assert Counting.calls == [0.5] and run.complete
