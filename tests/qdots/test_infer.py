"""qdots infer: the power mass model, the forward model's measures, the library of films, the posterior (when the
infer extra is installed), the command's refusals, and (slow) a small calibration on synthetic micrographs."""

import math

import numpy as np
import pytest
from helpers import has_avx512, one_line_error, refused
from PIL import Image

from labrig.validate import InputError
from qdots.cli.main import main
from qdots.deposition import dot_masses
from qdots.experiment import Deposition, Experiment
from qdots.inference.forward import (
    CONDITIONS,
    MASS_MODELS,
    PARAMETERS,
    SUMMARIES,
    FilmRunner,
    check_point,
    film_experiment,
    film_measures,
    peak_position,
)
from qdots.inference.library import build_library, library_size, observation, prior_point, training_arrays
from qdots.micrograph.film import film_state
from qdots.micrograph.synthetic import superlattice_board


def test_power_masses_follow_the_exponent_and_match_the_named_models():
    d = np.array([10.0, 15.0, 22.5])
    assert np.allclose(dot_masses(d, 15.0, "power", exponent=3.0), dot_masses(d, 15.0, "volume"))
    assert np.allclose(dot_masses(d, 15.0, "power", exponent=2.0), dot_masses(d, 15.0, "area"))
    assert np.allclose(dot_masses(d, 15.0, "power", exponent=0.0), 1.0)
    assert np.allclose(dot_masses(d, 15.0, "power", exponent=1.5), (d / 15.0) ** 1.5)
    refused(lambda: dot_masses(d, 15.0, "power"), "exponent")
    refused(lambda: dot_masses(d, 15.0, "power", exponent=7.0), "mass_exponent", "[0, 6]")
    refused(lambda: Deposition(mass_model="power"), "deposition.mass_exponent")
    refused(lambda: Deposition(mass_model="power", mass_exponent=-1.0), "deposition.mass_exponent")


def test_power_masses_reach_the_board_and_the_experiment_file(tmp_path):
    from qdots.experiment import run_experiment
    from qdots.io.experiment_file import load_experiment, save_experiment

    exp = Experiment(deposition=Deposition(n_dots=5, sigma=0.2, mass_model="power", mass_exponent=1.5,
                                           interval=0.1, settle=0.1)).quick(1.0)
    state = run_experiment(exp).state()
    assert np.allclose(state.masses, (2 * state.radii / 15.0) ** 1.5)
    save_experiment(exp, tmp_path / "e.toml")
    assert load_experiment(tmp_path / "e.toml") == exp
    # an experiment without the power model keeps its canonical parameters (no new key: sweep ids unchanged)
    from qdots.cli.sweep import experiment_to_dict
    assert "mass_exponent" not in experiment_to_dict(Experiment())["deposition"]


def point(**changes):
    return {"kick": 0.0, "mass_exponent": 0.0, "restitution": 0.8, "drag": -3.0, "attraction": 0.0, "sigma": 0.1,
            "coverage": 0.3, **changes}


def test_points_are_checked_and_build_the_thesis_deposition():
    exp = film_experiment(point(kick=math.log10(2.0), drag=-1.0, attraction=math.log10(0.5), n_dots=40, seed=3))
    assert exp.deposition.n_dots == 40 and exp.seed == 3 and exp.restitution.mean == 0.8
    pull = [f for f in exp.forces if f["type"] == "VanDerWaals"][0]
    assert pull["scale"] == pytest.approx(0.5)
    assert "scale" not in [f for f in film_experiment(point()).forces if f["type"] == "VanDerWaals"][0]
    kicks = [f for f in exp.forces if f["type"] == "ThermalKicks"][0]
    drag = [f for f in exp.forces if f["type"] == "Drag"][0]
    assert kicks["scale"] == pytest.approx(2.0) and drag["linear"] == pytest.approx(0.1)
    assert drag["quadratic"] == pytest.approx(0.1 / 30)
    area = 40 * math.pi * 15.0**2 * (1 + 0.1**2) / 4
    assert exp.board.width * exp.board.height == pytest.approx(area / 0.3)
    refused(lambda: check_point(point(restitution=0.5)), "restitution", "[0.7, 0.95]")
    refused(lambda: check_point(point(sigma=0.6)), "sigma")
    refused(lambda: check_point(point(coverage=0.8)), "coverage", "[0.05, 0.7]")
    refused(lambda: check_point(point(attraction=1.0)), "attraction", "[-0.6, 0.6]")
    refused(lambda: check_point({**point(), "kik": 1.0}), "unknown key 'kik'")
    refused(lambda: check_point({k: v for k, v in point().items() if k != "drag"}), "'drag'")


