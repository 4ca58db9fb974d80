"""The forward model of ``qdots infer``: deposition parameters in, the measures of the film they make out.

A point is a flat dict: the four continuous model parameters (`PARAMETERS`), the mass exponent of one of
the mass models (`MASS_MODELS`, the model choice), the two conditions taken from the micrograph (`CONDITIONS`:
the size spread sigma and the coverage), the dots of the simulated film and its seed. `film_experiment` turns
it into the thesis's deposition (random arrival one dot per second, 100 s to settle, van der Waals attraction
as the thesis's proxy and thermal kicks, on the event engine) on a closed square board whose side gives the
coverage, as `qdots.inference.compare` does. `film_measures` measures a film the way a micrograph is
measured: the neighbourhood measures over the dots whose whole neighbourhood is inside the picture (for a
simulated board: away from its walls), and every measure intensive (a share, a mean, a length in mean
diameters), so films of different sizes compare. `FilmRunner` runs a point for the sweep machinery
(`labrig.sweeps.run_sweep`): one row of measures per film.

The continuous parameters, each sampled uniformly between its bounds by the prior of the inference:

* ``kick``: log10 of the thermal kick speed in units of the thesis's (`qdots.forces.ThermalKicks`
  ``scale``).
* ``restitution``: the mean coefficient of restitution of dot-dot impacts (`qdots.Restitution`).
  Below 0.7 the event engine meets inelastic collapse (a film of 150 dots at 0.5 took 240 s against
  2 s at 0.8, measured on a 2-core machine), so the prior starts there.
* ``drag``: log10 of the substrate's linear friction ``f1`` (1/s) of `qdots.forces.Drag`, its quadratic
  part ``f1 / 30`` 1/px in the thesis's ratio; the thesis's figures have none (10^-3/s damps a dot by
  0.2 % over the whole run), its code's default is 0.025/s (-1.6).
* ``attraction``: log10 of the van der Waals pull over the thesis's (`qdots.forces.VanDerWaals` ``scale``),
  which the ligands and the solvent set: from a quarter to four times the thesis's.

The mass model, one of three with equal prior probability (`MASS_MODELS`): masses ``(d / mean d)^p``
(`qdots.deposition.dot_masses`, model ``"power"``) with p = 0 (the thesis's figures), 2 (its text) or 3 (its
Java code). The thesis's question, mass or damping, is a choice between such hypotheses, so the inference
gives each model's posterior probability rather than an interval on p.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from labrig.validate import InputError, count, real

from ..analysis.packing import INTERIOR_MIN_NEIGHBOURS, neighbour_counts
from ..analysis.structure import clusters, hexatic_order, radial_distribution
from ..deposition import MAX_MASS_EXPONENT
from ..engine import Event
from ..experiment import Board, Deposition, Experiment, build_simulation, populate
from ..forces import Drag, ThermalKicks, VanDerWaals
from ..micrograph.choices import FILM_DOTS, MAX_FILM_DOTS
from ..micrograph.film import complete_neighbourhood
from ..presets import MEAN_DIAMETER
from ..restitution import Restitution


@dataclass(frozen=True)
class Parameter:
    """One axis of the inference: its key in a point, bounds of its uniform prior, the thesis's value."""

    key: str
    label: str
    low: float
    high: float
    thesis: float
    doc: str


#: The continuous model parameters the picture is asked about (the posterior's networks).
PARAMETERS = (
    Parameter("kick", "log10 kick / thesis kick", -1.0, 0.7, 0.0, "thermal kick speed over the thesis's, log10"),
    Parameter("restitution", "restitution", 0.7, 0.95, 0.8, "mean coefficient of restitution of dot-dot impacts"),
    Parameter("drag", "log10 drag f1 (1/s)", -3.0, 0.0, -3.0, "linear substrate friction f1, 1/s, log10"),
    Parameter("attraction", "log10 pull / thesis pull", -0.6, 0.6, 0.0,
              "van der Waals pull over the thesis's, log10 (`qdots.forces.VanDerWaals` scale)"),
)


