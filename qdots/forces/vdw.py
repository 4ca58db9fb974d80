"""Van der Waals attraction between dots: the thesis proxy and Eq 2.2."""

from __future__ import annotations

import math
from typing import ClassVar

import numpy as np

from labrig.compiled import jit
from labrig.params import Param
from labrig.validate import InputError

from ..geometry import pair_separation
from .base import Force, StepContext

MODELS = ("thesis", "hamaker")
#: What the force does at gaps below ``min_gap``.
CONTACTS = ("zero", "hold")
#: Largest range R0 and gap, px (the thesis's R0 is 15 px, one mean diameter).
MAX_RANGE = 1000.0
#: Largest multiplier of the pull (`VanDerWaals.scale`).
MAX_SCALE = 1000.0
#: Largest Hamaker constant, mean-dot mass px^2/s^2 (the default is about 2e4).
MAX_STRENGTH = 1e12
#: Least sticking speed, px/s, the thesis proxy's offset ``b`` is derived from (`VanDerWaals.check_rule`): far below
#: it ``b`` overflows to -inf in floating point (about 1e-155 px/s at the thesis's gap and range).
MIN_PROXY_STICKING = 1e-150

def thesis_offset(r0: float, min_gap: float, sticking_speed: float) -> float:
    """The offset ``b`` of the thesis proxy, px.

    ``b = d_min - R0 * (d_min / (v_stick^2 / 0.01))^(1/7)`` as the Java
    static initializer computes it (-5.49 px for the defaults). The code's
    ``updateB()`` omits the ``/ 0.01`` but is called only when a parameter
    is changed, which no figure run does.
    """
    return min_gap - r0 * (min_gap / (sticking_speed * sticking_speed / 0.01)) ** (1.0 / 7.0)


@jit(inline=True)
def hamaker_force(gap, ri, rj, strength):
    """Magnitude of the sphere-sphere van der Waals force, thesis Eq 2.2.

    ``F = Ha/6 * 64 Ri^3 Rj^3 (h + Ri + Rj) / ((h^2 + 2Ri h + 2Rj h)^2 (h^2 + 2Ri h + 2Rj h + 4 Ri Rj)^2)``

    Parameters
    ----------
    gap : float or ndarray
        Surface separation ``h``, px (> 0).
    ri, rj : float or ndarray
        Radii, px.
    strength : float
        Hamaker constant ``Ha`` in simulation energy units (mean mass px^2/s^2).

    Returns
    -------
    float or ndarray
        Attractive force, mean mass * px / s^2.
    """
    s = gap * (gap + 2.0 * ri + 2.0 * rj)
    return strength / 6.0 * 64.0 * (ri * rj) ** 3 * (gap + ri + rj) / (s * s * (s + 4.0 * ri * rj) ** 2)


#: Codes of `MODELS` in the compiled pass.
THESIS, HAMAKER = 0, 1