def test_a_film_past_its_wall_time_budget_stops_and_one_within_it_is_unchanged():
    """The budget stops a film (one point must not stall a library) and, attached, changes nothing of a film."""
    from qdots.experiment import run_experiment
    from qdots.inference.forward import FilmTooSlow, simulate_film

    small = point(n_dots=12, seed=5)
    plain = run_experiment(film_experiment(small)).state()
    budgeted = simulate_film(small).state()
    assert np.array_equal(plain.positions, budgeted.positions) and np.array_equal(plain.velocities,
                                                                                  budgeted.velocities)
    # the budget counts from the 5th simulated second: a new worker's compilation never counts against a film
    with pytest.raises(FilmTooSlow, match="ran past its budget of 1e-06 wall s at t = 6 s"):
        simulate_film(small, max_seconds=1e-6)
    refused(lambda: simulate_film(small, max_seconds=0), "max_seconds")


def test_measures_of_a_hexagonal_film_and_of_scattered_dots():
    centres, diameters = superlattice_board(400, 400, 15.0, 0.0, 1.0, "hexagonal", seed=1, jitter=0.0)
    state = film_state(centres, diameters, (400, 400))
    m = film_measures(state)
    assert m["interior_fraction"] == 1.0 and m["mean_neighbours"] == pytest.approx(6.0)
    assert m["psi6_local"] == pytest.approx(1.0, abs=1e-6) and m["single_share"] == 0.0
    assert m["low_share"] == 0.0 and m["small_share"] == 0.0
    assert m["mean_gap"] == pytest.approx(1.0 / 15.0, rel=1e-3)  # the lattice's 1 px gaps
    assert m["gr_peak_diameters"] == pytest.approx(16.0 / 15.0, abs=0.02)
    assert m["film_sigma"] == 0.0
    # dots 3 diameters apart: no neighbours, every dot single
    x, y = np.meshgrid(np.arange(5) * 45.0 + 30, np.arange(5) * 45.0 + 30)
    sparse = film_state(np.column_stack([x.ravel(), y.ravel()]), np.full(25, 15.0), (250, 250))
    m = film_measures(sparse)
    assert m["single_share"] == 1.0 and m["interior_fraction"] == 0.0 and m["low_share"] == 1.0
    assert m["mean_gap"] == pytest.approx(2.0)


def test_peak_position_is_the_vertex_of_the_parabola():
    r = np.arange(10.0)
    g = -(r - 4.3) ** 2
    assert peak_position(r, g, int(np.argmax(g))) == pytest.approx(4.3)
    assert peak_position(r, g[::-1] * 0 + 1.0, 0) == 0.0  # flat: the bin itself


def test_prior_points_are_fixed_by_their_index_and_inside_the_prior():
    assert prior_point(7) == prior_point(7) and prior_point(7) != prior_point(8)
    assert prior_point(7) != prior_point(7, "calibration")
    models = []
    for k in range(60):
        p = check_point(prior_point(k))
        for a in (*PARAMETERS, *CONDITIONS):
            assert a.low <= p[a.key] <= a.high
        models.append(p["mass_exponent"])
    assert sorted(set(models)) == [m.exponent for m in MASS_MODELS]  # the three models, and only they
    refused(lambda: prior_point(1, "other"), "stream")


