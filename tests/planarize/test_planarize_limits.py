"""planarize's bounds: hostile height-map files, `anodize`'s arguments, and the size of a run.

Every refusal is one `InputError` line naming the key (or the file), the value and the bound, raised
before anything of the size asked for is read or allocated. Hostile files are made small: sparse files
(`truncate`) take no disk space.
"""

import importlib
import math
import os

import numpy as np
import pytest
from helpers import one_line_error

from labrig.validate import InputError
from planarize import Model, Surface, anodize, surfaces
from planarize.anodize import HISTORY_ROW_BYTES, MAX_RECORD, MAX_STEPS_PER_RUN, run_bytes
from planarize.cli import main as planarize_main
from planarize.grid import Grid
from planarize.heightfield import MAX_POINTS
from planarize.io import heights, load_heights, texttable
from planarize.io.gwy import gwy_channels
from planarize.io.limits import MAX_FILE_BYTES, TEXT_BYTES_PER_VALUE
from planarize.io.scenefile import scene_from_toml
from planarize.scene import RunSettings, SurfaceSpec
from planarize.surfaces import MAX_SCALES

FLAT = Surface(np.zeros((4, 4)))
sweeps_module = importlib.import_module("planarize.engines.base")  # where the thesis's engines check their memory


def refused(call, match: str) -> str:
    """``call()`` must raise an InputError of one line matching ``match``; returns the message."""
    with pytest.raises(InputError, match=match) as error:
        call()
    message = str(error.value)
    assert "\n" not in message
    return message


def sparse_file(path, size: int):
    """A file of ``size`` NUL bytes that takes no disk space."""
    with open(path, "wb") as stream:
        stream.truncate(size)
    return path


def no_reading(monkeypatch):
    """Make every open() fail the test: what follows must be refused before the file is read."""
    def forbidden(*args, **kwargs):
        raise AssertionError(f"opened {args[0]!r}")
    monkeypatch.setattr("builtins.open", forbidden)
    monkeypatch.setattr("io.open", forbidden)


# -- files ------------------------------------------------------------------------------------

def test_symlink_loops_are_refused_in_one_line(tmp_path):
    loop = tmp_path / "loop.csv"
    os.symlink("loop.csv", loop)
    os.symlink("b.gwy", tmp_path / "a.gwy")
    os.symlink("a.gwy", tmp_path / "b.gwy")
    for path, options in ((loop, {"spacing": 1}), (tmp_path / "a.gwy", {})):
        message = refused(lambda path=path, options=options: load_heights(path, unit="nm", **options), "symbolic links")
        assert message.startswith(str(path))
    refused(lambda: gwy_channels(tmp_path / "b.gwy"), "b.gwy: cannot open the file: .*symbolic links")
    spec = SurfaceSpec("file", {"path": str(loop), "unit": "nm", "spacing": 1.0})  # a scene's file surface
    refused(spec.build, "symbolic links")


@pytest.mark.parametrize("name, size", [
    ("nul.csv", 2**30),  # the fuzzer's 1 GiB of NUL bytes
    ("big.txt", MAX_FILE_BYTES["matrix"] + 1),
    ("big.xyz", MAX_FILE_BYTES["xyz"] + 1),
    ("big.npy", MAX_FILE_BYTES["npy"] + 1),
    ("big.gwy", int(1.5 * 2**30)),  # the fuzzer's 1.5 GiB .gwy (gwyfile would hold ~5 copies of it)
])
def test_files_larger_than_the_largest_surface_are_refused_unread(tmp_path, monkeypatch, name, size):
    path = sparse_file(tmp_path / name, size)
    options = {} if name.endswith((".xyz", ".gwy")) else {"spacing": 1.0}
    no_reading(monkeypatch)
    message = refused(lambda: load_heights(path, unit="nm", **options), f"the file has {size:,} bytes, more than the")
    assert f"{MAX_POINTS:,} points" in message


def test_a_gwy_file_that_grew_after_its_check_is_read_no_further_than_the_cap(tmp_path, monkeypatch):
    from planarize.io import gwy

    path = sparse_file(tmp_path / "grown.gwy", 5000)
    monkeypatch.setitem(MAX_FILE_BYTES, "gwy", 1000)
    monkeypatch.setattr(gwy, "checked_file", lambda path, format: None)  # as if it had grown since
    refused(lambda: gwy_channels(path), "grown.gwy: the file has more than the 1,000 bytes a gwy height map may have")


def test_the_import_command_refuses_hostile_files_in_one_line(tmp_path, capsys):
    nul = sparse_file(tmp_path / "nul.csv", 2**30)
    diagonal = tmp_path / "diagonal.xyz"
    np.savetxt(diagonal, np.repeat(np.arange(10_000.0)[:, None], 3, axis=1), fmt="%g")
    for argv in ([str(nul), "--unit", "nm", "--spacing", "1"], [str(diagonal), "--unit", "nm"]):
        assert planarize_main(["import", *argv, "--thickness", "1", "--out", str(tmp_path / "out")]) == 2
        err = capsys.readouterr().err
        assert err.startswith("planarize: error:") and len(err.strip().splitlines()) == 1
        assert "16,785,409" in err


