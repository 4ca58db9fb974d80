"""Measured height maps (AFM) in and out: plain-text XYZ, text matrices, ``.npy``, Gwyddion ``.gwy`` and the
files AFM instruments write.

`load_heights` returns a `planarize.Surface` in nm, levelled (`planarize.levelling`); `load_levelled` also
returns the artefacts found and removed; `save_heights` writes a surface.

Formats (chosen by suffix, or ``format=``):

``"xyz"`` (``.xyz``)
    Three columns ``x y z`` (whitespace, comma or semicolon separated), one
    row per grid point of a regular grid, in any order. The spacing is read
    from the coordinates.
``"matrix"`` (``.csv``, ``.txt``, ``.asc``, ``.dat``)
    A grid of heights. Without a header, row ``i`` is ``x_i`` (the layout of
    `Surface.z`, as ``np.savetxt(surface.z)`` writes it) and ``spacing`` must
    be given. With a Gwyddion text-export header (``# Width: 4.0 µm``,
    ``# Height: ...``, ``# Value units: m``) the rows are image rows (``y``)
    and the size and units come from the header.
``"npy"`` (``.npy``)
    A 2-D array laid out like `Surface.z`; ``spacing`` and ``unit`` must be given.
``"gwy"`` (``.gwy``)
    A Gwyddion file, read with the ``gwyfile`` package (``pip install
    "nanodisorder[afm]"``; `planarize.io.gwy`). One channel is imported: by number or
    title, by default the first whose values are lengths. Pixel size and
    units come from the file.
``"spm"``, ``"ibw"``, ``"jpk"``, ``"stp"``, ``"top"``, ``"nid"``, ``"park"``, ``"mi"``
    The files of Bruker, Asylum Research, JPK and WSxM instruments, read with the AFMReader package, of
    NanoSurf instruments, read with Nanosurf's NSFopen, and of Park Systems (``.tiff``) and Agilent / Keysight
    PicoView (``.mi``) instruments, read with SurfaceTopography (``pip install "nanodisorder[afm]"``;
    `planarize.io.instrument`). Pixel size and heights come from the file; ``channel`` names a channel (default:
    the height channel).

Levelling: ``level`` (`planarize.levelling`) removes scan-line offsets, spikes, scars, the tilt and a
polynomial background. Files that instruments and Gwyddion write are levelled ``"auto"`` by default (each
of line offsets, spikes, scars and tilt that is found is removed; a bow is reported, never removed unless
asked); the others are read as they are unless ``level`` asks.

Units: whatever the file states is used; ``unit`` (lateral, and heights
unless ``z_unit`` is given) supplies what it does not, and must agree with
what it does. Lengths: ``"nm"``, ``"um"`` (also ``"µm"``), ``"mm"``,
``"m"``, ``"pm"``, ``"A"`` (ångström, also ``"Å"``). In Gwyddion metadata
``"A"`` is the ampere (a current channel), not a length.

Rectangular pixels (``dx != dy``) are supported: the engines use both
spacings, and results are then as accurate as the coarser spacing allows
(measured: a Gaussian hill on 0.5 x 0.125 nm pixels planarizes between the
0.25 and 0.5 nm square grids). Pixels more elongated than ``max_aspect``
(default 8: e.g. a 512 x 32 line scan of a square area) are refused.

Sizes: a surface has at most `planarize.heightfield.MAX_POINTS` points, and nothing larger is read.
A file larger than such a surface could need is refused from its size before it is opened
(`planarize.io.limits.MAX_FILE_BYTES`); text is read piece by piece into floats and refused as
soon as it holds more numbers than that (`planarize.io.texttable`); the grid an XYZ file's
coordinates imply, a ``.npy`` array's shape and a ``.gwy`` channel's ``xres`` x ``yres`` are
checked before the heights are laid out.
"""

from __future__ import annotations

import os
import re
from pathlib import Path

import numpy as np

from labrig.files import atomic_path
from labrig.params import Param
from labrig.validate import InputError, array, real

from ..heightfield import BOUNDARIES, MAX_POINTS, Surface, check_heights
from ..levelling import Artefact, level_surface, parse_corrections
from .gwy import read_gwy, write_gwy
from .instrument import SUFFIXES as INSTRUMENT_SUFFIXES
from .instrument import read_instrument
from .limits import checked_file
from .texttable import is_number, read_table
from .units import LENGTH_UNITS, MAX_COORDINATE, file_unit, given_spacing, spacing_pair, unit_scales

