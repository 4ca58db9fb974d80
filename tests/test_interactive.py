"""The notebook widgets driven headless: controls set, buttons clicked, the board checked."""

import asyncio
import base64
import dataclasses
import html
import io
import json
import sys

import matplotlib
import numpy as np
import pytest

pytest.importorskip("ipywidgets")
pytest.importorskip("ipympl")
matplotlib.use("Agg")

import planarize  # noqa: E402
import qdots  # noqa: E402
from labrig.validate import InputError  # noqa: E402
from labrig.widgets import require_widgets, widget_figure  # noqa: E402
from planarize.interactive import ThicknessExplorer, nearest_snapshot  # noqa: E402
from qdots.analysis import packing_summary  # noqa: E402
from qdots.analysis.structure import hexatic_order  # noqa: E402
from qdots.deposition import deposit  # noqa: E402
from qdots.interactive import LiveBoard  # noqa: E402
from qdots.interactive.live import Knobs, LiveRun  # noqa: E402
from qdots.scene import grating_segments  # noqa: E402


def finish_drops(board):
    for _ in range(1000):
        if not board.live.pending:
            return
        board.buttons["step"].click()
    raise AssertionError("drops never finished")


def test_drop_button_deposits_n_dots_exactly_as_the_protocol():
    board = LiveBoard(seed=5, frame_steps=2)
    c = board.controls
    c["gravity"].value = "uniform"  # dots fall from the moment they land: timing shows in positions
    c["n_dots"].value, c["mean_diameter"].value, c["sigma"].value, c["interval"].value = 6, 12.0, 0.1, 0.04
    board.buttons["drop"].click()
    assert board.live.pending == 6 and board.sim.n_dots == 0
    finish_drops(board)
    assert board.sim.n_dots == 6
    board.live.advance(round((6 * 0.04 - board.sim.time) / board.sim.dt))
    # the same film as one deposit() call with the same seeds, bit for bit
    sim_seed, drop_seed = np.random.SeedSequence(5).spawn(2)
    scene = qdots.Scene(box=(400, 400), positions=np.zeros((0, 2)), radii=np.zeros(0))
    reference = qdots.Simulation(scene, Knobs(gravity="uniform").forces(scene.box), seed=sim_seed)
    diameters = deposit(reference, 6, 12.0, 0.1, interval=0.04, rng=np.random.default_rng(drop_seed))
    assert reference.steps_taken == board.sim.steps_taken == round(0.24 / reference.dt)
    np.testing.assert_array_equal(board.sim.state().positions, reference.state().positions)
    np.testing.assert_array_equal(board.sim.state().radii, diameters / 2)
    assert "6 (+0 queued)" in board.readout.value


def test_readout_follows_the_board():
    board = LiveBoard(seed=2, frame_steps=50)
    board.live.drop(40, interval=0.0)
    board.controls["gravity"].value = "centre"
    empty = board.readout.value
    for _ in range(20):
        board.buttons["step"].click()
    r, state = board.live.readout(), board.sim.state()
    summary, hexatic = packing_summary(state), hexatic_order(state)
    assert r["n_dots"] == 40 and r["time_s"] == pytest.approx(20 * 50 * board.sim.dt)
    assert r["interior_fraction"] == summary["interior_fraction"]
    assert r["mean_neighbours"] == summary["mean_neighbours"] > 1  # a cluster has formed
    assert (r["psi6_global"], r["psi6_local"]) == (hexatic.global_order, hexatic.local_order)
    assert board.readout.value != empty and f"{r['mean_neighbours']:.2f}" in board.readout.value