@jit
def add_pair_kicks(x, y, i, j, radii, inv_mass, model, r0, offset, strength, min_gap, gap_to, fade_from,
                   fade_to, far, zero_inside, dt, dv):
    """Add the van der Waals velocity changes over ``dt`` of the pairs ``(i[k], j[k])`` closer than the
    surface gap ``gap_to`` to ``dv``, in one pass: the near part of their pull, or (``far``) the far part.

    The law of `VanDerWaals` (its docstring states it): a pair at surface gap ``g < max_gap`` pulls
    each dot toward the other; gaps below ``min_gap`` are evaluated at ``min_gap`` (``zero_inside``
    False, contact "hold") or skipped (True, "zero"); coincident centres get no force. The near part
    is the pull times ``w(g)``: 1 up to ``fade_from``, a smoothstep down to 0 at ``fade_to``; the far
    part is the pull times ``1 - w(g)``. The two parts of a pair sum to its whole pull at every gap.

    Parameters
    ----------
    x, y : ndarray, shape (N,)
        Dot centres, px.
    i, j : ndarray of int, shape (P,)
        Candidate pairs (each once).
    radii, inv_mass : ndarray, shape (N,)
        Radii (px) and inverse masses (1 / mean dot mass).
    model : int
        `THESIS` (the Java proxy, capped at ``sqrt(g a)/2``) or `HAMAKER` (Eq 2.2).
    r0, offset, strength, min_gap : float
        The force's constants (px; strength in mean mass px^2/s^2).
    gap_to : float
        Pairs at this surface gap or farther are skipped, px (at most ``max_gap``).
    fade_from, fade_to : float
        The gaps between which the near part fades out, px (both ``max_gap`` for the whole pull).
    far : bool
        Add the far part instead of the near part.
    zero_inside : bool
        No force below ``min_gap``.
    dt : float
        Time the velocity change is for, s (a step, or the interval of the far pass).
    dv : ndarray, shape (N, 2)
        Velocity changes, px/s, added to in place.
    """
    half_dt = 0.5 * dt
    dt2 = dt * dt
    for k in range(i.size):
        a = i[k]
        b = j[k]
        dx, dy, d2, contact = pair_separation(x, y, radii, a, b)
        reach = contact + gap_to
        if d2 >= reach * reach or d2 <= 0.0:
            continue
        d = math.sqrt(d2)
        gap = d - contact
        if zero_inside and gap < min_gap:
            continue
        weight = 1.0  # of the near pass: 1 up to fade_from, smoothly to 0 at fade_to
        if gap >= fade_to:
            weight = 0.0
        elif gap > fade_from:
            s = (gap - fade_from) / (fade_to - fade_from)
            weight = 1.0 - s * s * (3.0 - 2.0 * s)
        if far:
            weight = 1.0 - weight
        if weight <= 0.0:
            continue
        g = max(gap, min_gap)
        ia = inv_mass[a]
        ib = inv_mass[b]
        if model == HAMAKER:
            impulse = hamaker_force(g, radii[a], radii[b], strength) * dt
            speed_a = impulse * ia
            speed_b = impulse * ib
        else:
            q = r0 / (g - offset)
            q2 = q * q
            pull = q2 * q2 * q2 * q  # (R0/(g - b))^7 for unit mass
            # min(dt pull / m / 2, sqrt(g pull / m) / 2): the first unless dt^2 pull / m >= g (no sqrt)
            speed_a = half_dt * pull * ia if dt2 * pull * ia < g else 0.5 * math.sqrt(g * pull * ia)
            speed_b = half_dt * pull * ib if dt2 * pull * ib < g else 0.5 * math.sqrt(g * pull * ib)
        inv_d = weight / d
        ux = dx * inv_d
        uy = dy * inv_d
        dv[a, 0] += speed_a * ux
        dv[a, 1] += speed_a * uy
        dv[b, 0] -= speed_b * ux
        dv[b, 1] -= speed_b * uy


