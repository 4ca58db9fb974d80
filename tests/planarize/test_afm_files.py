"""Real AFM instrument files (`planarize.io.instrument`, through AFMReader, NSFopen and SurfaceTopography): read with the
units their headers state, the same scan alike in two formats or through two readers, levelled, imported and refused
in one line.

The files are the public sample scans of `benchmarks/afm_real.toml`, fetched by ``python -m benchmarks.afm_files``
(CI fetches them before the tests); without them, or without the readers, these tests are skipped.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from benchmarks.afm_files import manifest, present
from labrig.validate import InputError
from planarize.io import load_heights
from planarize.io.heights import load_levelled

pytest.importorskip("AFMReader")
pytest.importorskip("NSFopen")
pytest.importorskip("SurfaceTopography")
MAPS = present()
ENTRIES = {e["file"]: e for e in manifest()["map"]}
pytestmark = pytest.mark.skipif(len(MAPS) < len(ENTRIES), reason="the real AFM maps are not fetched "
                                "(python -m benchmarks.afm_files)")


@pytest.mark.parametrize("name", [n for n, e in ENTRIES.items() if "scan_nm" in e])
def test_each_instrument_file_is_read_with_the_pixel_size_its_header_states(name):
    """The scan's width (along its lines) and height (across them) as its header states, over its points and lines
    (the NanoSurf MoS2 scan has 512 points a line and 256 lines over a square: pixels twice as long across lines)."""
    surface = load_heights(MAPS.get(name, name), level="none", format=ENTRIES[name].get("format"))
    nx, ny = surface.shape
    assert surface.spacing[0] == pytest.approx(ENTRIES[name]["scan_nm"] / nx, rel=1e-6)
    assert surface.spacing[1] == pytest.approx(ENTRIES[name]["scan_nm"] / ny, rel=1e-6)


@pytest.mark.parametrize("name", ["MoS2.nid", "SBS-PMMA.nid"])
def test_the_two_height_channels_of_a_nanosurf_scan_agree(name):
    """A NanoSurf scan records the height twice: the z sensor's (read by default) and the z actuator's, each with its
    own calibration in its own header. Levelled alike, the two agree in RMS within 5 % and correlate above 0.95 (the
    sapphire scan, 0.1 nm of relief, is the sensor's noise and is not compared)."""
    from planarize.metrics import rms

    sensor = load_heights(MAPS.get(name, name), level="lines,plane")
    actuator = load_heights(MAPS.get(name, name), level="lines,plane", channel="Z-Axis")
    assert sensor.spacing == actuator.spacing and sensor.shape == actuator.shape
    assert rms(sensor) == pytest.approx(rms(actuator), rel=0.05)
    assert np.corrcoef(sensor.z.ravel(), actuator.z.ravel())[0, 1] > 0.95


@pytest.mark.parametrize("name", [n for n, e in ENTRIES.items() if "same_scan" in e])
def test_a_top_file_reads_as_the_stp_file_of_the_same_scan(name):
    """AFMReader 0.0.7 alone reads a .top file's height span as its integer part (12 % short on
    sample_1_um_scale); the reader rescales to the header's span."""
    top = load_heights(MAPS.get(name, name), level="none").z
    stp = load_heights(MAPS.get(ENTRIES[name]["same_scan"], name), level="none").z
    span = np.ptp(stp)
    np.testing.assert_allclose(top - top.min(), stp - stp.min(), atol=2e-3 * span)


def test_the_gwy_file_reads_alike_through_gwyfile_and_through_afmreader():
    """Two independent readers of one file: ours (gwyfile) and AFMReader's own .gwy loader."""
    from AFMReader import gwy

    ours = load_heights(MAPS.get("sample_0.gwy", ""), level="none")
    image, pixel = gwy.load_gwy(MAPS.get("sample_0.gwy", ""), "ZSensor")[:2]
    assert ours.spacing[0] == pytest.approx(pixel, rel=1e-9)
    np.testing.assert_allclose(ours.z, np.asarray(image).T, rtol=1e-12)


@pytest.mark.parametrize("name", ["sample_0.spm", "sample_0.ibw", "sample_0.jpk", "sample_0.stp"])
def test_auto_levelling_removes_what_it_finds_and_leaves_nothing_of_it(name):
    surface, artefacts = load_levelled(MAPS.get(name, name))
    by_name = {a.name: a for a in artefacts}
    assert by_name["line offsets"].applied and by_name["tilt"].applied  # raw scans: both always found
    again = {a.name: a for a in load_levelled(MAPS.get(name, name), level="auto")[1]}
    assert again["line offsets"].size == by_name["line offsets"].size  # (the same file, the same levelling)
    from planarize.levelling import detect

    after = {a.name: a for a in detect(surface)}
    assert not after["line offsets"].found and not after["tilt"].found


def test_a_missing_channel_is_refused_in_one_line_listing_the_files_channels():
    with pytest.raises(InputError, match=r"no channel 'Nope'.*HeightRetrace") as error:
        load_heights(MAPS.get("sample_0.ibw", ""), channel="Nope")
    assert "\n" not in str(error.value)
    with pytest.raises(InputError, match=r"no channel 'Nope' in the forward scan; its channels: 'Amplitude', 'Phase', "
                                         r"'Z-Axis'$"):
        load_heights(MAPS.get("grid.nid", ""), channel="Nope")
    with pytest.raises(InputError, match=r"channel 'Phase' is not a height map in length units"):
        load_heights(MAPS.get("grid.nid", ""), channel="Phase")
    with pytest.raises(InputError, match="holds one channel"):
        load_heights(MAPS.get("sample_0.stp", ""), channel="Height")


def test_import_reports_the_artefacts_and_saves_the_levelling_it_applied(tmp_path):
    scene_file = tmp_path / "stp.toml"
    done = subprocess.run([sys.executable, "-m", "planarize", "import", str(MAPS.get("sample_0.stp", "")),
                           "--thickness", "2", "--save", str(scene_file)], capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    assert "line offsets RMS" in done.stdout and "removed" in done.stdout
    from planarize.io.scenefile import load_scene

    scene = load_scene(scene_file)
    level = scene.surface.params["level"]
    assert level.split(",")[0] == "lines" and "plane" in level
    np.testing.assert_array_equal(scene.build_surface().z, load_heights(MAPS.get("sample_0.stp", "")).z)


def test_without_afmreader_the_reader_names_the_extra(monkeypatch):
    monkeypatch.setitem(sys.modules, "AFMReader", None)
    with pytest.raises(InputError, match=r'needs the AFMReader package: pip install "nanodisorder\[afm\]"'):
        load_heights(MAPS.get("sample_0.jpk", ""))


def _park_file(path):
    """An independent reader of a Park Systems TIFF, from Park's published layout: the header (TIFF tag 50435: image
    type, source and mode names in UTF-16, ..., width, height, ..., X and Y scan size, ..., data gain, Z scale, unit,
    ..., data type) and the heights (tag 50434, float32 when the data type is 2), as stored (first line at the
    bottom); returns them (height unit), the scan size (um, um) and the instrument's 8-bit preview."""
    import struct

    import tifffile

    with tifffile.TiffFile(path) as tiff:
        tags = tiff.pages[0].tags
        header, data, preview = bytes(tags[50435].value), bytes(tags[50434].value), tiff.pages[0].asarray()
    width, height = struct.unpack_from("<2i", header, 100)  # (bytes 0-99: type, names, low-pass, flags)
    x_size, y_size = struct.unpack_from("<2d", header, 140)  # (100-139: angle, sine scan, overscan, directions)
    gain, z_scale = struct.unpack_from("<2d", header, 220)  # (156-219: offsets, rate, set point and its unit, biases)
    unit = header[244:260].decode("utf-16-le").split("\0")[0]  # (236: Z offset)
    (data_type,) = struct.unpack_from("<i", header, 348)  # (260-347: data range, flags, servo, voltage modes)
    assert data_type == 2 and unit == "um"  # (float heights in um: the sample file's)
    heights = np.frombuffer(data, "<f4").reshape(height, width) * gain * z_scale
    return heights, (x_size, y_size), preview


def test_a_park_tiff_reads_as_an_independent_reading_of_parks_layout_and_as_its_preview_shows():
    """SurfaceTopography's heights (nm) equal those of Park's layout read here; the map as read (row j of
    ``Surface.z.T`` is the picture's line j from the top) correlates with the 256 x 256 preview Park stores in the
    same file at above 0.99, its mirror image at under 0.1."""
    path = MAPS.get("example_ps.tiff", "")
    surface = load_heights(path, level="none")
    stored, sizes, preview = _park_file(path)
    assert surface.spacing == pytest.approx((1e3 * sizes[0] / stored.shape[1], 1e3 * sizes[1] / stored.shape[0]))
    picture = 1e3 * stored[::-1]  # (lines stored from the bottom up)
    np.testing.assert_allclose(surface.z.T, picture, rtol=1e-6, atol=1e-9)
    halved = surface.z.T.reshape(256, 2, 256, 2).mean(axis=(1, 3))
    assert np.corrcoef(halved.ravel(), preview.ravel())[0, 1] > 0.99
    assert abs(np.corrcoef(halved[::-1].ravel(), preview.ravel())[0, 1]) < 0.1


def test_a_picoview_file_reads_as_an_independent_reading_of_its_header_and_buffer():
    """The .mi file's text header states 256 x 256 pixels over 2e-5 m, and the Topography buffer's range (2.9025 um
    for the full int32 range); its data follow the header as int32 buffers, first line at the bottom (scanUp)."""
    path = MAPS.get("mi-1.mi", "")
    raw = Path(path).read_bytes()
    text = raw[:raw.index(b"data          BINARY_32")].decode("latin-1")
    field = {line[:14].strip(): line[14:].strip() for line in text.splitlines()}
    points, lines = int(field["xPixels"]), int(field["yPixels"])
    start = raw.index(b"\n", raw.index(b"data          BINARY_32")) + 1
    buffer = np.frombuffer(raw[start:start + 4 * points * lines], "<i4").reshape(lines, points)
    topography_range_um = float(text.split("bufferLabel   Topography")[1].split("bufferRange")[1].split()[0])
    surface = load_heights(path, level="none")
    assert surface.spacing == pytest.approx((1e9 * float(field["xLength"]) / points,
                                             1e9 * float(field["yLength"]) / lines))
    np.testing.assert_allclose(surface.z.T, 1e3 * topography_range_um * buffer[::-1] / 2 ** 31, rtol=1e-9)


def test_surface_topography_files_are_refused_in_one_line_when_they_are_not_what_they_say(tmp_path):
    with pytest.raises(InputError, match=r"no channel 'Nope'; its channels: 'Topography', 'Deflection', 'Friction'$"):
        load_heights(MAPS.get("mi-1.mi", ""), channel="Nope")
    with pytest.raises(InputError, match=r"channel 'Deflection' is not a height map in length units \(its unit: V\)"):
        load_heights(MAPS.get("mi-1.mi", ""), channel="Deflection")
    import tifffile

    plain = tmp_path / "photo.tiff"
    tifffile.imwrite(plain, np.zeros((8, 8), np.uint8))
    with pytest.raises(InputError, match=r"photo.tiff: SurfaceTopography cannot read the file as a Park Systems TIFF")\
            as error:
        load_heights(plain)
    assert "\n" not in str(error.value)


def test_without_surface_topography_the_reader_names_the_extra(monkeypatch):
    monkeypatch.setitem(sys.modules, "SurfaceTopography.IO", None)
    with pytest.raises(InputError, match=r'needs the SurfaceTopography package: pip install "nanodisorder\[afm\]"'):
        load_heights(MAPS.get("mi-1.mi", ""))
