"""AFM instruments' own files, read through the AFMReader package (optional extra ``afm``).

AFMReader (https://github.com/AFM-SPM/AFMReader, GPL-3.0, from the team of TopoStats) is the maintained
Python reader of the formats AFM users bring; it returns one channel's heights in nm and the pixel size
in nm, read from the file's own header. It is installed with ``pip install "nanodisorder[afm]"``; nanodisorder
imports it only when such a file is read and includes none of its code. Formats read through it:

======== =================================== =====================================================
format   suffixes                            instrument
======== =================================== =====================================================
``spm``  ``.spm`` (Bruker numbered files:    Bruker / Veeco Nanoscope (through pySPM)
         pass ``format="spm"``)
``ibw``  ``.ibw``                            Asylum Research / Oxford Instruments (Igor binary wave)
``jpk``  ``.jpk``                            JPK / Bruker NanoWizard
``stp``  ``.stp``                            WSxM (Nanotec and others), heights as floats
``top``  ``.top``                            WSxM, heights as 16-bit integers
======== =================================== =====================================================

NanoSurf ``.nid`` and Park Systems ``.tiff`` files are not read by AFMReader: open them in Gwyddion and
save them as ``.gwy``, which `planarize.io.load_heights` reads.

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
SUFFIXES = {".spm": "spm", ".ibw": "ibw", ".jpk": "jpk", ".stp": "stp", ".top": "top"}
#: Channels tried, in order, when none is given (the height channels instruments write, trace first).
HEIGHT_CHANNELS = {
    "spm": ("Height Sensor", "Height"),
    "ibw": ("HeightTrace", "HeightTracee", "HeightRetrace", "ZSensorTrace"),
    "jpk": ("height_trace", "measuredHeight_trace", "height_retrace", "measuredHeight_retrace"),
}
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
    image = np.asarray(image, dtype=float)
    if image.ndim != 2 or image.size > MAX_POINTS:
        raise InputError(f"the channel is {' x '.join(map(str, image.shape))} values, not a 2-D map of at most "
                         f"{MAX_POINTS:,} points")
    if format == "top":
        image = _top_span(path, image)
    pixel = float(pixel)
    if not np.isfinite(pixel) or pixel <= 0:
        raise InputError(f"the file states a pixel size of {pixel!r} nm")
    xy_scale, z_scale = unit_scales("nm", "nm", unit, z_unit)
    return image.T, (pixel, pixel), xy_scale, z_scale


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
