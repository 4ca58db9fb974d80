"""The napari plugin (`qdots.napari_plugin`): its manifest, its reader, and its dock widget driven as a user does,
in real viewers (on Linux without a display, on a virtual one the tests start, Xvfb). Skipped without the ``napari``
extra; the viewer tests also without a display and Xvfb."""

import csv
import os
import select
import shutil
import subprocess
import sys
import tempfile
import time

import numpy as np
import pytest

napari = pytest.importorskip("napari")


#: Opens a Qt application and a napari viewer in a process of its own: a Qt that cannot start (its platform libraries
#: missing) aborts its process, which must not be the test run's.
QT_PROBE = "import napari; napari.Viewer(show=False).close(); print('ok')"


def qt_fails(display: str | None) -> str:
    """Why a napari viewer does not open on ``display`` (Qt's first warning), tried in a child process; empty when it
    opens."""
    env = dict(os.environ, **({"DISPLAY": display} if display else {}))
    try:
        done = subprocess.run([sys.executable, "-c", QT_PROBE], env=env, capture_output=True, text=True, timeout=120)
    except subprocess.TimeoutExpired:
        return "it did not open within 120 s"
    if done.returncode == 0 and done.stdout.strip().endswith("ok"):
        return ""
    said = [line for line in done.stderr.splitlines() if line.startswith(("WARNING", "qt.", "Error"))]
    return said[0] if said else f"exit {done.returncode}"


@pytest.fixture(scope="module")
def display():
    """The display the viewers open on: ``DISPLAY`` when set (or not on Linux), else a virtual one (Xvfb) started for
    this module and stopped after it; the tests skip when there is neither, or when Qt cannot start on it."""
    if os.environ.get("DISPLAY") or not sys.platform.startswith("linux"):
        why = qt_fails(os.environ.get("DISPLAY"))
        if why:
            pytest.skip(f"a napari viewer does not open here: {why}")
        yield os.environ.get("DISPLAY")
        return
    if shutil.which("Xvfb") is None:
        pytest.skip("the napari viewer needs a display, or Xvfb to make one")
    read, write = os.pipe()
    log = tempfile.TemporaryFile()  # Xvfb's messages, for a skip that says why
    server = subprocess.Popen(["Xvfb", "-displayfd", str(write), "-screen", "0", "1600x1000x24", "-nolisten", "tcp"],
                              pass_fds=(write,), stdout=log, stderr=log)
    os.close(write)
    # Xvfb writes its display number, then a newline, once it accepts clients; the pipe stays open until the server
    # stops: closed after the number alone, the newline's write failed and the server ended ("Cannot write display
    # number to fd"), now and then, measured
    said, deadline = b"", time.monotonic() + 60
    while not said.endswith(b"\n") and select.select([read], [], [], max(deadline - time.monotonic(), 0))[0]:
        chunk = os.read(read, 64)
        if not chunk:
            break
        said += chunk
    number = said.decode().strip()
    try:
        if not number.isdigit():
            log.seek(0)
            messages = log.read().decode(errors="replace").strip().splitlines()
            pytest.skip(f"Xvfb did not start{': ' + messages[-1] if messages else ''}")
        why = qt_fails(f":{number}")
        if why:
            pytest.skip(f"a napari viewer does not open on Xvfb :{number}: {why}")
        yield f":{number}"
    finally:
        server.terminate()
        server.wait(timeout=30)
        os.close(read)
        log.close()


from helpers import disc_film_png  # noqa: E402

from qdots.cli import main  # noqa: E402
from qdots.napari_plugin.reader import get_reader  # noqa: E402
from qdots.napari_plugin.widget import DOTS, LEFT_OUT, MeasureWidget  # noqa: E402

pytestmark = [pytest.mark.filterwarnings("ignore::UserWarning"), pytest.mark.filterwarnings("ignore::DeprecationWarning"),
              pytest.mark.filterwarnings("ignore::PendingDeprecationWarning"), pytest.mark.timeout(300)]

#: Where the test also saves the docs' screenshot (docs/figures/napari_plugin.png) when this variable names a folder.
SCREENSHOT_DIR = "QDOTS_SCREENSHOT_DIR"


@pytest.fixture
def make_napari_viewer(display, monkeypatch):
    """Viewers for a test on ``display``, closed after it (napari's own fixture of that name is off: its plugin's
    other fixtures would import Qt in every test of the suite)."""
    if display is not None:
        monkeypatch.setenv("DISPLAY", display)
    made = []

    def make():
        viewer = napari.Viewer(show=False)
        made.append(viewer)
        return viewer

    yield make
    for viewer in made:
        viewer.close()


