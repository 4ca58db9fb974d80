"""Size colouring, PNG and MP4 output, and the ``qdots`` command line."""

import csv
import subprocess
import sys

import imageio.v2 as imageio
import matplotlib
import numpy as np
import pytest
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.collections import EllipseCollection, LineCollection
from matplotlib.figure import Figure
from movie_probe import assert_playable, probe, read_frames

import qdots
from qdots import cli
from qdots.deposition import dot_masses
from qdots.placement import random_sequential
from qdots.render import MovieWriter, add_key, draw_state, heavy_dots, key_label, save_png, size_colours, size_range


def small_sim(n=10, seed=2):
    positions, radii = random_sequential(n, (120, 120), sigma=0.1, rng=seed)
    scene = qdots.Scene(box=(120, 120), positions=positions, radii=radii, segments=[[0, 60, 80, 60]])
    return qdots.Simulation(scene, [qdots.VanDerWaals(), qdots.ThermalKicks()], seed=seed, dt=1e-3)


# --------------------------------------------------------------------------- colours


def luminance(rgb):
    """Relative luminance of sRGB colours (WCAG): what a reader without colour vision still tells apart."""
    rgb = np.asarray(rgb, dtype=float)
    linear = np.where(rgb <= 0.04045, rgb / 12.92, ((rgb + 0.055) / 1.055) ** 2.4)
    return linear @ [0.2126, 0.7152, 0.0722]


def test_sizes_take_viridis_from_the_smallest_dot_to_the_largest():
    viridis = matplotlib.colormaps["viridis"]
    np.testing.assert_allclose(size_colours([5.0, 7.5, 10.0]), [viridis(0.0)[:3], viridis(0.5)[:3], viridis(1.0)[:3]])
    assert size_range([5.0, 7.5, 10.0]) == (10.0, 20.0)  # diameters, px
    # a given range: dots outside it take its end colours
    np.testing.assert_allclose(size_colours([4.0, 7.5, 11.0], (10.0, 20.0)), size_colours([5.0, 7.5, 10.0]))
    with pytest.raises(ValueError, match="diameters must be"):
        size_colours([5.0], (3.0, 3.0))


def test_equal_sizes_take_the_middle_colour():
    np.testing.assert_allclose(size_colours(np.full(5, 7.5)), np.tile(matplotlib.colormaps["viridis"](0.5)[:3], (5, 1)))
    assert size_range(np.full(5, 7.5)) == pytest.approx((15.0 * 0.95, 15.0 * 1.05))


def test_larger_dots_are_lighter_so_that_sizes_read_without_colour_vision():
    colours = size_colours(np.linspace(6.0, 9.0, 50))
    assert np.all(np.diff(luminance(colours)) > 0)  # one ordering, in lightness alone
    assert luminance(colours[-1]) > 10 * luminance(colours[0])


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
    path = save_png(state, tmp_path / "board.png", title="a run\n10 dots")
    assert path == tmp_path / "board.png"
    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    image = imageio.imread(path)
    assert image.shape[:2] == (int(100 * (1.45 + 4.5 + 0.75)), 600)
    rgb = image[..., :3].astype(int)
    # the smallest and the largest dot in the map's end colours (and the colour bar has them too)
    for end in (0.0, 1.0):
        colour = np.round(255 * np.array(matplotlib.colormaps["viridis"](end)[:3])).astype(int)
        assert (np.abs(rgb - colour).max(axis=2) <= 2).sum() > 200
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


