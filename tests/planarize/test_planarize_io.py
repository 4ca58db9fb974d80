"""Importing measured height maps: .gwy (written by gwyfile), XYZ, matrices, .npy; units; every bad input."""

import io
import sys

import numpy as np
import pytest
from helpers import refused_file

import planarize
from planarize.io import level_plane, load_heights, save_heights
from planarize.io.gwy import gwy_channels

gwyfile = pytest.importorskip("gwyfile")
from gwyfile.objects import GwyContainer, GwyDataField  # noqa: E402

AMPLITUDE_NM = 3.0
NX, NY = 24, 16  # columns (x) and rows (y) of the AFM image


def npy_bytes(array) -> bytes:
    """``array`` as the bytes of a ``.npy`` file."""
    buffer = io.BytesIO()
    np.save(buffer, array)
    return buffer.getvalue()


def egg_crate(nx=NX, ny=NY, dx=5.0, dy=5.0, base=40.0):
    """``base + A sin(2 pi x / Lx) sin(2 pi y / Ly)`` over whole periods: RMS exactly A / 2 on the grid."""
    x = np.arange(nx) * dx
    y = np.arange(ny) * dy
    return base + AMPLITUDE_NM * np.outer(np.sin(2 * np.pi * x / (nx * dx)), np.sin(2 * np.pi * y / (ny * dy)))


def write_gwy(path, z_nm, dx=5.0, dy=5.0, extra=True, z_unit="m", xy_unit="m"):
    """A Gwyddion file as an AFM would save it: SI metres, rows are y, plus a phase channel."""
    nx, ny = z_nm.shape
    container = GwyContainer()
    container["/0/data/title"] = "Height"
    container["/0/data"] = GwyDataField(np.ascontiguousarray(z_nm.T * 1e-9), xreal=nx * dx * 1e-9,
                                        yreal=ny * dy * 1e-9, si_unit_xy=xy_unit, si_unit_z=z_unit)
    if extra:
        container["/1/data/title"] = "Phase"
        container["/1/data"] = GwyDataField(np.zeros((ny, nx)), xreal=nx * dx * 1e-9, yreal=ny * dy * 1e-9,
                                            si_unit_xy="m", si_unit_z="deg")
    container.tofile(str(path))
    return path


# -- Gwyddion ---------------------------------------------------------------------------------

def test_gwy_written_by_gwyfile_round_trips_with_the_rms(tmp_path):
    z = egg_crate(dx=5.0, dy=7.5)
    assert planarize.rms(z) == pytest.approx(AMPLITUDE_NM / 2, rel=1e-12)  # the known RMS
    path = write_gwy(tmp_path / "scan.gwy", z, dx=5.0, dy=7.5)
    surface = load_heights(path)
    assert surface.shape == (NX, NY)  # axis 0 is x: the image's columns
    assert surface.spacing == pytest.approx((5.0, 7.5), rel=1e-12)
    assert planarize.rms(surface) == pytest.approx(AMPLITUDE_NM / 2, rel=1e-9)
    np.testing.assert_allclose(surface.z, z, rtol=1e-12)
    assert [c["title"] for c in gwy_channels(path)] == ["Height", "Phase"]
    # the same surface by channel number and title, and with a unit that agrees with the file
    assert load_heights(path, channel=0) == surface
    assert load_heights(path, channel="height", unit="m") == surface
    # and our own writer gives a file Gwyddion's layout reads back the same way
    again = load_heights(save_heights(surface, tmp_path / "again.gwy"))
    np.testing.assert_allclose(again.z, surface.z, rtol=1e-12)
    assert again.spacing == pytest.approx(surface.spacing, rel=1e-12)


def test_gwy_bad_channels_and_units_name_the_problem(tmp_path):
    path = write_gwy(tmp_path / "scan.gwy", egg_crate())
    with pytest.raises(ValueError, match=r"channel 1 'Phase'.*'deg', not a length.*height channels: 0 'Height'"):
        load_heights(path, channel=1)
    with pytest.raises(ValueError, match=r"no channel 'topography'; channels: 0 'Height' \(m\), 1 'Phase' \(deg\)"):
        load_heights(path, channel="topography")
    with pytest.raises(ValueError, match=r"unit='nm' contradicts the file.*'m'"):
        load_heights(path, unit="nm")
    with pytest.raises(ValueError, match="states its grid spacing"):
        load_heights(path, spacing=1.0)
    phase_only = tmp_path / "phase.gwy"
    container = GwyContainer()
    container["/0/data/title"] = "Current"
    container["/0/data"] = GwyDataField(np.zeros((4, 4)), xreal=1e-6, yreal=1e-6, si_unit_xy="m", si_unit_z="A")
    container.tofile(str(phase_only))
    with pytest.raises(ValueError, match=r"no height channel.*0 'Current' \(A\)"):  # A is the ampere in Gwyddion
        load_heights(phase_only)
    (tmp_path / "junk.gwy").write_bytes(b"not a gwyddion file")
    with pytest.raises(ValueError, match="junk.gwy: not a readable Gwyddion file"):
        load_heights(tmp_path / "junk.gwy")


