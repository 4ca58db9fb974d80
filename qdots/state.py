"""`State`: a snapshot of a board, the input of every analysis function."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True, eq=False)
class State:
    """The board at one instant, as plain arrays (copies, safe to keep).

    Attributes
    ----------
    time : float
        Simulation time, s.
    positions, velocities : ndarray, shape (N, 2)
        Dot centres (px) and velocities (px/s).
    radii, masses : ndarray, shape (N,)
        Radii (px) and masses (mean dot mass = 1).
    box : (float, float)
        Board width and height, px.
    walls : ndarray, shape (M, 4)
        Every static segment ``(x0, y0, x1, y1)``, box edges included.
    closed : bool
        Whether the box edges are walls (else dots may leave the board).
    """

    time: float
    positions: np.ndarray
    velocities: np.ndarray
    radii: np.ndarray
    masses: np.ndarray
    box: tuple[float, float]
    walls: np.ndarray
    closed: bool = True

    @property
    def n_dots(self) -> int:
        return len(self.radii)

    def kinetic_energy(self) -> float:
        """Total kinetic energy, mean mass * px^2 / s^2."""
        return 0.5 * float(np.sum(self.masses * np.sum(self.velocities**2, axis=1)))

    def momentum(self) -> np.ndarray:
        """Total momentum, mean mass * px / s."""
        return np.sum(self.masses[:, None] * self.velocities, axis=0)
