"""Figures 3-8, 3-9, 3-11 and the surface movie: the data drawn, the files written."""

import imageio.v2 as imageio
import numpy as np
import pytest
from matplotlib.figure import Figure

import planarize
from planarize import render


@pytest.fixture(scope="module")
def run():
    return planarize.anodize(planarize.surfaces.hill(refine=2), 0.5, planarize.Model(step=0.05), record=5,
                             snapshots=[0.0, 0.1, 0.2, 0.3, 0.4, 0.5])


def test_slice_draws_the_centre_line_open_before_filled_after(run):
    ax = Figure().add_subplot()
    render.draw_slice(run, ax)
    lines = ax.get_lines()
    assert len(lines) == 4
    centre = run.initial.shape[1] // 2
    expected = [run.initial, render.initial_oxide(run), run.metal, run.oxide]
    for line, surface in zip(lines, expected):
        np.testing.assert_array_equal(line.get_xdata(), run.initial.x)
        np.testing.assert_array_equal(line.get_ydata(), surface.z[:, centre])
    assert [line.get_marker() for line in lines] == ["s", "o", "s", "o"]  # metal squares, oxide circles
    assert [line.get_markerfacecolor() for line in lines[:2]] == ["none", "none"]  # open: initial
    assert all(line.get_markerfacecolor() != "none" for line in lines[2:])  # filled: final
    other = Figure().add_subplot()
    render.draw_slice(run, other, axis=1, index=0)
    np.testing.assert_array_equal(other.get_lines()[3].get_ydata(), run.oxide.z[0, :])
    with pytest.raises(ValueError, match="index must be a grid line"):
        render.draw_slice(run, Figure().add_subplot(), index=99)
    with pytest.raises(ValueError, match="axis must be 0"):
        render.draw_slice(run, Figure().add_subplot(), axis=2)


def test_history_plots_rms_and_zrange_with_distance_spread(run):
    fig = Figure()
    rms_ax, range_ax = render.draw_history(run, fig.subplots(1, 2))
    h = run.history
    lines = rms_ax.get_lines()
    np.testing.assert_array_equal(lines[0].get_ydata(), h["metal_rms_nm"])
    np.testing.assert_array_equal(range_ax.get_lines()[-1].get_ydata(), h["oxide_zrange_nm"])
    # the horizontal error bars span thickness +- the std of the metal-oxide distances
    bars = rms_ax.containers[0].lines[2][0].get_segments()
    widths = np.array([seg[1][0] - seg[0][0] for seg in bars])
    np.testing.assert_allclose(widths, 2 * h["distance_std_nm"])


def test_figures_and_movie_files(run, tmp_path):
    paths = [render.save_figure(render.slice_figure(run, "hill"), tmp_path / "a.png"),
             render.save_figure(render.history_figure(run), tmp_path / "b.png"),
             render.save_figure(render.snapshots_figure(run, "both", columns=4), tmp_path / "c.png")]
    for path in paths:
        image = imageio.imread(path)
        assert image.ndim == 3 and image.shape[0] > 200 and image[..., :3].std() > 5  # not blank
    movie = render.save_movie(run, tmp_path / "m.mp4", size_px=200)
    reader = imageio.get_reader(movie)
    frames = [frame for frame in reader]
    reader.close()
    assert len(frames) == len(run.snapshots) and frames[0].shape == (200, 200, 3)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.png", "b.png", "c.png", "m.mp4"]


def test_fixed_scale_follows_the_mean(run):
    surfaces = [s.oxide for s in run.snapshots]
    half = render.surface_scale(surfaces)
    assert half == pytest.approx(max(np.abs(s.z - s.z.mean()).max() for s in surfaces))
    fig = Figure()
    for k, surface in enumerate(surfaces[:2]):
        ax = render.draw_surface(surface, fig.add_subplot(1, 2, k + 1, projection="3d"), half_range=half)
        assert ax.get_zlim() == pytest.approx((surface.z.mean() - half, surface.z.mean() + half))


def test_bad_arguments(run, tmp_path):
    with pytest.raises(ValueError, match="which must be"):
        render.snapshots_figure(run, "air")
    with pytest.raises(ValueError, match="which must be"):
        render.save_movie(run, tmp_path / "m.mp4", which="both")
    with pytest.raises(ValueError, match="half_range must be > 0"):
        render.draw_surface(run.oxide, Figure().add_subplot(projection="3d"), half_range=0)
    with pytest.raises(ValueError, match="size_px must be even"):
        render.SurfaceMovie(tmp_path / "m.mp4", 1.0, size_px=17)
    empty = planarize.Anodization(run.parameters, run.history, [], run.initial, run.metal, run.oxide)
    with pytest.raises(ValueError, match="no snapshots"):
        render.save_movie(empty, tmp_path / "m.mp4")
    assert not any(tmp_path.iterdir())
