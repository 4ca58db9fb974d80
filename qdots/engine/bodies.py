"""Bulk reads and writes of dot positions and velocities.

Reading or writing bodies one by one is slow at thousands of dots. The step's own reads (positions and
velocities) and writes (velocity changes) go straight to Chipmunk's body memory from compiled code, at the
offsets `qdots.engine.pymunk_adapter.internals` found, several times faster than a `pymunk.batch` call and its
Python wrapping (the measurements: docs/performance.md, "Design measurements"). Without them (an untested
pymunk), the same reads and writes go through `pymunk.batch`, with the same numbers.

Measured facts the `pymunk.batch` path relies on (pymunk 7.3, checked at construction):

* rows come as dynamic bodies in insertion order, then static bodies
  (``space.static_body`` included);
* ``set_space_bodies`` writes *every* row with no bounds check, so the write
  buffer is sized for all rows and its static rows stay zero;
* a buffer given to ``Buffer.set_float_buf`` points at numpy's memory, so
  reads and writes use separate buffers.
"""

from __future__ import annotations

import numpy as np
import pymunk
from numba import carray
from pymunk import batch

from labrig.compiled import jit, pointer

from .pymunk_adapter import POSITION, VELOCITY, body_address, internals

_POS_VEL = batch.BodyFields.POSITION | batch.BodyFields.VELOCITY


@jit
def read_bodies(addresses, offsets, rows):
    """Fill ``rows`` (N, 4) with ``(x, y, vx, vy)`` of the bodies at ``addresses`` (`qdots.engine.pymunk_adapter.Internals.body_offsets`)."""
    for a in range(addresses.size):
        p = carray(pointer(addresses[a] + offsets[POSITION]), 2, np.float64)
        v = carray(pointer(addresses[a] + offsets[VELOCITY]), 2, np.float64)
        rows[a, 0] = p[0]
        rows[a, 1] = p[1]
        rows[a, 2] = v[0]
        rows[a, 3] = v[1]


@jit
def add_body_velocities(addresses, offsets, dv):
    """Add ``dv`` (N, 2) to the velocity vectors of the bodies at ``addresses``."""
    for a in range(addresses.size):
        v = carray(pointer(addresses[a] + offsets[VELOCITY]), 2, np.float64)
        v[0] += dv[a, 0]
        v[1] += dv[a, 1]


class BodyArrays:
    """Bulk access to the positions and velocities of a space's dot bodies.

    Parameters
    ----------
    space : pymunk.Space
        The space; its first ``len(bodies)`` body rows must be ``bodies``.
    bodies : sequence of pymunk.Body
        The dot bodies, in the order the arrays use.

    Raises
    ------
    RuntimeError
        If pymunk's row order does not start with ``bodies`` (sleeping
        bodies, or a pymunk version that changed the order).
    """

    def __init__(self, space: pymunk.Space, bodies: list[pymunk.Body]):
        self._space = space
        self._bodies = list(bodies)  # alive as long as their addresses are used
        self.n = len(bodies)
        self._addresses = np.array([body_address(body) for body in bodies], dtype=np.uint64)
        self._rows = np.zeros((self.n, 4))
        self._rows_view = self._rows.view()
        self._rows_view.flags.writeable = False
        ids = batch.Buffer()
        batch.get_space_bodies(space, batch.BodyFields.BODY_ID, ids)
        row_ids = np.frombuffer(ids.int_buf(), dtype=np.uintp)
        expected = np.array([b.id for b in bodies], dtype=np.uintp)
        if len(row_ids) < self.n or not np.array_equal(row_ids[: self.n], expected):
            raise RuntimeError("pymunk.batch body rows do not start with the dot bodies in insertion order")
        self.rows = len(row_ids)
        self._read = batch.Buffer()
        self._velocity_rows = np.zeros((self.rows, 2))
        self._velocity_buffer = batch.Buffer()
        self._velocity_buffer.set_float_buf(self._velocity_rows)
        self._state_rows = np.zeros((self.rows, 4))
        self._state_buffer = batch.Buffer()
        self._state_buffer.set_float_buf(self._state_rows)
        found = internals()
        self._offsets = None if found is None else found.body_offsets

    @property
    def direct(self) -> bool:
        """True when reads and writes go straight to Chipmunk's memory (`qdots.engine.pymunk_adapter.internals`)."""
        return self._offsets is not None

    def read_rows(self) -> np.ndarray:
        """The dots' rows ``(x, y, vx, vy)``, shape (N, 4): a read-only array valid until the next read."""
        if self._offsets is not None:
            read_bodies(self._addresses, self._offsets, self._rows)
            return self._rows_view
        self._read.clear()
        batch.get_space_bodies(self._space, _POS_VEL, self._read)
        rows = np.frombuffer(self._read.float_buf(), dtype=np.float64).reshape(-1, 4)[: self.n]
        rows.flags.writeable = False
        return rows

    def read(self) -> tuple[np.ndarray, np.ndarray]:
        """Positions and velocities of the dots, two new (N, 2) arrays."""
        rows = self.read_rows()
        return rows[:, :2].copy(), rows[:, 2:].copy()

    def add_velocities(self, dv: np.ndarray, velocities: np.ndarray) -> None:
        """Add ``dv`` (N, 2) to every dot's velocity; ``velocities`` (N, 2) are their velocities now (what the
        public-API path writes, with ``dv`` added)."""
        if self._offsets is not None:
            add_body_velocities(self._addresses, self._offsets, dv)
            return
        self.write_velocities(velocities + dv)

    def write_velocities(self, velocities: np.ndarray) -> None:
        """Set every dot's velocity from an (N, 2) array."""
        self._velocity_rows[: self.n] = velocities
        batch.set_space_bodies(self._space, batch.BodyFields.VELOCITY, self._velocity_buffer)

    def write(self, positions: np.ndarray, velocities: np.ndarray) -> None:
        """Set every dot's position and velocity from (N, 2) arrays."""
        self._state_rows[: self.n, :2] = positions
        self._state_rows[: self.n, 2:] = velocities
        batch.set_space_bodies(self._space, _POS_VEL, self._state_buffer)