#: Formats by file suffix.
SUFFIXES = {".xyz": "xyz", ".csv": "matrix", ".txt": "matrix", ".asc": "matrix", ".dat": "matrix",
            ".npy": "npy", ".gwy": "gwy", **INSTRUMENT_SUFFIXES}
FORMATS = ("xyz", "matrix", "npy", "gwy", *INSTRUMENT_SUFFIXES.values())
#: Formats that instruments (or Gwyddion) write: their default levelling is ``"auto"`` (the others' is none).
MEASURED_FORMATS = ("gwy", *INSTRUMENT_SUFFIXES.values())
#: Header entries of text height maps that are read (Gwyddion's text export; keys in lower case).
HEADER_KEYS = ("xy units", "value units", "width", "height")
#: Most elongated pixel (longer / shorter side) accepted by default.
MAX_PIXEL_ASPECT = 8.0
#: The options of `load_heights` (`labrig.params.Param`), which it checks with these; a scene file's
#: ``[surface]`` keys for ``kind = "file"`` (`planarize.scene`).
LOAD_OPTIONS = {
    "path": Param("str", high=4096, doc="height map: .xyz, .csv/.txt/.asc/.dat matrix, .npy, .gwy, or an AFM "
                  "instrument's .spm, .ibw, .jpk, .stp, .top, .nid, .tiff (Park), .mi",
                  rule="relative to the scene file"),
    "unit": Param("str", choices=tuple(LENGTH_UNITS), optional=True,
                  doc="unit of lateral sizes (and heights), for files that do not state it", unset="the file's"),
    "z_unit": Param("str", choices=tuple(LENGTH_UNITS), optional=True, doc="unit of the heights",
                    unset="unit"),
    "spacing": Param("either", optional=True, doc="grid spacing in unit (.npy and plain matrices only)",
                     parts=(Param("float", 0.0, low_open=True, doc="a number"),
                            Param("float2", 0.0, doc="[dx, dy]", rule="each > 0")),
                     unset="the file's"),
    "level": Param("either", optional=True, doc="levelling (planarize.levelling)",
                   parts=(Param("bool", doc="true: the plane's tilt only"),
                          Param("str", high=200, doc="\"auto\", \"none\" or corrections joined by commas",
                                rule="corrections: lines, spikes, scars, plane, poly2, poly3")),
                   unset="\"auto\" for instruments' files and .gwy, none for the others"),
    "channel": Param("either", optional=True, doc="channel of a .gwy (number or title) or instrument file (name)",
                     parts=(Param("int", 0, doc="a channel number"), Param("str", high=1000, doc="a channel title")),
                     unset="the first height channel"),
    "format": Param("str", choices=FORMATS, optional=True, doc="format", unset="from the suffix"),
    "boundary": Param("str", choices=BOUNDARIES, doc="edges (\"periodic\": the map tiles the plane)"),
    "max_aspect": Param("float", 1.0, doc="largest pixel aspect ratio accepted"),
}


# -- checks ------------------------------------------------------------------------------------

def check_aspect(dx: float, dy: float, max_aspect: float = MAX_PIXEL_ASPECT) -> None:
    """ValueError unless the pixel ``dx`` x ``dy`` is at most ``max_aspect`` times longer than wide."""
    aspect = max(dx, dy) / min(dx, dy)
    if aspect > max_aspect * (1 + 1e-9):
        raise InputError(f"pixels are {dx:.6g} x {dy:.6g} nm (aspect {aspect:.3g}); rectangular pixels up to "
                         f"aspect {max_aspect:g} are supported (accuracy follows the coarser spacing): resample "
                         f"the scan, or pass a larger max_aspect")


def level_plane(surface: Surface) -> Surface:
    """``surface`` with its least-squares plane's tilt removed; the mean height is kept.

    Fits ``z = a + b x + c y`` to every grid point (equal weights) and
    subtracts ``b (x - mean x) + c (y - mean y)``.
    """
    x, y = np.meshgrid(surface.x, surface.y, indexing="ij")
    x, y = x - x.mean(), y - y.mean()
    design = np.column_stack([np.ones(x.size), x.ravel(), y.ravel()])
    (_, b, c), *_ = np.linalg.lstsq(design, surface.z.ravel(), rcond=None)
    return surface.with_heights(surface.z - b * x - c * y)


# -- reading -----------------------------------------------------------------------------------

