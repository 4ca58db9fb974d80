"""The thesis's deposition protocols, run on a live `Simulation`.

Appendix A's ``FileDepositer`` builds a film one dot at a time while the
board keeps moving: draw a diameter ``d = mean (1 + sigma N(0, 1))`` and a
uniformly random position; if the dot overlaps one already on the board,
draw both again; add it; advance the board ``interval`` seconds; repeat
(``addRandomBallInRect``, ``runRandomAttraction*``). `deposit` does that.
`deposit_around_centre` is ``runRandomCenter``: the i-th dot is dropped on a
ring that grows with the cluster around the centre of gravity.

Candidates are drawn in batches of `BATCH` and the first that fits is taken:
the one-at-a-time process exactly (candidates are independent), with the
batch size part of the random stream.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from labrig.progress import progress_bar
from labrig.validate import InputError, count, generator, real

from .geometry import DiscTree, clear_of_walls
from .placement import MAX_TRIES, draw_candidates
from .scene import MAX_DOTS, MAX_LENGTH, MAX_MASS, MIN_DIAMETER

#: Mass models (see `dot_masses`).
MASS_MODELS = ("equal", "area", "volume", "bimodal", "power")
#: Largest exponent of the "power" mass model (masses ~ d^p).
MAX_MASS_EXPONENT = 6.0
#: Area fraction of hexagonal close packing, ``pi sqrt(3) / 6`` (thesis ``packingInPlane``).
HEX_PACKING = math.pi * math.sqrt(3.0) / 6.0
#: Clearance between a new dot and other dots, walls and region edges, px (thesis ``2 epsilonSpace``).
GAP = 1e-6
#: Candidates drawn per batch. Part of the random stream: changing it changes the films.
BATCH = 32
#: Longest time between two dots, s (the thesis: 1 s, centre runs 0.5 s).
MAX_INTERVAL = 1e4



def as_generator(rng, sim=None) -> np.random.Generator:
    """``rng`` as a numpy Generator; ``None`` gives a child of ``sim.rng`` (spawning does not advance the
    simulation's own stream). Otherwise as `labrig.validate.generator`."""
    if rng is None and sim is not None:
        seed_seq = getattr(sim.rng.bit_generator, "seed_seq", None) or sim.rng.bit_generator._seed_seq
        return np.random.default_rng(seed_seq.spawn(1)[0])  # Generator.spawn needs numpy >= 1.25
    return generator("rng", rng)


def draw_diameters(n: int, mean_diameter: float, sigma: float, rng: np.random.Generator) -> np.ndarray:
    """Draw ``n`` diameters ``d = mean_diameter (1 + sigma N(0, 1))``, px, redrawing any ``d <= 0``.

    ``sigma`` is a fraction of the mean, in [0, 1). With ``sigma == 0`` no
    random number is used (the Java skips ``nextGaussian`` too).
    """
    n, sigma = count("n", n, 0, MAX_DOTS), real("sigma", sigma, 0.0, 1.0, high_open=True)
    mean_diameter = real("mean_diameter", mean_diameter, MIN_DIAMETER, MAX_LENGTH, unit="px")
    if sigma == 0.0:
        return np.full(n, mean_diameter)
    d = mean_diameter * (1.0 + sigma * rng.standard_normal(n))
    bad = np.flatnonzero(d <= 0)
    while bad.size:
        d[bad] = mean_diameter * (1.0 + sigma * rng.standard_normal(bad.size))
        bad = bad[d[bad] <= 0]
    return d


def dot_masses(diameters, mean_diameter: float, model: str = "equal", heavy_mass: float = 2.0,
               rng: np.random.Generator | None = None, exponent: float | None = None) -> np.ndarray:
    """Masses of dots of the given diameters, in units of a mean-size dot's mass.

    Parameters
    ----------
    diameters : array_like, shape (N,)
        Dot diameters, px (> 0).
    mean_diameter : float
        Mean diameter, px (> 0).
    model : {"equal", "area", "volume", "bimodal"}
        ``"equal"`` (default): all 1, as the thesis's figure runs
        (``relativeMasses = false``: Fig 2-2, the equal curve of 2-6a).
        ``"area"``: ``(d / mean)^2``, what the thesis text says ("scaling the
        mass with the surface area"). ``"volume"``: ``(d / mean)^3``, what the
        Java code does when masses scale (``baseMass (d/2)^3 / (mean/2)^3``).
        ``"bimodal"``: each dot independently ``heavy_mass`` with probability
        1/2, else 1 (``runRandomAttractionBimodal``, Table 2.1). ``"power"``:
        ``(d / mean)^exponent``, any exponent in [0, `MAX_MASS_EXPONENT`] (0 equal, 2 area, 3 volume).
    heavy_mass : float
        Mass of a heavy dot in the bimodal model (> 0; thesis 2.0).
    rng : numpy.random.Generator
        Needed by ``"bimodal"`` only.
    exponent : float, optional
        Needed by ``"power"`` only.

    Returns
    -------
    ndarray, shape (N,)
    """
    d = np.asarray(diameters, dtype=float)
    if d.ndim != 1 or not (np.isfinite(d).all() and (d > 0).all()):
        raise InputError("diameters must be a 1-D array of finite values > 0 px")
    return mass_rule(mean_diameter, model, heavy_mass, rng, exponent)(d)


def mass_rule(mean_diameter: float, model: str = "equal", heavy_mass: float = 2.0,
              rng: np.random.Generator | None = None,
              exponent: float | None = None) -> Callable[[np.ndarray], np.ndarray]:
    """The mass model of `dot_masses`, checked once: a function from diameters (px, > 0) to masses.

    A deposition checks its mass model with this before its first dot, and each dot's mass is then the
    function's value, with nothing checked again.
    """
    mean_diameter = real("mean_diameter", mean_diameter, 0.0, MAX_LENGTH, low_open=True, unit="px")
    if model == "equal":
        return lambda d: np.ones(len(d))
    if model in ("area", "volume"):
        return lambda d: (d / mean_diameter) ** (2 if model == "area" else 3)
    if model == "power":
        if exponent is None:
            raise InputError("mass model 'power' needs an exponent (deposition.mass_exponent)")
        p = real("mass_exponent", exponent, 0.0, MAX_MASS_EXPONENT)
        return lambda d: (d / mean_diameter) ** p
    if model == "bimodal":
        heavy = real("heavy_mass", heavy_mass, 0.0, MAX_MASS, low_open=True)
        if rng is None:
            raise InputError("mass model 'bimodal' needs an rng")
        return lambda d: np.where(rng.random(len(d)) < 0.5, heavy, 1.0)
    raise InputError(f"mass model must be one of {MASS_MODELS}, got {model!r}")


def ring_radius(i: int, mean_diameter: float, sigma: float) -> float:
    """Distance from the centre at which ``runRandomCenter`` drops its i-th dot (0-based), px.

    ``sqrt(HEX_PACKING i) mean / 2 + 3 mean + sigma mean``, verbatim from the
    Java (``i`` close-packed dots fill a radius ``sqrt(i / HEX_PACKING) mean / 2``;
    the Java multiplies).
    """
    return math.sqrt(HEX_PACKING * i) * mean_diameter / 2.0 + (3.0 + sigma) * mean_diameter


def _clear(pos: np.ndarray, r: np.ndarray, board: DiscTree, segments: np.ndarray) -> np.ndarray:
    """Which candidates keep `GAP` clear of every dot on the ``board`` and every extra wall."""
    return (board.clashing_partners(pos, r, GAP) < 0) & clear_of_walls(pos, r, segments, GAP)


def _sequential(sim, n, mean_diameter, mass_model, heavy_mass, interval, max_tries, rng, progress,
                draw, where, area, mass_exponent=None) -> np.ndarray:
    """Place, add, advance, ``n`` times; ``draw(i, m)`` gives ``m`` candidates for dot ``i``.

    The whole deposition is checked first: at most `qdots.scene.MAX_DOTS` dots on the board at the end,
    and its ``n`` runs of ``interval`` s checked as one run (`qdots.Simulation.check_run`: steps, forces,
    writers).
    """
    n, max_tries = count("n_dots", n, 0, MAX_DOTS), count("max_tries", max_tries, 1, MAX_TRIES)
    interval = real("interval", interval, 0.0, MAX_INTERVAL, unit="s")
    masses = mass_rule(mean_diameter, mass_model, heavy_mass, rng, mass_exponent)
    if sim.n_dots + n > MAX_DOTS:
        raise InputError(f"n_dots = {n:,} would bring the board to {sim.n_dots + n:,} dots ({sim.n_dots:,} on it), "
                         f"more than the {MAX_DOTS:,} allowed")
    try:
        sim.check_run(n * round(interval / sim.dt) * sim.dt)
    except InputError as exc:
        raise InputError(f"n_dots = {n:,} dots {interval:g} s apart: {exc}") from None
    diameters = np.empty(n)
    with progress_bar(n, unit="dot", desc="qdots deposit", show=progress, leave=False) as bar:
        for i in range(n):
            board, tries, hit = sim.state(), 0, None
            placed = DiscTree(board.positions, board.radii)
            while hit is None and tries < max_tries:
                pos, r, ok = draw(i, min(BATCH, max_tries - tries))
                good = np.flatnonzero(ok & _clear(pos, r, placed, sim.scene.segments))
                hit, tries = (good[0] if good.size else None), tries + len(r)
            if hit is None:
                fraction = float(np.sum(np.pi * board.radii**2)) / area
                raise InputError(f"board too full: placed {i} of {n} dots; {max_tries} consecutive candidates "
                                 f"for the next one overlapped a dot or wall or did not fit {where}; the "
                                 f"dots cover an area fraction {fraction:.3f} of it")
            diameters[i] = 2.0 * r[hit]
            sim.add_dots(pos[hit][None, :], r[hit : hit + 1], masses=masses(diameters[i : i + 1]))
            sim.run(interval)
            bar.update(1)
    return diameters


def _check_region(region, box) -> tuple[float, float, float, float]:
    w, h = box
    if region is None:
        return 0.0, 0.0, float(w), float(h)
    try:
        x0, y0, x1, y1 = (float(v) for v in region)
    except (TypeError, ValueError):
        raise InputError(f"region must be (x0, y0, x1, y1) in px, got {region!r}") from None
    if not (0 <= x0 < x1 <= w and 0 <= y0 < y1 <= h):
        raise InputError(f"region must satisfy 0 <= x0 < x1 <= {w:g} and 0 <= y0 < y1 <= {h:g} "
                         f"(the box), got {region!r}")
    return x0, y0, x1, y1


def deposit(sim, n_dots: int, mean_diameter: float = 15.0, sigma: float = 0.0, region=None,
            mass_model: str = "equal", heavy_mass: float = 2.0, interval: float = 1.0,
            max_tries: int = 10_000, rng=None, progress: bool = False,
            mass_exponent: float | None = None) -> np.ndarray:
    """Deposit dots one at a time at random positions (thesis ``runRandomAttraction*``).

    For each dot: draw ``d = mean_diameter (1 + sigma N(0, 1))`` (`qdots.placement.draw_candidates`)
    and a centre uniform over the positions where the dot lies inside
    ``region``; if it comes within `GAP` of a dot now on the board or of an
    extra wall segment, draw both again. Add it (mass from `dot_masses`) and
    run the board ``interval`` seconds (rounded to whole time steps, as `qdots.Simulation.run` does).

    Parameters
    ----------
    sim : Simulation
        The running board; advanced by ``n_dots * interval`` s (each rounded to whole steps).
    n_dots : int
        Dots to add (>= 0; the board holds at most `qdots.scene.MAX_DOTS`). The ``n_dots`` runs of
        ``interval`` s are checked as one run before the first dot (`qdots.Simulation.check_run`).
    mean_diameter : float
        Mean diameter, px (> 0; thesis 15).
    sigma : float
        Diameter standard deviation as a fraction of the mean, in [0, 1).
    region : (x0, y0, x1, y1), optional
        Rectangle the dots are dropped into, px; default the whole box. The
        thesis grating uses ``(0, 0, width, grating)``.
    mass_model, heavy_mass, mass_exponent
        See `dot_masses` (``mass_exponent`` is its ``exponent``).
    interval : float
        Simulated time between two dots, s (>= 0; thesis 1).
    max_tries : int
        Consecutive failed candidates for one dot before giving up (>= 1).
    rng : numpy.random.Generator, SeedSequence, int or None
        Source of the placement randomness. Default: a child of ``sim.rng``.
    progress : bool
        Show a progress bar over the dots. To record the deposition, attach writers to ``sim``
        (`qdots.Simulation.attach`) first: they see it as one continuous run.

    Returns
    -------
    ndarray, shape (N,)
        Diameters of the ``N = n_dots`` dots placed, px, in order.

    Raises
    ------
    labrig.validate.InputError
        On a bad argument (named, with its allowed range), or when
        ``max_tries`` candidates in a row fail: the board is too full (the
        message gives the dots placed, the region and its area fraction).
    """
    mean_diameter = real("mean_diameter", mean_diameter, MIN_DIAMETER, MAX_LENGTH, unit="px")
    sigma = real("sigma", sigma, 0.0, 1.0, high_open=True)
    x0, y0, x1, y1 = _check_region(region, sim.scene.box)
    if mean_diameter + 2 * GAP > min(x1 - x0, y1 - y0):
        raise InputError(f"mean_diameter {mean_diameter:g} px does not fit in region ({x0:g}, {y0:g}, "
                         f"{x1:g}, {y1:g}) px")
    gen = as_generator(rng, sim)

    def draw(i, m):
        return draw_candidates(gen, m, (x0, y0, x1, y1), mean_diameter, sigma, margin=GAP)

    return _sequential(sim, n_dots, mean_diameter, mass_model, heavy_mass, interval, max_tries, gen, progress,
                       draw, f"in region ({x0:g}, {y0:g}, {x1:g}, {y1:g}) px", (x1 - x0) * (y1 - y0), mass_exponent)


def deposit_around_centre(sim, n_dots: int, centre, mean_diameter: float = 15.0, sigma: float = 0.0,
                          interval: float = 0.5, mass_model: str = "equal", heavy_mass: float = 2.0,
                          max_tries: int = 10_000, rng=None, progress: bool = False,
                          mass_exponent: float | None = None) -> np.ndarray:
    """Deposit dots on a growing ring around ``centre`` (thesis ``runRandomCenter``).

    The i-th dot (0-based) is dropped at distance `ring_radius` ``(i)`` from
    ``centre`` at a uniformly random angle, its diameter drawn as in
    `deposit`; a candidate that overlaps a dot or wall or leaves the box is
    drawn again (angle and diameter). Pair it with `qdots.CentreGravity` at
    ``centre``, as ``runRandomCenterGravity`` does.

    Parameters
    ----------
    centre : (float, float)
        Centre of the ring, px.
    interval : float
        Simulated time between two dots, s (>= 0; thesis 0.5).
    sim, n_dots, mean_diameter, sigma, mass_model, heavy_mass, max_tries, rng, progress, mass_exponent
        As in `deposit`.

    Returns
    -------
    ndarray, shape (N,)
        Diameters of the ``N = n_dots`` dots placed, px.

    Raises
    ------
    ValueError
        On a bad argument, when the last ring leaves the box, or when the
        board is too full (as `deposit`).
    """
    mean_diameter = real("mean_diameter", mean_diameter, MIN_DIAMETER, MAX_LENGTH, unit="px")
    sigma, n = real("sigma", sigma, 0.0, 1.0, high_open=True), count("n_dots", n_dots, 0, MAX_DOTS)
    try:
        cx, cy = (float(v) for v in centre)
    except (TypeError, ValueError):
        raise InputError(f"centre must be (x, y) in px, got {centre!r}") from None
    w, h = sim.scene.box
    room, reach = min(cx, cy, w - cx, h - cy), ring_radius(max(n - 1, 0), mean_diameter, sigma)
    if n and reach + mean_diameter / 2 > room:
        raise InputError(f"n_dots = {n} needs a ring of radius {reach:.1f} px (+ a dot radius) around centre "
                         f"({cx:g}, {cy:g}) px, but the {w:g} x {h:g} px box leaves {room:.1f} px")
    gen = as_generator(rng, sim)

    def draw(i, m):
        radius, r = ring_radius(i, mean_diameter, sigma), 0.5 * draw_diameters(m, mean_diameter, sigma, gen)
        angle = gen.uniform(0.0, 2.0 * math.pi, m)
        pos = np.column_stack([cx + radius * np.cos(angle), cy + radius * np.sin(angle)])
        inside = ((pos - r[:, None] >= GAP) & (pos + r[:, None] <= np.array([w, h]) - GAP)).all(axis=1)
        return pos, r, inside

    return _sequential(sim, n, mean_diameter, mass_model, heavy_mass, interval, max_tries, gen, progress,
                       draw, f"on the ring around ({cx:g}, {cy:g}) px inside the box", w * h, mass_exponent)
