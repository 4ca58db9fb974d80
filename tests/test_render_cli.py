"""Size colouring, PNG and MP4 output, and the ``qdots`` command line."""

import csv
import math
import subprocess
import sys

import imageio.v2 as imageio
import numpy as np
import pytest
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.collections import EllipseCollection, LineCollection
from matplotlib.figure import Figure

import qdots
from qdots import cli
from qdots.placement import random_sequential
from qdots.protocols import dot_masses
from qdots.render import MovieWriter, draw_state, heavy_dots, key_entries, save_png, size_colours

from movie_probe import assert_playable

E = math.e


def small_sim(n=10, seed=2):
    positions, radii = random_sequential(n, (120, 120), sigma=0.1, rng=seed)
    scene = qdots.Scene(box=(120, 120), positions=positions, radii=radii, segments=[[0, 60, 80, 60]])
    return qdots.Simulation(scene, [qdots.VanDerWaals(), qdots.ThermalKicks()], seed=seed, dt=1e-3)


# --------------------------------------------------------------------------- colours


def test_equal_sizes_are_pure_green():
    np.testing.assert_array_equal(size_colours(np.full(5, 7.5)), np.tile([0.0, 1.0, 0.0], (5, 1)))
    np.testing.assert_array_equal(size_colours([6.0, 9.0], sigma=0.0), [[0, 1, 0], [0, 1, 0]])


def test_thesis_colour_formula():
    # mean diameter 15 px, sigma 10 % -> s = 1.5 px; diameters m, m + s, m - s.
    colours = size_colours([7.5, 8.25, 6.75], mean=15.0, sigma=0.1)
    expected = [[1 / E, 1.0, 1 / E], [1.0, 1 / E, E**-2], [E**-2, 1 / E, 1.0]]
    np.testing.assert_allclose(colours, expected, rtol=1e-12)


def test_default_mean_and_spread_from_the_sizes():
    # Diameters 10 and 20: mean 15, std 5, so the small dot is at m - s, the large at m + s.
    colours = size_colours([5.0, 10.0])
    np.testing.assert_allclose(colours, [[E**-2, 1 / E, 1.0], [1.0, 1 / E, E**-2]], rtol=1e-12)


def test_larger_is_redder_smaller_is_bluer():
    red, green, blue = size_colours(np.linspace(6.0, 9.0, 7)).T
    assert np.all(np.diff(red) >= 0) and red[-1] > red[0]
    assert np.all(np.diff(blue) <= 0) and blue[0] > blue[-1]
    assert green[3] == 1.0 and green[0] < 1 and green[-1] < 1  # the mean size is the greenest
    assert min(red.min(), green.min(), blue.min()) >= 0 and max(red.max(), blue.max()) <= 1


# --------------------------------------------------------------------------- pictures


def test_draw_state_artists():
    sim = small_sim()
    sim.step(1234)
    state = sim.state()
    fig = Figure()
    FigureCanvasAgg(fig)
    ax = draw_state(state, ax=fig.add_subplot())
    (dots,) = [c for c in ax.collections if isinstance(c, EllipseCollection)]
    (walls,) = [c for c in ax.collections if isinstance(c, LineCollection)]
    np.testing.assert_allclose(dots.get_offsets(), state.positions)
    assert len(walls.get_segments()) == len(state.walls) == 5
    assert ax.get_title() == "t = 1.2 s"
    assert ax.get_aspect() == 1.0
    assert ax.get_xlim()[0] < 0 and ax.get_xlim()[1] > 120


def test_draw_state_makes_its_own_axes():
    import matplotlib.pyplot as plt

    ax = draw_state(small_sim().state(), show_time=False)
    try:
        assert ax.get_title() == ""
        assert len(ax.collections) == 2
    finally:
        plt.close(ax.figure)


def test_save_png_is_atomic_and_readable(tmp_path):
    state = small_sim().state()
    path = save_png(state, tmp_path / "board.png")
    assert path == tmp_path / "board.png"
    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    image = imageio.imread(path)
    assert image.shape[:2] == (600, 600)
    rgb = image[..., :3].astype(int)
    # Some dots are drawn in saturated size colours (the extremes of a 10 % spread).
    assert np.any((rgb[..., 0] > 200) & (rgb[..., 2] < 80)) and np.any((rgb[..., 2] > 200) & (rgb[..., 0] < 80))
    assert sorted(p.name for p in tmp_path.iterdir()) == ["board.png"]  # no temporary left