def test_knob_controls_rebuild_the_simulation():
    board = LiveBoard(seed=1, frame_steps=20)
    board.live.drop(10, interval=0.0)
    board.buttons["step"].click()
    before, time_before = board.sim.state(), board.sim.time
    c = board.controls
    c["dt"].value = 2e-3
    assert board.sim.dt == 2e-3 and board.sim.time == time_before
    after = board.sim.state()
    np.testing.assert_array_equal(after.positions, before.positions)
    np.testing.assert_array_equal(after.velocities, before.velocities)
    c["elasticity"].value = 0.5
    assert board.sim.restitution.mean == 0.5
    c["thermal"].value, c["vdw_r0"].value = 0.0, 0.0
    assert board.sim.forces == ()  # a knob at 0 costs nothing
    c["vdw_r0"].value, c["thermal"].value, c["drag"].value = 10.0, 2.0, 0.3
    vdw, kicks, drag = board.sim.forces
    assert (vdw.r0, kicks.scale, drag.linear, drag.quadratic) == (10.0, 2.0, 0.3, 0.01)
    c["gravity"].value = "uniform"
    assert board.sim.forces[-1].acceleration == (0.0, -750.0)
    c["gravity_magnitude"].value = 100.0
    c["gravity"].value = "centre"
    assert board.sim.forces[-1].to_dict() == {"type": "CentreGravity", "centre": [200.0, 200.0], "magnitude": 100.0}
    c["frame_steps"].value = 7
    steps = board.sim.steps_taken
    board.buttons["step"].click()
    assert board.sim.steps_taken == steps + 7
    c["gravity_magnitude"].value = -5.0  # refused: said in the status line, nothing changes
    assert "gravity_magnitude must be in [0, " in html.unescape(board.status.value)
    assert board.live.knobs.gravity_magnitude == c["gravity_magnitude"].value == 100.0


def test_rebuild_continues_like_a_resumed_checkpoint(tmp_path):
    live = LiveRun(seed=4, frame_steps=25)
    live.drop(12, interval=0.0)
    live.advance(100)
    path = live.save(tmp_path / "board.npz")
    resumed = qdots.load(path)
    live.set(gravity_magnitude=1.0)  # gravity is off: a rebuild that changes no force
    live.advance(100)
    resumed.run(100 * resumed.dt)
    assert live.sim.time == pytest.approx(resumed.time)
    np.testing.assert_array_equal(live.sim.state().positions, resumed.state().positions)
    np.testing.assert_array_equal(live.sim.state().velocities, resumed.state().velocities)


def test_pause_stops_the_live_task():
    board = LiveBoard(seed=3, frame_steps=10, frame_pause=0.0)
    board.buttons["start"].click()  # no running event loop here: refused, said so
    assert "running asyncio event loop" in board.status.value and not board.running

    async def session():
        board.start()
        assert board.running and board.buttons["start"].disabled
        await asyncio.sleep(0.3)
        board.buttons["pause"].click()
        await asyncio.sleep(0)
        stopped_at = board.sim.steps_taken
        await asyncio.sleep(0.2)
        return stopped_at

    stopped_at = asyncio.run(session())
    assert stopped_at >= 10 and stopped_at % 10 == 0  # whole frames ran
    assert board.sim.steps_taken == stopped_at and not board.running
    assert not board.buttons["start"].disabled


def test_save_button_writes_a_loadable_checkpoint(tmp_path):
    board = LiveBoard(seed=6, frame_steps=40)
    board.live.drop(8, interval=0.01)
    finish_drops(board)
    board.controls["state_path"].value = str(tmp_path / "film.npz")
    board.buttons["save"].click()
    assert "saved" in board.status.value
    loaded = qdots.load(tmp_path / "film.npz")
    assert loaded.n_dots == 8 and loaded.time == board.sim.time
    np.testing.assert_array_equal(loaded.state().positions, board.sim.state().positions)
    board.controls["state_path"].value = str(tmp_path / "missing-dir" / "film.npz")
    board.buttons["save"].click()
    assert "Error" in board.status.value  # an unwritable path is reported, not raised


def test_record_button_writes_a_movie(tmp_path):
    board = LiveBoard(seed=7, frame_steps=20)
    board.live.drop(5, interval=0.0)
    board.controls["movie_path"].value = str(tmp_path / "film.mp4")
    board.buttons["record"].click()
    assert board.live.recording and "stop" in board.buttons["record"].description
    for _ in range(3):
        board.buttons["step"].click()
    board.buttons["record"].click()
    assert not board.live.recording and "wrote" in board.status.value
    from movie_probe import probe

    assert probe(tmp_path / "film.mp4")["frames"] == 4  # steps 0, 20, 40, 60


