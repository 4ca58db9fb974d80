"""Units of the simulation and the thesis's constants.

The engine works in the thesis's units:

* length in pixels (px); the thesis's board is 600 x 600 px and the mean dot
  diameter 15 px,
* time in seconds (s) of *simulation* time,
* mass in units of the mean dot mass, so a dot of mean size has mass 1.

Velocities are px/s, accelerations px/s^2 and energies mass_unit * px^2 / s^2.

The thesis never fixes the pixel size or the time scale: its thermal, van der
Waals and drag parameters were "estimated and then tuned using
phenomenological observations" (thesis section 2.3). `PhysicalScale` states a
conversion when one is wanted, for example to feed a Hamaker constant in
joules into the ``"hamaker"`` van der Waals model.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

if TYPE_CHECKING:  # numpy is imported where it is used: the command line reads this module at once
    import numpy as np

from labrig.validate import InputError

#: Boltzmann's constant as the thesis's Java code writes it, in g m^2 s^-2 K^-1.
THESIS_KB = 1.38e-20
#: Temperature of the thesis's thermal kicks, K.
THESIS_TEMPERATURE = 297.0
#: Mass of a mean-size dot in the thesis's code, g.
THESIS_MEAN_MASS_G = 5.24e-18
#: Interval between thermal kicks in the thesis's code, s.
THESIS_KICK_INTERVAL = 1.0 / 50.0
#: Hamaker constant of CdSe quoted by the thesis (Eq 2.2), taken to be in eV.
CDSE_HAMAKER_EV = 0.388
EV_IN_JOULE = 1.602176634e-19


def thesis_kick_speed(mass: float | np.ndarray) -> float | np.ndarray:
    """Magnitude of one thesis thermal kick, px/s.

    ``1.5 * sqrt(2 kb T / (m * avgMass))`` (thesis Appendix A,
    ``getRandomVelocityMagnitude``). The Java code evaluates this in SI-like
    units (m/s) and uses the number as px/s: for a mean-mass dot it is
    1.876 px/s. We keep the number, not a unit conversion, because the
    thesis tuned its other parameters against it.

    Parameters
    ----------
    mass : float or ndarray
        Dot mass in units of the mean dot mass.
    """
    import numpy as np

    return 1.5 * np.sqrt(2.0 * THESIS_KB * THESIS_TEMPERATURE / (np.asarray(mass) * THESIS_MEAN_MASS_G))


@dataclass(frozen=True)
class PhysicalScale:
    """Conversion from simulation units to SI.

    Parameters
    ----------
    nm_per_px : float
        Length of one pixel in nanometres. The default makes the thesis's
        15 px mean diameter a 5 nm CdSe dot.
    mean_mass_kg : float
        Mass of a mean-size dot in kilograms (thesis: 5.24e-18 g).
    seconds_per_time_unit : float
        Physical duration of one simulation second. The thesis's time is not
        calibrated; the default 1.0 keeps the numbers as they are.
    """

    nm_per_px: float = 5.0 / 15.0
    mean_mass_kg: float = THESIS_MEAN_MASS_G * 1e-3
    seconds_per_time_unit: float = 1.0

    def __post_init__(self) -> None:
        for name in ("nm_per_px", "mean_mass_kg", "seconds_per_time_unit"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise InputError(f"PhysicalScale.{name} must be a positive finite number, got {value!r}")

    @property
    def energy_unit_joule(self) -> float:
        """One simulation energy unit (mean mass * px^2 / s^2) in joules."""
        metres_per_px = self.nm_per_px * 1e-9
        return self.mean_mass_kg * metres_per_px**2 / self.seconds_per_time_unit**2
