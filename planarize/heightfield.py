"""`Surface`: a height field on a regular grid, piecewise linear with 4 triangles per cell.

The thesis's surface (section 3.2.1, Fig 3-5): grid points ``(x_i, y_j, z[i, j])``
with ``x_i = i dx`` and ``y_j = j dy``; each cell is split into four triangles
meeting at its centre, whose height is the mean of the cell's four corners.
Lengths are in nm throughout (any unit works if used consistently).

The volume under that surface is exactly linear in the heights: every cell
holds ``dx dy`` times the mean of its corners (Eq 3.4), so the volume is
``sum(w * z)`` with per-point weights ``w`` = the area each point carries:
``dx dy`` inside, half that on an open edge, a quarter in an open corner (the
trapezoid rule). The thesis's "grid area times mean z" treats every point as
interior, which is exact only on a periodic grid, where the grid wraps
around and every point is interior.
"""

from __future__ import annotations

import numpy as np
from scipy.interpolate import CubicSpline

from labrig.validate import InputError, array, choice, count, real, reals

#: Boundary conditions: "open" (a finite sample with edges) or "periodic" (the grid tiles the plane).
BOUNDARIES = ("open", "periodic")
#: Refinement methods: bilinear (the thesis) or tensor-product cubic spline.
REFINE_METHODS = ("linear", "cubic")


#: Most grid points of a surface (4097 x 4097; a fast engine run needs ~1 kB per point).
MAX_POINTS = 4097 * 4097
#: Largest refinement factor of `Surface.refine` (a grid of two points per side refined to the largest grid).
MAX_REFINE = 4096
#: Largest height magnitude, nm (1 m).
MAX_HEIGHT = 1e9
#: Grid spacing range, nm (a hundredth of an angstrom to a metre).
SPACING_RANGE = (1e-3, 1e9)


def _spacing(value) -> tuple[float, float]:
    pair = (value, value) if np.ndim(value) == 0 else value
    dx, dy = reals("spacing", pair, 2, unit="nm")
    for name, v in (("dx", dx), ("dy", dy)):
        real(f"spacing {name}", v, *SPACING_RANGE, unit="nm")
    return dx, dy


def check_heights(z, name: str = "z") -> np.ndarray:
    """``z`` as a finite 2-D float array of 2 x 2 to `MAX_POINTS` points, heights within `MAX_HEIGHT` nm,
    or an `InputError` naming the problem."""
    if isinstance(z, np.ndarray) and z.ndim == 2 and z.size > MAX_POINTS:
        raise InputError(f"{name} has {z.shape[0]} x {z.shape[1]} points, more than the {MAX_POINTS:,} allowed")
    raw = np.asarray(z) if isinstance(z, np.ndarray) or not isinstance(z, (list, tuple)) else None
    if raw is not None and raw.ndim != 2:
        raise InputError(f"{name} must be a 2-D array of heights, got {raw.ndim} dimension(s) {raw.shape}")
    if raw is not None and raw.dtype.kind == "f" and not np.isfinite(raw).all():
        bad = ~np.isfinite(raw)
        i, j = np.argwhere(bad)[0]
        raise InputError(f"{name} has {int(bad.sum())} non-finite height(s) (NaN or inf), the first at [{i}, {j}] "
                         f"= {raw[i, j]}")
    z = np.array(array(name, z, (None, None), limit=MAX_HEIGHT, max_size=MAX_POINTS))
    if z.shape[0] < 2 or z.shape[1] < 2:
        raise InputError(f"{name} must have at least 2 x 2 points, got {z.shape[0]} x {z.shape[1]}")
    return z