def test_wall_and_grating_buttons():
    board = LiveBoard(seed=8, frame_steps=10)
    c, b = board.controls, board.buttons
    c["wall_x0"].value, c["wall_y0"].value, c["wall_x1"].value, c["wall_y1"].value = 50.0, 300.0, 350.0, 300.0
    b["add_wall"].click()
    np.testing.assert_array_equal(board.sim.scene.segments, [[50, 300, 350, 300]])
    b["clear_walls"].click()
    c["pitch"].value = 100.0
    b["add_grating"].click()
    np.testing.assert_array_equal(board.sim.scene.segments, grating_segments((400, 400), 100.0))
    assert len(board.sim.state().walls) == 4 + 3
    board.live.add_segments(np.zeros((0, 4)))
    board.sim.add_dots([[200, 50]], [7.5])
    c["wall_x0"].value, c["wall_y0"].value, c["wall_x1"].value, c["wall_y1"].value = 0.0, 52.0, 400.0, 52.0
    b["add_wall"].click()  # across the dot: refused
    assert "crosses dot 0" in board.status.value and len(board.sim.scene.segments) == 3
    c["pitch"].value = 500.0
    b["add_grating"].click()
    assert "no grating line fits" in board.status.value


def test_live_run_rejects_bad_input():
    live = LiveRun(seed=0)
    with pytest.raises(ValueError, match="unknown knob 'friction'"):
        live.set(friction=1.0)
    with pytest.raises(ValueError, match="gravity must be one of"):
        live.set(gravity="down")
    with pytest.raises(ValueError, match=r"dt must be (a number )?in \[1e-7, 0.1\] s"):
        Knobs(dt=0.0)
    with pytest.raises(ValueError, match="sigma"):
        live.drop(5, sigma=1.5)
    assert live.pending == 0
    with pytest.raises(TypeError, match="dt"):  # the time step is a knob: Knobs(dt=...)
        LiveRun(dt=1e-3)
    small = LiveRun(qdots.Scene(box=(40, 40), positions=np.zeros((0, 2)), radii=np.zeros(0)), seed=0)
    small.drop(50, mean_diameter=15.0, interval=0.0)
    with pytest.raises(ValueError, match="board too full"):
        small.advance(1)
    assert small.pending == 0 and small.sim.n_dots > 0


def _sent_pictures(canvas, monkeypatch):
    """Record the binary frames ``canvas`` sends to the front end."""
    sent = []

    def send(content, buffers=None):
        if json.loads(content["data"])["type"] == "binary":
            sent.append(bytes(buffers[0]))

    monkeypatch.setattr(canvas, "send", send)
    return sent


def test_a_draw_before_the_canvas_is_shown_sends_a_png(monkeypatch):
    # ipympl sends raw pixels labelled PNG when it draws before a front end is there: the browser's
    # image is broken and a canvas inside a Box stays blank (labrig.widgets)
    from PIL import Image

    figure = widget_figure((3.0, 2.0))
    figure.add_subplot().plot([0, 1], [0, 1], color="tab:red")
    sent = _sent_pictures(figure.canvas, monkeypatch)
    figure.canvas.draw()
    assert len(sent) == 1 and sent[0].startswith(b"\x89PNG\r\n\x1a\n")
    url = figure.canvas._data_url
    assert url.startswith("data:image/png;base64,")
    for png in (sent[0], base64.b64decode(url.split(",", 1)[1])):
        with Image.open(io.BytesIO(png)) as image:
            pixels = np.asarray(image.convert("RGB"))
        assert pixels.shape == (200, 300, 3)
        assert np.all(pixels == (214, 39, 40), axis=2).any()  # the line is in it


def test_widgets_do_not_draw_while_they_are_built(monkeypatch, hill_run):
    # the front end asks for the first picture once the canvas is shown
    drawn = []
    monkeypatch.setattr("matplotlib.backends.backend_webagg_core.FigureCanvasWebAggCore.draw",
                        lambda canvas: drawn.append(canvas))
    board = LiveBoard(seed=1)
    explorer = ThicknessExplorer(hill_run)
    board.buttons["step"].click()
    explorer.slider.value = 2
    assert drawn == []
    assert board.figure.canvas._data_url is None and explorer.figure.canvas._data_url is None


def test_buttons_say_what_they_do_in_plain_words():
    board = LiveBoard(seed=1)
    labels = [button.description for button in board.buttons.values()]
    assert all(label.isascii() for label in labels), labels  # icons come from the front end's icon font
    assert board.buttons["pause"].icon == "pause" and board.buttons["record"].icon == "circle"


def test_missing_extra_is_named(monkeypatch):
    monkeypatch.setitem(sys.modules, "ipywidgets", None)
    with pytest.raises(ImportError, match=r"'widgets' extra .*nanodisorder\[widgets\]"):
        require_widgets()


