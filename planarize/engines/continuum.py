"""The continuum engine: the limit of the thesis's rule as grid and step shrink, computed as a flow.

The thesis's algorithm (`Reference`, `Fast`) moves grid points by a step at a time; as grid and step
shrink, it converges to a flow of the metal surface (`planarize.engines.flow`) under a conformal oxide
(`planarize.engines.offset`). This engine computes that flow on the grid, so that its answer depends
on the grid only by a small discretization error, which it estimates (`planarize.engines.resolution` runs it
at three resolutions and states Richardson's estimate at the order it observes, or that it observes none). Choose it with ``anodize(..., engine=Continuum())``
or ``engine="continuum"``; it is the default.

The model's ``k_exp`` and ``rule`` are the physics; its ``step``, ``distance`` and ``volume`` belong
to the thesis's discrete algorithm and do not apply (the flow uses the exact surface distance and
the exact volume).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from labrig.params import Param
from labrig.threads import available_threads, row_ranges, run_in_threads
from labrig.validate import InputError, count, real

from ..heightfield import Surface, volume_weights
from ..model import Model
from ..recording import Anodization
from . import PARAMS, RTOL
from .flow import GHOST, fill_ghosts, metal_rate, surface_area
from .offset import coat, extremes, surface_moments
from .resolution import converge

#: Refinement factors the engine may run at (internal grid = the surface's grid refined that many times).
MAX_REFINE = 16
#: Most threads.
MAX_THREADS = 256
#: Largest time step, in grid spacings of the internal grid (the hyperbolic part's Courant number).
COURANT = 0.5


@dataclass(frozen=True)
class Continuum:
    """The continuum engine and its accuracy settings: ``anodize(..., engine=Continuum(rtol=0.01))``.

    Parameters
    ----------
    rtol : float
        Relative discretization error of the RMS and z-range (metal and oxide, at every recorded
        thickness) that a run aims at, in [1e-4, 1]: the run refines its grid (internally, by
        factors of 2 from the surface's own) until its stated error estimate meets it, or until
        ``max_refine``, or until a finer grid would cost too much (`planarize.engines.resolution`).
        Default 0.02.
    refine : int, optional
        Compute at this refinement of the surface's grid instead (a power of 2 up to `MAX_REFINE`),
        with the error still estimated from the two coarser resolutions; at 1 (the map's own grid) no error is
        stated (`planarize.engines.resolution.OWN_GRID_FINER`).
    max_refine : int
        Largest refinement ``rtol`` may choose (a power of 2 up to `MAX_REFINE`; default 8).
    stability : float
        Time step as a fraction of the explicit scheme's stability limit, in (0, 1] (default 0.9);
        smaller steps change the answer by its time-discretization error.
    threads : int, optional
        Threads of the compiled kernels, in [1, `MAX_THREADS`]; results do not depend on it.
        Default: numba's default (the CPUs available).
    """

    rtol: float = RTOL
    refine: int | None = None
    max_refine: int = 8
    stability: float = 0.9
    threads: int | None = None

    name = "continuum"
    #: The declarations of the settings a scene file's ``[engine]`` table takes (`labrig.params.Param`).
    PARAMS: ClassVar[dict[str, Param]] = PARAMS["continuum"]

    def __post_init__(self) -> None:
        object.__setattr__(self, "rtol", self.PARAMS["rtol"].check("rtol", self.rtol))
        for key in ("refine", "max_refine"):
            value = getattr(self, key)
            if value is None:
                continue
            value = count(key, value, 1, MAX_REFINE)
            if value & (value - 1):
                raise InputError(f"{key} must be a power of 2 in [1, {MAX_REFINE}], got {value}")
            object.__setattr__(self, key, value)
        object.__setattr__(self, "stability", real("stability", self.stability, 0.0, 1.0, low_open=True))
        if self.threads is not None:
            object.__setattr__(self, "threads", count("threads", self.threads, 1, MAX_THREADS))

    def build(self, metal: Surface, oxide, model: Model, factor: float = 1.0) -> ContinuumEngine:
        """The engine for ``metal`` under ``model`` on its grid resampled by ``factor`` (a power of 2,
        below 1 for a coarser grid)."""
        return ContinuumEngine(metal, oxide, model, self, factor)

    def options(self) -> dict:
        """The settings as plain data (the fields that differ from the defaults)."""
        return {f.name: getattr(self, f.name) for f in dataclasses.fields(self) if getattr(self, f.name) != f.default}

    def run(self, metal: Surface, oxide, thickness: float, model: Model, rows_at: np.ndarray, shots_at: np.ndarray, *,
            progress: bool = False, observer=None, max_seconds: float | None = None) -> Anodization:
        """A run at the resolution ``rtol`` asks for, with its error estimate (`planarize.engines.resolution`);
        the arguments are `planarize.anodize`'s, checked. The continuum engine starts from bare metal."""
        if oxide is not None:
            raise InputError("the continuum engine starts from bare metal: oxide must be None (continue an "
                             "existing oxide with engine=\"fast\")")
        return converge(metal, thickness, model, self, rows_at, shots_at, progress=progress, observer=observer,
                        max_seconds=max_seconds)


def resample(surface: Surface, factor: float) -> Surface:
    """``surface`` on a grid ``factor`` times finer (``factor`` >= 1, linear: the same piecewise-linear
    surface) or coarser (``factor`` < 1: every ``1 / factor``-th point where the grid allows it, else
    its piecewise-linear surface sampled on the grid of ``1 / factor`` times fewer cells, rounded up,
    spanning the same extent)."""
    if factor >= 1:
        return surface.refine(int(round(factor)), "linear")
    step = int(round(1 / factor))
    z = surface.z
    nx, ny = surface.shape
    if surface.periodic:
        sub = nx % step == 0 and ny % step == 0
    else:
        sub = (nx - 1) % step == 0 and (ny - 1) % step == 0
    if sub:
        return Surface(z[::step, ::step], (surface.dx * step, surface.dy * step), surface.boundary)
    axes = []
    for n, d in ((nx, surface.dx), (ny, surface.dy)):
        if surface.periodic:
            m = max(2, -(-n // step))
            axes.append((np.arange(m) * (n / m), d * n / m))
        else:
            m = max(2, -(-(n - 1) // step) + 1)
            axes.append((np.linspace(0.0, n - 1, m), d * (n - 1) / (m - 1)))
    out = z
    for axis, (positions, _) in enumerate(axes):
        out = _linear_axis(out, positions, axis, surface.periodic)
    return Surface(out, (axes[0][1], axes[1][1]), surface.boundary)


def _linear_axis(z: np.ndarray, positions: np.ndarray, axis: int, periodic: bool) -> np.ndarray:
    z = np.moveaxis(z, axis, 0)
    values = np.concatenate([z, z[:1]]) if periodic else z
    k = np.minimum(np.floor(positions).astype(int), len(values) - 2)
    w = (positions - k)[:, None]
    return np.moveaxis((1.0 - w) * values[k] + w * values[k + 1], 0, axis)


class ContinuumEngine:
    """The flow of the metal under its conformal oxide, on one grid (see `Continuum`).

    Parameters
    ----------
    metal : Surface
        The metal at the start (bare: no oxide yet).
    oxide : None
        Must be None: the flow starts from bare metal.
    model : Model
        ``k_exp`` and ``rule``.
    settings : Continuum
    factor : float
        The internal grid is ``metal``'s resampled by this factor (`resample`).

    Notes
    -----
    The time steps are the explicit scheme's (a fraction of its stability limit), whatever the run
    records: a thickness asked for between two steps is reached by a step from the last one, shown
    until the next `advance`, and not continued from. The oxide's running maximum (`coat`) is updated
    once per grid spacing of thickness. So a run's surfaces do not depend on what it records.

    Attributes
    ----------
    iterations : int
        Time steps taken.
    """

    name = "continuum"

    def __init__(self, metal: Surface, oxide=None, model: Model | None = None, settings: Continuum | None = None,
                 factor: float = 1.0):
        if not isinstance(metal, Surface):
            raise InputError(f"metal must be a planarize.Surface, got {type(metal).__name__}")
        if oxide is not None:
            raise InputError("the continuum engine starts from bare metal (oxide=None); continue an oxide with "
                             "engine=\"fast\"")
        self.model = Model() if model is None else model
        self.settings = Continuum() if settings is None else settings
        self.k_exp = self.model.k_exp
        self.surface = metal
        self.factor = factor
        self.inner = resample(metal, factor)
        self.stride = int(round(factor)) if factor >= 1 else 0
        nx, ny = self.inner.shape
        self.dx, self.dy = self.inner.spacing
        self.periodic = self.inner.periodic
        self.padded = np.zeros((nx + 2 * GHOST, ny + 2 * GHOST))
        self.padded[GHOST:-GHOST, GHOST:-GHOST] = self.inner.z
        self.stage = self.padded.copy()
        self.rate = np.empty((nx, ny))
        self.rate2 = np.empty((nx, ny))
        self.row_stiff = np.zeros(nx)
        self.oxide_area: float | None = None  # the "conformal" rule's: the oxide's area as last coated, nm^2
        self.imbalance = 0.0  # and its volume balance then, nm^3 (`balance`)
        self.m0 = self.inner.z.copy()
        self.ox = self.inner.z.copy()
        ii, jj = np.indices((nx, ny))
        self.foot_i, self.foot_j = ii.astype(np.int64), jj.astype(np.int64)
        self.weights = volume_weights((nx, ny), self.dx, self.dy, self.inner.boundary)
        self.t = 0.0  # the thickness of the committed steps
        self.coated = 0.0  # the thickness at which `ox` was last updated
        # (thickness, padded metal) of a step to a thickness asked for, shown until the next
        self.shown: tuple[float, np.ndarray] | None = None
        self.shown_oxide: np.ndarray | None = None  # that state's oxide, once computed
        self.iterations = 0
        self.point_updates = 0
        threads = available_threads() if self.settings.threads is None else self.settings.threads
        self.parts = row_ranges(nx, threads)

    # -- state -----------------------------------------------------------------------------

    @property
    def thickness(self) -> float:
        """Oxide thickness reached, nm (every metal point lies exactly this far below the oxide)."""
        return self.t if self.shown is None else self.shown[0]

    @property
    def metal_z(self) -> np.ndarray:
        """The metal on the internal grid, nm (a view)."""
        padded = self.padded if self.shown is None else self.shown[1]
        return padded[GHOST:-GHOST, GHOST:-GHOST]

    def _outer(self, z: np.ndarray) -> np.ndarray:
        return z[::self.stride, ::self.stride] if self.stride else z

    @property
    def zm(self) -> np.ndarray:
        return self._outer(self.metal_z).ravel().copy()

    @property
    def zo(self) -> np.ndarray:
        return self._outer(self.oxide_z()).ravel().copy()

    @property
    def D(self) -> np.ndarray:
        """Every metal point's distance to the oxide: the thickness (the flow keeps it uniform)."""
        return np.full(self._outer(self.metal_z).size, self.thickness)

    def metal(self) -> Surface:
        """The metal on the surface's grid (internal grid, for a coarser companion)."""
        grid = self.surface if self.stride else self.inner
        return grid.with_heights(self._outer(self.metal_z))

    def oxide(self) -> Surface:
        grid = self.surface if self.stride else self.inner
        return grid.with_heights(self._outer(self.oxide_z()))

    def distances(self) -> np.ndarray:
        return self.D.reshape(self._outer(self.metal_z).shape)

    def metal_lost(self) -> float:
        """Metal volume consumed since the start, nm^3 (internal grid, exact for its surface)."""
        return float(np.sum(self.weights * (self.m0 - self.metal_z)))

    def oxide_gained(self) -> float:
        """Oxide volume added above the starting surface, nm^3."""
        return float(np.sum(self.weights * (self.oxide_z() - self.m0)))

    def roughness(self) -> dict:
        """RMS (over the area of the piecewise-linear surface) and z-range (between the extremes of the
        surface the grid samples, `planarize.engines.offset.extremes`) of both surfaces, nm, on the
        internal grid."""
        out = {}
        for name, z in (("metal", self.metal_z), ("oxide", self.oxide_z())):
            z = np.ascontiguousarray(z)
            high, low = extremes(z, self.periodic)
            out[f"{name}_rms_nm"] = surface_moments(z, self.periodic)[1]
            out[f"{name}_zrange_nm"] = high - low
        return out

    def oxide_z(self) -> np.ndarray:
        """The oxide on the internal grid at the thickness shown: the running maximum of the metal's
        conformal coats, brought up to date (`planarize.engines.offset.coat`)."""
        if self.shown is None and self.coated == self.t:
            return self.ox
        if self.shown_oxide is None:
            self.shown_oxide = self._coat(self.thickness, commit=False)
        return self.shown_oxide

    def _coat(self, t: float, commit: bool) -> np.ndarray:
        """The running maximum with the metal shown coated at ``t``; ``commit`` keeps it (and the feet)."""
        h = min(self.dx, self.dy)
        window = min(1 + int(math.ceil((t - self.coated) / h)), 2 + int(math.ceil(t / h)))
        z = np.ascontiguousarray(self.metal_z)
        out = np.empty_like(self.ox)
        fi, fj = np.empty_like(self.foot_i), np.empty_like(self.foot_j)
        run_in_threads(lambda part: coat(z, t, self.dx, self.dy, self.periodic, window, self.foot_i, self.foot_j,
                                         self.ox, out, fi, fj, *part), self.parts)
        if commit:
            self.ox, self.foot_i, self.foot_j, self.coated = out, fi, fj, t
        return out

    # -- the flow --------------------------------------------------------------------------

    def _rate(self, padded: np.ndarray, t: float, out: np.ndarray) -> float:
        """Fill ``out`` with dM/dt; return the largest diffusion coefficient (nm)."""
        fill_ghosts(padded, self.periodic)
        if self.model.rule == "conformal":
            speed = self._conformal_speed(padded)
        else:
            speed = -1.0
        run_in_threads(lambda part: metal_rate(padded, self.dx, self.dy, t, self.k_exp, speed, out, self.row_stiff,
                                               *part), self.parts)
        return float(self.row_stiff.max()) if speed < 0 else 0.0

    def _conformal_speed(self, padded: np.ndarray) -> float:
        """The ``"conformal"`` rule's one normal speed of the metal, per unit of thickness: the volume balance
        over the whole surface, ``V = A_ox / (A_ox + (k_exp - 1) A_metal)`` with the areas of the two surfaces
        themselves (`surface_area`: the oxide as last coated, the metal now), and the imbalance measured at
        the last coating (`balance`) made up over the next grid spacing of thickness, so that the discrete
        volumes balance instead of drifting as the grid refines."""
        metal = surface_area(padded[GHOST:-GHOST, GHOST:-GHOST], self.dx, self.dy, self.periodic, self.weights)
        if self.oxide_area is None:
            self.oxide_area = surface_area(self.ox, self.dx, self.dy, self.periodic, self.weights)
        catch_up = self.imbalance / min(self.dx, self.dy)
        total = self.oxide_area + (self.k_exp - 1.0) * metal
        return min(max((self.oxide_area + catch_up) / total, 0.0), 1.0) if total > 0 else 1.0

    def balance(self) -> float:
        """Oxide volume gained less ``(k_exp - 1)`` times the metal volume lost, nm^3, at the last coating."""
        lost = float(np.sum(self.weights * (self.m0 - self.metal_z)))
        gained = float(np.sum(self.weights * (self.ox - self.m0)))
        return gained - (self.k_exp - 1.0) * lost

    def time_step(self, stiffness: float) -> float:
        """The explicit step for the largest diffusion coefficient ``stiffness`` (nm), nm of thickness."""
        h = min(self.dx, self.dy)
        dt = COURANT * h
        if stiffness > 0:
            dt = min(dt, 1.0 / (2.0 * stiffness * (1.0 / self.dx ** 2 + 1.0 / self.dy ** 2)))
        return self.settings.stability * dt

    def advance(self, until: float = math.inf) -> None:
        """One time step of Heun's method; if it would pass ``until`` (nm of oxide), a step to ``until``
        instead, shown until the next call (see the class notes)."""
        self.shown = self.shown_oxide = None
        stiff = self._rate(self.padded, self.t, self.rate)
        dt = self.time_step(stiff)
        if not dt > 1e-9 * min(self.dx, self.dy):
            raise RuntimeError(f"the continuum engine's time step fell to {dt:.3g} nm at thickness {self.t:.6g} nm: "
                               "the surface is outside the flow's range")
        commit = self.t + dt < until * (1 - 1e-12)
        if not commit:
            dt = until - self.t
        target = self.padded if commit else self.padded.copy()
        inner = target[GHOST:-GHOST, GHOST:-GHOST]
        stage = self.stage[GHOST:-GHOST, GHOST:-GHOST]
        np.multiply(self.rate, dt, out=stage)
        stage += inner
        self._rate(self.stage, self.t + dt, self.rate2)
        self.rate2 += self.rate
        self.rate2 *= 0.5 * dt
        inner += self.rate2
        if not commit:
            self.shown = (float(until), target)
            return
        self.t += dt
        self.iterations += 1
        self.point_updates += inner.size
        if self.t - self.coated >= min(self.dx, self.dy):
            self._coat(self.t, commit=True)
            if self.model.rule == "conformal":
                self.oxide_area, self.imbalance = None, self.balance()
