"""Deposition protocols, experiments and presets (thesis Appendix A, FileDepositer)."""

import math

import numpy as np
import pytest
from helpers import TimeRecorder, worst_overlap

import qdots
from qdots.deposition import HEX_PACKING, deposit, deposit_around_centre, dot_masses, draw_diameters, ring_radius
from qdots.experiment import Board, Deposition, Experiment, run_experiment
from qdots.presets import GRATING_WIDTH, PRESETS, get_preset


def empty_sim(box=(100.0, 100.0), forces=(), segments=None, seed=1):
    scene = qdots.Scene(box=box, positions=np.zeros((0, 2)), radii=[], segments=segments)
    return qdots.Simulation(scene, list(forces), seed=seed)


# --- diameters and masses -------------------------------------------------------------------

@pytest.mark.parametrize("sigma", [0.05, 0.15])
def test_diameters_have_requested_mean_and_std(rng, sigma):
    n, mean = 600, 15.0
    d = draw_diameters(n, mean, sigma, rng)
    std = mean * sigma
    assert abs(d.mean() - mean) < 4 * std / math.sqrt(n)
    assert abs(d.std(ddof=1) - std) < 4 * std / math.sqrt(2 * (n - 1))


def test_uniform_diameters_are_exact_and_use_no_randomness(rng):
    before = rng.bit_generator.state
    assert np.array_equal(draw_diameters(50, 15.0, 0.0, rng), np.full(50, 15.0))
    assert rng.bit_generator.state == before


def test_nonpositive_diameters_are_redrawn(rng):
    d = draw_diameters(2000, 15.0, 0.9, rng)  # N < -1.11 happens ~13 % of the time
    assert (d > 0).all()


def test_mass_models_give_the_documented_values(rng):
    d = np.array([7.5, 15.0, 30.0])
    assert np.array_equal(dot_masses(d, 15.0, "equal"), [1.0, 1.0, 1.0])
    assert np.allclose(dot_masses(d, 15.0, "area"), [0.25, 1.0, 4.0])
    assert np.allclose(dot_masses(d, 15.0, "volume"), [0.125, 1.0, 8.0])
    m = dot_masses(np.full(2000, 15.0), 15.0, "bimodal", heavy_mass=2.0, rng=rng)
    assert set(np.unique(m)) == {1.0, 2.0}
    assert abs(np.mean(m == 2.0) - 0.5) < 4 * 0.5 / math.sqrt(2000)


def test_mass_model_errors():
    with pytest.raises(ValueError, match="mass model must be one of"):
        dot_masses([15.0], 15.0, "density")
    with pytest.raises(ValueError, match="needs an rng"):
        dot_masses([15.0], 15.0, "bimodal")


# --- deposit ----------------------------------------------------------------------------------

def test_deposit_places_dots_inside_region_without_overlap():
    sim = empty_sim()
    region = (20.0, 30.0, 90.0, 80.0)
    d = deposit(sim, 12, mean_diameter=10.0, sigma=0.1, region=region, interval=0.0, rng=7)
    state = sim.state()
    assert state.n_dots == 12 and np.allclose(2 * state.radii, d)
    x, y, r = state.positions[:, 0], state.positions[:, 1], state.radii
    assert (x - r >= region[0]).all() and (x + r <= region[2]).all()
    assert (y - r >= region[1]).all() and (y + r <= region[3]).all()
    assert worst_overlap(state.positions, state.radii) == 0.0


def test_deposit_advances_time_per_dot_and_sets_masses():
    sim = empty_sim(box=(120.0, 120.0), forces=[qdots.VanDerWaals(), qdots.ThermalKicks()])
    d = deposit(sim, 8, sigma=0.15, mass_model="volume", interval=0.04, rng=3)
    assert sim.n_dots == 8
    assert sim.steps_taken == 8 * round(0.04 / sim.dt) and sim.time == pytest.approx(0.32)
    assert np.allclose(sim.masses, (d / 15.0) ** 3)


def test_deposit_avoids_extra_walls():
    sim = empty_sim(box=(100.0, 100.0), segments=[[0.0, 50.0, 100.0, 50.0]])
    deposit(sim, 20, mean_diameter=8.0, interval=0.0, rng=5)
    state = sim.state()
    assert (np.abs(state.positions[:, 1] - 50.0) >= state.radii).all()


def test_too_full_board_raises_a_clear_error():
    sim = empty_sim(box=(40.0, 40.0))
    with pytest.raises(ValueError, match=r"board too full: placed \d+ of 30 dots.*region \(0, 0, 40, 40\).*"
                                         r"area fraction 0\.\d+"):
        deposit(sim, 30, interval=0.0, max_tries=300, rng=1)