@pytest.fixture(scope="module")
def hill_run():
    return planarize.anodize(planarize.surfaces.hill(), 1.0, planarize.Model(step=0.05), record=20,
                             snapshots=[0.0, 0.25, 0.5, 0.75, 1.0])


def test_thickness_slider_selects_the_snapshot(hill_run):
    explorer = ThicknessExplorer(hill_run)
    assert explorer.snapshot is hill_run.snapshots[0]
    for index in (3, 1, 4):
        explorer.slider.value = index
        shot = hill_run.snapshots[index]
        assert explorer.snapshot is shot
        np.testing.assert_array_equal(explorer.metal_line.get_ydata(), shot.metal.z[:, explorer.row])
        np.testing.assert_array_equal(explorer.oxide_line.get_ydata(), shot.oxide.z[:, explorer.row])
        assert list(explorer.marker.get_xdata()) == [shot.thickness] * 2
        np.testing.assert_allclose(explorer.points.get_offsets()[:, 1],
                                   [planarize.rms(shot.metal), planarize.rms(shot.oxide),
                                    planarize.z_range(shot.metal), planarize.z_range(shot.oxide)])
        assert f"{shot.thickness:.4g}" in explorer.slider.label
    assert explorer.select(0.3) is hill_run.snapshots[1] and explorer.slider.value == 1
    explorer.figure.canvas.draw()


def test_explorer_looks_like_the_static_figures(hill_run):
    from matplotlib.colors import to_hex

    from planarize.render import METAL, OXIDE

    explorer = ThicknessExplorer(hill_run)
    assert explorer.figure.get_size_inches()[0] * explorer.figure.dpi <= 800  # fits beside the file browser
    for line, style in ((explorer.metal_line, METAL), (explorer.oxide_line, OXIDE)):
        assert (to_hex(line.get_color()), line.get_marker()) == (to_hex(style["color"]), style["marker"])
    legend = explorer.legend
    explorer.figure.canvas.draw()
    where = legend.get_window_extent().bounds
    for index in (4, 0, 2):
        explorer.slider.value = index
        explorer.figure.canvas.draw()
        assert legend.get_window_extent().bounds == where  # one legend, in a fixed place
    assert [text.get_text() for text in legend.get_texts()] == ["initial metal", "metal", "oxide", "RMS", "z-range"]


def test_nearest_snapshot(hill_run):
    reached = [s.thickness for s in hill_run.snapshots]
    assert [nearest_snapshot(hill_run, t) for t in (-1.0, 0.12, 0.6, 9.0)] == [0, 0, 2, 4]
    assert nearest_snapshot(hill_run, reached[3]) == 3
    with pytest.raises(ValueError, match="no snapshots"):
        ThicknessExplorer(dataclasses.replace(hill_run, snapshots=[]))
    with pytest.raises(ValueError, match="finite"):
        nearest_snapshot(hill_run, float("nan"))


def test_the_engine_knob_switches_the_running_board_to_the_event_engine_and_back():
    live = LiveRun(seed=3, frame_steps=5)
    live.drop(20, 15.0, 0.1, 0.1)
    for _ in range(4):
        live.advance()
    live.set(engine="event")
    assert type(live.sim.backend).__name__ == "EventBackend" and live.sim.engine.kind == "event"
    dropped, impacts = live.sim.n_dots, live.sim.collisions.dot_dot
    for _ in range(30):
        live.advance()
    assert live.sim.n_dots == 20 > dropped and live.sim.collisions.dot_dot >= impacts  # the count goes on
    live.set(engine="chipmunk")
    live.advance()
    assert type(live.sim.backend).__name__ == "ChipmunkBackend" and live.sim.time == pytest.approx(3.5)
    with pytest.raises(InputError, match="engine must be one of 'chipmunk', 'event'"):
        live.set(engine="lammps")


def test_an_engine_toggled_away_and_back_keeps_its_own_settings():
    live = LiveRun(seed=3, frame_steps=5, engine=qdots.Chipmunk(iterations=9, max_substeps=64))
    live.set(engine="event", dt=0.01)
    assert live.sim.engine == qdots.Event(dt=0.01)
    live.set(engine="chipmunk")
    assert live.sim.engine == qdots.Chipmunk(iterations=9, max_substeps=64, dt=0.01)
