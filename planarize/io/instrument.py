"""AFM instruments' own files, read through the AFMReader and NSFopen packages (optional extra ``afm``).

AFMReader (https://github.com/AFM-SPM/AFMReader, GPL-3.0, from the team of TopoStats) is the maintained
Python reader of the formats AFM users bring; it returns one channel's heights in nm and the pixel size
in nm, read from the file's own header. NSFopen (MIT, from Nanosurf AG, the instruments' maker) reads NanoSurf
``.nid`` files: heights in the unit each channel's header states, with each channel's scan range and points. Both
are installed with ``pip install "nanodisorder[afm]"``; nanodisorder imports them only when such a file is read and
includes none of their code. Formats read through them:

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
======== =================================== =====================================================

Park Systems ``.tiff`` files are read by neither: open them in Gwyddion and save them as ``.gwy``, which
`planarize.io.load_heights` reads.

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

#: Formats read through AFMReader, by suffix.
SUFFIXES = {".spm": "spm", ".ibw": "ibw", ".jpk": "jpk", ".stp": "stp", ".top": "top", ".nid": "nid"}
#: Channels tried, in order, when none is given (the height channels instruments write, trace first).
HEIGHT_CHANNELS = {
    "spm": ("Height Sensor", "Height"),
    "ibw": ("HeightTrace", "HeightTracee", "HeightRetrace", "ZSensorTrace"),
    "jpk": ("height_trace", "measuredHeight_trace", "height_retrace", "measuredHeight_retrace"),
    "nid": ("Z-Axis Sensor", "Z-Axis", "Topography"),  # (of the forward scan)
}
#: Length units of a NanoSurf channel's header, nm per unit.
_NID_UNITS = {"m": 1e9, "um": 1e3, "µm": 1e3, "nm": 1.0}
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
                    tried = f"no channel {channel!r}" if channel is not None else \
                        f"no height channel ({', '.join(map(repr, names))})"
                    raise InputError(f"{tried}; {missing}") from None
    pixel = float(pixel)
    if not np.isfinite(pixel) or pixel <= 0:
        raise InputError(f"the file states a pixel size of {pixel!r} nm")
    return np.asarray(image, dtype=float), pixel


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
        tried = f"no channel {channel!r}" if channel is not None else \
            f"no height channel ({', '.join(map(repr, names))})"
        raise InputError(f"{tried} in the forward scan; its channels: {', '.join(map(repr, sorted(images.keys()))) or 'none'}")
    header = scans[found]
    units = [str(header.get(key)) for key in ("Dim0Unit", "Dim1Unit", "Dim2Unit")]
    if any(u not in _NID_UNITS for u in units):
        raise InputError(f"channel {found!r} is not a height map in length units (its units: {', '.join(units)})")
    image = np.asarray(images[found], dtype=float) * _NID_UNITS[units[2]]
    lines, points = int(header["Lines"]), int(header["Points"])
    if image.shape != (lines, points):
        raise InputError(f"channel {found!r} holds {' x '.join(map(str, image.shape))} values where its header states "
                         f"{lines} lines of {points} points")
    pixels = (float(header["Dim0Range"]) * _NID_UNITS[units[0]] / points,
              float(header["Dim1Range"]) * _NID_UNITS[units[1]] / lines)
    if not all(np.isfinite(p) and p > 0 for p in pixels):
        raise InputError(f"the file states a pixel size of {pixels[0]!r} x {pixels[1]!r} nm")
    return image, pixels


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


__all__ = ["read_instrument", "SUFFIXES", "HEIGHT_CHANNELS"]