def test_the_library_runs_only_the_films_it_lacks(tmp_path):
    lib = build_library(tmp_path / "lib", 3, workers=1, progress=False, n_dots=12)
    # a film of 12 dots may leave no dot with its whole neighbourhood on the board: it is replaced, and counted
    ran = library_size(tmp_path / "lib")
    assert len(lib.ids) == 3 and lib.ran == ran == len(lib.rows) >= 3
    assert [row["seed"] for row in lib.rows] == [prior_point(k, n_dots=12)["seed"] for k in range(ran)]
    again = build_library(tmp_path / "lib", 4, workers=1, progress=False, n_dots=12)
    assert len(again.ids) == 4 and again.ran == library_size(tmp_path / "lib") - ran >= 1
    assert [r["run"] for r in again.rows[:ran]] == [r["run"] for r in lib.rows]
    fewer = build_library(tmp_path / "lib", 2, workers=1, progress=False, n_dots=12)
    assert fewer.ran == 0 and len(fewer.ids) == 2 and library_size(tmp_path / "lib") == ran + again.ran
    refused(lambda: build_library(tmp_path / "lib", 2, workers=1, progress=False, n_dots=20), "12 dots")
    # a film's row is its measures, and running its point again gives the same board, so the same row
    runner = FilmRunner()
    row = runner(runner.canonical(prior_point(0, n_dots=12)))
    assert all(row[k] == lib.rows[0][k] or (math.isnan(row[k]) and math.isnan(lib.rows[0][k])) for k in row)