def load_heights(path, *, unit: str | None = None, z_unit: str | None = None, spacing=None,
                 level=None, channel: int | str | None = None, format: str | None = None,
                 boundary: str = "open", max_aspect: float = MAX_PIXEL_ASPECT) -> Surface:
    """Read a measured height map as a `Surface` in nm, levelled as ``level`` asks.

    Parameters
    ----------
    path : str or Path
        The file; its format follows the suffix (see the module docstring).
    unit : str, optional
        Unit of the lateral coordinates and ``spacing`` (and of the heights
        unless ``z_unit`` is given), for files that do not state it.
    z_unit : str, optional
        Unit of the heights, if different from ``unit``.
    spacing : float or (float, float), optional
        Grid spacing ``dx`` (between rows of a plain matrix) and ``dy``, in
        ``unit``; required for ``.npy`` and header-less matrices, not used otherwise.
    level : str, sequence of str or bool, optional
        The corrections of `planarize.levelling` (``"lines,spikes,scars,plane"``), ``"auto"`` (those of
        lines, spikes, scars and plane whose artefact is found) or ``"none"``; True means ``"plane"``.
        Default: ``"auto"`` for the files instruments and Gwyddion write (`MEASURED_FORMATS`), none for
        the others. `load_levelled` also returns what was found and removed.
    channel : int or str, optional
        ``.gwy``: channel number or title (default: the first height channel); an instrument's file: the
        channel's name (default: its height channel, `planarize.io.instrument.HEIGHT_CHANNELS`).
    format : str, optional
        One of `FORMATS`; overrides the suffix.
    boundary : {"open", "periodic"}
        Boundary of the returned surface.
    max_aspect : float
        Largest accepted pixel aspect ratio (see the module docstring).

    Raises
    ------
    FileNotFoundError
        If ``path`` does not exist.
    ValueError
        Naming the file and the problem: unreadable or unparsable file, a
        non-2-D or too small grid, NaN/inf heights, an irregular XYZ grid,
        missing units or spacing, a channel that is not a height or does not
        exist (listing the available ones), too elongated pixels, an unknown correction.
    """
    return load_levelled(path, unit=unit, z_unit=z_unit, spacing=spacing, level=level, channel=channel,
                         format=format, boundary=boundary, max_aspect=max_aspect)[0]


def load_levelled(path, *, level=None, format: str | None = None, **options) -> tuple[Surface, list[Artefact]]:
    """`load_heights` (the same arguments), and the artefacts `planarize.levelling.level_surface` found on the
    map as read, each with its size and whether it was removed."""
    if not isinstance(path, (str, os.PathLike)):
        raise InputError(f"path must be a file name (str or Path), got {type(path).__name__}")
    path = Path(path)
    if format is None:
        format = SUFFIXES.get(path.suffix.lower())
        if format is None:
            raise InputError(f"{path}: unknown height-map suffix {path.suffix!r}; use one of "
                             f"{', '.join(SUFFIXES)} or pass format= ({', '.join(FORMATS)})")
    else:
        LOAD_OPTIONS["format"].check("format", format)
    unit, z_unit, spacing, channel = (options.get(k) for k in ("unit", "z_unit", "spacing", "channel"))
    boundary, max_aspect = options.get("boundary", "open"), options.get("max_aspect", MAX_PIXEL_ASPECT)
    try:
        _check_options(unit, z_unit, spacing, level, channel, boundary, max_aspect)
        corrections = parse_corrections(level, "auto" if format in MEASURED_FORMATS else "none")
        checked_file(path, format)  # a regular file within the format's size cap: nothing read yet
        if format in INSTRUMENT_SUFFIXES.values():
            z, (dx, dy), xy_scale, z_scale = read_instrument(path, format, unit, z_unit, spacing, channel)
        else:
            reader = {"xyz": _read_xyz, "matrix": _read_matrix, "npy": _read_npy, "gwy": read_gwy}[format]
            z, (dx, dy), xy_scale, z_scale = reader(path, unit, z_unit, spacing, channel)
        z = check_heights(z, "heights") * z_scale
        dx, dy = dx * xy_scale, dy * xy_scale
        check_aspect(dx, dy, max_aspect)
        surface = Surface(z, (dx, dy), boundary)
    except ValueError as exc:
        raise InputError(f"{path}: {exc}") from None
    return level_surface(surface, corrections)


def _check_options(unit, z_unit, spacing, level, channel, boundary, max_aspect) -> None:
    """`InputError` naming the first bad argument of `load_heights` (before the file is opened)."""
    options = {"unit": unit, "z_unit": z_unit, "level": level, "channel": channel, "boundary": boundary,
               "max_aspect": max_aspect}
    for name, value in options.items():
        LOAD_OPTIONS[name].check(name, value)
    if spacing is not None:
        spacing_pair(spacing)  # a number, a pair or an array of two