def test_gwy_without_units_needs_them_from_the_user(tmp_path):
    z = egg_crate()
    path = tmp_path / "bare.gwy"
    container = GwyContainer()
    container["/0/data"] = GwyDataField(np.ascontiguousarray(z.T), xreal=NX * 5.0, yreal=NY * 5.0)
    container.tofile(str(path))
    with pytest.raises(ValueError, match="does not state the unit"):
        load_heights(path)
    surface = load_heights(path, unit="nm")
    assert surface.spacing == pytest.approx((5.0, 5.0)) and planarize.rms(surface) == pytest.approx(1.5)


def test_gwyddion_fields_without_sizes_are_one_line_errors(tmp_path):
    for xres in (None, 0):
        field = GwyDataField(np.zeros((3, 3)), xreal=1e-9, yreal=1e-9, si_unit_xy="m", si_unit_z="m")
        if xres is None:
            del field["xres"]
        else:
            field["xres"] = xres
        container = GwyContainer()
        container["/0/data"] = field
        path = tmp_path / f"bad{xres}.gwy"
        container.tofile(str(path))
        with pytest.raises(ValueError, match="xres"):
            load_heights(path)


def test_missing_gwyfile_names_the_extra(tmp_path, monkeypatch):
    path = write_gwy(tmp_path / "scan.gwy", egg_crate())
    monkeypatch.setitem(sys.modules, "gwyfile", None)  # import gwyfile now raises ImportError
    with pytest.raises(ValueError, match=r"gwyfile package: pip install \"nanodisorder\[afm\]\""):
        load_heights(path)


# -- text and npy -----------------------------------------------------------------------------

@pytest.mark.parametrize("name", ["s.xyz", "s.csv", "s.txt", "s.asc", "s.npy", "s.gwy"])
def test_save_and_load_round_trip(tmp_path, name):
    surface = planarize.Surface(egg_crate(), (5.0, 2.5))
    path = save_heights(surface, tmp_path / name)
    back = load_heights(path, **({"unit": "nm", "spacing": (5.0, 2.5)} if name.endswith(".npy") else {}))
    np.testing.assert_allclose(back.z, surface.z, rtol=1e-12)
    assert back.spacing == pytest.approx(surface.spacing, rel=1e-12)
    assert sorted(p.name for p in tmp_path.iterdir()) == [name]  # no temporary left behind


def test_xyz_in_any_order_with_user_units(tmp_path, rng):
    z = egg_crate(nx=6, ny=4)
    x, y = np.meshgrid(np.arange(6) * 0.02, np.arange(4) * 0.05, indexing="ij")  # um
    rows = np.column_stack([x.ravel(), y.ravel(), z.ravel() / 1000])[rng.permutation(24)]  # z in um as well
    path = tmp_path / "scan.xyz"
    np.savetxt(path, rows, fmt="%.9g", delimiter="\t")
    surface = load_heights(path, unit="um")
    assert surface.shape == (6, 4) and surface.spacing == pytest.approx((20.0, 50.0))
    np.testing.assert_allclose(surface.z, z, rtol=1e-8)
    heights_in_nm = np.column_stack([rows[:, :2], rows[:, 2] * 1000])
    np.savetxt(path, heights_in_nm, fmt="%.9g", delimiter=",", header="x,y,z", comments="")  # a names row
    np.testing.assert_allclose(load_heights(path, unit="um", z_unit="nm").z, z, rtol=1e-8)


def test_matrix_and_npy_units_and_spacing(tmp_path):
    z = egg_crate(nx=5, ny=7)
    np.savetxt(tmp_path / "m.csv", z * 1e-9, delimiter=",")  # metres, rows are x
    surface = load_heights(tmp_path / "m.csv", unit="m", spacing=2e-9)
    np.testing.assert_allclose(surface.z, z, rtol=1e-12)
    assert surface.spacing == pytest.approx((2.0, 2.0))
    np.save(tmp_path / "a.npy", z * 10)  # angstrom
    surface = load_heights(tmp_path / "a.npy", unit="A", spacing=(10, 20))
    np.testing.assert_allclose(surface.z, z)
    assert surface.spacing == pytest.approx((1.0, 2.0))
    # a Gwyddion-style text export: header with sizes and units, rows are y
    (tmp_path / "g.txt").write_text("# Channel: Height\n# Width: 0.01 µm\n# Height: 0.014 µm\n# Value units: m\n"
                                    + "\n".join("\t".join(repr(float(v) * 1e-9) for v in row) for row in z.T) + "\n")
    surface = load_heights(tmp_path / "g.txt")
    np.testing.assert_allclose(surface.z, z, rtol=1e-12)
    assert surface.spacing == pytest.approx((2.0, 2.0))