class VanDerWaals(Force):
    """Pairwise van der Waals attraction, applied as velocity changes: physics only.

    The force states its law (`add_pair_kicks`): how hard a pair at a surface gap pulls over some seconds. Which
    pairs are pulled in which step is the engine's numerical scheme, handed to the force in each step's context
    (`qdots.engine.PairScheme`, ``ctx.pairs``): every pair in range every step by default, as the thesis pulled
    every pair once per frame, or the far pairs once per interval (multiple time stepping). The thesis
    proxy's cap applies to the pull of the time it is given, a step or an interval, as it did to the thesis's
    frame (it binds only for dots lighter than ~1/400 of the mean mass).

    Parameters
    ----------
    model : {"thesis", "hamaker"}
        ``"thesis"``: the Java proxy. For a pair at surface gap ``g`` each dot
        gets, toward the other, ``dv = min(a dt/2, sqrt(g a)/2)`` with
        ``a = (R0/(g - b))^7 / m``; as ``dt -> 0`` this is an acceleration ``a/2``.
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
    contact : {"zero", "hold"}
        Force on pairs closer than ``min_gap``. ``"zero"`` (default): none, the thesis's rule ("no force
        outside 0.1 <= g < 30 px"): touching dots do not pull each other, so only a kick or an impact
        drives them together. ``"hold"``: the force at ``min_gap``, which presses every touching pair
        together at every step (each press an impact of the collision rule); it deepens the pair well by
        the force at ``min_gap`` times ``min_gap``, about 2 % of the well. (Until 0.3 "hold" was the
        default, to keep Chipmunk's contacts from chattering under a Python callback per re-contact.)
    scale : float
        Multiplies the pull of either model (default 1, the thesis's): how strongly the ligands and the
        solvent let the dots attract (``qdots infer``'s ``attraction`` is its log10). The proxy's cap scales
        with it as the pull does (``dv = min(s a dt/2, sqrt(g s a)/2)``).
    offset : float, optional
        The thesis proxy's offset ``b``, px. Default: as the Java computes it from ``r0``, ``min_gap`` and
        the sticking speed of the simulation's collision rule (`thesis_offset`; -5.49 px for the
        thesis's values): the sticking speed is the collision rule's, defined once
        (`qdots.Restitution.sticking_speed`).
    """

    #: Declarations of the parameters: checks and file comments (`labrig.params`); max_gap above min_gap and
    #: offset below it are checked in the constructor.
    PARAMS: ClassVar[dict[str, Param]] = {
        "model": Param("str", choices=MODELS, doc='pull law ("thesis": the Java proxy, "hamaker": Eq 2.2)'),
        "r0": Param("float", 0.0, MAX_RANGE, low_open=True, unit="px", doc="range R0 of the proxy"),
        "strength": Param("float", 0.0, MAX_STRENGTH, unit="mean-dot mass px^2/s^2", optional=True,
                          doc="Hamaker constant of the hamaker model",
                          unset="gives two mean-size dots at a 1 px gap the thesis proxy's pull"),
        "min_gap": Param("float", 0.0, MAX_RANGE, low_open=True, unit="px", doc="closer counts as contact"),
        "max_gap": Param("float", 0.0, 2 * MAX_RANGE, low_open=True, unit="px", optional=True,
                         doc="no force beyond this gap", rule="above min_gap", unset="2 r0"),
        "contact": Param("str", choices=CONTACTS, doc='force below min_gap ("zero": none, "hold": the force at min_gap)'),
        "offset": Param("float", -MAX_RANGE, MAX_RANGE, unit="px", optional=True, doc="the proxy's b",
                        rule="below min_gap", unset="from restitution.sticking_speed"),
        "scale": Param("float", 0.0, MAX_SCALE, doc="multiplies the pull (1: the thesis's)"),
    }

    def __init__(
        self,
        model: str = "thesis",
        *,
        r0: float = 15.0,
        strength: float | None = None,
        min_gap: float = 0.1,
        max_gap: float | None = None,
        contact: str = "zero",
        offset: float | None = None,
        scale: float = 1.0,
    ):
        p = self.PARAMS
        model = p["model"].check("VanDerWaals.model", model)
        contact = p["contact"].check("VanDerWaals.contact", contact)
        # Derived defaults stay "unset" in params(), so a saved scene whose r0 is
        # edited recomputes them instead of freezing the old values.
        self._unset = {name for name, value in (("strength", strength), ("max_gap", max_gap)) if value is None}
        r0 = p["r0"].check("VanDerWaals.r0", r0)
        max_gap = p["max_gap"].check("VanDerWaals.max_gap", 2.0 * r0 if max_gap is None else max_gap)
        min_gap = p["min_gap"].check("VanDerWaals.min_gap", min_gap)
        if max_gap <= min_gap:
            raise InputError(f"VanDerWaals.max_gap ({max_gap}) must exceed min_gap ({min_gap})")
        offset = p["offset"].check("VanDerWaals.offset", offset)
        if offset is not None and offset >= min_gap:
            raise InputError(f"VanDerWaals.offset ({offset}) must be below min_gap ({min_gap})")
        self.offset = offset
        self.model = model
        self.r0 = float(r0)
        self.min_gap = float(min_gap)
        self.max_gap = float(max_gap)
        self.contact = contact
        self.strength = p["strength"].check("VanDerWaals.strength", strength)
        self.scale = p["scale"].check("VanDerWaals.scale", scale)

    def params(self) -> dict:
        params = super().params()
        if self.scale == 1.0:  # the thesis's pull: scene files written before the scale existed stay as they were
            del params["scale"]
        return {key: (None if key in self._unset else value) for key, value in params.items()}

    def check_rule(self, restitution) -> None:
        """`InputError` when the offset ``b`` would come from a sticking speed under `MIN_PROXY_STICKING` (0, or
        so small that ``b`` overflows to -inf in floating point: no pull)."""
        if self.offset is None and (self.model == "thesis" or self.strength is None) \
                and not restitution.sticking_speed >= MIN_PROXY_STICKING:
            raise InputError("VanDerWaals derives the thesis proxy's offset b from restitution.sticking_speed, which "
                             f"is {restitution.sticking_speed:g} (b would be -inf, no pull): give a sticking speed "
                             f"of at least {MIN_PROXY_STICKING:g} px/s, or VanDerWaals.offset")

    def proxy_offset(self, sticking_speed: float) -> float:
        """The offset ``b`` of the thesis proxy, px: `offset`, else `thesis_offset` at ``sticking_speed`` px/s."""
        return self.offset if self.offset is not None else thesis_offset(self.r0, self.min_gap, sticking_speed)

    def hamaker_strength(self, offset: float) -> float:
        """The Hamaker constant of the ``"hamaker"`` model: `strength`, else the one that gives two mean-size dots
        (7.5 px) at a 1 px gap the thesis proxy's acceleration ``a/2`` at offset ``offset`` px."""
        if self.strength is not None:
            return self.strength
        proxy = 0.5 * (self.r0 / (1.0 - offset)) ** 7
        return self.PARAMS["strength"].check("VanDerWaals.strength", proxy / hamaker_force(1.0, 7.5, 7.5, 1.0))

    def kick(self, ctx: StepContext) -> None:
        ctx.pairs.pull(self, ctx)

    def pair_constants(self, ctx: StepContext) -> dict:
        """What the pull derives from the dots and the collision rule once per run: the inverse masses, the
        proxy's offset and the Hamaker constant (`qdots.engine.pair_scheme.PairLaw`)."""
        assert ctx.restitution is not None  # the engine hands each step the collision rule
        offset = self.proxy_offset(ctx.restitution.sticking_speed)
        # the pull enters every kick and the proxy's cap as pull / mass: its scale rides on the inverse masses
        return {"inv_mass": np.ascontiguousarray(self.scale / ctx.masses, dtype=float), "offset": offset,
                "strength": self.hamaker_strength(offset)}

    def add_pair_kicks(self, constants: dict, x, y, i, j, radii, gap_to: float, fade_from: float, fade_to: float,
                       far: bool, seconds: float, dv) -> None:
        """Add the pull over ``seconds`` of the pairs ``(i, j)`` closer than the surface gap ``gap_to`` to ``dv``:
        the near or the far part (`add_pair_kicks`, the module's compiled pass) at positions ``x, y`` (px)."""
        add_pair_kicks(x, y, i, j, radii, constants["inv_mass"], HAMAKER if self.model == "hamaker" else THESIS,
                       self.r0, constants["offset"], constants["strength"], self.min_gap, gap_to, fade_from, fade_to,
                       far, self.contact == "zero", seconds, dv)