@dataclass(frozen=True)
class MassModel:
    """One hypothesis on the dots' masses, ``m ~ (d / mean d)^exponent``: the model choice of the inference."""

    key: str
    label: str
    exponent: float


#: The mass models the picture is asked to choose between, each a third of the prior: equal masses (the
#: thesis's figures), masses ~ d^2 (its text) and ~ d^3 (its Java code, a dot's volume).
MASS_MODELS = (MassModel("equal", "equal masses (p = 0)", 0.0), MassModel("area", "masses ~ d^2 (p = 2)", 2.0),
               MassModel("volume", "masses ~ d^3 (p = 3)", 3.0))
#: The point's key of the mass exponent (any value in [0, `MAX_MASS_EXPONENT`] simulates; the prior draws
#: only those of `MASS_MODELS`).
MASS_KEY = "mass_exponent"
#: What the micrograph gives and the simulation is built to match (sampled over these ranges in training). The
#: coverage runs from sparse films to dense monolayers: a closed board of 150 dots takes about 2 s at 0.05 as at
#: 0.7 (2-core machine); 0.7 is about where random arrival still places every dot without a jam.
CONDITIONS = (
    Parameter("sigma", "size spread sigma", 0.03, 0.25, 0.15, "standard deviation of the diameter over its mean"),
    Parameter("coverage", "coverage", 0.05, 0.7, 0.336, "share of the area the dots cover"),
)
#: Every measure of a film (`film_measures`), with its label; the inference uses `SUMMARIES` of them.
MEASURES = {
    "interior_fraction": "interior fraction (>= 5 neighbours)",
    "mean_neighbours": "mean neighbours",
    "psi6_local": "psi6 local",
    "psi6_global": "psi6 global",
    "gr_peak_diameters": "g(r) first peak (mean diameters)",
    "gr_peak_height": "g(r) first peak height",
    "aggregates": "aggregates (>= 5 dots) per 100 dots",
    "largest_share": "largest cluster (share)",
    "low_share": "dots with <= 2 neighbours (share)",
    "single_share": "single dots (share)",
    "small_share": "dots in clusters of < 5 (share)",
    "mean_gap": "nearest surface gap (mean diameters)",
}
#: The measures the posterior is conditioned on: intensive, and read from a picture as from a board. Left
#: out: psi6 global, the largest cluster and the aggregates per dot (they depend on the film's size or the
#: picture's edge), and the g(r) peak and the nearest gap (a diameter measured 2 % off moves them as much as the
#: parameters do: on the shared micrograph the nearest gap reads 0.037 mean diameters where the films it
#: resembles give 0.013-0.021).
SUMMARIES = ("interior_fraction", "mean_neighbours", "psi6_local", "low_share", "single_share", "small_share")


#: The mass exponent as a point's value is checked: any exponent in the deposition's range simulates.
MASS_PARAMETER = Parameter(MASS_KEY, "mass exponent p (m ~ d^p)", 0.0, MAX_MASS_EXPONENT, 0.0, "masses (d / mean d)^p")


def parameter_keys() -> tuple[str, ...]:
    """The keys of the model parameters, in order."""
    return tuple(p.key for p in PARAMETERS)


def mass_model_index(exponent: float) -> int:
    """The index in `MASS_MODELS` of the model with this ``exponent``; `InputError` for any other."""
    for k, model in enumerate(MASS_MODELS):
        if float(exponent) == model.exponent:
            return k
    raise InputError(f"{MASS_KEY} {exponent!r} is none of the mass models' "
                     f"({', '.join(f'{m.exponent:g}' for m in MASS_MODELS)})")


def condition_keys() -> tuple[str, ...]:
    """The keys of the conditions, in order."""
    return tuple(c.key for c in CONDITIONS)