def test_height_maps_with_absurd_numbers_are_one_line_errors(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)  # the default output directory, ./planarize-import, must not be left behind
    cases = {
        "zero.csv": "# Width: 0 nm\n# Height: 1 nm\n# Value units: nm\n1,2\n3,4\n",
        "huge.xyz": "0 0 1\n0 1e308 1\n1e308 0 1\n1e308 1e308 1\n",
        "tall.xyz": "0 0 1\n0 1 1.8e19\n1 0 1\n1 1 1\n",
    }
    for name, text in cases.items():
        (tmp_path / name).write_text(text)
        assert planarize_main(["import", str(tmp_path / name), "--thickness", "1", "--unit", "nm"]) == 2
        one_line_error(capsys, "planarize")
    for name, array in (("u64.npy", np.full((3, 3), 18_000_000_000_000_000_000, dtype=np.uint64)),
                        ("dates.npy", np.zeros((3, 3), dtype="timedelta64[s]")), ("big.npy", np.full((3, 3), 1e300))):
        np.save(tmp_path / name, array)
        assert planarize_main(["import", str(tmp_path / name), "--thickness", "1", "--unit", "nm", "--spacing",
                               "1"]) == 2
        one_line_error(capsys, "planarize")
    np.save(tmp_path / "flat.npy", np.zeros((3, 3)))
    for spacing in ("1e300", "1e-300"):
        assert planarize_main(["import", str(tmp_path / "flat.npy"), "--thickness", "1", "--unit", "nm",
                               "--spacing", spacing, "--step", "0.1"]) == 2
        assert "spacing" in one_line_error(capsys, "planarize")
    assert not (tmp_path / "planarize-import").exists()


def test_the_byte_caps_follow_the_point_limit():
    assert MAX_FILE_BYTES["matrix"] == TEXT_BYTES_PER_VALUE * MAX_POINTS  # one number per point
    assert MAX_FILE_BYTES["xyz"] == 3 * MAX_FILE_BYTES["matrix"]  # three
    assert MAX_FILE_BYTES["gwy"] > 8 * MAX_POINTS  # room for the largest channel of doubles


def test_a_binary_file_within_the_cap_is_refused_at_its_first_piece(tmp_path, monkeypatch):
    path = sparse_file(tmp_path / "nul.csv", 2**28)
    pieces = []
    read = texttable._TableReader.read

    def counted(reader, piece):
        pieces.append(len(piece))
        return read(reader, piece)
    monkeypatch.setattr(texttable._TableReader, "read", counted)
    refused(lambda: load_heights(path, unit="nm", spacing=1), "line 1 holds a NUL character")
    assert pieces == [texttable.PIECE_CHARS]  # 64 kB of the 256 MiB read


def test_text_tables_stop_at_the_point_limit(tmp_path, monkeypatch):
    monkeypatch.setattr(heights, "MAX_POINTS", 1000)
    matrix = tmp_path / "m.csv"
    matrix.write_text("\n".join(",".join(["1.5"] * 100) for _ in range(50)) + "\nnot,a,number\n")
    # refused while reading: the bad line at the end is never reached
    refused(lambda: load_heights(matrix, unit="nm", spacing=1), r"holds more than 1,000 numbers: a surface has at most "
                                                                r"1,000 points")
    xyz = tmp_path / "p.xyz"
    xyz.write_text("".join(f"{i} {j} 1\n" for i in range(40) for j in range(30)))
    refused(lambda: load_heights(xyz, unit="nm"), r"more than 3,000 numbers: .*1,000 points \(3 numbers each\)")


def test_a_long_line_without_separators_is_refused_early(tmp_path):
    path = tmp_path / "line.csv"
    path.write_text("7" * 10**6)
    refused(lambda: load_heights(path, unit="nm", spacing=1), "line 1: a value of more than 256 characters")


def test_xyz_grids_are_bounded_before_they_are_made(tmp_path, monkeypatch):
    diagonal = np.arange(10_000.0)
    path = tmp_path / "diagonal.xyz"
    np.savetxt(path, np.column_stack([diagonal, diagonal, diagonal]), fmt="%g")
    monkeypatch.setattr(np, "bincount", lambda *a, **k: pytest.fail("a grid-sized array was made"))
    refused(lambda: load_heights(path, unit="nm"), r"span a grid of 10,000 x 10,000 points, more than the "
                                                   r"16,785,409 a surface may have \(10,000 points in the file\)")
    dense = np.arange(20_001.0)  # closer than 1e-4 of the span: no grid lines at all
    np.savetxt(path, np.column_stack([dense, dense, dense]), fmt="%g")
    refused(lambda: load_heights(path, unit="nm"), "irregular grid: the x values form no grid lines")


