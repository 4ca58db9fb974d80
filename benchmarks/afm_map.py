"""A rendered AFM height map of a sputtered Ta film, written as a Gwyddion .gwy file as a microscope's
software saves it (no licensed measured map could be had for the benchmarks).

How it is made (`render`): two scales of roughness as in the thesis's Ta film (section 3.4), grains
about 200 nm wide and 30 nm high and deposition roughness about 40 nm wide and 20 nm high, each a
Gaussian-smoothed random field (an AFM tip rounds what it scans, so a measured map is smooth at the
pixel scale, unlike the thesis's linear interpolation); then what a scan adds: a sample tilt of half
a degree, a random height offset per scan line (0.3 nm RMS) and white noise (0.1 nm RMS). The file
holds the height channel in metres with its lateral size, and a phase channel, as Gwyddion writes
them; `planarize import MAP.gwy --level` removes the tilt (the line offsets and noise stay, as in a
real import).

Run: ``python -m benchmarks.afm_map OUT.gwy [--pixels N] [--size NM]``.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
from scipy.ndimage import gaussian_filter

#: (width nm, peak-to-peak height nm) of the Ta film's two scales of roughness (thesis section 3.4).
SCALES = ((200.0, 30.0), (40.0, 20.0))


def render(pixels: int = 512, size: float = 2000.0, seed: int = 0) -> np.ndarray:
    """Heights (nm) of a ``pixels`` x ``pixels`` AFM map ``size`` nm wide (see the module docstring)."""
    rng = np.random.default_rng(seed)
    pixel = size / pixels
    z = np.full((pixels, pixels), 1000.0)
    for width, height in SCALES:
        field = gaussian_filter(rng.normal(size=(pixels, pixels)), sigma=width / 4 / pixel, mode="wrap")
        z += height * field / (field.max() - field.min())
    x = np.arange(pixels) * pixel
    z += np.tan(np.radians(0.5)) * x[:, None]  # the sample's tilt
    z += rng.normal(scale=0.3, size=(1, pixels))  # a height offset per scan line (lines run along x)
    z += rng.normal(scale=0.1, size=z.shape)
    return z


def write_gwy(path: str | Path, z_nm: np.ndarray, pixel_nm: float) -> Path:
    """``z_nm`` (x, y) as a Gwyddion file: SI metres, rows along y, with a phase channel."""
    from gwyfile.objects import GwyContainer, GwyDataField

    nx, ny = z_nm.shape
    container = GwyContainer()
    container["/0/data/title"] = "Height"
    container["/0/data"] = GwyDataField(np.ascontiguousarray(z_nm.T * 1e-9), xreal=nx * pixel_nm * 1e-9,
                                        yreal=ny * pixel_nm * 1e-9, si_unit_xy="m", si_unit_z="m")
    container["/1/data/title"] = "Phase"
    container["/1/data"] = GwyDataField(np.zeros((ny, nx)), xreal=nx * pixel_nm * 1e-9, yreal=ny * pixel_nm * 1e-9,
                                        si_unit_xy="m", si_unit_z="deg")
    path = Path(path)
    container.tofile(str(path))
    return path


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("out", type=Path)
    parser.add_argument("--pixels", type=int, default=512)
    parser.add_argument("--size", type=float, default=2000.0, help="scan size, nm")
    args = parser.parse_args(argv)
    print(write_gwy(args.out, render(args.pixels, args.size), args.size / args.pixels))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