def _text_table(path: Path, columns: int) -> tuple[dict, np.ndarray]:
    """Header and numeric table of a text height map with ``columns`` numbers per grid point, read in memory
    bounded by the most points a surface may have (`planarize.io.texttable`)."""
    note = f": a surface has at most {MAX_POINTS:,} points" + (f" ({columns} numbers each)" if columns > 1 else "")
    return read_table(path, columns * MAX_POINTS, HEADER_KEYS, note)


_QUANTITY = re.compile(r"^\s*([-+0-9.eE]+)\s*(\S*)\s*$")


def _quantity(header: dict, key: str) -> tuple[float, str] | None:
    """``(value, unit)`` of a header entry like ``Width: 4.000 µm``, or None if absent."""
    if key not in header:
        return None
    match = _QUANTITY.match(header[key])
    if not match or not is_number(match.group(1)):
        raise InputError(f"header {key!r}: cannot read {header[key]!r} as a number and a unit")
    value = real(f"header {key!r}", float(match.group(1)), 0.0, MAX_COORDINATE, low_open=True)
    return value, file_unit(match.group(2), f"header {key!r} values")


def _read_xyz(path, unit, z_unit, spacing, channel):
    if channel is not None:
        raise InputError("channel applies to .gwy files only")
    given_spacing(spacing, stated=True)  # (the coordinates state it)
    header, table = _text_table(path, 3)
    if table.shape[1] != 3:
        raise InputError(f"wrong shape: an XYZ file has 3 columns (x y z), this one has {table.shape[1]}")
    stated_xy = file_unit(header["xy units"], "header 'XY units'") if "xy units" in header else None
    stated_z = file_unit(header["value units"], "header 'Value units'") if "value units" in header else None
    xy_scale, z_scale = unit_scales(stated_xy, stated_z, unit, z_unit)
    x = array("x coordinates", table[:, 0], (None,), limit=MAX_COORDINATE)
    y = array("y coordinates", table[:, 1], (None,), limit=MAX_COORDINATE)
    z = table[:, 2]
    i, x0, dx = _axis(x, "x")
    j, y0, dy = _axis(y, "y")
    nx, ny = int(i.max()) + 1, int(j.max()) + 1
    if nx * ny > MAX_POINTS:  # before any array of the grid's size is made
        raise InputError(f"the x and y values span a grid of {nx:,} x {ny:,} points, more than the {MAX_POINTS:,} a "
                         f"surface may have ({len(z):,} points in the file)")
    counts = np.bincount(i * ny + j, minlength=nx * ny)
    if (counts != 1).any():
        k = int(np.flatnonzero(counts != 1)[0])
        missing, repeated = int((counts == 0).sum()), int((counts > 1).sum())
        raise InputError(f"irregular grid: the x and y values span {nx} x {ny} points, but {missing} grid point(s) "
                         f"are missing and {repeated} repeated (the first at x = {x0 + k // ny * dx:.6g}, "
                         f"y = {y0 + k % ny * dy:.6g}); resample onto a regular grid first")
    heights = np.empty(nx * ny)
    heights[i * ny + j] = z
    return heights.reshape(nx, ny), (dx, dy), xy_scale, z_scale


def _axis(values: np.ndarray, name: str) -> tuple[np.ndarray, float, float]:
    """Grid index of each coordinate, the first coordinate and the spacing; ValueError if not evenly spaced."""
    ordered = np.sort(values)
    span = float(ordered[-1] - ordered[0])
    if span <= 0:
        raise InputError(f"every point has the same {name}: not a 2-D grid")
    # coordinates of one grid line differ by rounding only; lines are >= span / 4096 apart
    tol = 1e-4 * span
    starts = np.concatenate([[0], np.flatnonzero(np.diff(ordered) > tol) + 1])
    levels = np.add.reduceat(ordered, starts) / np.diff(np.append(starts, len(ordered)))
    if len(levels) < 2:
        raise InputError(f"irregular grid: the {name} values form no grid lines (values closer than 1e-4 of their span "
                         f"count as one line, so an axis has at most 10,001 lines); resample onto a regular grid first")
    step = (levels[-1] - levels[0]) / (len(levels) - 1)
    gaps = np.diff(levels)
    if np.abs(gaps - step).max() > 1e-3 * step:
        raise InputError(f"irregular grid: {name} values are not evenly spaced (steps from {gaps.min():.6g} "
                         f"to {gaps.max():.6g}); resample onto a regular grid first")
    index = np.rint((values - levels[0]) / step).astype(int)
    if np.abs(values - levels[0] - index * step).max() > 1e-3 * step:
        raise InputError(f"irregular grid: some {name} values lie between grid lines")
    return index, float(levels[0]), float(step)