class Surface:
    """A height field ``z[i, j]`` at ``(i dx, j dy)``, nm.

    Parameters
    ----------
    z : array_like, shape (nx, ny)
        Heights, nm; finite, at least 2 x 2 points. Axis 0 is x, axis 1 is y.
    spacing : float or (float, float)
        Grid spacing ``dx`` (along axis 0) and ``dy`` (axis 1), nm, > 0.
    boundary : {"open", "periodic"}
        ``"open"``: a finite sample spanning ``(nx - 1) dx`` by ``(ny - 1) dy``.
        ``"periodic"``: the grid repeats with period ``nx dx`` by ``ny dy``
        (point ``nx`` is point 0 again), so there are no edges.

    Notes
    -----
    A Surface is immutable: `z` is a read-only copy, and methods return new
    surfaces.

    Examples
    --------
    >>> s = Surface([[0.0, 0.0], [0.0, 1.0]], spacing=1.0)
    >>> s.volume()
    0.25
    """

    __slots__ = ("_z", "dx", "dy", "boundary")

    def __init__(self, z, spacing=1.0, boundary: str = "open"):
        choice("boundary", boundary, BOUNDARIES)
        self._z = check_heights(z)
        self._z.flags.writeable = False
        self.dx, self.dy = _spacing(spacing)
        self.boundary = boundary

    @property
    def z(self) -> np.ndarray:
        """Heights, nm, shape ``(nx, ny)`` (read-only)."""
        return self._z

    @property
    def shape(self) -> tuple[int, int]:
        return self._z.shape

    @property
    def spacing(self) -> tuple[float, float]:
        return self.dx, self.dy

    @property
    def periodic(self) -> bool:
        return self.boundary == "periodic"

    @property
    def x(self) -> np.ndarray:
        """x coordinate of each row (axis 0), nm."""
        return np.arange(self.shape[0]) * self.dx

    @property
    def y(self) -> np.ndarray:
        """y coordinate of each column (axis 1), nm."""
        return np.arange(self.shape[1]) * self.dy

    @property
    def size(self) -> tuple[float, float]:
        """Extent in x and y, nm: the span of the grid (open) or its period (periodic)."""
        nx, ny = self.shape
        if self.periodic:
            return nx * self.dx, ny * self.dy
        return (nx - 1) * self.dx, (ny - 1) * self.dy

    @property
    def weights(self) -> np.ndarray:
        """Area carried by each point, nm^2: ``volume = sum(weights * z)`` exactly."""
        return volume_weights(self.shape, self.dx, self.dy, self.boundary)

    def volume(self, base: float = 0.0) -> float:
        """Volume between the surface and the plane ``z = base``, nm^3 (exact for this surface)."""
        return float(np.sum(self.weights * (self._z - real("base", base, unit="nm"))))

    def with_heights(self, z) -> Surface:
        """The same grid with new heights."""
        return Surface(z, (self.dx, self.dy), self.boundary)

    def shifted(self, dz: float) -> Surface:
        """The surface moved up by ``dz`` nm."""
        return self.with_heights(self._z + real("dz", dz, -2 * MAX_HEIGHT, 2 * MAX_HEIGHT, unit="nm"))

    def transposed(self) -> Surface:
        """The surface mirrored across the line x = y (axes and spacings swapped)."""
        return Surface(self._z.T, (self.dy, self.dx), self.boundary)

    def refine(self, factor: int, method: str = "linear") -> Surface:
        """The surface resampled on a grid ``factor`` times finer in x and y.

        Parameters
        ----------
        factor : int
            Integer >= 1. An open grid of ``n`` points gets ``(n - 1) factor + 1``
            (the old points are kept); a periodic one gets ``n factor``.
        method : {"linear", "cubic"}
            ``"linear"``: bilinear interpolation between the old points (the
            thesis's refinement; creases at every old grid line). ``"cubic"``:
            tensor-product cubic spline through the old points (not-a-knot ends
            on an open grid, periodic on a periodic one), smooth to the second
            derivative (thesis weakness 3).
        """
        factor = count("factor (grid steps each split into this many)", factor, 1, MAX_REFINE)
        nx, ny = self.shape
        fine = (nx * factor, ny * factor) if self.periodic else ((nx - 1) * factor + 1, (ny - 1) * factor + 1)
        if fine[0] * fine[1] > MAX_POINTS:
            raise InputError(f"refining {nx} x {ny} points by {factor} gives {fine[0]} x {fine[1]} points, more than "
                             f"the {MAX_POINTS:,} a surface may have")
        if method not in REFINE_METHODS:
            raise InputError(f"method must be one of {REFINE_METHODS}, got {method!r}")
        factor = int(factor)
        z = self._z
        for axis in (0, 1):
            z = _refine_axis(z, axis, factor, method, self.periodic)
        return Surface(z, (self.dx / factor, self.dy / factor), self.boundary)

    def __repr__(self) -> str:
        nx, ny = self.shape
        return (f"Surface({nx} x {ny} points, spacing {self.dx:g} x {self.dy:g} nm, {self.boundary}, "
                f"z in [{self._z.min():.6g}, {self._z.max():.6g}] nm)")

    def __eq__(self, other) -> bool:
        if not isinstance(other, Surface):
            return NotImplemented
        return (self.spacing == other.spacing and self.boundary == other.boundary
                and self.shape == other.shape and bool(np.array_equal(self._z, other._z)))

    __hash__ = None  # type: ignore[assignment]  # the unhashable idiom; typeshed types it as a method


def volume_weights(shape: tuple[int, int], dx: float, dy: float, boundary: str = "open") -> np.ndarray:
    """Area each grid point carries in the volume under the surface, nm^2.

    ``dx dy`` for every point of a periodic grid; on an open grid, ``dx dy``
    inside, half on an edge and a quarter in a corner (each cell gives a
    quarter of its area to each of its corners).
    """
    if boundary == "periodic":
        return np.full(shape, dx * dy)
    wx = np.ones(shape[0])
    wx[[0, -1]] = 0.5
    wy = np.ones(shape[1])
    wy[[0, -1]] = 0.5
    return np.outer(wx, wy) * (dx * dy)


def _refine_axis(z: np.ndarray, axis: int, factor: int, method: str, periodic: bool) -> np.ndarray:
    if factor == 1:
        return z
    z = np.moveaxis(z, axis, 0)
    n = z.shape[0]
    if periodic:
        old = np.arange(n + 1, dtype=float)
        new = np.arange(n * factor) / factor
        values = np.concatenate([z, z[:1]])
    else:
        old = np.arange(n, dtype=float)
        new = np.arange((n - 1) * factor + 1) / factor
        values = z
    if method == "linear":
        k = np.minimum(np.floor(new).astype(int), len(old) - 2)
        t = (new - k)[:, None]
        out = (1.0 - t) * values[k] + t * values[k + 1]
    else:
        if periodic:
            bc = "periodic"
        else:
            bc = "not-a-knot" if n >= 4 else "natural"  # not-a-knot needs 4 points
        out = CubicSpline(old, values, axis=0, bc_type=bc)(new)
        # keep the old points bit-identical (the spline reproduces them only to round-off)
        out[::factor] = values[: len(out[::factor])]
    return np.moveaxis(out, 0, axis)
