"""Reading a micrograph: one grey image and its scale, through the ecosystem's readers.

Formats and readers (none hand-written):

=====================================  ===========================================================
``.tif``, ``.tiff`` (8/16/32-bit,      tifffile; the scale from the instrument's own tag (FEI/Thermo
multi-page)                            ``PixelWidth``, Zeiss SEM ``Image Pixel Size``, Olympus SIS),
                                       else ImageJ metadata (``unit`` with the X resolution)
``.png``, ``.jpg``, ``.jpeg``,         Pillow (through which imageio reads these); no scale
``.bmp``, ``.gif``
``.dm3``, ``.dm4`` (Gatan), ``.emd``,  rosettasciio (``pip install "qdots[microscope]"``); the
``.ser`` (FEI TIA)                     scale from the file's calibrated axes
=====================================  ===========================================================

Each reader is asked for the image's declared size first; an image of more than `MAX_PIXELS`
pixels (or a side of more than `MAX_SIDE`) is refused before its pixels are read. Colour is
turned into grey as the mean of the channels; the result is float64. `Micrograph.scale_source` says
where the file's scale was read (`tiff_scale`).
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass
from pathlib import Path
from typing import cast

import numpy as np

from labrig.files import existing_file
from labrig.validate import InputError, count

from .choices import MICROSCOPE, TIFF, unknown_suffix

#: Smallest and largest image side, px (a particle and its background need more than a few pixels), and largest
#: number of pixels (a 8192 x 8192 image; float64: 512 MiB).
MIN_SIDE, MAX_SIDE = 16, 65_536
MAX_PIXELS = 8192 * 8192
#: nm in one unit of a file's scale.
UNIT_NM = {"nm": 1.0, "nanometer": 1.0, "nanometre": 1.0, "um": 1e3, "µm": 1e3, "micron": 1e3,
           "microns": 1e3, "micrometer": 1e3, "micrometre": 1e3, "mm": 1e6, "m": 1e9, "pm": 1e-3, "a": 0.1, "å": 0.1,
           "angstrom": 0.1}


@dataclass(frozen=True)
class Micrograph:
    """A grey image and what its file says about it.

    Attributes
    ----------
    pixels : ndarray, shape (H, W), float64
        Grey values as stored (not rescaled); row 0 is the top of the picture.
    nm_per_px : float or None
        The file's own scale, nm per pixel, or None when it has none.
    source : str
        The file's name.
    page : int
        Which page (or image) of the file this is.
    pages : int
        How many the file holds.
    scale_source : str
        Where in the file ``nm_per_px`` was read (such as ``"the Zeiss SEM tag (Image Pixel Size 4.466 nm)"``),
        or ``""``.
    """

    pixels: np.ndarray
    nm_per_px: float | None
    source: str
    page: int = 0
    pages: int = 1
    scale_source: str = ""

    @property
    def shape(self) -> tuple[int, int]:
        return self.pixels.shape


def check_size(height: int, width: int, path) -> None:
    """Refuse an image of `MAX_PIXELS` pixels or more, or of a side outside [`MIN_SIDE`, `MAX_SIDE`], before reading
    it."""
    if height < MIN_SIDE or width < MIN_SIDE:
        raise InputError(f"{path}: the image is {width} x {height} px; a micrograph needs at least "
                         f"{MIN_SIDE} x {MIN_SIDE} px")
    if height > MAX_SIDE or width > MAX_SIDE or height * width > MAX_PIXELS:
        raise InputError(f"{path}: the image declares {width} x {height} px, more than the {MAX_PIXELS:,} pixels "
                         f"(sides <= {MAX_SIDE:,}) allowed; crop or bin it first")


def nm_per_unit(unit) -> float | None:
    """nm in one ``unit`` (a length unit's name as files write it), or None when it is not a length."""
    if not isinstance(unit, str):
        return None
    return UNIT_NM.get(unit.strip().lower())


def grey(pixels: np.ndarray, path) -> np.ndarray:
    """``pixels`` as a 2-D float64 grey image: colour channels (last axis of 3 or 4) averaged, alpha dropped."""
    a = np.asarray(pixels)
    if a.ndim == 3 and a.shape[-1] in (3, 4):
        a = a[..., :3].astype(float).mean(axis=-1)
    if a.ndim != 2:
        raise InputError(f"{path}: expected a 2-D grey or colour image, got an array of shape {a.shape}")
    if not np.issubdtype(a.dtype, np.number) or np.issubdtype(a.dtype, np.complexfloating):
        raise InputError(f"{path}: pixels of type {a.dtype} are not grey values")
    return a.astype(float)


def scale_in(value, unit) -> float | None:
    """``value`` ``unit`` (a length unit's name) in nm, or None when either is not a positive finite length."""
    per_unit = nm_per_unit(unit)
    try:
        value = float(value)
    except (TypeError, ValueError):
        return None
    if per_unit is None or not (math.isfinite(value) and value > 0):
        return None
    return value * per_unit


def tiff_scale(tif, page) -> tuple[float | None, str]:
    """The scale a TIFF states (nm per px) and where: the instrument's own tag first (FEI/Thermo ``[Scan]
    PixelWidth``, m; Zeiss SEM ``Image Pixel Size`` or ``Pixel Size``; Olympus SIS ``pixelsizex``, m), then ImageJ
    metadata (``unit`` and the X resolution, pixels per unit). ``(None, "")`` when it states none."""
    fei = tif.fei_metadata or {}
    for section in ("Scan", "EScan"):
        value = scale_in((fei.get(section) or {}).get("PixelWidth"), "m")
        if value is not None:
            return value, f"the FEI/Thermo tag ([{section}] PixelWidth {value:.4g} nm)"
    zeiss = tif.sem_metadata or {}
    for key in ("ap_image_pixel_size", "ap_pixel_size"):
        entry = zeiss.get(key)
        if isinstance(entry, tuple) and len(entry) == 3:
            value = scale_in(entry[1], entry[2])
            if value is not None:
                return value, f"the Zeiss SEM tag ({entry[0]} {entry[1]} {entry[2]})"
    sis = tif.sis_metadata or {}
    value = scale_in(sis.get("pixelsizex"), "m")
    if value is not None:
        return value, f"the Olympus SIS tag (pixel size {value:.4g} nm)"
    imagej = tif.imagej_metadata or {}
    per_unit = nm_per_unit(imagej.get("unit"))
    resolution = page.tags.get("XResolution")
    if per_unit is not None and resolution is not None:
        numerator, denominator = resolution.value
        if numerator > 0 and denominator > 0:
            value = per_unit * denominator / numerator  # the tag is pixels per unit
            return value, f"ImageJ metadata ({numerator / denominator:.6g} px per {imagej.get('unit')})"
    return None, ""


def _read_tiff(path: Path, page: int) -> tuple[np.ndarray, float | None, int, str]:
    import tifffile

    with tifffile.TiffFile(path) as tif:
        pages = len(tif.pages)
        page = count("page", page, 0, pages - 1)
        tiff_page = tif.pages[page]
        shape = tiff_page.shape
        height, width = (shape[0], shape[1]) if len(shape) >= 2 else (1, shape[0] if shape else 0)
        if len(shape) >= 3 and shape[0] in (3, 4) and shape[-1] not in (3, 4):  # planar colour
            height, width = shape[1], shape[2]
        check_size(height, width, path)
        pixels = tiff_page.asarray()
        if pixels.ndim == 3 and pixels.shape[0] in (3, 4) and pixels.shape[-1] not in (3, 4):
            pixels = np.moveaxis(pixels, 0, -1)
        scale, where = tiff_scale(tif, tiff_page)
    return pixels, scale, pages, where


def _read_pillow(path: Path, page: int) -> tuple[np.ndarray, None, int, str]:
    from PIL import Image

    try:
        image: Image.Image = Image.open(path)  # reads the header only
    except Image.DecompressionBombError:  # Pillow's own bound, twice its MAX_IMAGE_PIXELS, above ours
        raise InputError(f"{path}: the image declares more than {2 * cast(int, Image.MAX_IMAGE_PIXELS):,} pixels; at most "
                         f"{MAX_PIXELS:,} are read (crop or bin it first)") from None
    with image:
        width, height = image.size
        check_size(height, width, path)
        pages = getattr(image, "n_frames", 1)
        image.seek(count("page", page, 0, pages - 1))
        image.load()
        if image.mode == "P":
            image = image.convert("RGB")
        pixels = np.asarray(image)
    return pixels, None, pages, ""


def _read_microscope(path: Path, page: int) -> tuple[np.ndarray, float | None, int, str]:
    import importlib

    try:
        reader = importlib.import_module(f"rsciio.{MICROSCOPE[path.suffix.lower()]}").file_reader
    except ImportError:
        raise InputError(f"{path}: reading {path.suffix} files needs rosettasciio: pip install \"qdots[microscope]\""
                         ) from None
    signals = [s for s in reader(str(path), lazy=True) if np.ndim(s["data"]) >= 2]
    if not signals:
        raise InputError(f"{path}: the file holds no 2-D image")
    signal = signals[count("page", page, 0, len(signals) - 1)]
    data = signal["data"]
    if data.ndim != 2:
        raise InputError(f"{path}: image {page} has shape {tuple(data.shape)}; qdots measures 2-D images "
                         "(pick one frame of a stack first)")
    check_size(int(data.shape[0]), int(data.shape[1]), path)
    pixels = np.asarray(data.compute() if hasattr(data, "compute") else data)
    axes = signal.get("axes", [])
    scale = None
    if len(axes) >= 2:
        step = axes[-1].get("scale")
        scale = scale_in(step, axes[-1].get("units")) if isinstance(step, (int, float)) else None
    where = f"the file's calibrated axes ({axes[-1].get('units')})" if scale is not None else ""
    return pixels, scale, len(signals), where


def read_micrograph(path: str | os.PathLike, page: int = 0) -> Micrograph:
    """Read one grey image (and its scale, when the file has one) from a micrograph file.

    Parameters
    ----------
    path : path-like
        A TIFF, PNG, JPEG, BMP or GIF image, or a Gatan (.dm3, .dm4), EMD or TIA (.ser) file.
    page : int
        Which page of a multi-page file (default the first).

    Returns
    -------
    Micrograph

    Raises
    ------
    labrig.validate.InputError
        One line naming what is wrong: not an image, a truncated file, too small or too large an
        image (refused before its pixels are read), constant or all-NaN pixels.
    """
    path = existing_file(path, "micrograph")
    unknown = unknown_suffix(path.name)
    if unknown is not None:
        raise InputError(unknown)
    suffix = path.suffix.lower()
    try:
        if suffix in TIFF:
            pixels, scale, pages, where = _read_tiff(path, page)
        elif suffix in MICROSCOPE:
            pixels, scale, pages, where = _read_microscope(path, page)
        else:
            pixels, scale, pages, where = _read_pillow(path, page)
    except InputError:
        raise
    except (OSError, ValueError, SyntaxError, EOFError, KeyError, IndexError, TypeError) as exc:
        raise InputError(f"{path}: not a readable image: {type(exc).__name__}: "
                         f"{str(exc).splitlines()[0] if str(exc) else 'no details'}") from None
    image = grey(pixels, path)
    height, width = image.shape  # `grey` returns a 2-D image
    check_size(height, width, path)
    finite = np.isfinite(image)
    if not finite.any():
        raise InputError(f"{path}: every pixel is NaN or infinite")
    if not finite.all():
        raise InputError(f"{path}: {int(image.size - finite.sum()):,} pixels are NaN or infinite; "
                         "fill or crop them out first")
    if float(image.max()) == float(image.min()):
        raise InputError(f"{path}: every pixel has the value {float(image.min()):g}: there is nothing to measure")
    return Micrograph(image, scale, path.name, int(page), int(pages), where)
