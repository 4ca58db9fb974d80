"""The thesis's starting surfaces (section 3.4), and a few more for tests and studies.

Every function returns a `planarize.Surface` in nm; random ones take a seed
and are reproducible.
"""

from __future__ import annotations

import numpy as np

from labrig.validate import InputError, count, generator, real, reals

from .heightfield import BOUNDARIES, MAX_HEIGHT, Surface

#: Most grid points per side a builder lays out before refinement.
MAX_SIDE = 4097
#: Most roughness scales of `random_roughness` (the thesis has 2), each a pass of random heights over the whole
#: grid: widths that shrink from one scale to the next (by 2 or more) fit at most 39 times between the largest
#: width (1e9 nm) and twice the smallest grid spacing (1e-3 nm).
MAX_SCALES = 64


def _check(name: str, value, low: float = 0.0, low_open: bool = True) -> float:
    return real(name, value, low, MAX_HEIGHT, low_open=low_open, unit="nm")


def _count(name: str, value, low: int) -> int:
    return count(name, value, low, MAX_SIDE)


def bump(height: float = 4.5, *, base: float = 4.0, points: int = 5, spacing: float = 1.0, refine: int = 4,
         method: str = "linear", boundary: str = "open") -> Surface:
    """A flat film with its centre grid point raised or lowered, then refined (thesis Fig 3-8).

    Parameters
    ----------
    height : float
        Height of the centre point before refinement, nm (thesis: 4.5 for the
        hill, 3.5 for the depression).
    base : float
        Film thickness elsewhere, nm (thesis 4).
    points : int
        Grid points per side before refinement, odd (thesis 5).
    spacing : float
        Grid spacing before refinement, nm (thesis 1).
    refine : int
        Refinement factor (thesis 4: 17 x 17 points, 0.25 nm apart).
    method : {"linear", "cubic"}
        Refinement (`Surface.refine`); linear turns the raised point into a
        pyramid ``2 spacing`` wide.
    """
    points = _count("points", points, 3)
    if points % 2 == 0:
        raise InputError(f"points must be odd (the bump sits on the centre point), got {points}")
    z = np.full((points, points), _check("base", base, low_open=False))
    z[points // 2, points // 2] = _check("height", height, low_open=False)
    return Surface(z, _check("spacing", spacing), boundary).refine(_count("refine", refine, 1), method)


def hill(**kwargs) -> Surface:
    """The thesis's hill: 4 nm film, centre point 4.5 nm, 5 x 5 grid at 1 nm refined 4x (see `bump`)."""
    return bump(4.5, **kwargs)


def depression(**kwargs) -> Surface:
    """The thesis's depression: the hill's mirror image, centre point 3.5 nm (see `bump`)."""
    return bump(3.5, **kwargs)


def tilted_plane(slope: tuple[float, float] = (0.2, 0.0), *, base: float = 4.0, points: int = 17,
                 spacing: float = 0.25) -> Surface:
    """A flat film tilted by ``slope`` = (dz/dx, dz/dy); anodization should leave its shape unchanged.

    Open boundary only: a tilted plane is not periodic.
    """
    sx, sy = reals("slope", slope, 2, -1e6, 1e6)
    points = _count("points", points, 2)
    spacing = _check("spacing", spacing)
    x = np.arange(points) * spacing
    return Surface(_check("base", base, low_open=False) + sx * x[:, None] + sy * x[None, :], spacing)


#: The thesis's tantalum roughness (section 3.4): (width, height) of each scale, nm, largest first.
TA_SCALES = ((200.0, 30.0), (40.0, 20.0))


def random_roughness(size: float = 500.0, *, thickness: float = 1000.0, scales=TA_SCALES, refine: int = 4,
                     method: str = "linear", boundary: str = "open", seed: int = 0) -> Surface:
    """Multi-scale random roughness by the thesis's procedure (section 3.4, the Ta film).

    1. A grid with spacing half the widest feature, all at ``thickness``.
    2. Add uniform random heights in ``[-h/2, h/2]`` for that scale's height ``h``.
    3. Refine (linearly) to half the next feature's width and add its heights; repeat.
    4. Refine ``refine`` times more with ``method``.

    Parameters
    ----------
    size : float
        Side of the square sample, nm (thesis 500); must be a whole number of
        the first grid spacing.
    thickness : float
        Mean metal thickness, nm (thesis 1000).
    scales : sequence of (width, height)
        Feature widths and heights, nm, widest first; each width must divide
        the previous one into a whole number of parts (thesis ``TA_SCALES``:
        200 / 30 then 40 / 20).
    refine : int
        Final refinement factor (thesis 4).
    method : {"linear", "cubic"}
        Final refinement (the intermediate ones are linear, as in the thesis).
    boundary : {"open", "periodic"}
        Periodic samples tile the plane (no edges; random heights wrap).
    seed : int
        Seed of the random heights.
    """
    if boundary not in BOUNDARIES:
        raise InputError(f"boundary must be one of {BOUNDARIES}, got {boundary!r}")
    size = _check("size", size)
    if isinstance(scales, (str, bytes, dict)) or not hasattr(scales, "__len__"):
        raise InputError(f"scales must be a list of (width, height) pairs in nm, widest first, got {scales!r}")
    if len(scales) == 0:
        raise InputError("scales must hold at least one (width, height) pair")
    if len(scales) > MAX_SCALES:
        raise InputError(f"scales must hold at most {MAX_SCALES} (width, height) pairs, got {len(scales):,}")
    try:
        scales = [(_check("scale width", w), _check("scale height", h, low_open=False)) for w, h in scales]
    except (TypeError, ValueError) as exc:
        raise InputError(f"scales must be (width, height) pairs in nm, widest first: {exc}") from None
    rng = generator("seed", seed)
    spacing = scales[0][0] / 2.0
    cells = size / spacing
    if abs(cells - round(cells)) > 1e-9 * cells or round(cells) < 1:
        raise InputError(f"size ({size:g} nm) must be a whole number of half the widest width ({spacing:g} nm)")
    if boundary == "periodic" and round(cells) < 2:
        raise InputError(f"a periodic sample must span at least two of the widest grid cells "
                         f"(size >= {2 * spacing:g} nm), got size {size:g} nm")
    n = int(round(cells)) + (0 if boundary == "periodic" else 1)
    if n > MAX_SIDE:
        raise InputError(f"size / (widest width / 2) = {n} grid points per side, more than the {MAX_SIDE} allowed")
    surface = Surface(np.full((n, n), _check("thickness", thickness, low_open=False)), spacing, boundary)
    for k, (width, height) in enumerate(scales):
        if k:
            factor = spacing / (width / 2.0)
            if abs(factor - round(factor)) > 1e-9 * factor or round(factor) < 1:
                raise InputError(f"each scale width must divide the previous one: {scales[k - 1][0]:g} nm "
                                 f"into {width:g} nm")
            surface = surface.refine(int(round(factor)), "linear")
            spacing = width / 2.0
        surface = surface.with_heights(surface.z + height / 2.0 * (2.0 * rng.random(surface.shape) - 1.0))
    return surface.refine(_count("refine", refine, 1), method)