def _read_matrix(path, unit, z_unit, spacing, channel):
    if channel is not None:
        raise InputError("channel applies to .gwy files only")
    header, z = _text_table(path, 1)
    width, height = _quantity(header, "width"), _quantity(header, "height")
    stated_z = file_unit(header["value units"], "header 'Value units'") if "value units" in header else None
    if (width is None) != (height is None):
        raise InputError("the header states only one of Width and Height")
    if width is None:  # plain matrix: rows are x, as in Surface.z
        xy_scale, z_scale = unit_scales(None, stated_z, unit, z_unit)
        return z, given_spacing(spacing, stated=False), xy_scale, z_scale
    # Gwyddion text export: rows are image rows (y); Width spans the columns
    given_spacing(spacing, stated=True)
    if width[1] != height[1]:
        raise InputError("the header states Width and Height in different units")
    xy_scale, z_scale = unit_scales(width[1], stated_z, unit, z_unit)
    ny, nx = z.shape
    return z.T, (width[0] / nx, height[0] / ny), xy_scale, z_scale


def _read_npy(path, unit, z_unit, spacing, channel):
    if channel is not None:
        raise InputError("channel applies to .gwy files only")
    try:
        z = np.load(path, mmap_mode="r", allow_pickle=False)  # the header first: nothing is read before the checks
    except (OSError, ValueError, EOFError) as exc:
        raise InputError(f"cannot read the file as a .npy array: {exc}") from None
    if not isinstance(z, np.ndarray):
        raise InputError(f"the file is not a .npy array (a .npz archive renamed?), got {type(z).__name__}")
    if z.dtype.kind not in "iuf":
        raise InputError(f"heights must be real numbers, the array holds {z.dtype}")
    if z.size > MAX_POINTS:
        raise InputError(f"the array has {z.size:,} values, more than the {MAX_POINTS:,} points a surface may have")
    z = np.array(z)
    xy_scale, z_scale = unit_scales(None, None, unit, z_unit)
    return z, given_spacing(spacing, stated=False), xy_scale, z_scale


# -- writing -----------------------------------------------------------------------------------

def save_heights(surface: Surface, path, *, format: str | None = None, title: str = "Height") -> Path:
    """Write ``surface`` to ``path`` (format by suffix, as `load_heights` reads it), atomically.

    ``.xyz`` and matrix files get a header with their units (nm) and size, so
    `load_heights` needs no ``unit`` or ``spacing`` for them; ``.npy`` holds
    the heights only (nm); ``.gwy`` holds one channel ``title`` in metres
    (SI, as Gwyddion expects) with its physical size. Matrices are written in
    Gwyddion's layout (rows are ``y``).
    """
    if not isinstance(surface, Surface):
        raise TypeError(f"surface must be a planarize.Surface, got {type(surface).__name__}")
    path = Path(path)
    format = format or SUFFIXES.get(path.suffix.lower())
    if format not in FORMATS:
        raise InputError(f"cannot tell the format of {str(path)!r}: use a suffix of {', '.join(SUFFIXES)} "
                         f"or pass format= ({', '.join(FORMATS)})")
    (nx, ny), (dx, dy) = surface.shape, surface.spacing
    with atomic_path(path) as tmp:
        if format == "npy":
            with open(tmp, "wb") as stream:
                np.save(stream, np.asarray(surface.z))
        elif format == "gwy":
            write_gwy(surface, tmp, title)
        else:
            if format == "xyz":
                x, y = np.meshgrid(surface.x, surface.y, indexing="ij")
                table, delimiter = np.column_stack([x.ravel(), y.ravel(), surface.z.ravel()]), " "
                header = ["XY units: nm", "Value units: nm"]
            else:
                table, delimiter = surface.z.T, "," if path.suffix.lower() == ".csv" else "\t"
                header = [f"Channel: {title}", f"Width: {nx * dx!r} nm", f"Height: {ny * dy!r} nm", "Value units: nm"]
            lines = [f"# {h}" for h in header] + [delimiter.join(repr(float(v)) for v in row) for row in table]
            tmp.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return path
