"""`Scene`: what exists on the board, as plain validated data.

A scene is the board (a rectangle with optional hard edges), static line
segments (walls, grating lines) and the dots (positions, radii, masses,
velocities), plus the collision rule. It holds no engine state; a
`qdots.Simulation` is built from it.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field

import numpy as np
from scipy.spatial import cKDTree

from labrig.validate import InputError

from .collisions import Restitution


def _as_float_array(name: str, value: object, shape: tuple[int | None, ...]) -> np.ndarray:
    """Copy ``value`` to a read-only float64 array, checking shape and finiteness."""
    try:
        arr = np.array(value, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise InputError(f"{name} must be numeric: {exc}") from None
    if arr.size == 0 and len(shape) == 2:
        arr = arr.reshape(0, shape[1])
    if arr.ndim != len(shape) or any(want is not None and got != want for got, want in zip(arr.shape, shape)):
        want = "(" + ", ".join("N" if s is None else str(s) for s in shape) + ")"
        raise InputError(f"{name} must have shape {want}, got {arr.shape}")
    bad = ~np.isfinite(arr)
    if bad.any():
        index = tuple(int(i) for i in np.argwhere(bad)[0])
        raise InputError(f"{name}[{index[0]}] is not finite ({float(arr[index])!r})")
    arr.setflags(write=False)
    return arr


def _first_nonpositive(name: str, arr: np.ndarray) -> None:
    bad = np.flatnonzero(arr <= 0)
    if bad.size:
        i = int(bad[0])
        raise InputError(f"{name}[{i}] = {float(arr[i])!r} must be > 0")


@dataclass(frozen=True, eq=False)
class Scene:
    """A board of dots and static segments.

    Parameters
    ----------
    box : (float, float)
        Board width and height, px. The board spans ``[0, width] x [0, height]``.
    positions : array_like, shape (N, 2)
        Dot centres, px.
    radii : array_like, shape (N,)
        Dot radii, px; each > 0.
    masses : array_like, shape (N,), optional
        Dot masses in units of the mean dot mass; each > 0. Default all 1.
    velocities : array_like, shape (N, 2), optional
        Dot velocities, px/s. Default all zero.
    segments : array_like, shape (M, 4), optional
        Static walls ``(x0, y0, x1, y1)``, px, in addition to the box edges.
    closed : bool
        If True (default) the four box edges are hard walls.
    restitution : Restitution
        The collision rule (thesis Eq 2.5).
    overlap_tolerance : float
        Largest accepted relative overlap ``(r_i + r_j - d) / ((r_i + r_j)/2)``
        between two dots, in [0, 1). 0 (default) for boards built by hand. A
        board taken from a running simulation carries Chipmunk's soft-contact
        overlap (bounded at 1.5 % of a radius in the tests at default
        settings); pass e.g. 0.05 to accept it.

    Raises
    ------
    ValueError
        On a non-finite value, a non-positive radius or mass, a dot outside
        the box, two overlapping dots or a zero-length segment; the message
        names the field and the index.
    """

    box: tuple[float, float]
    positions: np.ndarray
    radii: np.ndarray
    masses: np.ndarray | None = None
    velocities: np.ndarray | None = None
    segments: np.ndarray | None = None
    closed: bool = True
    restitution: Restitution = field(default_factory=Restitution)
    overlap_tolerance: float = 0.0

    def __post_init__(self) -> None:
        if not (np.isfinite(self.overlap_tolerance) and 0.0 <= self.overlap_tolerance < 1.0):
            raise InputError(f"overlap_tolerance must be in [0, 1), got {self.overlap_tolerance!r}")
        box = _as_float_array("box", self.box, (2,))
        _first_nonpositive("box", box)
        positions = _as_float_array("positions", self.positions, (None, 2))
        n = len(positions)
        radii = _as_float_array("radii", self.radii, (n,))
        _first_nonpositive("radii", radii)
        masses = _as_float_array("masses", np.ones(n) if self.masses is None else self.masses, (n,))
        _first_nonpositive("masses", masses)
        velocities = _as_float_array(
            "velocities", np.zeros((n, 2)) if self.velocities is None else self.velocities, (n, 2)
        )
        segments = _as_float_array(
            "segments", np.zeros((0, 4)) if self.segments is None else self.segments, (None, 4)
        )
        lengths = np.hypot(segments[:, 2] - segments[:, 0], segments[:, 3] - segments[:, 1])
        short = np.flatnonzero(lengths == 0)
        if short.size:
            raise InputError(f"segments[{int(short[0])}] has zero length")
        if not isinstance(self.restitution, Restitution):
            raise InputError(f"restitution must be a qdots.Restitution, got {type(self.restitution).__name__}")
        object.__setattr__(self, "box", (float(box[0]), float(box[1])))
        for name, value in (("positions", positions), ("radii", radii), ("masses", masses),
                            ("velocities", velocities), ("segments", segments)):
            object.__setattr__(self, name, value)
        self._check_inside_box()
        self._check_no_overlap()

    @property
    def n_dots(self) -> int:
        """Number of dots."""
        return len(self.radii)

    def _check_inside_box(self) -> None:
        lo = self.positions - self.radii[:, None]
        hi = self.positions + self.radii[:, None]
        outside = np.flatnonzero((lo < 0).any(axis=1) | (hi > np.array(self.box)).any(axis=1))
        if outside.size:
            i = int(outside[0])
            x, y = self.positions[i]
            raise InputError(
                f"positions[{i}] = ({x:g}, {y:g}) with radius {self.radii[i]:g} lies outside "
                f"the box [0, {self.box[0]:g}] x [0, {self.box[1]:g}]"
            )

    def _check_no_overlap(self) -> None:
        if self.n_dots < 2:
            return
        pairs = cKDTree(self.positions).query_pairs(2.0 * self.radii.max(), output_type="ndarray")
        if not len(pairs):
            return
        i, j = pairs[:, 0], pairs[:, 1]
        distance = np.linalg.norm(self.positions[i] - self.positions[j], axis=1)
        contact = self.radii[i] + self.radii[j]
        allowed = contact * (1.0 - 0.5 * self.overlap_tolerance)
        bad = np.flatnonzero(distance < allowed)
        if bad.size:
            k = bad[np.argmin((distance[bad] - contact[bad]) / contact[bad])]
            a, b = sorted((int(i[k]), int(j[k])))
            overlap = 2.0 * (contact[k] - distance[k]) / contact[k]
            raise InputError(
                f"dots {a} and {b} overlap: centre distance {distance[k]:.6g} px < "
                f"radii[{a}] + radii[{b}] = {contact[k]:.6g} px (relative overlap {overlap:.3g}, "
                f"overlap_tolerance {self.overlap_tolerance:g})"
            )

    def replace(self, **changes: object) -> "Scene":
        """A copy with some fields changed, validated again."""
        return dataclasses.replace(self, **changes)

    def wall_segments(self) -> np.ndarray:
        """All static segments, box edges first when the box is closed, shape (M, 4)."""
        if not self.closed:
            return self.segments
        w, h = self.box
        edges = np.array([[0, 0, w, 0], [w, 0, w, h], [w, h, 0, h], [0, h, 0, 0]], dtype=float)
        return np.vstack([edges, self.segments])


def segment_distances(points: np.ndarray, segments: np.ndarray) -> np.ndarray:
    """Distance from each point to each segment, px; shape (P, M).

    Parameters
    ----------
    points : ndarray, shape (P, 2)
    segments : ndarray, shape (M, 4)
        ``(x0, y0, x1, y1)`` with nonzero length.
    """
    points = np.asarray(points, dtype=float).reshape(-1, 2)
    segments = np.asarray(segments, dtype=float).reshape(-1, 4)
    start, along = segments[None, :, :2], segments[None, :, 2:] - segments[None, :, :2]
    offset = points[:, None, :] - start
    t = np.clip(np.einsum("pmk,pmk->pm", offset, along) / np.einsum("pmk,pmk->pm", along, along), 0.0, 1.0)
    return np.linalg.norm(offset - t[:, :, None] * along, axis=2)


def grating_segments(box: tuple[float, float], pitch: float, offset: float = 0.0) -> np.ndarray:
    """Horizontal grating lines spanning the board, ``pitch`` px apart.

    The thesis's grating (Fig 2-3) is a single wall at ``6 * d * sqrt(3)/2``
    from the board edge; with ``pitch`` equal to that value and a board of the
    same height this gives the channel it describes.

    Returns
    -------
    ndarray, shape (M, 4)
        Segments ``(0, y, width, y)`` for ``y = offset + pitch, offset + 2 pitch, ...`` below the
        top edge.
    """
    width, height = box
    if not pitch > 0:
        raise InputError(f"grating pitch must be > 0 px, got {pitch!r}")
    ys = np.arange(offset + pitch, height, pitch)
    return np.column_stack([np.zeros_like(ys), ys, np.full_like(ys, width), ys])
