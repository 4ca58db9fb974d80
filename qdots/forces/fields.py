"""External fields and substrate drag: `Gravity`, `CentreGravity`, `Drag`."""

from __future__ import annotations

from typing import ClassVar

import numpy as np

from labrig.params import Param

from ..scene import MAX_LENGTH
from .base import Force, StepContext

#: Gravity of the thesis's deposition code: ``setGravity(25)`` times 30 px per length unit, px/s^2.
THESIS_GRAVITY = 750.0
#: Largest acceleration, px/s^2 (1e5 thesis gravities).
MAX_ACCELERATION = 1e8
#: Largest drag coefficients (1/s and 1/px).
MAX_DRAG = 1e6


class Gravity(Force):
    """Uniform acceleration.

    Parameters
    ----------
    acceleration : (float, float)
        Acceleration vector, px/s^2. Default: the thesis's 750 px/s^2
        toward y = 0 (our y axis points up; the thesis's screen y pointed
        down).
    """

    #: Declarations of the parameters: checks and file comments (`labrig.params`).
    PARAMS: ClassVar[dict[str, Param]] = {"acceleration": Param("float2", -MAX_ACCELERATION, MAX_ACCELERATION, unit="px/s^2",
                                    doc="acceleration [ax, ay]")}

    def __init__(self, acceleration: tuple[float, float] = (0.0, -THESIS_GRAVITY)):
        self.acceleration = self.PARAMS["acceleration"].check("Gravity.acceleration", acceleration)

    def kick(self, ctx: StepContext) -> None:
        ctx.dv += np.multiply(self.acceleration, ctx.dt)


class CentreGravity(Force):
    """Constant-magnitude acceleration toward a point (thesis ``runRandomCenterGravity``).

    Parameters
    ----------
    centre : (float, float)
        The attracting point, px.
    magnitude : float
        Acceleration, px/s^2 (>= 0). Default 750 px/s^2 as in the thesis.
    """

    #: Declarations of the parameters: checks and file comments (`labrig.params`).
    PARAMS: ClassVar[dict[str, Param]] = {"centre": Param("float2", -MAX_LENGTH, MAX_LENGTH, unit="px", doc="attracting point [x, y]"),
              "magnitude": Param("float", 0.0, MAX_ACCELERATION, unit="px/s^2", doc="acceleration toward the centre")}

    def __init__(self, centre: tuple[float, float], magnitude: float = THESIS_GRAVITY):
        self.centre = self.PARAMS["centre"].check("CentreGravity.centre", centre)
        self.magnitude = self.PARAMS["magnitude"].check("CentreGravity.magnitude", magnitude)

    def kick(self, ctx: StepContext) -> None:
        dx = self.centre[0] - ctx.x
        dy = self.centre[1] - ctx.y
        d = np.sqrt(dx * dx + dy * dy)
        # A dot exactly on the centre feels no pull (the direction is undefined).
        scale = np.divide(self.magnitude * ctx.dt, d, out=np.zeros_like(d), where=d > 0)
        ctx.dv[:, 0] += scale * dx
        ctx.dv[:, 1] += scale * dy


class Drag(Force):
    """The thesis's substrate friction: ``v *= max(1 - f1 dt - f2 |v| dt, 0)``.

    Parameters
    ----------
    linear : float
        ``f1``, 1/s (>= 0). Thesis default 0.025.
    quadratic : float
        ``f2``, 1/px (>= 0). The thesis passes 0.025 per length unit and
        divides by its 30 px per length unit, so 0.025/30 px^-1.
    """

    #: Declarations of the parameters: checks and file comments (`labrig.params`).
    PARAMS: ClassVar[dict[str, Param]] = {"linear": Param("float", 0.0, MAX_DRAG, unit="1/s", doc="linear friction f1"),
              "quadratic": Param("float", 0.0, MAX_DRAG, unit="1/px", doc="quadratic friction f2")}

    def __init__(self, linear: float = 0.025, quadratic: float = 0.025 / 30.0):
        self.linear = self.PARAMS["linear"].check("Drag.linear", linear)
        self.quadratic = self.PARAMS["quadratic"].check("Drag.quadratic", quadratic)

    def kick(self, ctx: StepContext) -> None:
        v = ctx.velocity
        speed = np.sqrt(v[:, 0] * v[:, 0] + v[:, 1] * v[:, 1])
        loss = np.minimum((self.linear + self.quadratic * speed) * ctx.dt, 1.0)
        ctx.dv -= v * loss[:, None]
