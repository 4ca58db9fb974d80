"""AFM instruments' own files, read through the AFMReader, NSFopen and SurfaceTopography packages (optional extra
``afm``).

AFMReader (https://github.com/AFM-SPM/AFMReader, GPL-3.0, from the team of TopoStats) is the maintained
Python reader of the formats AFM users bring; it returns one channel's heights in nm and the pixel size
in nm, read from the file's own header. NSFopen (MIT, from Nanosurf AG, the instruments' maker) reads NanoSurf
``.nid`` files: heights in the unit each channel's header states, with each channel's scan range and points.
SurfaceTopography (https://github.com/ContactEngineering/SurfaceTopography, MIT, maintained by the team of
contact.engineering) reads Park Systems ``.tiff`` and Agilent / Keysight PicoView ``.mi`` files, which neither
of the others reads: heights and sizes in the unit the file states. All three are installed with
``pip install "nanodisorder[afm]"``; nanodisorder imports them only when such a file is read and includes none of
their code. Formats read through them:

======== =================================== =====================================================
format   suffixes                            instrument
======== =================================== =====================================================
``spm``  ``.spm`` (Bruker numbered files:    Bruker / Veeco Nanoscope (through pySPM)
         pass ``format="spm"``)
``ibw``  ``.ibw``                            Asylum Research / Oxford Instruments (Igor binary wave)
``jpk``  ``.jpk``                            JPK / Bruker NanoWizard
``stp``  ``.stp``                            WSxM (Nanotec and others), heights as floats
``top``  ``.top``                            WSxM, heights as 16-bit integers
``nid``  ``.nid``                            NanoSurf (through NSFopen)
``park`` ``.tiff``, ``.tif``                 Park Systems (XE, NX; through SurfaceTopography)
``mi``   ``.mi``                             Agilent / Keysight / Molecular Imaging PicoView (through
                                             SurfaceTopography)
======== =================================== =====================================================

SurfaceTopography returns a scan with its first row at the bottom of the picture (``heights[x, y]``, ``y`` up);
both files store their lines from the bottom up. The map is taken as the picture shows it: on the Park sample
file, its heights averaged over 2 x 2 pixels correlate at 0.995 with the 256 x 256 preview the instrument stores
in the same TIFF, and at 0.04 mirrored.

AFMReader 0.0.7 reads a ``.top`` file's height span (``Z Amplitude: 59.7449 nm``) as its integer part
(59 nm), so its heights come out 1-12 % short on the sample files (measured against the ``.stp`` export of
the same scan, which stores floats); `read_instrument` rescales them to the span the header states.
"""

from __future__ import annotations

import contextlib
import gc
import re
import warnings
from pathlib import Path

import numpy as np

from labrig.validate import InputError

from ..heightfield import MAX_POINTS
from .limits import checked_file
from .units import given_spacing, unit_scales

#: Formats read through AFMReader, NSFopen and SurfaceTopography, by suffix.
SUFFIXES = {".spm": "spm", ".ibw": "ibw", ".jpk": "jpk", ".stp": "stp", ".top": "top", ".nid": "nid",
            ".tiff": "park", ".tif": "park", ".mi": "mi"}
#: Formats read through SurfaceTopography: its name of each.
SURFACE_TOPOGRAPHY_FORMATS = {"park": "ps", "mi": "mi"}
#: Channels tried, in order, when none is given (the height channels instruments write, trace first).
HEIGHT_CHANNELS = {
    "spm": ("Height Sensor", "Height"),
    "ibw": ("HeightTrace", "HeightTracee", "HeightRetrace", "ZSensorTrace"),
    "jpk": ("height_trace", "measuredHeight_trace", "height_retrace", "measuredHeight_retrace"),
    "nid": ("Z-Axis Sensor", "Z-Axis", "Topography"),  # (of the forward scan)
    "park": ("Z Height", "Topography", "Z Detector", "Height"),
    "mi": ("Topography", "Height"),
}
#: Length units of a NanoSurf channel's header and of SurfaceTopography's channels, nm per unit.
_FILE_UNITS = {"m": 1e9, "mm": 1e6, "um": 1e3, "µm": 1e3, "nm": 1.0, "Å": 0.1, "pm": 1e-3}
#: WSxM height spans in the header of a ``.top`` file, nm per unit.
_WSXM_UNITS = {"nm": 1.0, "Å": 0.1, "pm": 1e-3, "µm": 1e3, "um": 1e3}


