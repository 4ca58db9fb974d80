"""Van der Waals attraction between dots: the thesis proxy and Eq 2.2."""

from __future__ import annotations

import numpy as np

from labrig.validate import InputError, choice, real

from ..neighbours import VerletPairs
from .base import Force, StepContext

MODELS = ("thesis", "hamaker")
#: What the force does at gaps below ``min_gap``.
CONTACTS = ("hold", "zero")
#: Largest range R0 and gap, px (the thesis's R0 is 15 px, one mean diameter).
MAX_RANGE = 1000.0
#: Largest Hamaker constant, mean-dot mass px^2/s^2 (the default is about 2e4).
MAX_STRENGTH = 1e12


def thesis_offset(r0: float, min_gap: float, sticking_speed: float) -> float:
    """The offset ``b`` of the thesis proxy, px.

    ``b = d_min - R0 * (d_min / (v_stick^2 / 0.01))^(1/7)`` as the Java
    static initializer computes it (-5.49 px for the defaults). The code's
    ``updateB()`` omits the ``/ 0.01`` but is called only when a parameter
    is changed, which no figure run does.
    """
    return min_gap - r0 * (min_gap / (sticking_speed * sticking_speed / 0.01)) ** (1.0 / 7.0)


def hamaker_force(gap: np.ndarray, ri: np.ndarray, rj: np.ndarray, strength: float) -> np.ndarray:
    """Magnitude of the sphere-sphere van der Waals force, thesis Eq 2.2.

    ``F = Ha/6 * 64 Ri^3 Rj^3 (h + Ri + Rj) / ((h^2 + 2Ri h + 2Rj h)^2 (h^2 + 2Ri h + 2Rj h + 4 Ri Rj)^2)``

    Parameters
    ----------
    gap : ndarray
        Surface separation ``h``, px (> 0).
    ri, rj : ndarray
        Radii, px.
    strength : float
        Hamaker constant ``Ha`` in simulation energy units (mean mass px^2/s^2).

    Returns
    -------
    ndarray
        Attractive force, mean mass * px / s^2.
    """
    s = gap * (gap + 2.0 * ri + 2.0 * rj)
    return strength / 6.0 * 64.0 * (ri * rj) ** 3 * (gap + ri + rj) / (s * s * (s + 4.0 * ri * rj) ** 2)