def check_point(point: dict) -> dict:
    """``point`` checked (every key known, each value in its prior's range) and as plain floats and ints."""
    if not isinstance(point, dict):
        raise InputError(f"a film point must be a dict, got {type(point).__name__}")
    known = {p.key: p for p in (*PARAMETERS, MASS_PARAMETER, *CONDITIONS)}
    unknown = sorted(set(point) - set(known) - {"n_dots", "seed"})
    if unknown:
        raise InputError(f"unknown key {unknown[0]!r} in a film point (known: {', '.join([*known, 'n_dots', 'seed'])})")
    out = {}
    for key, p in known.items():
        if key not in point:
            raise InputError(f"a film point needs {key!r} ({p.doc})")
        out[key] = real(key, point[key], p.low, p.high)
    out["n_dots"] = count("n_dots", point.get("n_dots", FILM_DOTS), 10, MAX_FILM_DOTS)
    out["seed"] = count("seed", point.get("seed", 0), 0, 2**63 - 1)
    return out


def film_experiment(point: dict) -> Experiment:
    """The thesis's deposition at ``point`` (see the module) on the event engine."""
    point = check_point(point)
    n, sigma = point["n_dots"], point["sigma"]
    side = math.sqrt(n * math.pi * MEAN_DIAMETER**2 * (1.0 + sigma**2) / (4.0 * point["coverage"]))
    f1 = 10.0 ** point["drag"]
    forces = (VanDerWaals(scale=10.0 ** point["attraction"]), ThermalKicks(scale=10.0 ** point["kick"]), Drag(linear=f1, quadratic=f1 / 30.0))
    deposition = Deposition(protocol="random", n_dots=n, mean_diameter=MEAN_DIAMETER, sigma=sigma,
                            mass_model="power", mass_exponent=point[MASS_KEY], interval=1.0, settle=100.0)
    return Experiment(name="film of qdots infer", seed=point["seed"], board=Board(side, side, True),
                      deposition=deposition, restitution=Restitution(mean=point["restitution"]), forces=forces,
                      engine=Event())


def film_measures(state, complete: np.ndarray | None = None) -> dict:
    """Every measure of `MEASURES` of a board, edge-aware.

    Parameters
    ----------
    state : qdots.State
        A simulated board or a measured film (`qdots.micrograph.film.film_state`).
    complete : bool array (N,), optional
        Dots whose whole neighbourhood is in the picture; default `complete_neighbourhood` of the board's box
        (for a simulated board: the dots away from its walls). The neighbourhood measures, the shares and the
        gaps are over these dots; every dot takes part as a neighbour.

    Returns
    -------
    dict
        The measures of `MEASURES`; ``complete_dots`` (how many dots they are over); ``film_sigma`` and
        ``film_coverage``, the size spread (SD / mean of every diameter) and coverage (disc area over the box's)
        the film has (a simulated film's differ from its point's by the draw of its diameters).
    """
    n = len(state.radii)
    complete = complete_neighbourhood(state) if complete is None else np.asarray(complete, dtype=bool)
    out = {key: math.nan for key in MEASURES}
    out["complete_dots"] = int(complete.sum())
    d = 2.0 * np.asarray(state.radii, dtype=float)
    out["film_sigma"] = float(d.std(ddof=1) / d.mean()) if n > 1 else math.nan
    out["film_coverage"] = float(np.sum(np.pi * d**2 / 4.0) / (state.box[0] * state.box[1]))
    if n < 3 or not complete.any():
        return out
    radii = np.asarray(state.radii, dtype=float)
    mean_d = 2.0 * float(radii.mean())
    counts = neighbour_counts(state)
    hexatic = hexatic_order(state)
    inner = complete & (counts > 0)
    labels, sizes = clusters(state)
    own = sizes[labels]
    out.update(interior_fraction=float(np.mean(counts[complete] >= INTERIOR_MIN_NEIGHBOURS)),
               mean_neighbours=float(counts[complete].mean()),
               aggregates=100.0 * float(np.sum(sizes >= 5)) / n, largest_share=float(sizes[0]) / n,
               low_share=float(np.mean(counts[complete] <= 2)), single_share=float(np.mean(own[complete] == 1)),
               small_share=float(np.mean(own[complete] < 5)))
    if inner.any():
        out.update(psi6_local=float(np.abs(hexatic.psi[inner]).mean()),
                   psi6_global=float(abs(hexatic.psi[inner].mean())))
    from scipy.spatial import cKDTree  # a nearest-neighbour query, not a pair search (tests/qdots/test_geometry.py)

    positions = np.asarray(state.positions, dtype=float)
    chosen = np.flatnonzero(complete)
    distance, nearest = cKDTree(positions).query(positions[chosen], k=2)
    other = np.where(nearest[:, 1] == chosen, nearest[:, 0], nearest[:, 1])  # a twin at the same centre comes first
    gaps = distance[:, 1] - radii[chosen] - radii[other]
    out["mean_gap"] = float(np.mean(np.maximum(gaps, 0.0))) / mean_d
    rdf = radial_distribution(state, r_max=min(3.0 * mean_d, *state.box), bins=120)
    g = np.where(np.isfinite(rdf.g), rdf.g, -np.inf)
    k = int(np.argmax(g))
    if math.isfinite(g[k]):
        out.update(gr_peak_diameters=peak_position(rdf.r, g, k) / mean_d, gr_peak_height=float(g[k]))
    return out