def test_deposit_rejects_bad_arguments():
    sim = empty_sim()
    with pytest.raises(ValueError, match=r"sigma must be in \[0, 1\), got 1.5"):
        deposit(sim, 1, sigma=1.5)
    with pytest.raises(ValueError, match="region must satisfy"):
        deposit(sim, 1, region=(0, 0, 200, 50))
    with pytest.raises(ValueError, match="does not fit in region"):
        deposit(sim, 1, region=(0, 0, 100, 10))
    with pytest.raises(ValueError, match=r"n_dots must be an integer in \[0, "):
        deposit(sim, 2.5)


def test_writers_see_one_continuous_run():
    sim, rec = empty_sim(), TimeRecorder(every=10)
    sim.attach(rec)
    deposit(sim, 3, interval=0.05, rng=2)
    steps = round(0.15 / sim.dt)  # steps 0, 10, 20, ... to the end, no repeats
    assert np.allclose(rec.times, np.arange(1 + steps // 10) * 10 * sim.dt)


def test_deposit_around_centre_uses_the_thesis_ring():
    sim = empty_sim(box=(300.0, 300.0))
    deposit_around_centre(sim, 10, (150.0, 150.0), sigma=0.1, interval=0.0, rng=4)
    distance = np.linalg.norm(sim.state().positions - 150.0, axis=1)
    expected = [math.sqrt(HEX_PACKING * i) * 7.5 + 3.1 * 15.0 for i in range(10)]
    assert np.allclose(distance, expected) and np.allclose(distance, [ring_radius(i, 15.0, 0.1) for i in range(10)])
    with pytest.raises(ValueError, match="needs a ring of radius"):
        deposit_around_centre(empty_sim(box=(100.0, 100.0)), 10, (50.0, 50.0))


# --- experiments -------------------------------------------------------------------------------

def small_experiment(seed=3):
    return Experiment(name="small", seed=seed, board=Board(120.0, 120.0),
                      deposition=Deposition(n_dots=8, sigma=0.1, interval=0.04, settle=0.3))


def test_run_experiment_is_reproducible_and_seed_dependent():
    a, b, c = (run_experiment(small_experiment(seed)) for seed in (3, 3, 4))
    sa, sb, sc = a.state(), b.state(), c.state()
    assert sa.time == pytest.approx(8 * 0.04 + 0.3) and sa.n_dots == 8
    assert np.array_equal(sa.positions, sb.positions) and np.array_equal(sa.velocities, sb.velocities)
    assert np.array_equal(sa.radii, sb.radii)
    assert not np.array_equal(sa.positions, sc.positions)


def test_grating_keeps_dots_in_the_channel():
    exp = get_preset("fig2-3", quick=True)[0]
    assert exp.grating == pytest.approx(77.94228634059948) == GRATING_WIDTH
    sim = run_experiment(exp)
    state = sim.state()
    y, r = state.positions[:, 1], state.radii
    assert state.n_dots == 15
    assert (y - r > -0.05 * r).all() and (y + r < exp.grating + 0.05 * r).all()
    sim.set_velocities(np.tile([0.0, 300.0], (state.n_dots, 1)))  # throw everything at the wall
    y, r = sim.run(0.5).positions[:, 1], state.radii
    assert (y + r < exp.grating + 0.05 * r).all()
    assert np.allclose(state.masses, (2 * r / 15.0) ** 3)  # runRandomAttractionGrating(..., true)


def test_center_gravity_quick_run_gathers_dots():
    exp = get_preset("centre-gravity", quick=True)[1]
    sim = run_experiment(exp)
    state = sim.state()
    assert state.n_dots == 50
    spread = np.linalg.norm(state.positions - 300.0, axis=1).max()
    assert spread < ring_radius(49, 15.0, 0.15)  # pulled inside the deposition ring


def test_every_preset_builds_with_thesis_parameters():
    assert set(PRESETS) == {"fig2-2", "fig2-3", "fig2-6", "centre-gravity"}
    for name, runs in PRESETS.items():
        for exp, quick in zip(runs, get_preset(name, quick=True)):
            assert exp.seed == 154 and exp.board == Board(600.0, 600.0, True)
            assert quick.deposition.n_dots < exp.deposition.n_dots
            assert quick.scene().n_dots == 0
    fig22 = PRESETS["fig2-2"]
    assert [e.deposition.sigma for e in fig22] == [0.0, 0.15]
    assert all(e.deposition.n_dots == 300 and e.deposition.settle == 100.0 for e in fig22)
    assert [f["type"] for f in fig22[0].forces] == ["VanDerWaals", "ThermalKicks"]
    fig26 = PRESETS["fig2-6"]
    assert [e.deposition.mass_model for e in fig26].count("volume") == 4
    assert fig26[-1].deposition.mass_model == "bimodal" and fig26[-1].deposition.sigma == 0.0
    central = PRESETS["centre-gravity"][0]
    types = {f["type"]: f for f in central.forces}
    assert types["CentreGravity"]["centre"] == [300.0, 300.0] and types["CentreGravity"]["magnitude"] == 750.0
    assert types["Drag"]["linear"] == 0.1 and types["Drag"]["quadratic"] == 0.1 / 30.0


def test_unknown_preset_lists_the_known_ones():
    with pytest.raises(ValueError, match="unknown preset 'fig9'.*fig2-2, fig2-3, fig2-6, centre-gravity"):
        get_preset("fig9")


@pytest.mark.parametrize("build, message", [
    (lambda: Deposition(sigma=1.5), r"deposition.sigma must be in \[0, 1\), got 1.5"),
    (lambda: Deposition(n_dots=2.5), r"deposition.n_dots must be an integer in \[0, 1,000,000\], got 2.5"),
    (lambda: Deposition(protocol="spiral"), r"deposition.protocol must be one of"),
    (lambda: Deposition(mass_model="heavy"), r"deposition.mass_model must be one of"),
    (lambda: Board(width=-1.0), r"board.width must be in \(0, 1e6\] px"),
    (lambda: Board(closed=1), r"board.closed must be true or false"),
    (lambda: Experiment(grating=700.0), r"grating must be 0 \(none\) or in \(deposition.mean_diameter"),
    (lambda: Experiment(grating=50.0, deposition=Deposition(protocol="centre")), r"cannot be combined with a grating"),
    (lambda: Experiment(seed=-1), r"seed must be an integer in \[0, "),
    (lambda: Experiment(name=""), r"name must be a non-empty string"),
    (lambda: Experiment(engine={"dt": 1e-3}), r"engine must be a qdots.Chipmunk or qdots.Event"),
    (lambda: Experiment(forces=({"type": "Magnetic"},)), r"forces\[0\]: unknown force type 'Magnetic'"),
    (lambda: Experiment(forces=({"type": "Drag", "lin": 1.0},)), r"forces\[0\]: Drag has no parameter 'lin'"),
    (lambda: Experiment(deposition=Deposition(protocol="centre", n_dots=5000)),
     r"deposition.n_dots = 5000 needs a deposition ring"),
])
def test_experiment_validation_names_the_key(build, message):
    with pytest.raises(ValueError, match=message):
        build()


def test_forces_are_stored_in_full_and_quick_scales_the_board():
    exp = Experiment(forces=[qdots.Drag(), {"type": "ThermalKicks"}])
    assert exp.forces[1] == qdots.ThermalKicks().to_dict() and exp.forces[0]["linear"] == 0.025
    assert len({exp, exp.replace(), Experiment()}) == 2  # hashable, equal ones hash alike
    quick = PRESETS["fig2-2"][0].quick(0.25)
    assert quick.board.width == pytest.approx(300.0) and quick.deposition.n_dots == 75
    assert quick.deposition.interval == 0.25 and quick.deposition.settle == 25.0
    with pytest.raises(ValueError, match=r"factor must be in \(0, 1\]"):
        exp.quick(1.5)


def test_an_experiment_checks_each_force_once_and_a_simulation_builds_it_once_more(monkeypatch):
    """Values are checked once where they enter: a force given as an object is taken as it is, a table is built
    (and so checked) once; only the simulation builds its own (issue 64: the inference's films built their
    thermal kicks 4 times each)."""
    import functools

    from qdots.experiment import build_simulation
    from qdots.forces import ThermalKicks
    from qdots.inference.forward import film_experiment
    from qdots.inference.library import prior_point

    built = []
    original = ThermalKicks.__init__

    @functools.wraps(original)  # the signature stays: a force's params() reads it
    def counting(self, *args, **kwargs):
        built.append(1)
        original(self, *args, **kwargs)

    monkeypatch.setattr(ThermalKicks, "__init__", counting)
    exp = film_experiment(prior_point(0))
    assert len(built) == 1
    build_simulation(exp)
    assert len(built) == 2
    Experiment(forces=[{"type": "ThermalKicks", "scale": 2.0}])
    assert len(built) == 3


def test_a_power_mass_model_is_checked_before_the_first_dot():
    sim = empty_sim()
    with pytest.raises(ValueError, match=r"mass_exponent must be in \[0, 6\], got 7"):
        deposit(sim, 5, mass_model="power", mass_exponent=7.0, rng=np.random.default_rng(0))
    assert sim.n_dots == 0
