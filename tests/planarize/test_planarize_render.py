"""Figures 3-8, 3-9, 3-11 and the surface movie: the data drawn, the files written."""

import imageio.v2 as imageio
import numpy as np
import pytest
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from movie_probe import read_frames

import planarize
from planarize import render


@pytest.fixture(scope="module")
def run():
    return planarize.anodize(planarize.surfaces.hill(refine=2), 0.5, planarize.Model(step=0.05), "fast", record=5,
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


def test_history_of_a_continuum_run_draws_its_estimated_error():
    run = planarize.anodize(planarize.surfaces.hill(refine=2), 0.5, record=5)
    rms_ax, _ = render.draw_history(run, Figure().subplots(1, 2))
    h = run.history
    bars = rms_ax.containers[0].lines[2][0].get_segments()  # vertical: value +- the estimated error
    heights = np.array([seg[1][1] - seg[0][1] for seg in bars])
    np.testing.assert_allclose(heights, 2 * h["metal_rms_error_nm"])
    assert h["metal_rms_error_nm"][-1] > 0


def test_history_on_log_axes_is_read_from_the_data(run):
    fig = Figure()
    FigureCanvasAgg(fig)
    axes = render.draw_history(run, fig.subplots(1, 2), log=True)
    fig.canvas.draw()
    for ax, measure in zip(axes, ("rms", "zrange")):
        data = np.concatenate([run.history[f"{name}_{measure}_nm"] for name in ("metal", "oxide")])
        bottom, top = ax.get_ylim()
        assert ax.get_yscale() == "log"
        assert 0 < bottom < data.min() and data.max() < top  # inside, on neither edge
        assert np.log10(data.max() / data.min()) > 0.25 * np.log10(top / bottom)  # and spread over the axis
        assert len(labelled_ticks(ax)) >= 2
    linear = render.draw_history(run, Figure().subplots(1, 2))
    assert linear[0].get_yscale() == "linear" and linear[0].get_ylim()[0] == 0


def labelled_ticks(ax):
    """The y ticks inside the view that carry a label (major or minor)."""
    bottom, top = ax.get_ylim()
    ticks = [*ax.yaxis.get_major_ticks(), *ax.yaxis.get_minor_ticks()]
    return [t.get_loc() for t in ticks if t.label1.get_visible() and t.label1.get_text() and bottom <= t.get_loc() <= top]


@pytest.mark.parametrize("values", [[3.1, 3.3], [3.0, 3.0], [0.02, 0.09], [0.5, 12.0], [1e-3, 10.0, 0.0]])
def test_log_axis_has_two_labelled_ticks_whatever_the_range(values):
    fig = Figure()
    FigureCanvasAgg(fig)
    ax = fig.add_subplot()
    ax.plot(values)
    bottom, top = render.log_axis(ax, values)
    fig.canvas.draw()
    positive = [v for v in values if v > 0]
    assert 0 < bottom < min(positive) and max(positive) < top and np.log10(top / bottom) >= 0.5 - 1e-9
    assert len(labelled_ticks(ax)) >= 2
    with pytest.raises(ValueError, match="needs data > 0"):
        render.log_axis(ax, [0.0, -1.0])


def test_lone_raised_point_draws_four_like_faces_lit_from_above():
    hill = planarize.surfaces.hill(refine=1)  # 5 x 5, the centre point 0.5 nm up: a pyramid of four faces
    flat = Figure().add_subplot(projection="3d")
    render.draw_surface(hill, flat, shade=False)
    (mesh,) = flat.collections
    colours = mesh.get_facecolor()
    assert len(colours) == 16
    kinds, counts = np.unique(colours.round(6), axis=0, return_counts=True)
    assert sorted(counts) == [4, 12]  # the pyramid's four faces alike, the twelve flat ones alike
    lit = Figure().add_subplot(projection="3d")
    render.draw_surface(hill, lit)
    shaded = lit.collections[0].get_facecolor()
    level = [np.allclose(c, kinds[np.argmax(counts)], atol=1e-6) for c in colours.round(6)]
    # the flat faces face the light (from above): lit, they keep ~90 % of their colour (from below: ~53 %)
    np.testing.assert_allclose(shaded[level, :3] / colours[level, :3], 0.3 + 0.35 * (1 + np.sqrt(0.5)), rtol=1e-6)
    x, y, z, faces = render.surface_faces(planarize.surfaces.hill(refine=4), max_lines=5)
    np.testing.assert_array_equal(x[:, 0], [0, 1, 2, 3, 4])  # every 4th line of 17, both ends kept
    np.testing.assert_array_equal(y[0], [0, 1, 2, 3, 4])
    assert faces.shape == (4, 4) and faces[1, 1] == faces[2, 2] == pytest.approx(4.125)


def test_movie_frames_are_labelled_with_the_state_shown_and_end_at_the_final_state(run):
    frames = render.movie_frames(run)
    assert [t for _, t in frames] == [shot.thickness for shot in run.snapshots]
    assert frames[-1][1] == run.thickness and frames[-1][0] == run.oxide
    assert render.thickness_label("oxide", 1.0006103826481292) == "oxide after 1.001 nm of oxide"
    assert render.thickness_label("metal", 0.0) == render.thickness_label("oxide", 0.0) == \
        "initial surface (no oxide yet)"  # before any oxide, metal and oxide are one surface
    # snapshots that stop short of the end: the final state is appended
    short = planarize.anodize(planarize.surfaces.hill(refine=1), 0.5, planarize.Model(step=0.05), record=2,
                              snapshots=[0.0, 0.2])
    frames = render.movie_frames(short, "metal")
    assert len(frames) == 3 and frames[-1][1] == short.thickness >= 0.5 and frames[-1][0] == short.metal
    assert frames[1][1] == short.snapshots[1].thickness


def test_figures_and_movie_files(run, tmp_path):
    paths = [render.save_figure(render.slice_figure(run, "hill"), tmp_path / "a.png"),
             render.save_figure(render.history_figure(run), tmp_path / "b.png"),
             render.save_figure(render.snapshots_figure(run, "both", columns=4), tmp_path / "c.png")]
    for path in paths:
        image = imageio.imread(path)
        assert image.ndim == 3 and image.shape[0] > 200 and image[..., :3].std() > 5  # not blank
    movie = render.save_movie(run, tmp_path / "m.mp4", size_px=200)
    frames = read_frames(movie)
    # one frame per snapshot, the last (the final state) held for a second at 10 frames/s
    assert len(frames) == len(run.snapshots) + 9 and frames[0].shape == (200, 200, 3)
    held = np.array(frames[len(run.snapshots) - 1:], dtype=float)
    assert np.abs(held - held[0]).mean() < 2 < np.abs(held[0] - np.array(frames[0], dtype=float)).mean()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.png", "b.png", "c.png", "m.mp4"]


def colour_bar(figure):
    """The axes of the colour bar of `snapshots_figure` (an inset of its last cell)."""
    (bar,) = [ax for ax in figure.axes + [c for a in figure.axes for c in a.child_axes]
              if ax.get_ylabel().startswith(render.HEIGHT_LABEL)]
    return bar


def test_fixed_scale_follows_the_mean_and_the_z_axes_show_what_the_colours_show(run):
    surfaces = [s.oxide for s in run.snapshots]
    half = render.surface_scale(surfaces)
    assert half == pytest.approx(max(np.abs(s.z - s.z.mean()).max() for s in surfaces))
    fig = Figure()
    for k, surface in enumerate(surfaces[:2]):
        ax = render.draw_surface(surface, fig.add_subplot(1, 2, k + 1, projection="3d"), half_range=half, title="t")
        assert ax.get_zlim() == pytest.approx((-half, half)) and ax.get_zlabel() == render.HEIGHT_LABEL
        assert ax.get_title() == f"t\nmean height {surface.z.mean():.4g} nm"
    figure = render.snapshots_figure(run)
    bar = colour_bar(figure)
    assert bar.get_ylim() == pytest.approx((-half, half)) and bar.get_ylabel().startswith(render.HEIGHT_LABEL)
    assert all(ax.get_zlim() == pytest.approx((-half, half)) for ax in figure.axes if hasattr(ax, "get_zlim"))
    titles = [ax.get_title() for ax in figure.axes if hasattr(ax, "get_zlim")]
    assert titles[0].startswith("initial surface (no oxide yet)") and "oxide after" in titles[-1]


def test_the_surfaces_figure_keeps_its_titles_and_colour_bar_label_inside_it(run):
    figure = render.snapshots_figure(run)
    figure.canvas.draw()
    box = figure.bbox
    texts = [ax.title for ax in figure.axes if hasattr(ax, "get_zlim")] + [colour_bar(figure).yaxis.label]
    for text in texts:
        extent = text.get_window_extent()
        assert text.get_text() and box.x0 <= extent.x0 and extent.x1 <= box.x1 and box.y0 <= extent.y0 and \
            extent.y1 <= box.y1, text.get_text()


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