def peak_position(r: np.ndarray, g: np.ndarray, k: int) -> float:
    """Where the parabola through the bins ``k - 1, k, k + 1`` of ``g`` peaks (``r[k]`` at an end or a flat top)."""
    if 0 < k < len(g) - 1 and np.isfinite(g[k - 1 : k + 2]).all():
        curve = g[k - 1] - 2.0 * g[k] + g[k + 1]
        if curve < 0:
            return float(r[k] + 0.5 * (g[k - 1] - g[k + 1]) / curve * (r[k + 1] - r[k]))
    return float(r[k])


def image_point(film) -> dict:
    """The conditions of a measured film (`qdots.micrograph.measure.MeasuredFilm`): its sigma and coverage;
    `InputError` (one line, naming the range) when either lies outside what the library is trained on."""
    s = film.summary
    out = {}
    for c, value in zip(CONDITIONS, (s["size_spread"], s["coverage"])):
        if not (math.isfinite(value) and c.low <= value <= c.high):
            raise InputError(f"{film.image.source}: the film's {c.label} is {value:.3g}, outside the "
                             f"[{c.low:g}, {c.high:g}] the inference's simulations cover")
        out[c.key] = float(value)
    return out


def image_measures(film, complete: np.ndarray | None = None) -> dict:
    """`film_measures` of a measured film: its board and the dots whose neighbourhood is in the picture (or those
    of them in ``complete``, a part of the picture: `image_parts`)."""
    return film_measures(film.state, film.complete if complete is None else film.complete & complete)


#: Fewest dots with their whole neighbourhood in a part of a picture for it to count as an observation.
MIN_PART_DOTS = 40


def image_parts(film, dots: int = FILM_DOTS) -> list[np.ndarray]:
    """A picture cut into parts of about ``dots`` measured dots each: a grid of rectangles over the region its
    measured dots span, as square as that region allows, one bool mask (N,) per part of the dots whose whole neighbourhood is in the
    picture and whose centre is in that part; every dot takes part as a neighbour.

    The library's films hold `FILM_DOTS` dots: a picture of thousands of dots is, to the posterior, many such
    films, each an independent observation of the same deposition (the measures are local: a dot's neighbours,
    its cluster's size). A picture with fewer than twice ``dots`` such dots is one part; parts with fewer than
    `MIN_PART_DOTS` are merged into no other and left out."""
    complete = np.asarray(film.complete, dtype=bool)
    total = int(complete.sum())
    parts = max(1, int(round(total / max(1, dots))))
    if parts < 2:
        return [complete]
    x, y = np.asarray(film.state.positions, dtype=float).T
    x0, x1, y0, y1 = x[complete].min(), x[complete].max(), y[complete].min(), y[complete].max()
    w, h = max(x1 - x0, 1e-9), max(y1 - y0, 1e-9)  # the region the measured dots span
    cols = max(1, int(round(math.sqrt(parts * w / h))))
    rows = max(1, int(round(parts / cols)))
    col = np.clip(((x - x0) / w * cols).astype(int), 0, cols - 1)
    row = np.clip(((y - y0) / h * rows).astype(int), 0, rows - 1)
    masks = [complete & (col == c) & (row == r) for r in range(rows) for c in range(cols)]
    return [m for m in masks if m.sum() >= MIN_PART_DOTS] or [complete]