class VanDerWaals(Force):
    """Pairwise van der Waals attraction, applied as a velocity change per step.

    Parameters
    ----------
    model : {"thesis", "hamaker"}
        ``"thesis"``: the Java proxy. For a pair at surface gap ``g`` each dot
        gets, toward the other, ``dv = min(a dt/2, sqrt(g a)/2)`` with
        ``a = (R0/(g - b))^7 / m`` (`thesis_offset` gives ``b``); as
        ``dt -> 0`` this is an acceleration ``a/2``.
        ``"hamaker"``: Eq 2.2, ``dv = F dt / m`` with `hamaker_force`.
    r0 : float
        ``R0`` of the thesis proxy, px (thesis 15).
    strength : float, optional
        Hamaker constant for ``"hamaker"``, simulation energy units. Default:
        the value that gives two mean-size (15 px) dots at a 1 px gap the same
        acceleration as the thesis proxy (so the two models are comparable).
        Divide an energy in joules by `qdots.units.PhysicalScale.energy_unit_joule`.
    min_gap : float
        Gaps below this (px) are treated as contact (thesis
        ``forceDistanceThresh = 0.1``).
    max_gap : float, optional
        No force beyond this gap, px. Default ``2 * r0`` (thesis).
    contact : {"hold", "zero"}
        Force on pairs closer than ``min_gap``. ``"zero"`` is the thesis's
        rule. With an event-driven engine the thesis kept touching dots at a
        1e-6 gap and resolved every re-contact exactly; with Chipmunk's soft
        contacts the zero rule makes touching pairs chatter (contact lost and
        re-made every step, a Python ``begin`` callback each time).
        ``"hold"`` (default) evaluates the force at ``min_gap`` instead, so
        contacts persist; it deepens the pair well by the force at
        ``min_gap`` times ``min_gap``, about 2 % of the well.
    sticking_speed : float
        Enters the thesis offset ``b`` (px/s, thesis 1).
    skin : float
        Verlet skin of the pair list, px (see `qdots.neighbours.VerletPairs`).
    """

    def __init__(
        self,
        model: str = "thesis",
        *,
        r0: float = 15.0,
        strength: float | None = None,
        min_gap: float = 0.1,
        max_gap: float | None = None,
        contact: str = "hold",
        sticking_speed: float = 1.0,
        skin: float = 3.0,
    ):
        choice("VanDerWaals.model", model, MODELS)
        choice("VanDerWaals.contact", contact, CONTACTS)
        # Derived defaults stay "unset" in params(), so a saved scene whose r0 is
        # edited recomputes them instead of freezing the old values.
        self._unset = {name for name, value in (("strength", strength), ("max_gap", max_gap)) if value is None}
        r0 = real("VanDerWaals.r0", r0, 0.0, MAX_RANGE, low_open=True, unit="px")
        max_gap = real("VanDerWaals.max_gap", 2.0 * r0 if max_gap is None else max_gap, 0.0, 2 * MAX_RANGE,
                       low_open=True, unit="px")
        min_gap = real("VanDerWaals.min_gap", min_gap, 0.0, MAX_RANGE, low_open=True, unit="px")
        sticking_speed = real("VanDerWaals.sticking_speed", sticking_speed, 0.0, 1e6, low_open=True, unit="px/s")
        if max_gap <= min_gap:
            raise InputError(f"VanDerWaals.max_gap ({max_gap}) must exceed min_gap ({min_gap})")
        self.model = model
        self.r0 = float(r0)
        self.min_gap = float(min_gap)
        self.max_gap = float(max_gap)
        self.contact = contact
        self.sticking_speed = float(sticking_speed)
        self.offset = thesis_offset(self.r0, self.min_gap, self.sticking_speed)
        if strength is None:
            # Match the thesis proxy's acceleration a/2 for mean dots (r = 7.5 px) at a 1 px gap.
            proxy = 0.5 * (self.r0 / (1.0 - self.offset)) ** 7
            strength = proxy / float(hamaker_force(np.array(1.0), np.array(7.5), np.array(7.5), 1.0))
        self.strength = real("VanDerWaals.strength", strength, 0.0, MAX_STRENGTH)
        self._pairs = VerletPairs(skin)
        self.skin = self._pairs.skin
        self.bind(np.zeros(0), np.zeros(0))

    def params(self) -> dict:
        params = super().params()
        return {key: (None if key in self._unset else value) for key, value in params.items()}

    @property
    def pairs(self) -> VerletPairs:
        """The pair list (its ``rebuilds`` counter is useful in benchmarks)."""
        return self._pairs

    def bind(self, radii: np.ndarray, masses: np.ndarray) -> None:
        self._radii = radii
        self._inv_mass = 1.0 / masses
        self._equal_masses = bool(np.all(masses == masses[0])) if len(masses) else True
        self._inv_mass_max = float(self._inv_mass.max(initial=0.0))
        self._cutoff = self.max_gap + 2.0 * float(radii.max(initial=0.0))
        self._pairs.invalidate()

    def _cache_pair_constants(self) -> None:
        i, j = self._pairs.i, self._pairs.j
        self._ri, self._rj = self._radii[i], self._radii[j]
        self._rsum = self._ri + self._rj
        self._inv_mi, self._inv_mj = self._inv_mass[i], self._inv_mass[j]

    def _pair_speeds(self, gap: np.ndarray, dt: float) -> tuple[np.ndarray, np.ndarray]:
        """Speed change of ``i`` toward ``j`` and of ``j`` toward ``i`` over one step, px/s."""
        if self.model == "hamaker":
            impulse = hamaker_force(gap, self._ri, self._rj, self.strength) * dt
            return impulse * self._inv_mi, impulse * self._inv_mj
        q = self.r0 / (gap - self.offset)
        q2 = q * q
        pull = q2 * q2 * q2 * q  # (R0/(g - b))^7 for unit mass; ** 7 is 2x slower
        linear = (0.5 * dt) * pull
        if self._cap_cannot_bind(dt):
            if self._equal_masses:
                same = linear * self._inv_mass[0]
                return same, same
            return linear * self._inv_mi, linear * self._inv_mj
        capped = 0.5 * np.sqrt(gap * pull)

        def speed(inv_m: np.ndarray) -> np.ndarray:
            return np.minimum(linear * inv_m, capped * np.sqrt(inv_m))

        if self._equal_masses:
            same = speed(self._inv_mass[0])
            return same, same
        return speed(self._inv_mi), speed(self._inv_mj)

    def _cap_cannot_bind(self, dt: float) -> bool:
        """True when ``a dt/2 <= sqrt(g a)/2`` for every pair, i.e. ``a(g) dt^2 <= g``.

        ``a(g) / g`` falls with ``g``, so checking the smallest gap and the
        lightest dot is enough; at the defaults this holds for dt < 10 ms.
        """
        a_max = (self.r0 / (self.min_gap - self.offset)) ** 7 * self._inv_mass_max
        return a_max * dt * dt <= self.min_gap

    def kick(self, ctx: StepContext) -> None:
        if self._pairs.update(ctx.x, ctx.y, self._cutoff):
            self._cache_pair_constants()
        i, j = self._pairs.i, self._pairs.j
        if not len(i):
            return
        dx = ctx.x[j] - ctx.x[i]
        dy = ctx.y[j] - ctx.y[i]
        d = np.sqrt(dx * dx + dy * dy)
        gap = d - self._rsum
        active = gap < self.max_gap
        if self.contact == "zero":
            active &= gap >= self.min_gap
        # Weighting by the mask is cheaper than compressing six arrays (~88 % of listed pairs act).
        # Coincident centres (d = 0) have no direction and get no force.
        weight = np.divide(active, d, out=np.zeros_like(d), where=d > 0)
        speed_i, speed_j = self._pair_speeds(np.maximum(gap, self.min_gap), ctx.dt)
        n = len(ctx.x)
        if speed_i is speed_j:
            f = speed_i * weight
            fx, fy = f * dx, f * dy
            ctx.dv[:, 0] += np.bincount(i, fx, n) - np.bincount(j, fx, n)
            ctx.dv[:, 1] += np.bincount(i, fy, n) - np.bincount(j, fy, n)
        else:
            fi, fj = speed_i * weight, speed_j * weight
            ctx.dv[:, 0] += np.bincount(i, fi * dx, n) - np.bincount(j, fj * dx, n)
            ctx.dv[:, 1] += np.bincount(i, fi * dy, n) - np.bincount(j, fj * dy, n)