def _module(format: str):
    try:
        import AFMReader  # noqa: F401  (the package, to tell a missing install from a broken one)
    except ImportError:
        raise InputError(f'reading .{format} files needs the AFMReader package: pip install "nanodisorder[afm]" '
                         "(or pip install AFMReader)") from None
    import importlib

    from loguru import logger

    module = importlib.import_module(f"AFMReader.{format}")
    logger.disable("AFMReader")  # (it logs every file it opens to stderr; each module enables that on import)
    return module


def read_instrument(path: Path, format: str, unit, z_unit, spacing, channel):
    """Heights, pixel size and unit scales of one channel of an instrument's file (the reader
    `planarize.io.load_heights` calls; see the module docstring). AFMReader states sizes and heights in nm."""
    checked_file(path, format)  # within the format's size cap before AFMReader opens it
    given_spacing(spacing, stated=True)
    if channel is not None and format in ("stp", "top"):
        raise InputError(f"a WSxM .{format} file holds one channel: leave channel unset")
    if isinstance(channel, int):
        raise InputError(f"channel of a .{format} file is its name (a number picks a .gwy channel), got {channel}")
    if format == "nid":
        image, pixels = _read_nid(path, channel)
    elif format in SURFACE_TOPOGRAPHY_FORMATS:
        image, pixels = _read_surface_topography(path, format, channel)
    else:
        image, pixel = _read_afmreader(path, format, channel)
        pixels = (pixel, pixel)
    if image.ndim != 2 or image.size > MAX_POINTS:
        raise InputError(f"the channel is {' x '.join(map(str, image.shape))} values, not a 2-D map of at most "
                         f"{MAX_POINTS:,} points")
    if format == "top":
        image = _top_span(path, image)
    xy_scale, z_scale = unit_scales("nm", "nm", unit, z_unit)
    return image.T, pixels, xy_scale, z_scale


def _read_afmreader(path: Path, format: str, channel: str | None) -> tuple[np.ndarray, float]:
    """One channel of a file AFMReader reads (its height channel by default), heights in nm, and its pixel size, nm."""
    module = _module(format)
    load = getattr(module, f"load_{format}")
    if format in ("stp", "top"):
        image, pixel = _call(load, path)
    else:
        names = (channel,) if channel is not None else HEIGHT_CHANNELS[format]
        for k, name in enumerate(names):
            try:
                image, pixel = _call(load, path, name)
                break
            except _ChannelMissing as missing:
                if k == len(names) - 1:
                    raise _no_channel(channel, names, f"; {missing}") from None
    pixel = float(pixel)
    if not np.isfinite(pixel) or pixel <= 0:
        raise InputError(f"the file states a pixel size of {pixel!r} nm")
    return np.asarray(image, dtype=float), pixel


def _listed(names) -> str:
    """Names as a list of their reprs, or 'none'."""
    return ", ".join(map(repr, names)) or "none"


def _no_channel(channel: str | None, names, rest: str) -> InputError:
    """The one-line refusal of a file without the ``channel`` asked for (or, when none is, without any of the height
    channels ``names``), followed by ``rest`` (what the file holds)."""
    tried = f"no channel {channel!r}" if channel is not None else f"no height channel ({_listed(names)})"
    return InputError(f"{tried}{rest}")