def test_the_manifest_offers_the_reader_and_the_widget():
    from npe2 import PluginManager

    manager = PluginManager.instance()
    manager.discover()
    manifest = next(m for m in manager.iter_manifests() if m.name == "nanodisorder")
    assert "*.dm4" in manifest.contributions.readers[0].filename_patterns
    assert manifest.contributions.widgets[0].display_name == "Measure dots (qdots)"
    assert get_reader("film.png") is not None and get_reader("film.xyz") is None and get_reader(["a.png", "b.png"]) is None


def test_the_widget_measures_shows_takes_corrections_and_exports_as_the_command_line(make_napari_viewer, tmp_path,
                                                                                      capsys):
    truth = disc_film_png(tmp_path / "film.png")
    viewer = make_napari_viewer()
    layers = viewer.open(str(tmp_path / "film.png"), plugin="nanodisorder")
    assert layers[0].metadata["qdots_path"] == str(tmp_path / "film.png")
    widget = MeasureWidget(viewer)
    viewer.window.add_dock_widget(widget, name="Measure dots (qdots)")
    widget.nm_per_px.setText("0.5")
    widget.measure_button.click()
    film = widget.film
    assert film is not None and not widget.refused, widget.status.text()
    dots = viewer.layers[DOTS]
    assert len(dots.data) == film.detection.n_dots and abs(len(dots.data) - len(truth)) <= 3
    assert np.allclose(dots.size, film.detection.diameters) and abs(np.median(dots.size) - 16.0) < 1.0
    assert widget.table.rowCount() > 5 and "dots measured" in widget.status.text()
    if os.environ.get(SCREENSHOT_DIR):
        viewer.window.resize(1500, 950)
        viewer.screenshot(os.path.join(os.environ[SCREENSHOT_DIR], "napari_plugin.png"), canvas_only=False)

    # the same files as qdots measure, with the same numbers
    widget.out.setText(str(tmp_path / "exported"))  # (its default, ./qdots-measure, is the working folder's)
    exported = widget.export()
    assert sorted(p.name for p in exported.iterdir()) == ["film.npz", "film_detections.png", "film_summary.csv"]
    assert main(["measure", str(tmp_path / "film.png"), "--nm-per-px", "0.5", "--out", str(tmp_path / "cli")]) == 0
    capsys.readouterr()
    with open(exported / "film_summary.csv") as a, open(tmp_path / "cli" / "film" / "film_summary.csv") as b:
        assert list(csv.DictReader(a)) == list(csv.DictReader(b))

    # delete three dots, add one where there is none, and measure again
    before = len(dots.data)
    dots.selected_data = {0, 1, 2}
    dots.remove_selected()
    dots.current_size = 12.0  # as the point-size slider sets it
    dots.add([[5.0, 5.0]])
    widget.edited_button.click()
    edited = widget.film
    assert edited.summary["dots"] == before - 2, widget.status.text()
    assert edited.summary["dots_edited"] == 1 and edited.summary["dots_deleted"] == 3
    assert "edited by hand" in edited.summary["doubts"]
    assert len(viewer.layers[DOTS].data) == before - 2


def test_a_refused_picture_shows_what_was_found_and_can_be_measured_anyway(make_napari_viewer, tmp_path):
    disc_film_png(tmp_path / "sparse.png", n=4, size=200)
    viewer = make_napari_viewer()
    viewer.open(str(tmp_path / "sparse.png"), plugin="nanodisorder")
    widget = MeasureWidget(viewer)
    widget.measure()
    assert widget.refused and widget.status.text().startswith("Refused:") and "round object" in widget.status.text()
    assert len(viewer.layers[DOTS].data) >= 4  # what was found, drawn for the user to judge
    assert widget.export() is None and "Nothing to export" in widget.status.text()
    widget.force.setChecked(True)
    assert widget.measure() is not None and not widget.refused


def test_a_layer_without_a_file_is_measured_from_its_pixels_and_scale(make_napari_viewer, tmp_path):
    from PIL import Image

    disc_film_png(tmp_path / "film.png")
    viewer = make_napari_viewer()
    viewer.add_image(np.asarray(Image.open(tmp_path / "film.png")), name="pasted", scale=(0.5, 0.5))
    widget = MeasureWidget(viewer)
    film = widget.measure()
    assert film is not None and film.nm_per_px == pytest.approx(0.5)
    assert LEFT_OUT not in viewer.layers or len(viewer.layers[LEFT_OUT].data) >= 0
    assert not list(tmp_path.glob("qdots-napari-*"))


def test_the_reader_gives_the_pixel_size_of_the_file(tmp_path):
    from qdots.napari_plugin.reader import read_layers

    disc_film_png(tmp_path / "film.png")
    (pixels, attributes, kind), = read_layers(str(tmp_path / "film.png"))
    assert kind == "image" and pixels.shape == (240, 240)
    assert attributes["scale"] == (1.0, 1.0) and attributes["metadata"]["nm_per_px"] is None
    assert attributes["metadata"]["scale_source"] == "none in the file"
