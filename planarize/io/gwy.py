"""Gwyddion ``.gwy`` files through the ``gwyfile`` package (optional extra ``afm``).

A ``.gwy`` file is a ``GwyContainer`` whose channels are ``GwyDataField``
objects under ``/N/data`` (title at ``/N/data/title``): ``yres`` rows by
``xres`` columns of values, a physical size ``xreal`` by ``yreal`` and SI
units ``si_unit_xy`` and ``si_unit_z`` (heights are usually in metres).
Gwyddion's pixels are areas, so the grid spacing is ``xreal / xres``. Row
``r``, column ``c`` of the image becomes ``z[c, r]`` of a `Surface` (axis 0
is x). Use `planarize.io.load_heights` and `save_heights`; this module holds
the format details.
"""

from __future__ import annotations

import io
import os
import re
from pathlib import Path

import numpy as np

from labrig import validate
from labrig.validate import InputError, count

from ..heightfield import MAX_POINTS, Surface
from .limits import MAX_FILE_BYTES, checked_file
from .units import FILE_UNITS, MAX_COORDINATE, file_unit, given_spacing, unit_scales


def _gwyfile():
    try:
        import gwyfile
    except ImportError:
        raise InputError('reading and writing .gwy files needs the gwyfile package: pip install "nanodisorder[afm]" '
                         "(or pip install gwyfile)") from None
    return gwyfile


def gwy_channels(path) -> list[dict]:
    """The data channels of a ``.gwy`` file: number, title, lateral and value units, shape (rows, columns)."""
    try:
        channels = _channels(_load_gwy(Path(path)))
    except InputError as exc:
        raise InputError(f"{path}: {exc}") from None
    return [{k: v for k, v in c.items() if k != "field"} for c in channels]


def _load_gwy(path: Path):
    """The file's GwyContainer. gwyfile decodes a whole file at once (holding several copies of it), so the
    file's size is checked first and no more than `MAX_FILE_BYTES` ``["gwy"]`` bytes are ever read."""
    gwyfile = _gwyfile()
    limit = MAX_FILE_BYTES["gwy"]
    checked_file(path, "gwy")
    try:
        with open(path, "rb") as stream:
            data = stream.read(limit + 1)  # (the file may have grown since it was checked)
    except OSError as exc:
        raise InputError(f"cannot read the file: {exc.strerror or exc}") from None
    if len(data) > limit:
        raise InputError(f"the file has more than the {limit:,} bytes a gwy height map may have")
    try:
        return gwyfile.load(io.BytesIO(data))  # (BytesIO hands gwyfile these bytes without a copy)
    except Exception as exc:  # gwyfile asserts on a bad magic number and fails on truncated data
        raise InputError(f"not a readable Gwyddion file: {type(exc).__name__} {exc}".rstrip()) from None


def _unit(value) -> str | None:
    return None if value is None else str(value.get("unitstr", "")) if hasattr(value, "get") else str(value)


def _channels(container) -> list[dict]:
    found = []
    for key, field in container.items():
        match = re.fullmatch(r"/(\d+)/data", str(key))
        if match and getattr(field, "name", None) == "GwyDataField":
            number = int(match.group(1))
            shape = tuple(count(f"channel {number} {key}", field.get(key), 1, MAX_POINTS) for key in ("yres", "xres"))
            if shape[0] * shape[1] > MAX_POINTS:
                raise InputError(f"channel {number} has {shape[1]} x {shape[0]} pixels, more than the {MAX_POINTS:,} "
                                 "points a surface may have")
            found.append({"number": number, "title": str(container.get(f"/{number}/data/title", f"channel {number}")),
                          "xy_unit": _unit(field.get("si_unit_xy")), "z_unit": _unit(field.get("si_unit_z")),
                          "shape": shape, "field": field})
    return sorted(found, key=lambda c: c["number"])


def _describe(channels) -> str:
    return ", ".join(f"{c['number']} {c['title']!r} ({c['z_unit'] or 'no unit'})" for c in channels) or "none"


def read_gwy(path, unit, z_unit, spacing, channel):
    """Heights, pixel size and unit scales of one channel (the reader `planarize.io.load_heights` calls)."""
    channels = _channels(_load_gwy(path))
    if not channels:
        raise InputError("the file holds no data channel (GwyDataField)")
    if channel is None:
        # a channel without a unit may be heights: then the user must give the unit
        heights = [c for c in channels if c["z_unit"] in FILE_UNITS] or [c for c in channels if not c["z_unit"]]
        if not heights:
            raise InputError(f"no height channel (values in a length unit); channels: {_describe(channels)}")
        chosen = heights[0]
    else:
        wanted = [c for c in channels if (c["number"] == channel if isinstance(channel, int)
                                          else c["title"].lower() == str(channel).lower())]
        if not wanted:
            raise InputError(f"no channel {channel!r}; channels: {_describe(channels)}")
        chosen = wanted[0]
    label = f"channel {chosen['number']} {chosen['title']!r}"
    try:
        stated_z = None if chosen["z_unit"] is None else file_unit(chosen["z_unit"], f"{label} values")
    except ValueError as exc:
        heights = [c for c in channels if c["z_unit"] in FILE_UNITS]
        raise InputError(f"{exc}: not a height channel; height channels: {_describe(heights)}") from None
    stated_xy = None if chosen["xy_unit"] is None else file_unit(chosen["xy_unit"], f"{label} lateral sizes")
    xy_scale, z_scale = unit_scales(stated_xy, stated_z, unit, z_unit)
    field = chosen["field"]
    ny, nx = chosen["shape"]
    raw = field.get("data")
    if raw is None:
        raise InputError(f"{label} holds no data")
    if not isinstance(raw, np.ndarray) or raw.dtype.kind not in "iuf":
        raise InputError(f"{label}: the data is not an array of numbers")
    if raw.size != nx * ny:
        raise InputError(f"{label}: {raw.size} values for {nx} x {ny} pixels")
    data = np.asarray(raw, dtype=float)  # (xres * yres, checked by _channels, bounds what this allocates)
    real = (field.get("xreal"), field.get("yreal"))
    stated = all(v is not None for v in real)
    given = given_spacing(spacing, stated)
    if stated:
        for name, v in zip(("xreal", "yreal"), real):
            validate.real(f"{label}: {name}", v, 0.0, MAX_COORDINATE, low_open=True)
        pixel = (real[0] / nx, real[1] / ny)
    else:
        pixel = given
    return data.reshape(ny, nx).T, pixel, xy_scale, z_scale


def write_gwy(surface: Surface, target: Path, title: str) -> None:
    """One channel ``title`` in metres with its physical size, as Gwyddion writes height data."""
    objects = _gwyfile().objects
    metres = 1e-9
    (nx, ny), (dx, dy) = surface.shape, surface.spacing
    field = objects.GwyDataField(np.ascontiguousarray(surface.z.T * metres), xreal=nx * dx * metres, yreal=ny * dy * metres,
                         si_unit_xy="m", si_unit_z="m")
    container = objects.GwyContainer()
    container["/0/data/title"] = title
    container["/0/data"] = field
    container.tofile(os.fspath(target))