@pytest.mark.slow
def test_the_shipped_films_are_those_the_current_code_makes():
    """The training and replicate films shipped with the package (`SHIPPED`, `SHIPPED_REPLICATES`) are the prior's
    draws of this release, and three of them (first, middle, last), simulated again, give the same measures to the
    last bit. They were simulated on a CPU without AVX-512: on one with it, numpy's other code paths may round a
    polydisperse film's collisions differently; there a film that differs is skipped with that reason."""
    from qdots.inference.library import replicate_groups, shipped_replicates, shipped_rows
    from qdots.micrograph.choices import LIBRARY_FILMS

    rows = shipped_rows()
    usable = [k for k, row in enumerate(rows) if row["status"] == "ok"]
    assert len(usable) >= LIBRARY_FILMS - 20 and len(rows) >= LIBRARY_FILMS  # every point of the table is the prior's
    assert len(replicate_groups(shipped_replicates())) >= 55
    runner = FilmRunner()
    for k in (usable[0], usable[len(usable) // 2], usable[-1]):
        again = runner(runner.canonical(prior_point(k)))
        # the measures within 1e-12: a trajectory that differed at all would move them far more, and a sum's last bit
        # follows the CPU's vector width and the array's alignment (psi6 differed by 2e-17 on a second 2-core machine)
        same = all(again[key] == rows[k][key] or (math.isnan(again[key]) and math.isnan(rows[k][key]))
                   or math.isclose(again[key], rows[k][key], rel_tol=1e-12, abs_tol=1e-15) for key in again)
        if not same and has_avx512():
            pytest.skip("the shipped films were simulated on a CPU without AVX-512; this one has it, and film "
                        f"{k} differs")
        assert same, (k, {key: (again[key], rows[k][key]) for key in again if again[key] != rows[k][key]})


def test_films_that_fail_are_replaced_so_the_training_gets_the_films_asked_for(tmp_path, monkeypatch):
    import qdots.inference.library as library

    asked = []

    def every_third_fails(points, folder, **where):  # a stand-in for the simulations: each point's row
        asked.append(len(points))
        return [{"status": "failed" if k % 3 == 0 else "ok", "run": f"r{k}", **p, **{key: 0.5 for key in SUMMARIES},
                 "film_sigma": 0.1, "film_coverage": 0.3} for k, p in enumerate(points)]

    monkeypatch.setattr(library, "run_points", every_third_fails)
    lib = build_library(tmp_path / "lib", 20, progress=False, n_dots=12)
    assert len(lib.ids) == 20 and len(lib.rows) == 30 and lib.failed == 10 and "r0" not in lib.ids
    assert asked[0] == 20 and asked[-1] >= 30 and library_size(tmp_path / "lib") == asked[-1]
    assert lib.ids == [f"r{k}" for k in range(asked[-1]) if k % 3][:20]  # the first usable ones, in order

    def all_fail(points, folder, **where):
        return [{"status": "failed", "run": f"r{k}", **p} for k, p in enumerate(points)]

    monkeypatch.setattr(library, "run_points", all_fail)
    none = build_library(tmp_path / "dead", 20, progress=False, n_dots=12)  # bounded: 20 more at most
    assert len(none.ids) == 0 and library_size(tmp_path / "dead") == 40


def test_training_arrays_keep_whole_rows_and_the_observation_refuses_gaps():
    good = {"status": "ok", "run": "a", **{k: 0.5 for k in SUMMARIES}, **point(), "film_sigma": 0.1,
            "film_coverage": 0.3}
    theta, models, x, ids = training_arrays([good, {**good, "run": "b", "psi6_local": float("nan")},
                                             {**good, "run": "c", "status": "failed"},
                                             {**good, "run": "d", "mass_exponent": 3.0}])
    assert ids == ["a", "d"] and theta.shape == (2, 4) and x.shape == (2, len(SUMMARIES) + 2)
    assert list(models) == [0, 2]
    refused(lambda: training_arrays([{**good, "mass_exponent": 1.5}]), "mass_exponent", "none of the mass models")
    assert list(x[0][-2:]) == [0.1, 0.3]
    refused(lambda: observation({**{k: 0.5 for k in SUMMARIES}, "psi6_local": float("nan")},
                                {"sigma": 0.1, "coverage": 0.3}), "psi6_local")


def test_infer_refuses_a_picture_that_is_not_a_film_in_one_line(tmp_path, capsys):
    pytest.importorskip("sbi")  # without the extra, the command says so first
    noise = (np.random.default_rng(1).normal(128, 5, (128, 128))).clip(0, 255).astype(np.uint8)
    Image.fromarray(noise).save(tmp_path / "empty.png")
    out, library = tmp_path / "out", tmp_path / "library"
    assert main(["infer", str(tmp_path / "empty.png"), "--out", str(out), "--library", str(library)]) == 2
    assert "no dots found" in one_line_error(capsys)
    assert not out.exists() and not library.exists()
    assert main(["infer", str(tmp_path / "missing.png"), "--library", str(library)]) == 2
    one_line_error(capsys)


def test_a_film_outside_the_trained_conditions_is_refused_before_any_simulation(tmp_path, capsys):
    pytest.importorskip("sbi")  # without the extra, the command says so first
    from qdots.micrograph.synthetic import render_micrograph

    centres, diameters = superlattice_board(300, 300, 16.0, 0.01, 2.0, "hexagonal", seed=2)
    Image.fromarray((render_micrograph(centres, diameters, (300, 300), seed=2) * 220).clip(0, 255)
                    .astype(np.uint8)).save(tmp_path / "film.png")
    library = tmp_path / "library"
    assert main(["infer", str(tmp_path / "film.png"), "--out", str(tmp_path / "out"), "--library", str(library)]) == 2
    err = one_line_error(capsys)
    assert "outside the" in err and ("size spread" in err or "coverage" in err)
    assert not library.exists()


def test_infer_without_the_extra_says_how_to_install_it(monkeypatch):
    import sys

    from qdots.inference.posterior import require_sbi

    monkeypatch.setitem(sys.modules, "sbi", None)
    with pytest.raises(InputError, match=r"pip install torch==2.13.0 'nanodisorder\[infer\]'"):
        require_sbi()


@pytest.mark.slow
def test_the_posterior_recovers_a_known_linear_model_and_is_calibrated(tmp_path, monkeypatch):
    """The NPE wrapper on a toy model with a known answer: x = A theta + a shift by the mass model + noise (8
    numbers, as the films give). The posterior medians track the truth and calibrated 90 % intervals hold it in
    80-100 % of 120 held-out cases; the mass model's probabilities pick the true model where the shift tells it and
    stay near a third each where it does not. A fifth of the films calibrates and the rest trains. Training
    leaves no log folder where the user is."""
    pytest.importorskip("sbi")
    user = tmp_path / "user"
    user.mkdir()
    monkeypatch.chdir(user)
    from qdots.inference.posterior import credible_intervals, load_or_train

    rng, low, high, simulate = toy_model(0)

    theta = rng.uniform(low, high, (600, 4))
    models = rng.integers(0, 3, 600)
    ids = [f"toy{k}" for k in range(600)]
    x_train = simulate(theta, models)
    posterior, loaded = load_or_train(tmp_path, theta, models, x_train, ids, ensemble=1)
    assert not loaded
    assert 80 <= posterior.calibration.films <= 160 and posterior.training_films == 600 - posterior.calibration.films
    assert np.all((posterior.calibration.factors > 0.5) & (posterior.calibration.factors < 2.0))
    again, loaded = load_or_train(tmp_path, theta, models, x_train, ids, ensemble=1)
    assert loaded  # the same films: the saved posterior
    truth = rng.uniform(low, high, (120, 4))  # 120 cases: a binomial SE of 2.7 points at 90 %
    truth_models = np.arange(120) % 3
    x = simulate(truth, truth_models)
    hits = np.zeros(4)
    right = 0
    for t, m, obs in zip(truth, truth_models, x):
        rows = credible_intervals(again.sample(obs, 500))
        hits += [row["low"] <= v <= row["high"] for row, v in zip(rows, t)]
        assert all(row["width_share"] < 0.6 for row in rows)  # the toy data pin every parameter
        chance = again.model_probabilities(obs)
        assert chance.shape == (3,) and chance.sum() == pytest.approx(1.0)
        right += int(np.argmax(chance) == m)
    assert ((hits / 120 >= 0.8) & (hits / 120 <= 1.0)).all(), hits / 120
    assert right >= 100, right  # a shift of 0.6 against noise of 0.05 on top of a spread of 0.5: most are told
    assert list(user.iterdir()) == []  # sbi would write ./sbi-logs without our tracker
    # where the measures do not depend on the model, its probabilities stay near the prior's third
    blind, _ = load_or_train(tmp_path / "blind", theta, models, simulate(theta, models, 0.0), ids, ensemble=1)
    chances = np.array([blind.model_probabilities(obs) for obs in simulate(truth, truth_models, 0.0)])
    assert np.all(np.abs(chances - 1 / 3) < 0.2), chances.round(2)


def toy_model(seed: int = 0):
    """The toy of the posterior tests: x = A u + a shift by the mass model + noise, u the parameters scaled to the
    prior's box (8 numbers, as the films give)."""
    rng = np.random.default_rng(seed)
    low = np.array([p.low for p in PARAMETERS])
    high = np.array([p.high for p in PARAMETERS])
    a = np.array([[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1], [1, 1, 0, 0], [0, 0, 1, -1],
                  [0.5, 0, 0, 0], [0, 0, 0, 0.5]], dtype=float)

    def simulate(theta, models, shift=0.6):
        x = (theta - low) / (high - low) @ a.T + 0.05 * rng.standard_normal((len(theta), 8))
        x[:, 6] += shift * np.asarray(models)
        return x

    return rng, low, high, simulate


@pytest.mark.slow
@pytest.mark.timeout(900)
def test_the_joint_posterior_of_several_observations_is_calibrated_on_replicate_sets(tmp_path):
    """Several independent observations of one truth: the joint posterior (`joint_draws`) is narrower than one
    observation's and, calibrated on replicate sets (one truth, 8 observations each), still holds the truth; the
    mass model's probability multiplies. Without the replicate calibration, one network's shared errors left the
    4-observation intervals holding the truth in 67-87 % of 30 toy cases (measured)."""
    pytest.importorskip("sbi")
    from qdots.inference.posterior import credible_intervals, load_or_train

    rng, low, high, simulate = toy_model(1)
    theta = rng.uniform(low, high, (600, 4))
    models = rng.integers(0, 3, 600)
    replicates = [(t, int(m), simulate(np.repeat(t[None, :], 8, axis=0), [m] * 8))
                  for t, m in zip(rng.uniform(low, high, (60, 4)), rng.integers(0, 3, 60))]
    again, _ = load_or_train(tmp_path, theta, models, simulate(theta, models), [f"toy{k}" for k in range(600)],
                             ensemble=1, replicates=replicates)
    assert again.joint is not None and again.joint.counts == (2, 4, 8) and again.joint.groups == 60
    truth = rng.uniform(low, high, (30, 4))
    truth_models = np.arange(30) % 3
    joint_hits, single_width, joint_width = np.zeros(4), [], []
    for t, m in zip(truth[:30], truth_models[:30]):
        seen = simulate(np.repeat(t[None, :], 4, axis=0), [m] * 4)
        draws, effective = again.sample_joint(seen, 1000, seed=1)
        rows = credible_intervals(draws)
        joint_hits += [row["low"] <= v <= row["high"] for row, v in zip(rows, t)]
        joint_width.append([row["width_share"] for row in rows])
        single_width.append([row["width_share"] for row in credible_intervals(again.sample(seen[0], 1000))])
        assert effective > 200
        assert again.model_probabilities(seen)[m] >= again.model_probabilities(seen[0])[m] - 0.05
    assert (joint_hits / 30 >= 0.75).all(), joint_hits / 30
    assert np.mean(joint_width) < 0.75 * np.mean(single_width), (np.mean(joint_width), np.mean(single_width))


def test_a_large_picture_is_cut_into_parts_of_about_a_library_films_dots():
    from types import SimpleNamespace

    from qdots.inference.forward import MIN_PART_DOTS, image_measures, image_parts
    from qdots.micrograph.film import complete_neighbourhood

    centres, diameters = superlattice_board(1200, 600, 15.0, 0.05, 2.0, "hexagonal", seed=3)
    state = film_state(centres, diameters, (1200, 600))
    film = SimpleNamespace(state=state, complete=complete_neighbourhood(state))
    total = int(film.complete.sum())
    parts = image_parts(film, 150)
    assert abs(len(parts) - round(total / 150)) <= 1 and len(parts) >= 8  # a grid: as square as the board allows
    assert all(75 <= p.sum() <= 300 for p in parts), [int(p.sum()) for p in parts]
    together = np.sum(parts, axis=0)
    assert together.max() == 1 and np.all(film.complete[together > 0])  # disjoint, and only measured dots
    assert all(p.sum() >= MIN_PART_DOTS for p in parts) and together.sum() == total
    assert image_parts(film, 10 * total) == [film.complete] or np.array_equal(image_parts(film, 10 * total)[0],
                                                                                film.complete)
    whole, part = image_measures(film), image_measures(film, parts[0])
    assert whole["complete_dots"] == total and part["complete_dots"] == parts[0].sum()


def test_an_interval_piled_against_its_priors_bound_reaches_it():
    """The thesis's figures have no drag: -3, the prior's lower bound. A posterior piled against it gives an
    interval that holds the bound itself, not one that stops a hair short of it."""
    from qdots.inference.posterior import EDGE, credible_intervals

    rng = np.random.default_rng(2)
    low = np.array([p.low for p in PARAMETERS])
    high = np.array([p.high for p in PARAMETERS])
    draws = low + (high - low) * rng.uniform(0.3, 0.6, (4000, 4))
    drag = [p.key for p in PARAMETERS].index("drag")
    draws[:, drag] = -3.0 + np.abs(rng.normal(0.0, 0.4, 4000))  # piled against -3
    rows = credible_intervals(draws)
    assert rows[drag]["low"] == -3.0 and rows[drag]["at_bound"] == "low"
    assert np.quantile(draws[:, drag], 0.05) > -3.0  # the central interval alone would have left -3 out
    inner = [r for k, r in enumerate(rows) if k != drag]
    assert all(r["at_bound"] == "" and r["low"] > r["prior_low"] + EDGE * (r["prior_high"] - r["prior_low"])
               for r in inner)


def test_model_choice_tables_count_what_was_chosen_against_the_truth():
    from qdots.inference.modelchoice import confusion_table, reliability_table

    p = np.array([[0.9, 0.05, 0.05], [0.2, 0.7, 0.1], [0.3, 0.3, 0.4], [0.1, 0.85, 0.05]])
    truth = np.array([0, 1, 0, 2])
    assert confusion_table(p, truth).tolist() == [[1, 0, 1], [0, 1, 0], [0, 1, 0]]
    rows = {(r["low"], r["high"]): r for r in reliability_table(p, truth)}
    assert rows[(0.4, 0.5)]["films"] == 1 and rows[(0.4, 0.5)]["right"] == 0.0
    assert rows[(0.8, 0.9)]["films"] == 1 and rows[(0.8, 0.9)]["right"] == 0.0
    assert rows[(0.9, 1.0)]["films"] == 1 and rows[(0.9, 1.0)]["right"] == 1.0
    assert rows[(0.7, 0.8)]["stated"] == pytest.approx(0.7) and rows[(0.7, 0.8)]["right"] == 1.0


@pytest.mark.slow
@pytest.mark.release
@pytest.mark.timeout(1800)
def test_a_small_calibration_on_synthetic_micrographs(tmp_path):
    """A small version of the calibration (benchmarks.qdots_infer): a library of 300 films of 60 dots, 30 held-out
    films drawn as micrographs and measured. What docs/micrograph.md claims, at this size:
    - the picture tells the kicks: their posterior medians follow the truth (correlation 0.61 measured; a posterior
      that ignored the data, or put the mass exponent or the drag in the kicks' place, gives about 0);
    - the mass exponent and the drag are blind: their intervals stay wide (76 % of the prior measured);
    - the calibrated intervals hold the truth in at least 70 % of the films (90 % expected; 30 films give a
      binomial SE of 5.5 points), the networks' own in at least 60 %."""
    pytest.importorskip("sbi")
    from qdots.inference.calibration import calibration_films, coverage_table, truths
    from qdots.inference.posterior import load_or_train

    lib = build_library(tmp_path / "lib", 300, workers=2, progress=False, n_dots=60)
    posterior, _ = load_or_train(tmp_path / "lib", lib.theta, lib.models, lib.x, lib.ids)  # the default ensemble
    films = calibration_films(posterior, 30, tmp_path / "held-out", n_dots=60, workers=2, samples=1000)
    assert len(films) >= 28
    table = coverage_table(films)
    medians = np.array([[row["median"] for row in f.image] for f in films])
    truth = truths(films)
    r = [float(np.corrcoef(medians[:, k], truth[:, k])[0, 1]) for k in range(4)]
    assert r[0] > 0.3, r  # 0.40 measured with the attraction in the prior (0.61 without)
    for row in table:
        assert 0.7 <= row["coverage_image"] <= 1.0 and 0.7 <= row["coverage_board"] <= 1.0, row
        assert 0.6 <= row["coverage_image_raw"] <= 1.0, row
        if row["parameter"] in ("mass_exponent", "drag"):
            assert row["width_image"] > 0.5, row