@pytest.mark.parametrize("delimiter, newline", [(",", "\n"), (";", "\r\n"), ("\t", "\n"), (" ", "\r\n")])
@pytest.mark.parametrize("piece", [texttable.MAX_FIELD_CHARS + 1, 1000, texttable.PIECE_CHARS])
def test_rows_longer_than_a_piece_read_exactly(tmp_path, monkeypatch, rng, delimiter, newline, piece):
    monkeypatch.setattr(texttable, "PIECE_CHARS", piece)
    z = rng.normal(0.0, 1e-7, (3, 2500)) * 10.0 ** rng.integers(-3, 4, (3, 2500))  # values of 8 to 24 characters
    names = delimiter.join(f"c{k}" for k in range(2500))
    lines = ["# a comment", names, ""] + [delimiter.join(repr(float(v)) for v in row) for row in z]
    path = tmp_path / "wide.csv"
    path.write_bytes(newline.join(lines).encode())  # no newline at the end
    np.testing.assert_array_equal(load_heights(path, unit="nm", spacing=1).z, z)


def test_load_heights_checks_its_options_before_opening_the_file(tmp_path):
    absent = tmp_path / "absent.csv"  # every bad option is named before the missing file is noticed
    for options, match in [
        ({"max_aspect": "x"}, "max_aspect must be a number >= 1"), ({"max_aspect": 0.5}, "max_aspect must be >= 1"),
        ({"max_aspect": math.inf}, "max_aspect must be >= 1"), ({"level": "yes"}, "level: unknown correction 'yes'"),
        ({"channel": 1.5}, "channel must be a channel number .* or a channel title"), ({"boundary": "round"}, "boundary must be"),
        ({"unit": 5}, "unit must be one of .nm."), ({"z_unit": "furlong"}, "z_unit must be one of .nm."),
        ({"spacing": -1}, "spacing must be finite and > 0"), ({"format": "tiff"}, "format must be one of"),
    ]:
        refused(lambda options=options: load_heights(absent, **options), match)
    refused(lambda: load_heights(3), "path must be a file name")
    with pytest.raises(FileNotFoundError, match="does not exist"):
        load_heights(absent, unit="nm", spacing=1)


# -- anodize's arguments ----------------------------------------------------------------------

@pytest.mark.parametrize("kwargs, match", [
    ({"oxide": "x"}, r"oxide must be a planarize.Surface or None, got str"),
    ({"oxide": Surface(np.zeros((3, 3)))}, r"oxide must be on the metal's grid"),
    ({"oxide": Surface(-np.ones((4, 4)))}, r"oxide must lie nowhere below the metal"),
    ({"progress": "yes"}, r"progress must be true or false, got 'yes'"),
    ({"observer": 3}, r"observer must be a function observer\(engine\) or None, got int"),
    ({"record": 0}, r"record must be an integer in \[1, 100,000\], got 0"),
    ({"record": True}, r"record must be a count in \[1, 100,000\]"),
    ({"record": [0.05, 0.5]}, r"record must hold numbers in \[0, 0.1\] nm, got 0.5"),
    ({"snapshots": "end"}, r"snapshots must be a count"),
    ({"max_seconds": 0}, r"max_seconds must be > 0 s, got 0"),
    ({"max_seconds": math.inf}, r"max_seconds must be > 0 s, got inf"),
    ({"model": "thesis"}, r"model must be a planarize.Model, got str"),
    ({"engine": "slow"}, r"engine must be one of 'continuum', 'fast', 'reference', 'matlab'"),
    ({"thickness": -1.0}, r"thickness must be in \[0, 1e6\] nm, got -1.0"),
    ({"thickness": math.nan}, r"thickness must be in \[0, 1e6\] nm, got nan"),
    ({"thickness": "1"}, r"thickness must be a number in \[0, 1e6\] nm, got '1'"),
    ({"metal": FLAT.z}, r"metal must be a planarize.Surface, got ndarray"),
])
def test_anodize_refuses_bad_arguments_in_one_line(kwargs, match):
    call = {"metal": FLAT, "thickness": 0.1, **kwargs}
    refused(lambda: anodize(**call), match)


# -- the size of a run ------------------------------------------------------------------------

def test_the_steps_of_a_run_are_bounded():
    match = r"thickness / step = 1e\+12 steps per grid point, more than the 1,000,000 a run may take"
    refused(lambda: anodize(FLAT, 1000.0, Model(step=1e-9)), match)
    refused(lambda: RunSettings(thickness=1000.0, step=1e-9), match)
    refused(lambda: scene_from_toml("[run]\nthickness = 1000.0\nstep = 1e-9\n"), "run." + match)
    assert MAX_STEPS_PER_RUN >= 400  # the thesis's Ta film: 200 nm at 0.5 nm


