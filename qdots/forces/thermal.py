"""Thermal motion: the thesis's periodic kicks and a Langevin thermostat."""

from __future__ import annotations

import math
from typing import ClassVar

import numpy as np

from labrig.params import Param
from labrig.validate import InputError, number

from ..units import THESIS_KICK_INTERVAL, thesis_kick_speed
from .base import Force, StepContext, instants_in_step

#: Longest interval between kicks, s.
MAX_INTERVAL = 1e4
#: Largest multiple of the thesis's kick (a kick of 1e4 thesis kicks is ~2e4 px/s).
MAX_SCALE = 1e4
#: Largest Langevin friction rate, 1/s, and thermal energy, mean-dot mass px^2/s^2 (the default is ~1.8).
MAX_GAMMA = 1e6
MAX_KT = 1e8
#: Most kicks within one time step: a kick interval shorter than the step repeats the kick (one random
#: draw per dot each time) this many times at most.
MAX_KICKS_PER_STEP = 1000
#: Most kicks in one run (the thesis's 400 s film takes 20,000).
MAX_KICKS_PER_RUN = 1_000_000_000


class ThermalKicks(Force):
    """The thesis's thermal motion: periodic velocity kicks in random directions.

    Every ``interval`` seconds each dot's velocity gets a vector of magnitude
    ``scale * 1.5 * sqrt(2 kb T / (m avgMass))`` (1.876 px/s for a mean-mass
    dot, see `qdots.units.thesis_kick_speed`) in a uniformly random
    direction. Kicks happen at the times ``interval, 2 interval, ...``; a step
    that spans several of them applies each one, so the schedule does not
    depend on ``dt`` and needs no state to resume.

    This is not a thermostat: without drag or inelastic collisions the speed
    of a free dot random-walks upward. Use `Langevin` for a temperature.

    Parameters
    ----------
    interval : float
        Time between kicks, s (> 0; a simulation refuses an interval that gives more than
        `MAX_KICKS_PER_STEP` kicks per time step or `MAX_KICKS_PER_RUN` per run). Thesis: 1/50 s.
    scale : float
        Multiplier on the thesis magnitude (>= 0).
    """

    #: Declarations of the parameters: checks and file comments (`labrig.params`); the kicks per step and per
    #: run are checked by `check_run`.
    PARAMS: ClassVar[dict[str, Param]] = {"interval": Param("float", 0.0, MAX_INTERVAL, low_open=True, unit="s", doc="time between kicks",
                                rule=f"at most {MAX_KICKS_PER_STEP:,} kicks per engine.dt and {MAX_KICKS_PER_RUN:,} "
                                     "per run"),
              "scale": Param("float", 0.0, MAX_SCALE, doc="multiple of the thesis kick speed")}

    def __init__(self, interval: float = THESIS_KICK_INTERVAL, scale: float = 1.0):
        self.interval = self.PARAMS["interval"].check("ThermalKicks.interval", interval)
        self.scale = self.PARAMS["scale"].check("ThermalKicks.scale", scale)

    def kicks_in_step(self, time: float, dt: float) -> int:
        """How many kick instants fall in ``(time, time + dt]`` (`instants_in_step`)."""
        return instants_in_step(time, dt, self.interval)

    def check_run(self, dt: float, steps: int | None = None) -> None:
        """`InputError` when ``interval`` gives more than `MAX_KICKS_PER_STEP` kicks in a step of ``dt`` s, or
        more than `MAX_KICKS_PER_RUN` in ``steps`` steps."""
        per_step = dt / self.interval
        if per_step > MAX_KICKS_PER_STEP:
            raise InputError(f"ThermalKicks.interval = {self.interval:g} s gives {per_step:.3g} kicks per time step of "
                             f"{dt:g} s, more than the {MAX_KICKS_PER_STEP:,} allowed: use an interval >= "
                             f"{number(dt / MAX_KICKS_PER_STEP)} s (thesis: 0.02 s)")
        if steps is not None and per_step * steps > MAX_KICKS_PER_RUN:
            raise InputError(f"ThermalKicks.interval = {self.interval:g} s gives {per_step * steps:.3g} kicks in a run of "
                             f"{steps * dt:g} s, more than the {MAX_KICKS_PER_RUN:,} a run may take: use an interval >= "
                             f"{number(steps * dt / MAX_KICKS_PER_RUN)} s")

    def kick(self, ctx: StepContext) -> None:
        kicks = self.kicks_in_step(ctx.time, ctx.dt)
        if not kicks:
            return
        if "speed" not in ctx.cache:
            ctx.cache["speed"] = self.scale * thesis_kick_speed(ctx.masses)
        speed = ctx.cache["speed"]
        assert ctx.rng is not None  # the engine hands each step its generator
        for _ in range(kicks):
            angle = ctx.rng.uniform(0.0, 2.0 * math.pi, size=len(speed))
            ctx.dv[:, 0] += speed * np.cos(angle)
            ctx.dv[:, 1] += speed * np.sin(angle)


class Langevin(Force):
    """Langevin thermostat: drag ``gamma`` and noise consistent with it.

    The velocity of each dot follows ``dv = -gamma v dt + sqrt(2 gamma kT / m) dW``,
    integrated exactly over a step (Ornstein-Uhlenbeck update)::

        v <- c v + sqrt(kT/m (1 - c^2)) xi,   c = exp(-gamma dt),  xi ~ N(0, 1)

    so a free dot samples the Maxwell distribution, ``<m v_x^2> = kT``,
    for any ``dt`` (fluctuation-dissipation holds by construction).

    Parameters
    ----------
    gamma : float
        Friction rate, 1/s (>= 0).
    kT : float
        Thermal energy in simulation units (mean mass * px^2 / s^2, >= 0).
        The default makes the rms speed of a mean-mass dot equal to one
        thesis kick, ``kT = thesis_kick_speed(1)**2 / 2`` (about 1.76).
    """

    #: Declarations of the parameters: checks and file comments (`labrig.params`).
    PARAMS: ClassVar[dict[str, Param]] = {"gamma": Param("float", 0.0, MAX_GAMMA, unit="1/s", doc="friction rate"),
              "kT": Param("float", 0.0, MAX_KT, unit="mean-dot mass px^2/s^2", doc="thermal energy")}

    def __init__(self, gamma: float = 1.0, kT: float | None = None):
        if kT is None:
            kT = float(thesis_kick_speed(1.0)) ** 2 / 2.0
        self.gamma = self.PARAMS["gamma"].check("Langevin.gamma", gamma)
        self.kT = self.PARAMS["kT"].check("Langevin.kT", kT)

    def kick(self, ctx: StepContext) -> None:
        if "sigma_unit" not in ctx.cache:
            ctx.cache["sigma_unit"] = np.sqrt(self.kT / ctx.masses)
        c = math.exp(-self.gamma * ctx.dt)
        sigma = ctx.cache["sigma_unit"] * math.sqrt(1.0 - c * c)
        assert ctx.rng is not None  # the engine hands each step its generator
        noise = ctx.rng.standard_normal(ctx.dv.shape)
        ctx.dv += (c - 1.0) * ctx.velocity + sigma[:, None] * noise