#: Most wall seconds a film may take (checked every simulated second). A typical film of 150 dots takes about
#: 1.5 s; weak kicks with dissipative impacts can bring a cluster to inelastic collapse, and one such film took more
#: than 5 minutes (2-core machine). A film over budget is stopped and recorded as failed, so that one point cannot
#: stall a library; failed films are left out of the training and counted (`qdots.inference.library.Library`).
MAX_FILM_SECONDS = 60.0


class FilmTooSlow(RuntimeError):
    """A film ran past its wall-time budget (`MAX_FILM_SECONDS`)."""


#: The simulated seconds a film runs before its wall-time budget starts (by then its first dots have met, and every
#: compiled kernel a film calls has been compiled or loaded), and the most wall seconds that start may take
#: (numba's first compilation on a new install, two workers at once on a busy machine).
WARM_SECONDS, MAX_WARM_WALL_SECONDS = 5.0, 600.0


class WallBudget:
    """A run writer that stops the run, raising `FilmTooSlow`, once ``seconds`` of wall time have passed since the
    film reached `WARM_SECONDS` of simulated time: the compilation the first films of a new worker pay never counts
    against a film. Bounded all the same: a film that has not reached it within `MAX_WARM_WALL_SECONDS` is stopped
    too."""

    def __init__(self, seconds: float):
        self.seconds = seconds
        self.started = time.perf_counter()
        self.deadline: float | None = None

    def write(self, state) -> None:
        now = time.perf_counter()
        if self.deadline is None and state.time >= WARM_SECONDS:
            self.deadline = now + self.seconds
        if self.deadline is not None and now > self.deadline:
            raise FilmTooSlow(f"the film ran past its budget of {self.seconds:g} wall s at t = {state.time:.0f} s "
                              "(inelastic collapse is the usual cause: weak kicks, dissipative impacts)")
        if self.deadline is None and now > self.started + MAX_WARM_WALL_SECONDS:
            raise FilmTooSlow(f"the film's first {WARM_SECONDS:g} simulated s took over {MAX_WARM_WALL_SECONDS:g} wall "
                              "s (compilation included)")


def simulate_film(point: dict, max_seconds: float | None = None):
    """Run the film of ``point``; returns the `qdots.Simulation` at its end. `FilmTooSlow` past ``max_seconds`` of
    wall time (default `MAX_FILM_SECONDS`)."""
    exp = film_experiment(point)
    sim = build_simulation(exp)
    budget = MAX_FILM_SECONDS if max_seconds is None else real("max_seconds", max_seconds, 0.0, low_open=True, unit="s")
    sim.attach(WallBudget(budget), seconds=1.0)
    return populate(sim, exp)


@dataclass(frozen=True)
class FilmRunner:
    """A runner of `labrig.sweeps.run_sweep`: one film per point, its row `film_measures` (and its state file)."""

    kind = "qdots.inference.forward.FilmRunner/1"
    state_suffix = ".npz"

    def canonical(self, params: dict) -> dict:
        """The checked point (`check_point`), floats rounded to 12 significant digits (stable hashes)."""
        point = check_point(params)
        return {k: (float(f"{v:.12g}") if isinstance(v, float) else v) for k, v in point.items()}

    def estimate(self, params: dict) -> float:
        """About how many wall seconds one film takes on one core: 2 s at 150 dots, growing as n^1.5 (measured on
        a 2-core machine; 300 dots take about 4.6 s)."""
        return 2.0 * (params.get("n_dots", FILM_DOTS) / FILM_DOTS) ** 1.5

    def __call__(self, params: dict, state_path: Path | None = None) -> dict:
        from ..io import checkpoint

        sim = simulate_film(params)
        row = film_measures(sim.state())
        if state_path is not None:
            checkpoint.save(sim, state_path)
        return row