def test_level_removes_the_tilt_and_keeps_the_mean(tmp_path):
    flat = planarize.Surface(egg_crate(), 5.0)
    x, y = np.meshgrid(flat.x, flat.y, indexing="ij")
    tilted = flat.with_heights(flat.z + 0.3 * x - 0.1 * y)
    levelled = level_plane(tilted)
    assert levelled.z.mean() == pytest.approx(tilted.z.mean(), abs=1e-9)
    np.testing.assert_allclose(levelled.z - levelled.z.mean(), flat.z - flat.z.mean(), atol=1e-9)
    np.save(tmp_path / "t.npy", tilted.z)
    assert planarize.rms(load_heights(tmp_path / "t.npy", unit="nm", spacing=5, level=True)) == pytest.approx(1.5)


# -- bad input --------------------------------------------------------------------------------

def test_rectangular_pixels_up_to_the_limit(tmp_path):
    np.save(tmp_path / "z.npy", egg_crate(nx=8, ny=8))
    assert load_heights(tmp_path / "z.npy", unit="nm", spacing=(1.0, 8.0)).spacing == (1.0, 8.0)
    with pytest.raises(ValueError, match=r"aspect 10.*up to aspect 8 are supported"):
        load_heights(tmp_path / "z.npy", unit="nm", spacing=(1.0, 10.0))
    assert load_heights(tmp_path / "z.npy", unit="nm", spacing=(1.0, 10.0), max_aspect=10).dy == 10.0


@pytest.mark.parametrize("name, content, kwargs, match", [
    ("ragged.csv", "1,2,3\n4,5\n", {}, r"wrong shape: rows have different numbers of values"),
    ("row.csv", "1,2,3\n", {}, r"at least 2 x 2 points"),
    ("text.csv", "1,2\n3,abc\n", {}, r"line 2: cannot read 'abc' as a number"),
    ("nan.csv", "1,2\n3,nan\n", {}, r"1 non-finite height\(s\).*\[1, 1\]"),
    ("inf.txt", "1 2\ninf 3\n", {}, r"non-finite"),
    ("empty.csv", "# nothing\n", {}, r"no numbers"),
    ("cols.xyz", "0 0\n1 1\n", {}, r"3 columns"),
    ("missing.xyz", "0 0 1\n0 1 1\n1 0 1\n1 2 1\n0 2 1\n", {}, r"irregular grid.*1 grid point\(s\) are missing"),
    ("twice.xyz", "0 0 1\n0 1 1\n1 0 1\n1 1 1\n1 1 2\n", {}, r"irregular grid.*repeated"),
    ("uneven.xyz", "0 0 1\n0 1 1\n1 0 1\n1 1 1\n3 0 1\n3 1 1\n", {}, r"x values are not evenly spaced"),
    ("nanz.xyz", "0 0 1\n0 1 1\n1 0 1\n1 1 nan\n", {}, r"non-finite"),
    ("nanx.xyz", "0 0 1\n0 1 1\n1 0 1\nnan 1 1\n", {}, r"x coordinates\[3\] is not finite"),
    ("scan.jpg", b"x", {}, r"unknown height-map suffix '.jpg'"),
    ("binary.csv", b"\xff\xfe\x00garbage", {}, "cannot read the file as UTF-8 text"),
    ("bad.npy", b"not numpy", {}, r"cannot read the file as a \.npy array"),
    ("line.npy", npy_bytes(np.arange(5.0)), {}, r"2-D array.*1 dimension"),
    ("ok.npy", npy_bytes(np.ones((3, 3))), {"spacing": None}, "does not state its grid spacing"),
    ("ok.npy", npy_bytes(np.ones((3, 3))), {"unit": "furlong"}, r"unit must be one of 'nm'.*got 'furlong'"),
    ("ok.npy", npy_bytes(np.ones((3, 3))), {"spacing": -1}, r"spacing must be finite and > 0"),
    ("ok.npy", npy_bytes(np.ones((3, 3))), {"channel": 0}, "channel applies to .gwy files only"),
])
def test_bad_files_and_arguments(tmp_path, name, content, kwargs, match):
    options = {"unit": "nm", **({"spacing": 1.0} if not name.endswith(".xyz") else {}), **kwargs}
    refused_file(load_heights, tmp_path / name, content, match, **options)


def test_a_missing_file_and_an_unknown_format(tmp_path):
    with pytest.raises(FileNotFoundError, match="does not exist"):
        load_heights(tmp_path / "absent.csv", unit="nm", spacing=1)
    np.save(tmp_path / "ok.npy", np.ones((3, 3)))
    with pytest.raises(ValueError, match="format must be one of"):
        load_heights(tmp_path / "ok.npy", format="tiff")
