"""The partial-elasticity collision rule of the thesis (Eq 2.5), as physics: its parameters and its draws.

Eq 2.5 mixes the elastic outgoing velocity with the centre-of-mass velocity along the line of
centres, ``v = eps * v_elastic + (1 - eps) * v_cm``, and keeps the tangential velocity. That is
exactly a normal coefficient of restitution ``eps`` with zero friction. Each dot-dot impact draws
``eps`` from Normal(mean, std) clipped to [0, 1], and an impact slower than the sticking speed is
perfectly inelastic; dot-wall impacts have their own restitution (elastic in the thesis).

Random draws. The n-th elasticity draw of a simulation is a hash of (key, n) turned into a
normal number (`impact_normal`), so a draw does not depend on who makes it and a run resumes bit
for bit from its key and its count of draws. How an engine applies the rule (Chipmunk's compiled
callbacks, the counts a checkpoint saves) is `qdots.engine.contacts`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from labrig.compiled import jit
from labrig.params import Param, check_fields

#: Largest sticking speed, px/s.
MAX_STICKING_SPEED = 1e6


@dataclass(frozen=True)
class Restitution:
    """Coefficients of restitution of the thesis's collision model.

    Parameters
    ----------
    mean : float
        Mean elasticity ``e`` of dot-dot collisions, in [0, 1] (thesis 0.8).
        Each impact draws ``eps ~ Normal(e, min((1 - e)/2, e/2))`` clipped
        to [0, 1], so that complete inelasticity is two standard deviations
        from the mean (thesis ``setElasticity``).
    wall : float
        Restitution of dot-wall impacts, in [0, 1]. The thesis's walls are
        elastic (1.0).
    sticking_speed : float
        Normal approach speed (px/s) below which a dot-dot impact is
        perfectly inelastic (thesis ``completelyInelasticThresh = 1``).
    """

    mean: float = 0.8
    wall: float = 1.0
    sticking_speed: float = 1.0

    #: Declarations of the fields: checks and file comments (`labrig.params`).
    PARAMS: ClassVar[dict[str, Param]] = {
        "mean": Param("float", 0.0, 1.0, doc="mean dot-dot coefficient of restitution"),
        "wall": Param("float", 0.0, 1.0, doc="dot-wall coefficient of restitution"),
        "sticking_speed": Param("float", 0.0, MAX_STICKING_SPEED, unit="px/s",
                                doc="dot-dot impacts slower than this are perfectly inelastic"),
    }

    def __post_init__(self) -> None:
        check_fields(self, self.PARAMS, "Restitution.")

    @property
    def std(self) -> float:
        """Standard deviation of the per-impact elasticity draw."""
        return min((1.0 - self.mean) / 2.0, self.mean / 2.0)



@jit(inline=True)
def mix64(z):
    """SplitMix64's finaliser: a bijective 64-bit hash."""
    z = z + np.uint64(0x9E3779B97F4A7C15)
    z = (z ^ (z >> np.uint64(30))) * np.uint64(0xBF58476D1CE4E5B9)
    z = (z ^ (z >> np.uint64(27))) * np.uint64(0x94D049BB133111EB)
    return z ^ (z >> np.uint64(31))


@jit
def impact_normal(key, n):
    """The ``n``-th standard normal draw of the stream ``key`` (uint64s): Box-Muller on two hashed uniforms."""
    key, n = np.uint64(key), np.uint64(n)
    a = mix64(key ^ (np.uint64(2) * n))
    b = mix64(key ^ (np.uint64(2) * n + np.uint64(1)))
    u1 = (float(a >> np.uint64(11)) + 1.0) / 9007199254740992.0  # (0, 1]
    u2 = float(b >> np.uint64(11)) / 9007199254740992.0  # [0, 1)
    return math.sqrt(-2.0 * math.log(u1)) * math.cos(2.0 * math.pi * u2)