def heavy_board():
    """Four dots in a row: diameters 12, 14, 16, 18 px; the 2nd and 4th twice as heavy (Fig 2-6b's model)."""
    return qdots.State(time=0.0, positions=np.array([[20.0, 30], [40, 30], [60, 30], [80, 30]]),
                       velocities=np.zeros((4, 2)), radii=np.array([6.0, 7.0, 8.0, 9.0]),
                       masses=np.array([1.0, 2.0, 1.0, 2.0]), box=(100.0, 60.0), walls=np.zeros((0, 4)))


def test_board_axes_in_px_and_heavy_dots_with_a_dark_edge():
    fig = Figure()
    FigureCanvasAgg(fig)
    ax = draw_state(heavy_board(), ax=fig.add_subplot())
    assert ax.get_xlabel() == "x (px)" and ax.get_ylabel() == "y (px)"
    (dots,) = [c for c in ax.collections if isinstance(c, EllipseCollection)]
    widths = np.asarray(dots.get_linewidths())
    edges = np.asarray(dots.get_edgecolors())
    heavy = np.array([False, True, False, True])
    assert np.all(widths[heavy] > 3 * widths[~heavy])  # thick edges on the heavy dots only
    np.testing.assert_allclose(edges[heavy], [[0, 0, 0, 1]] * 2)  # opaque black
    assert np.all(edges[~heavy, 3] < 1)
    assert ax.get_legend() is None  # the key only when asked for


def test_heavy_dots_are_those_heavier_than_their_size_makes_them():
    rng = np.random.default_rng(3)
    d = 15.0 * (1 + 0.15 * rng.standard_normal(400)).clip(0.5)
    for model in ("equal", "area", "volume"):  # masses that follow size: no dot is heavy
        assert not heavy_dots(dot_masses(d, 15.0, model), d / 2).any(), model
    bimodal = dot_masses(d, 15.0, "bimodal", 2.0, rng)
    heavy = heavy_dots(bimodal, d / 2)
    given_heavy = bimodal == 2.0
    assert not heavy[~given_heavy].any()  # a large light dot is not heavy
    # a heavy dot is missed only when its size alone would make it as heavy: 1.05 (d / mean)^3 >= 2
    np.testing.assert_array_equal(heavy[given_heavy], 1.05 * (d[given_heavy] / d.mean()) ** 3 < 2.0)
    assert heavy.sum() > 0.9 * given_heavy.sum()
    assert heavy_dots(None, d / 2).shape == (400,) and not heavy_dots(None, d / 2).any()


def test_key_states_the_colour_rule_and_the_heavy_dots():
    state = heavy_board()
    d = 2 * state.radii
    m, s = d.mean(), d.std()  # 15 px and 2.24 px: size_colours' defaults
    handles, labels, title = key_entries(state)
    assert [h.get_markerfacecolor() for h in handles[:3]] == [(1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0)]
    assert labels[0].startswith("red: large") and f"m + s = {m + s:.3g} px" in labels[0]
    assert labels[1].startswith("green: mean") and f"m = {m:.3g} px" in labels[1]
    assert labels[2].startswith("blue: small") and f"m \u2212 s = {m - s:.3g} px" in labels[2]
    assert f"s = {s:.2g} px" in title
    # the stated thresholds are where size_colours saturates
    red, green, blue = size_colours(np.array([m + s, m, m - s, m + 0.9 * s, m - 0.9 * s]) / 2, mean=m, sigma=s / m).T
    assert red[0] == green[1] == blue[2] == 1 and red[3] < 1 and blue[4] < 1 and red[1] < 1 and blue[1] < 1
    assert "heavy" in labels[3] and "(2 of 4)" in labels[3] and handles[3].get_markeredgewidth() > 1
    # equal sizes and masses: one entry, no heavy dots
    equal = qdots.State(time=0.0, positions=state.positions, velocities=state.velocities, radii=np.full(4, 7.5),
                        masses=np.ones(4), box=state.box, walls=state.walls)
    assert key_entries(equal)[1] == ["green: all one size, d = 15 px"]
    fig = Figure()
    ax = draw_state(state, ax=fig.add_subplot(), key=True)
    assert [t.get_text() for t in ax.get_legend().get_texts()] == labels


def test_save_png_to_missing_directory_raises(tmp_path):
    with pytest.raises(OSError):
        save_png(small_sim().state(), tmp_path / "missing" / "board.png")


# --------------------------------------------------------------------------- movies


