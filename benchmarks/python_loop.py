"""Our forces written as a plain per-body Python loop (benchmark-only code: what vectorizing buys).

`LoopForces` applies the thesis's van der Waals proxy, thermal kicks and drag the way a
straightforward pymunk program would: read each body's position and velocity, loop over the
pairs of a KD-tree query (built every step, no Verlet list, every pair every step) and over the bodies in Python, and
write each body's velocity back. It follows the formulas of `qdots.VanDerWaals` (thesis model,
``contact="hold"``), `qdots.ThermalKicks` and `qdots.Drag` term for term and draws its random
numbers in the same order, so from the same state and generator it gives the same velocity
changes as the vectorized forces up to round-off.
"""

from __future__ import annotations

import math

import numpy as np
import pymunk
from scipy.spatial import cKDTree

import qdots


class LoopForces:
    """van der Waals (thesis proxy) + thermal kicks + drag on a pymunk space, one body at a time."""

    def __init__(self, space: pymunk.Space, vdw: qdots.VanDerWaals, kicks: qdots.ThermalKicks, drag: qdots.Drag,
                 pairs: qdots.engine.PairScheme, restitution: qdots.Restitution):
        if vdw.model != "thesis" or vdw.contact != "hold" or pairs.splits(vdw.max_gap):
            raise ValueError("the loop version implements VanDerWaals('thesis', contact='hold') with every pair "
                             "every step (PairScheme(far_interval=None)) only")
        #: The proxy's offset b under the collision rule ``restitution``, px.
        self.offset = vdw.proxy_offset(restitution.sticking_speed)
        self.bodies = [b for b in space.bodies if b.body_type == pymunk.Body.DYNAMIC]
        self.radii = [next(iter(b.shapes)).radius for b in self.bodies]
        self.vdw, self.kicks, self.drag = vdw, kicks, drag
        self.kick_speeds = [kicks.scale * float(qdots.units.thesis_kick_speed(b.mass)) for b in self.bodies]
        self.cutoff = vdw.max_gap + 2.0 * max(self.radii)

    def velocity_changes(self, time: float, dt: float, rng: np.random.Generator) -> list[list[float]]:
        """[dvx, dvy] of every body for one step from ``time``."""
        bodies, radii, vdw = self.bodies, self.radii, self.vdw
        positions = [(b.position.x, b.position.y) for b in bodies]
        velocities = [(b.velocity.x, b.velocity.y) for b in bodies]
        dv = [[0.0, 0.0] for _ in bodies]
        pairs = cKDTree(np.array(positions)).query_pairs(self.cutoff, output_type="ndarray")
        for i, j in pairs.tolist():
            dx = positions[j][0] - positions[i][0]
            dy = positions[j][1] - positions[i][1]
            d = math.sqrt(dx * dx + dy * dy)
            gap = d - radii[i] - radii[j]
            if gap >= vdw.max_gap or d == 0.0:
                continue
            g = max(gap, vdw.min_gap)
            pull = (vdw.r0 / (g - self.offset)) ** 7
            linear = 0.5 * dt * pull
            capped = 0.5 * math.sqrt(g * pull)
            inv_i, inv_j = 1.0 / bodies[i].mass, 1.0 / bodies[j].mass
            speed_i = min(linear * inv_i, capped * math.sqrt(inv_i))
            speed_j = min(linear * inv_j, capped * math.sqrt(inv_j))
            dv[i][0] += speed_i * dx / d
            dv[i][1] += speed_i * dy / d
            dv[j][0] -= speed_j * dx / d
            dv[j][1] -= speed_j * dy / d
        for _ in range(self.kicks.kicks_in_step(time, dt)):
            for k in range(len(bodies)):
                angle = rng.uniform(0.0, 2.0 * math.pi)
                dv[k][0] += self.kick_speeds[k] * math.cos(angle)
                dv[k][1] += self.kick_speeds[k] * math.sin(angle)
        for k, (vx, vy) in enumerate(velocities):
            loss = min((self.drag.linear + self.drag.quadratic * math.sqrt(vx * vx + vy * vy)) * dt, 1.0)
            dv[k][0] -= vx * loss
            dv[k][1] -= vy * loss
        return dv

    def apply(self, time: float, dt: float, rng: np.random.Generator) -> None:
        """Add one step's velocity changes to the bodies, one body at a time."""
        for body, (dvx, dvy) in zip(self.bodies, self.velocity_changes(time, dt, rng)):
            v = body.velocity
            body.velocity = (v.x + dvx, v.y + dvy)