def _read_nid(path: Path, channel: str | None) -> tuple[np.ndarray, tuple[float, float]]:
    """One forward-scan channel of a NanoSurf ``.nid`` file (NSFopen), heights in nm as (lines, points), and its
    pixel size (along a line, across lines) in nm from that channel's own header (its ``Dim0Range`` over its points,
    its ``Dim1Range`` over its lines)."""
    try:
        from NSFopen.read import nid_read
    except ImportError:
        raise InputError('reading .nid files needs the NSFopen package: pip install "nanodisorder[afm]" '
                         "(or pip install NSFopen)") from None
    try:
        with contextlib.redirect_stdout(None), warnings.catch_warnings():  # (pandas warns of NSFopen's calls)
            warnings.simplefilter("ignore")
            nid = nid_read(str(path), verbose=False)
        scans = {h.get("Dim2Name"): h for name, h in nid.param["HeaderDump"].items()
                 if name.startswith("DataSet-") and isinstance(h, dict) and h.get("Frame") == "Scan forward"}
        images = nid.data["Image"]["Forward"] if scans else {}
    except Exception as exc:  # a truncated or foreign file fails anywhere inside the parser
        raise InputError(f"NSFopen cannot read the file: {type(exc).__name__} {exc}".rstrip()) from None
    names = (channel,) if channel is not None else HEIGHT_CHANNELS["nid"]
    found = next((name for name in names if name in scans and name in images), None)
    if found is None:
        raise _no_channel(channel, names, f" in the forward scan; its channels: {_listed(sorted(images.keys()))}")
    header = scans[found]
    units = [str(header.get(key)) for key in ("Dim0Unit", "Dim1Unit", "Dim2Unit")]
    if any(u not in _FILE_UNITS for u in units):
        raise InputError(f"channel {found!r} is not a height map in length units (its units: {', '.join(units)})")
    image = np.asarray(images[found], dtype=float) * _FILE_UNITS[units[2]]
    lines, points = int(header["Lines"]), int(header["Points"])
    if image.shape != (lines, points):
        raise InputError(f"channel {found!r} holds {' x '.join(map(str, image.shape))} values where its header states "
                         f"{lines} lines of {points} points")
    pixels = (float(header["Dim0Range"]) * _FILE_UNITS[units[0]] / points,
              float(header["Dim1Range"]) * _FILE_UNITS[units[1]] / lines)
    if not all(np.isfinite(p) and p > 0 for p in pixels):
        raise InputError(f"the file states a pixel size of {pixels[0]!r} x {pixels[1]!r} nm")
    return image, pixels