def test_records_and_snapshots_are_bounded():
    refused(lambda: anodize(FLAT, 0.1, record=MAX_RECORD + 1), r"record must be an integer in \[1, 100,000\]")
    many = np.linspace(0.0, 0.1, MAX_RECORD + 1).tolist()
    refused(lambda: anodize(FLAT, 0.1, record=many), "record lists 100,001 thicknesses, more than the 100,000 allowed")
    refused(lambda: anodize(FLAT, 0.1, snapshots=many), "snapshots lists 100,001 thicknesses")
    refused(lambda: scene_from_toml("[run]\nrecord = 100001\n"), r"run.record must be an integer in \[1, 100,000\]")


def test_the_memory_of_a_run_counts_the_engine_snapshots_and_history(monkeypatch):
    hill = surfaces.hill()
    need = run_bytes(hill.z.size, 51, 2)  # record=50: 51 rows; the default snapshots: start and end
    assert run_bytes(hill.z.size, 52, 2) - need == HISTORY_ROW_BYTES
    assert run_bytes(hill.z.size, 51, 3) - need == 24 * hill.z.size  # metal, oxide and distances
    monkeypatch.setattr(sweeps_module, "available_memory", lambda: need - 1)
    refused(lambda: anodize(hill, 0.01, Model(step=0.01), "fast"), "the run would need about .* GiB of memory, more than")
    monkeypatch.setattr(sweeps_module, "available_memory", lambda: need)
    assert anodize(hill, 0.01, Model(step=0.01), "fast").complete


def test_grids_are_bounded_before_they_are_made():
    refused(lambda: Surface(np.zeros((3, 3))).refine(4096), r"gives 8193 x 8193 points, more than the 16,785,409")
    refused(lambda: surfaces.random_roughness(size=1e6), "grid points per side, more than the 4097 allowed")
    refused(lambda: surfaces.random_roughness(scales=[(200.0, 1.0)] * (MAX_SCALES + 1)),
            r"scales must hold at most 64 pairs, got 65")
    refused(lambda: surfaces.random_roughness(seed=-1), r"seed must be .*got -1")
    refused(lambda: Grid((10**6, 10**6), (1.0, 1.0), False), "grid shape is 1000000 x 1000000 points, more than")
    refused(lambda: Grid((0, 5), (1.0, 1.0), False), r"grid shape nx must be an integer in \[1, 16,785,409\]")
    refused(lambda: Grid((3, 3), (0.0, 1.0), False), "grid spacing dx must be > 0 nm")
    refused(lambda: Grid((3, 3), (1.0, 1.0), "yes"), "periodic must be true or false")


def test_surface_methods_check_their_numbers():
    refused(lambda: FLAT.shifted("1"), r"dz must be a number in \[-2e9, 2e9\] nm")
    refused(lambda: FLAT.volume(base=math.inf), "base must be a finite number nm, got inf")


def test_scene_files_bound_the_pixel_aspect_and_the_quick_fraction():
    refused(lambda: scene_from_toml("[surface]\nkind = 'file'\npath = 'x.npy'\nmax_aspect = inf\n"),
            "surface.max_aspect must be >= 1, got inf")
    scene = scene_from_toml("[run]\nthickness = 1.0\n")
    refused(lambda: scene.quick(True), r"quick fraction must be a number in \(0, 1\]")


def test_import_of_a_symlink_loop_is_one_line(tmp_path, capsys):
    os.symlink("loop.csv", tmp_path / "loop.csv")
    assert planarize_main(["import", str(tmp_path / "loop.csv"), "--thickness", "1"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("planarize: error: ") and "symbolic links" in err and err.count("\n") == 1


def test_figures_are_bounded_before_they_are_drawn(tmp_path):
    from matplotlib.figure import Figure

    from labrig.figures import MAX_DPI, save_figure
    from planarize import render

    with pytest.raises(InputError, match=r"^dpi must be in \(0, 1200\], got 1201"):
        save_figure(Figure(figsize=(2, 2)), tmp_path / "x.png", dpi=MAX_DPI + 1)
    with pytest.raises(InputError, match="has 2.59e\\+08 pixels, more than the 2e\\+08 allowed"):
        save_figure(Figure(figsize=(12, 15)), tmp_path / "x.png", dpi=MAX_DPI)
    assert not list(tmp_path.iterdir())
    run = anodize(surfaces.hill(points=5, refine=1), 0.2, Model(step=0.05), snapshots=np.linspace(0, 0.2, 101))
    with pytest.raises(InputError, match=r"the run has 10[12] snapshots: .* more than the 100 a figure takes"):
        render.snapshots_figure(run)
