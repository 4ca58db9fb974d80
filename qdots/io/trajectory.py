"""Trajectories in GSD (HOOMD-blue's format), readable by OVITO, freud and gsd.

Optional: needs the ``gsd`` package (``pip install "nanodisorder[gsd]"``).

Conventions of the file, which follow HOOMD so other tools read it as is:

* ``configuration.box = [width, height, 0, 0, 0, 0]``, ``dimensions = 2``;
* positions are *centred*: ``x_gsd = x - width/2``, ``y_gsd = y - height/2``, ``z = 0``
  (HOOMD boxes span ``[-L/2, L/2)``); add ``box/2`` back to get qdots coordinates;
* ``particles.diameter`` (px), ``particles.mass`` (mean dot mass), ``particles.velocity`` (px/s);
* ``particles.types = ["dot", "heavy"]``: a dot heavier than its size makes it (`qdots.render.heavy_dots`:
  the heavy half of the bimodal mass model of Fig 2-6b) is ``"heavy"``, as in the pictures;
* ``log/particles/Color`` (RGB in [0, 1]): the size colours of the pictures (`qdots.render.size_colours`:
  large red, mean green, small blue); OVITO reads it as its ``Color`` property and the diameter
  as ``Radius``, so the board looks as in our pictures without any setting;
* ``configuration.step`` is the frame's step count and ``log/qdots/time`` its time in s;
* ``log/qdots/walls``: the wall segments, shape (M, 4), ``x0 y0 x1 y1`` in the file's centred
  coordinates (OVITO shows it as the global attribute ``qdots/walls``);
* ``log/qdots/periodic = [0, 0]``: the board is **not periodic**. GSD has no flag for it, so
  OVITO and freud take the box as periodic. In OVITO untick the cell's periodic boundary
  conditions (Python: ``data.cell_.pbc = (False, False, False)``); in freud use a box twice the
  board's size (``freud.box.Box(2 * width, 2 * height, is2D=True)``) so that no distance wraps
  round the walls (freud's RDF then needs the board's density, not the box's).
"""

from __future__ import annotations

import os

import numpy as np

from labrig.files import StreamedFile
from labrig.validate import InputError

from ..render import heavy_dots, size_colours
from ..state import State

#: Particle types of the file (``typeid`` indexes them).
TYPES = ("dot", "heavy")


class GSDWriter(StreamedFile):
    """A run writer that appends a frame to a GSD file every ``every`` steps.

    Frames stream to disk as they come (memory stays bounded); the file is
    written under a temporary name and renamed into place by `close`, so an
    interrupted run never leaves a half-written file under ``path``.

    Parameters
    ----------
    path : str or os.PathLike
        Output ``.gsd`` file.
    every : int
        Steps between frames (>= 1).
    dt : float, optional
        Time step of the run, s; when given, ``configuration.step`` is
        ``round(time / dt)``, else the frame index.
    """

    def __init__(self, path: str | os.PathLike, every: int = 100, dt: float | None = None):
        try:
            import gsd.hoomd
        except ImportError:  # pragma: no cover - depends on the environment
            raise ImportError("GSD output needs the gsd package: pip install 'nanodisorder[gsd]'") from None
        if not (isinstance(every, int) and every >= 1):
            raise InputError(f"every must be an integer >= 1 step, got {every!r}")
        super().__init__(path)
        self.every = every
        self.dt = dt
        self.frames = 0
        self._file = gsd.hoomd.open(self._tmp, mode="w")
        self._hoomd = gsd.hoomd

    def write(self, state: State) -> None:
        """Append ``state`` as one frame."""
        frame = self._hoomd.Frame()
        width, height = state.box
        frame.configuration.box = [width, height, 0.0, 0.0, 0.0, 0.0]
        frame.configuration.dimensions = 2
        frame.configuration.step = round(state.time / self.dt) if self.dt else self.frames
        n = state.n_dots
        position = np.zeros((n, 3), dtype=np.float32)
        position[:, 0] = state.positions[:, 0] - width / 2
        position[:, 1] = state.positions[:, 1] - height / 2
        velocity = np.zeros((n, 3), dtype=np.float32)
        velocity[:, :2] = state.velocities
        frame.particles.N = n
        frame.particles.types = list(TYPES)
        frame.particles.typeid = heavy_dots(state.masses, state.radii).astype(np.uint32)
        frame.particles.position = position
        frame.particles.velocity = velocity
        frame.particles.diameter = (2.0 * state.radii).astype(np.float32)
        frame.particles.mass = state.masses.astype(np.float32)
        frame.log["particles/Color"] = size_colours(state.radii).astype(np.float32)
        frame.log["qdots/time"] = np.array([state.time], dtype=np.float64)
        walls = np.array(state.walls, dtype=np.float64).reshape(-1, 4) - [width / 2, height / 2, width / 2, height / 2]
        frame.log["qdots/walls"] = walls if len(walls) else np.zeros((0, 4))
        frame.log["qdots/periodic"] = np.zeros(2, dtype=np.uint8)
        self._file.append(frame)
        self.frames += 1

    def _close_stream(self) -> None:
        self._file.close()
