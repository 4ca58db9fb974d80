"""`Scene`: what exists on the board, as plain validated data.

A scene is the board (a rectangle with optional hard edges), static line
segments (walls, grating lines) and the dots (positions, radii, masses,
velocities): what exists, not what acts on it (forces and the collision rule
are given to the `qdots.Simulation` built from it) and no engine state.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from labrig.validate import InputError, array, flag, is_real, number, real, reals

from .geometry import DiscTree, worst_overlap, worst_wall_overlap
from .limits import MAX_DOTS, MAX_LENGTH, MAX_MASS, MAX_SEGMENTS, MAX_SPEED, MIN_DIAMETER  # noqa: F401 (public here too)


def _positive(name: str, arr: np.ndarray, high: float) -> None:
    bad = np.flatnonzero((arr <= 0) | (arr > high))
    if bad.size:
        i = int(bad[0])
        raise InputError(f"{name}[{i}] = {float(arr[i])!r} must be in (0, {number(high)}]")


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
    overlap_tolerance : float
        Largest accepted relative overlap ``(r_i + r_j - d) / ((r_i + r_j)/2)``
        between two dots (`qdots.geometry.relative_overlap`), in [0, 1). 0 (default) for boards built
        by hand.
    from_engine : bool
        True for a board a simulation produced (`Simulation.current_scene`, a checkpoint): its dots
        may overlap (Chipmunk's contacts are soft), touch a wall from outside its line or have left
        an open board. Those are measured quantities (`qdots.analysis.overlaps`,
        `qdots.analysis.escaped`), reported by the runs, not errors: only the values themselves
        are checked.

    Raises
    ------
    labrig.validate.InputError
        On a non-finite or out-of-range value (sizes up to `MAX_LENGTH` px, `MAX_DOTS` dots,
        masses in (1/`MAX_MASS`, `MAX_MASS`], speeds up to `MAX_SPEED` px/s), a dot outside the
        box, two overlapping dots or a zero-length segment; the message names the field and the
        index. Also when the overlap check (pairs within twice the largest radius) would list more
        than `qdots.geometry.MAX_PAIRS` pairs: a few huge dots among very many small ones.
    """

    box: tuple[float, float]
    positions: np.ndarray
    radii: np.ndarray
    masses: np.ndarray | None = None
    velocities: np.ndarray | None = None
    segments: np.ndarray | None = None
    closed: bool = True
    overlap_tolerance: float = 0.0
    from_engine: bool = False

    def __post_init__(self) -> None:
        real("overlap_tolerance", self.overlap_tolerance, 0.0, 1.0, high_open=True)
        flag("from_engine", self.from_engine)
        box = array("box", self.box, (2,))
        _positive("box", box, MAX_LENGTH)
        positions = array("positions", self.positions, (None, 2), limit=MAX_LENGTH, max_size=2 * MAX_DOTS)
        n = len(positions)
        radii = array("radii", self.radii, (n,))
        _positive("radii", radii, MAX_LENGTH)
        masses = array("masses", np.ones(n) if self.masses is None else self.masses, (n,))
        _positive("masses", masses, MAX_MASS)
        if masses.min(initial=1.0) < 1.0 / MAX_MASS:
            raise InputError(f"masses must be at least {number(1 / MAX_MASS)} mean dot masses, got {masses.min()!r}")
        velocities = array("velocities", np.zeros((n, 2)) if self.velocities is None else self.velocities, (n, 2),
                           limit=MAX_SPEED)
        segments = array("segments", np.zeros((0, 4)) if self.segments is None else self.segments, (None, 4),
                         limit=MAX_LENGTH, max_size=4 * MAX_SEGMENTS)
        lengths = np.hypot(segments[:, 2] - segments[:, 0], segments[:, 3] - segments[:, 1])
        short = np.flatnonzero(lengths == 0)
        if short.size:
            raise InputError(f"segments[{int(short[0])}] has zero length")
        flag("closed", self.closed)
        object.__setattr__(self, "box", (float(box[0]), float(box[1])))
        object.__setattr__(self, "closed", bool(self.closed))
        for name, value in (("positions", positions), ("radii", radii), ("masses", masses),
                            ("velocities", velocities), ("segments", segments)):
            object.__setattr__(self, name, value)
        if not self.from_engine:
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
        rmax = float(self.radii.max(initial=0.0))
        worst, (a, b) = worst_overlap(self.positions, self.radii, self.overlap_tolerance,
                                      f"radii: the overlap check (2 x the largest radius, {rmax:g} px)")
        if a >= 0:
            contact = float(self.radii[a] + self.radii[b])
            distance = math.dist(self.positions[a], self.positions[b])
            raise InputError(
                f"dots {a} and {b} overlap: centre distance {distance:.6g} px < "
                f"radii[{a}] + radii[{b}] = {contact:.6g} px (relative overlap {worst:.3g}, "
                f"overlap_tolerance {self.overlap_tolerance:g})"
            )

    def replace(self, **changes: Any) -> Scene:
        """A copy with some fields changed, validated again."""
        return dataclasses.replace(self, **changes)

    def wall_segments(self) -> np.ndarray:
        """All static segments, box edges first when the box is closed, shape (M, 4)."""
        assert self.segments is not None  # __post_init__ replaces the default None by an array
        if not self.closed:
            return self.segments
        w, h = self.box
        edges = np.array([[0, 0, w, 0], [w, 0, w, h], [w, h, 0, h], [0, h, 0, 0]], dtype=float)
        return np.vstack([edges, self.segments])