def test_movie_writer_frames(tmp_path):
    sim = small_sim()
    path = tmp_path / "run.mp4"
    with MovieWriter(path, every=20, fps=10, size_px=128) as movie:
        sim.attach(movie)
        sim.run(0.2)  # 200 steps: frames at steps 0, 20, ..., 200
        assert not path.exists()  # renamed into place only on close
    assert movie.frames == 11 and movie.closed
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run.mp4"]
    reader = imageio.get_reader(path)
    try:
        assert reader.count_frames() == 11
        frame = reader.get_data(0)
        assert frame.shape == (128, 128, 3)
        assert reader.get_meta_data()["fps"] == pytest.approx(10)
    finally:
        reader.close()


def test_movie_writer_cleans_up_on_error(tmp_path):
    sim = small_sim()
    with pytest.raises(RuntimeError, match="boom"):
        with MovieWriter(tmp_path / "run.mp4", every=10, size_px=64) as movie:
            sim.attach(movie)
            sim.run(0.05)
            raise RuntimeError("boom")
    assert list(tmp_path.iterdir()) == []
    with pytest.raises(ValueError, match="closed"):
        movie.write(sim.state())


@pytest.mark.parametrize(
    "kwargs, message",
    [(dict(every=0), "every must be an integer >= 1"), (dict(size_px=101), "size_px must be even"),
     (dict(fps=0), r"fps must be in \(0, ")],
)
def test_movie_writer_validates(tmp_path, kwargs, message):
    with pytest.raises(ValueError, match=message):
        MovieWriter(tmp_path / "x.mp4", **kwargs)
    assert list(tmp_path.iterdir()) == []


# --------------------------------------------------------------------------- command line


def test_cli_demo_writes_outputs(tmp_path, capsys):
    assert cli.main(["demo", "--out", str(tmp_path), "--dots", "30", "--seconds", "1"]) == 0
    assert sorted(p.name for p in tmp_path.iterdir()) == ["demo.mp4", "demo.png", "summary.csv"]
    with open(tmp_path / "summary.csv") as f:
        (row,) = list(csv.DictReader(f))
    assert int(row["dots"]) == 30 and int(row["steps"]) == round(1.0 / qdots.EngineSettings().dt)
    assert float(row["simulated_s"]) == pytest.approx(1.0)
    assert 0.0 <= float(row["interior_fraction"]) <= 1.0
    assert 0.0 <= float(row["max_overlap_pct_radius"]) < 5  # percent of a radius
    out = capsys.readouterr().out
    for label in ("dots", "simulated time", "wall time", "steps/s", "interior fraction",
                  "mean neighbours (interior)", "max overlap", "kinetic energy", "files"):
        assert label in out
    # a frame every 0.2 s over 1 s, start included; 25 frames/s and 600 px (MovieWriter's defaults)
    assert_playable(tmp_path / "demo.mp4", frames=6, fps=25, size_px=600)


def test_cli_demo_is_reproducible(tmp_path):
    args = ["demo", "--dots", "20", "--seconds", "0.3", "--no-movie", "--seed", "4"]
    assert cli.main(args + ["--out", str(tmp_path / "a")]) == 0
    assert cli.main(args + ["--out", str(tmp_path / "b")]) == 0
    a = list(csv.DictReader(open(tmp_path / "a" / "summary.csv")))[0]
    b = list(csv.DictReader(open(tmp_path / "b" / "summary.csv")))[0]
    for key in ("interior_fraction", "max_overlap_pct_radius", "kinetic_energy"):
        assert a[key] == b[key]
    assert not (tmp_path / "a" / "demo.mp4").exists()


@pytest.mark.parametrize(
    "argv, message",
    [
        (["demo", "--dots", "-5"], "argument --dots: must be an integer in [1, 460], got -5"),
        (["demo", "--dots", "460", "--no-movie"], "board too full"),
        (["demo", "--sigma", "1.5"], r"argument --sigma: must be in [0, 1)"),
        (["demo", "--bogus"], "unrecognized arguments: --bogus"),
        ([], "required: COMMAND"),
    ],
)
def test_cli_bad_input_is_one_line_exit_2(tmp_path, capsys, argv, message):
    argv = argv + (["--out", str(tmp_path / "out")] if argv else [])
    assert cli.main(argv) == 2
    err = capsys.readouterr().err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("qdots: error: ")
    assert message in lines[0]
    assert "Traceback" not in err
    assert not (tmp_path / "out").exists()


def test_cli_help(capsys):
    assert cli.main(["demo", "--help"]) == 0
    out = capsys.readouterr().out
    assert "--dots" in out and "--no-movie" in out


def test_python_dash_m():
    result = subprocess.run([sys.executable, "-m", "qdots", "--version"], capture_output=True, text=True, timeout=60)
    assert result.returncode == 0
    assert result.stdout.strip() == f"qdots {qdots.__version__}"
