"""The thesis's starting surfaces (section 3.4), and a few more for tests and studies.

Every function returns a `planarize.Surface` in nm; random ones take a seed
and are reproducible.
"""

from __future__ import annotations

import numpy as np

from labrig.params import Param
from labrig.validate import InputError, generator

from .heightfield import BOUNDARIES, MAX_HEIGHT, REFINE_METHODS, Surface

#: Most grid points per side a builder lays out before refinement.
MAX_SIDE = 4097
#: Most roughness scales of `random_roughness` (the thesis has 2), each a pass of random heights over the whole
#: grid: widths that shrink from one scale to the next (by 2 or more) fit at most 39 times between the largest
#: width (1e9 nm) and twice the smallest grid spacing (1e-3 nm).
MAX_SCALES = 64



def _length(doc: str, low_open: bool = True, rule: str = "") -> Param:
    """A length in nm, in (0, `MAX_HEIGHT`] (``low_open``) or [0, `MAX_HEIGHT`]."""
    return Param("float", 0.0, MAX_HEIGHT, low_open=low_open, unit="nm", doc=doc, rule=rule)


_REFINE = Param("int", 1, MAX_SIDE, doc="refinement factor (thesis 4: the hill's 17 x 17 points)")
_METHOD = Param("str", choices=REFINE_METHODS, doc='refinement ("linear": the thesis\'s)')
_BOUNDARY = Param("str", choices=BOUNDARIES, doc="edges (\"periodic\": the sample tiles the plane)")
#: The parameters of each builder (`labrig.params.Param`): the builders check their arguments with these, and
#: scene files (`planarize.scene`) state them in their comments.
BUMP = {
    "height": _length("height of the centre point before refinement", low_open=False),
    "base": _length("film thickness around the bump", low_open=False),
    "points": Param("int", 3, MAX_SIDE, doc="grid points per side before refinement",
                    rule="odd (the bump sits on the centre point)"),
    "spacing": _length("grid spacing before refinement"),
    "refine": _REFINE, "method": _METHOD, "boundary": _BOUNDARY,
}
TILTED_PLANE = {
    "slope": Param("float2", -1e6, 1e6, doc="[dz/dx, dz/dy]"),
    "base": _length("height at x = y = 0", low_open=False),
    "points": Param("int", 2, MAX_SIDE, doc="grid points per side"),
    "spacing": _length("grid spacing"),
}
RANDOM_ROUGHNESS = {
    "size": _length("side of the square sample", rule="a whole number of half the widest width"),
    "thickness": _length("mean metal thickness", low_open=False),
    "scales": Param("float2s", 0.0, MAX_HEIGHT, unit="nm", most=MAX_SCALES, doc="[width, height] of each scale",
                    rule="widest first, each width > 0 and dividing the previous one"),
    "refine": _REFINE, "method": _METHOD, "boundary": _BOUNDARY,
}


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
    points = BUMP["points"].check("points", points)
    if points % 2 == 0:
        raise InputError(f"points must be odd (the bump sits on the centre point), got {points}")
    z = np.full((points, points), BUMP["base"].check("base", base))
    z[points // 2, points // 2] = BUMP["height"].check("height", height)
    surface = Surface(z, BUMP["spacing"].check("spacing", spacing), BUMP["boundary"].check("boundary", boundary))
    return surface.refine(BUMP["refine"].check("refine", refine), BUMP["method"].check("method", method))


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
    sx, sy = TILTED_PLANE["slope"].check("slope", slope)
    points = TILTED_PLANE["points"].check("points", points)
    spacing = TILTED_PLANE["spacing"].check("spacing", spacing)
    x = np.arange(points) * spacing
    return Surface(TILTED_PLANE["base"].check("base", base) + sx * x[:, None] + sy * x[None, :], spacing)


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
    params = RANDOM_ROUGHNESS
    boundary = params["boundary"].check("boundary", boundary)
    size = params["size"].check("size", size)
    scales = params["scales"].check("scales", scales)
    if any(width <= 0 for width, _ in scales):
        raise InputError(f"scales must have widths > 0 nm, got {scales!r}")
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
    surface = Surface(np.full((n, n), params["thickness"].check("thickness", thickness)), spacing, boundary)
    for k, (width, height) in enumerate(scales):
        if k:
            factor = spacing / (width / 2.0)
            if abs(factor - round(factor)) > 1e-9 * factor or round(factor) < 1:
                raise InputError(f"each scale width must divide the previous one: {scales[k - 1][0]:g} nm "
                                 f"into {width:g} nm")
            surface = surface.refine(int(round(factor)), "linear")
            spacing = width / 2.0
        surface = surface.with_heights(surface.z + height / 2.0 * (2.0 * rng.random(surface.shape) - 1.0))
    return surface.refine(params["refine"].check("refine", refine), params["method"].check("method", method))