def _read_surface_topography(path: Path, format: str, channel: str | None) -> tuple[np.ndarray, tuple[float, float]]:
    """One channel of a Park Systems ``.tiff`` or PicoView ``.mi`` file (SurfaceTopography), heights in nm as the
    picture shows them (lines, points), and its pixel size (along a line, across lines) in nm from the file's
    scan size and points. The channel's size is checked before its heights are read."""
    try:
        from SurfaceTopography.IO import open_topography
    except ImportError:
        raise InputError(f'reading .{format} files needs the SurfaceTopography package: pip install '
                         '"nanodisorder[afm]" (or pip install SurfaceTopography)') from None
    what = {"park": "a Park Systems TIFF", "mi": "a PicoView .mi file"}[format]
    try:
        with contextlib.redirect_stdout(None), warnings.catch_warnings():
            warnings.simplefilter("ignore")
            reader = open_topography(str(path), format=SURFACE_TOPOGRAPHY_FORMATS[format])
            channels: dict = {}
            for each in reader.channels:  # (the first of a name: a .mi file holds a Friction trace and retrace)
                channels.setdefault(each.name, each)
    except Exception as exc:  # a foreign or truncated file fails anywhere inside the parser
        raise InputError(f"SurfaceTopography cannot read the file as {what}: {type(exc).__name__} {exc}".rstrip()) \
            from None
    names = (channel,) if channel is not None else HEIGHT_CHANNELS[format]
    found = next((name for name in names if name in channels), None)
    if found is None:
        raise _no_channel(channel, names, f"; its channels: {_listed(channels)}")
    chosen = channels[found]
    unit, data_unit = str(chosen.unit), str(getattr(chosen, "data_unit", chosen.unit))
    if unit not in _FILE_UNITS or data_unit != unit:  # (a deflection or friction channel: its values in V)
        raise InputError(f"channel {found!r} is not a height map in length units (its unit: {data_unit})")
    points, lines = (int(n) for n in chosen.nb_grid_pts)
    if points * lines > MAX_POINTS:
        raise InputError(f"the channel is {lines} x {points} values, not a 2-D map of at most {MAX_POINTS:,} points")
    try:
        with contextlib.redirect_stdout(None), warnings.catch_warnings():
            warnings.simplefilter("ignore")
            topography = chosen.topography()
            heights = np.asarray(topography.heights(), dtype=float)
            sizes = tuple(float(s) for s in topography.physical_sizes)
    except Exception as exc:
        raise InputError(f"SurfaceTopography cannot read channel {found!r}: {type(exc).__name__} {exc}".rstrip()) \
            from None
    if str(topography.unit) != unit or heights.shape != (points, lines):
        raise InputError(f"channel {found!r} holds {' x '.join(map(str, heights.shape))} values in "
                         f"{topography.unit} where its header states {points} x {lines} in {unit}")
    pixels = (sizes[0] * _FILE_UNITS[unit] / points, sizes[1] * _FILE_UNITS[unit] / lines)
    if not all(np.isfinite(p) and p > 0 for p in pixels):
        raise InputError(f"the file states a pixel size of {pixels[0]!r} x {pixels[1]!r} nm")
    return heights.T * _FILE_UNITS[unit], pixels


class _ChannelMissing(Exception):
    pass


def _call(load, path: Path, *channel):
    """AFMReader's ``load`` on ``path``; its errors as one-line `InputError`, a missing channel as
    `_ChannelMissing` carrying the file's channel list."""
    try:
        with contextlib.redirect_stdout(None), warnings.catch_warnings():  # (pySPM prints while it reads)
            warnings.simplefilter("ignore", ResourceWarning)
            try:
                return load(path, *channel)[:2]
            finally:
                gc.collect()  # AFMReader 0.0.7 leaves .jpk files open: closed here, without a warning
    except (ValueError, KeyError) as exc:
        text = str(exc).strip().strip('"')
        if channel and ("not in" in text or "not found" in text) and "channel" in text:
            raise _ChannelMissing(text[text.find("channel list"):] if "channel list" in text else text) from None
        raise InputError(f"AFMReader cannot read the file: {text or type(exc).__name__}") from None
    except Exception as exc:  # a truncated or foreign file fails anywhere inside the format's parser
        raise InputError(f"AFMReader cannot read the file: {type(exc).__name__} {exc}".rstrip()) from None


def _top_span(path: Path, image: np.ndarray) -> np.ndarray:
    """``image`` (AFMReader's: the 16-bit values stretched to 0 ... int(span)) stretched to the header's span."""
    with open(path, "rb") as stream:
        head = stream.read(1 << 16).decode("latin-1")
    match = re.search(r"Z Amplitude:\s*([0-9.eE+-]+)\s*(nm|Å|pm|µm|um)", head)
    if match is None:
        raise InputError("the WSxM header states no 'Z Amplitude' (the height span) in a length unit")
    span = float(match.group(1)) * _WSXM_UNITS[match.group(2)]
    top = float(image.max() - image.min())
    if not np.isfinite(span) or span < 0:
        raise InputError(f"the WSxM header states a height span of {match.group(0)!r}")
    if top == 0.0:
        if span > 0:
            raise InputError(f"AFMReader reads this .top file flat (its span {match.group(1)} {match.group(2)} is under "
                             "1 nm, which it truncates to 0): export it as .stp")
        return image
    return (image - image.min()) * (span / top)


__all__ = ["read_instrument", "SUFFIXES", "HEIGHT_CHANNELS", "SURFACE_TOPOGRAPHY_FORMATS"]