def test_the_colour_bar_says_what_the_colours_mean_and_which_dots_are_heavy():
    state = heavy_board()
    d = 2 * state.radii
    assert key_label(state) == (f"dot diameter d (px): mean {d.mean():.3g}, SD {d.std():.2g}\n"
                                "thick dark edge: heavy, heavier than its size makes it (2 of 4 dots)")
    equal = qdots.State(time=0.0, positions=state.positions, velocities=state.velocities, radii=np.full(4, 7.5),
                        masses=np.ones(4), box=state.box, walls=state.walls)
    assert key_label(equal, "nm") == "dot diameter d (nm): mean 15, SD 0 (all one size)"
    fig = Figure()
    FigureCanvasAgg(fig)
    ax = draw_state(state, ax=fig.add_subplot(), key=True)
    (bar,) = [a for a in fig.axes if a is not ax]  # the colour bar, under the board
    assert bar.get_xlabel() == key_label(state) and bar.get_xlim() == pytest.approx((12.0, 18.0))
    assert bar.get_position().y1 < ax.get_position().y0
    bar = add_key(ax, state, diameters=(10.0, 20.0), cax=fig.add_axes((0.1, 0.0, 0.8, 0.02)))
    assert bar.ax.get_xlim() == pytest.approx((10.0, 20.0))


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
    # every frame has the colour bar of the sizes (over this board's, no range being given)
    (bar,) = [ax for ax in movie.figure.axes if ax.get_xlabel().startswith("dot diameter d (px): mean")]
    assert bar.get_xlim() == pytest.approx(size_range(sim.state().radii))
    found = probe(path)
    assert found["frames"] == 11 and found["fps"] == pytest.approx(10)
    assert read_frames(path)[0].shape == (128, 128, 3)


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
    assert sorted(p.name for p in (tmp_path / "demo").iterdir()) == ["demo.mp4", "demo.png", "summary.csv"]
    with open(tmp_path / "demo" / "summary.csv") as f:
        (row,) = list(csv.DictReader(f))
    assert int(row["dots"]) == 30 and int(row["steps"]) == round(1.0 / qdots.Chipmunk().dt)
    assert float(row["simulated_s"]) == pytest.approx(1.0)
    assert 0.0 <= float(row["interior_fraction"]) <= 1.0
    assert 0.0 <= float(row["max_overlap_pct_radius"]) < 5  # percent of a radius
    out = capsys.readouterr().out
    for label in ("dots", "simulated time", "wall time", "steps/s", "interior fraction",
                  "mean neighbours (interior)", "max overlap", "kinetic energy", "files"):
        assert label in out
    # a frame every 0.2 s over 1 s, start included; 25 frames/s and 600 px (MovieWriter's defaults)
    assert_playable(tmp_path / "demo" / "demo.mp4", frames=6, fps=25, size_px=600)


def test_cli_demo_is_reproducible(tmp_path):
    args = ["demo", "--dots", "20", "--seconds", "0.3", "--no-movie", "--seed", "4"]
    assert cli.main(args + ["--out", str(tmp_path / "a")]) == 0
    assert cli.main(args + ["--out", str(tmp_path / "b")]) == 0
    with open(tmp_path / "a" / "demo" / "summary.csv") as f, open(tmp_path / "b" / "demo" / "summary.csv") as g:
        a, b = next(csv.DictReader(f)), next(csv.DictReader(g))
    for key in ("interior_fraction", "max_overlap_pct_radius", "kinetic_energy"):
        assert a[key] == b[key]
    assert not (tmp_path / "a" / "demo" / "demo.mp4").exists()


@pytest.mark.parametrize(
    "argv, message",
    [
        (["demo", "--dots", "-5"], "argument --dots: must be an integer in [1, 460], got -5"),
        (["demo", "--dots", "460", "--no-movie"], "board too full"),
        (["demo", "--sigma", "1.5"], r"argument --sigma: must be in [0, 1)"),
        (["demo", "--bogus"], "unknown option '--bogus' (see 'qdots demo --help')"),
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


def test_the_pictures_and_movies_of_a_run_say_which_run_they_show(tmp_path, capsys, monkeypatch):
    from helpers import gravity_scene_file

    import qdots.render as render

    shown = []
    save, init = render.save_png, render.MovieWriter.__init__

    def noted_save(state, path, **options):
        shown.append(("png", options["title"]))
        return save(state, path, **options)

    def noted_movie(self, path, **options):
        shown.append(("mp4", options["title"]))
        init(self, path, **options)

    monkeypatch.setattr(render, "save_png", noted_save)
    monkeypatch.setattr(render.MovieWriter, "__init__", noted_movie)
    scene = gravity_scene_file(tmp_path, settle=0.2)
    assert cli.main(["run", str(scene), "--out", str(tmp_path / "out"), "--movie", "--seed", "7"]) == 0
    identity = "grav\n12 dots, sigma 0, equal masses, chipmunk engine, seed 7"
    assert shown == [("mp4", identity), ("png", identity)]
    assert cli.main(["resume", str(tmp_path / "out" / "grav" / "grav.npz"), "--seconds", "0.1"]) == 0
    assert shown[-1] == ("png", identity.replace("grav\n", "grav-t0.3s\n"))
    assert cli.main(["render", str(tmp_path / "out" / "grav" / "grav.npz"), "--out", str(tmp_path / "r.png")]) == 0
    assert shown[-1] == ("png", identity)  # the state file says which run it is
    assert cli.main(["demo", "--out", str(tmp_path / "demo"), "--dots", "10", "--seconds", "0.1", "--seed", "3"]) == 0
    assert shown[-1] == ("png", "qdots demo\n10 dots, sigma 0.05, equal masses, chipmunk engine, seed 3")
    capsys.readouterr()