def check_clear(new: Scene, board, segments: np.ndarray) -> None:
    """Raise `InputError` if a dot of ``new`` crosses a wall segment or overlaps a dot of ``board`` (a `State`):
    the deepest wall crossing (`qdots.geometry.worst_wall_overlap`) is named first, then the first new dot that
    overlaps a dot of the board (`qdots.geometry.DiscTree`; touching is allowed)."""
    _, (k, m) = worst_wall_overlap(new.positions, new.radii, segments)
    if k >= 0:
        raise InputError(f"new dot {k} crosses wall segments[{m}]")
    partners = DiscTree(board.positions, board.radii).clashing_partners(new.positions, new.radii)
    clash = np.flatnonzero(partners >= 0)
    if clash.size:
        k = int(clash[0])
        raise InputError(f"new dot {k} overlaps dot {int(partners[k])} already on the board")


def grating_segments(box: tuple[float, float], pitch: float, offset: float = 0.0) -> np.ndarray:
    """Horizontal grating lines spanning the board, ``pitch`` px apart.

    The thesis's grating (Fig 2-3) is a single wall at ``6 * d * sqrt(3)/2``
    from the board edge; with ``pitch`` equal to that value and a board of the
    same height this gives the channel it describes.

    Returns
    -------
    ndarray, shape (M, 4)
        Segments ``(0, y, width, y)`` for ``y = offset + pitch, offset + 2 pitch, ...`` below the
        top edge: at most `MAX_SEGMENTS`.
    """
    reals("box", box, 2, 0.0, MAX_LENGTH, unit="px")
    width, height = box
    real("offset", offset, -MAX_LENGTH, MAX_LENGTH, unit="px")
    if not (is_real(pitch) and math.isfinite(pitch) and pitch > 0):
        raise InputError(f"grating pitch must be > 0 px, got {pitch!r}")
    lines = (height - offset) / pitch - 1.0
    if lines > MAX_SEGMENTS:
        raise InputError(f"grating pitch = {pitch:g} px gives {lines:.3g} lines on a board {height:g} px high, "
                         f"more than the {MAX_SEGMENTS:,} allowed")
    ys = np.arange(offset + pitch, height, pitch)
    return np.column_stack([np.zeros_like(ys), ys, np.full_like(ys, width), ys])
