"""A planarize scene: a starting surface and the anodization to run on it (`PlanarizeScene`).

A scene holds top-level ``name`` and ``seed``, a surface (`SurfaceSpec`: ``kind`` and that kind's
parameters) and a run (`RunSettings`: the arguments of `planarize.anodize`). Every parameter but the
``path`` of a ``"file"`` surface has a default (the surface kinds' defaults are those of the
`planarize.surfaces` functions); each is declared once here with its type, unit and range, which the
scene files (`planarize.io.scenefile`) write as comments. Wrong types and out-of-range values raise a
`labrig.validate.InputError` naming the key (e.g. ``run.step``).

Surface kinds: ``"hill"``, ``"depression"``, ``"bump"``, ``"tilted_plane"``,
``"random_roughness"`` (seeded by the top-level ``seed``) and ``"file"``
(a measured height map, `planarize.io.load_heights`).
"""

from __future__ import annotations

import dataclasses
import inspect
from dataclasses import dataclass, field

from labrig.tomlfile import check_keys
from labrig.validate import MAX_SEED, InputError, number, real, seed, text, typed

from . import surfaces
from .anodize import MAX_RECORD, MAX_THICKNESS, Anodization, anodize, check_steps, thickness_targets
from .engines import ENGINES, Continuum, Fast, engine_settings
from .heightfield import Surface
from .io.heights import FORMATS, load_heights
from .io.units import LENGTH_UNITS
from .model import K_EXP_RANGE, MAX_STEP, RULES, Model

#: The boundary key, as the surface kinds that take one have it.
_BOUNDARY = {"boundary": ("str", '"open" | "periodic"')}
_BUMP = {
    "base": ("float", "nm, film thickness around the bump, >= 0"),
    "points": ("int", "grid points per side before refinement, odd integer >= 3"),
    "spacing": ("float", "nm, grid spacing before refinement, > 0"),
    "refine": ("int", "refinement factor, integer >= 1 (thesis 4: 17 x 17 points)"),
    "method": ("str", '"linear" (the thesis) | "cubic" refinement'),
    **_BOUNDARY,
}
#: Surface kinds: kind -> (builder, {parameter: (type, comment)}).
SURFACES = {
    "hill": (surfaces.hill, _BUMP),
    "depression": (surfaces.depression, _BUMP),
    "bump": (surfaces.bump, {"height": ("float", "nm, height of the centre point before refinement, >= 0"),
                           **_BUMP}),
    "tilted_plane": (surfaces.tilted_plane, {
        "slope": ("float2", "[dz/dx, dz/dy], finite"),
        "base": ("float", "nm, height at x = y = 0, >= 0"),
        "points": ("int", "grid points per side, integer >= 2"),
        "spacing": ("float", "nm, > 0"),
    }),
    "random_roughness": (surfaces.random_roughness, {
        "size": ("float", "nm, side of the square sample, a whole number of half the widest width"),
        "thickness": ("float", "nm, mean metal thickness, >= 0"),
        "scales": ("float2s", "[[width, height], ...] nm, widest first, each width dividing the previous"),
        "refine": ("int", "final refinement factor, integer >= 1"),
        "method": ("str", '"linear" | "cubic" final refinement'),
        **_BOUNDARY,
    }),
    "file": (load_heights, {
        "path": ("str", "height map: .xyz, .csv/.txt/.asc/.dat matrix, .npy or .gwy; relative to this file"),
        "unit": ("str?", f"unit of lateral sizes (and heights), for files that do not state it: "
                         f"{' | '.join(repr(u) for u in ('nm', 'um', 'm', 'A'))}"),
        "z_unit": ("str?", "unit of the heights if different from unit"),
        "spacing": ("float|float2?", "grid spacing in unit, number or [dx, dy]; .npy and plain matrices only"),
        "level": ("bool", "remove the least-squares plane's tilt"),
        "channel": ("int|str?", ".gwy channel number or title; unset: the first height channel"),
        "format": ("str?", f"{' | '.join(repr(f) for f in FORMATS)}; unset: from the suffix"),
        **_BOUNDARY,
        "max_aspect": ("float", "largest pixel aspect ratio accepted, >= 1"),
    }),
}
#: Run settings: key -> (type, comment).
RUN = {
    "thickness": ("float", f"nm, oxide thickness to grow, in [0, {number(MAX_THICKNESS)}]"),
    "step": ("float", f"nm, metal height consumed per oxidation, in (0, thickness] and at most {number(MAX_STEP)} "
                      "(thesis: 0.01 hill, 0.5 Ta; the thesis's engines only)"),
    "k_exp": ("float", f"oxide volume per metal volume consumed, in [{number(K_EXP_RANGE[0])}, "
                       f"{number(K_EXP_RANGE[1])}] (Ta 2.3, Al ~1.3)"),
    "engine": ("str", " | ".join(f'"{e}"' for e in ENGINES) + ' ("continuum": the thesis rule\'s converged limit, '
                      'with its error; "reference": the thesis algorithm, slow)'),
    "rule": ("str", " | ".join(f'"{r}"' for r in RULES) + ' (where the oxide grows; "conformal": continuum engine only)'),
    "rtol": ("float?", "continuum engine: relative discretization error aimed at, in [0.0001, 1]; unset: 0.02"),
    "distance": ("str", '"thesis" (points and segments) | "exact" (the triangulated surfaces)'),
    "volume": ("str", '"exact" | "thesis" (equal point weights)'),
    "tolerance": ("float?", "nm, fast engine batch tolerance, >= 0; unset: step / 10"),
    "interacting": ("str", '"wait" | "together" (fast engine: interacting candidates of a batch; together is faster, '
                           'changes the result by what the tolerance lets in)'),
    "record": ("int|floats", f"history rows: a count n (n + 1 evenly spaced) or [thicknesses nm]; at most "
                             f"{MAX_RECORD:,}"),
    "snapshots": ("floats?", "[thicknesses nm] at which both surfaces are kept, in [0, thickness]; unset: [0, thickness]"),
}
#: Top-level keys.
TOP = {"name": ("str", "label of the run"), "seed": ("int", f"integer in [0, {MAX_SEED}], seeds random_roughness")}


def _defaults(kind: str) -> dict:
    builder, schema = SURFACES[kind]
    params = inspect.signature(builder).parameters
    if kind in ("hill", "depression"):
        params = inspect.signature(surfaces.bump).parameters
    return {key: _plain(params[key].default) for key in schema if params[key].default is not inspect.Parameter.empty}


def _plain(value):
    """Tuples (of tuples) as lists: the form TOML reads back."""
    return [_plain(v) for v in value] if isinstance(value, (list, tuple)) else value


# -- the scene ---------------------------------------------------------------------------------

@dataclass(frozen=True)
class SurfaceSpec:
    """A starting surface: a kind of `SURFACES` and all its parameters (defaults filled in).

    Building it (`build`) makes the `Surface`; construction only checks
    types and, for the synthetic kinds, builds it once to check the values.
    """

    kind: str = "hill"
    params: dict = field(default_factory=dict)

    def __post_init__(self):
        if self.kind not in SURFACES:
            raise InputError(f"kind must be one of {', '.join(map(repr, SURFACES))}, got {self.kind!r}")
        schema = SURFACES[self.kind][1]
        if not isinstance(self.params, dict):
            raise InputError(f"params must be a dict, got {type(self.params).__name__}")
        check_keys("surface", self.params, ["kind", *schema])
        if self.kind == "file" and "path" not in self.params:
            raise InputError("surface.path is required for kind = \"file\" (the height map to import)")
        given = {key: typed(f"surface.{key}", value, schema[key][0]) for key, value in self.params.items()}
        full = {**_defaults(self.kind), **given}
        object.__setattr__(self, "params", {key: full[key] for key in schema if key in full})
        if self.kind == "file":
            for key in ("unit", "z_unit"):
                if full.get(key) is not None and full[key] not in LENGTH_UNITS:
                    raise InputError(f"surface.{key} must be one of {', '.join(LENGTH_UNITS)}, got {full[key]!r}")
            if full.get("format") is not None and full["format"] not in FORMATS:
                raise InputError(f"surface.format must be one of {FORMATS}, got {full['format']!r}")
            real("surface.max_aspect", full["max_aspect"], 1.0)
        else:
            self.build()  # the builders check every value

    def build(self, seed: int = 0) -> Surface:
        """The `Surface` (``seed`` is used by ``"random_roughness"``)."""
        builder = SURFACES[self.kind][0]
        params = dict(self.params)
        if self.kind == "random_roughness":
            params["seed"] = seed
        if self.kind == "file":
            return builder(params.pop("path"), **params)
        if "slope" in params:
            params["slope"] = tuple(params["slope"])
        try:
            return builder(**params)
        except (ValueError, TypeError) as exc:
            raise InputError(_name_key(str(exc), params)) from None


def _name_key(message: str, keys) -> str:
    head = message.split(" ", 1)[0]
    return f"surface.{message}" if head in keys else f"surface: {message}"


@dataclass(frozen=True)
class RunSettings:
    """What `planarize.anodize` is asked to do, as a scene file's ``[run]`` table: the thickness, the
    `planarize.Model` (``step``, ``k_exp``, ``distance``, ``volume``, ``rule``), the engine and its settings
    (``rtol`` is the continuum engine's, ``tolerance`` and ``interacting`` the fast engine's), the
    records and snapshots."""

    thickness: float = 1.0
    step: float = 0.01
    k_exp: float = 2.3
    engine: str = "continuum"
    rule: str = "thesis"
    rtol: float | None = None
    distance: str = "thesis"
    volume: str = "exact"
    tolerance: float | None = None
    interacting: str = "wait"
    record: int | list = 50
    snapshots: list | None = None

    def __post_init__(self):
        for key, (kind, _) in RUN.items():
            object.__setattr__(self, key, typed(key, getattr(self, key), kind))
        real("thickness", self.thickness, 0.0, MAX_THICKNESS, unit="nm")
        self.model()
        if self.engine != "fast" and (self.tolerance is not None or self.interacting != "wait"):
            raise InputError(f"tolerance and interacting are settings of the fast engine, not of engine "
                             f"{self.engine!r}: leave them out")
        if self.engine != "continuum" and self.rtol is not None:
            raise InputError(f"rtol is a setting of the continuum engine, not of engine {self.engine!r}: leave it out")
        if self.engine != "continuum" and self.rule != "thesis":
            raise InputError(f"rule {self.rule!r} is computed by the continuum engine only, not by engine "
                             f"{self.engine!r}")
        self.engine_settings()
        check_steps(self.thickness, self.step)
        thickness_targets(self.record, self.thickness, "record")
        if self.snapshots is not None:
            thickness_targets(self.snapshots, self.thickness, "snapshots", empty=True)

    def model(self) -> Model:
        """The physics of the run."""
        return Model(k_exp=self.k_exp, step=self.step, distance=self.distance, volume=self.volume, rule=self.rule)

    def engine_settings(self):
        """The engine and its settings (`planarize.engines.Fast`, `Reference` or `Matlab`)."""
        settings = engine_settings(self.engine)
        if isinstance(settings, Fast):
            settings = Fast(tolerance=self.tolerance, interacting=self.interacting)
        if isinstance(settings, Continuum) and self.rtol is not None:
            settings = Continuum(rtol=self.rtol)
        return settings

    def options(self) -> dict:
        """Keyword arguments of `planarize.anodize` (all but the surface and ``progress``)."""
        return {"thickness": self.thickness, "model": self.model(), "engine": self.engine_settings(),
                "record": self.record, "snapshots": self.snapshots}


@dataclass(frozen=True)
class PlanarizeScene:
    """A planarize scene: a starting surface and a run.

    Attributes
    ----------
    name : str
    seed : int
        Seeds ``"random_roughness"`` surfaces.
    surface : SurfaceSpec
    run : RunSettings
    """

    name: str = "scene"
    seed: int = 0
    surface: SurfaceSpec = field(default_factory=SurfaceSpec)
    run: RunSettings = field(default_factory=RunSettings)

    def __post_init__(self):
        text("name", self.name)
        seed("seed", self.seed)
        if not isinstance(self.surface, SurfaceSpec) or not isinstance(self.run, RunSettings):
            raise InputError("surface must be a SurfaceSpec and run a RunSettings")

    def build_surface(self) -> Surface:
        """The starting metal surface."""
        return self.surface.build(self.seed)

    def anodize(self, *, progress: bool = False, **options) -> Anodization:
        """Run the scene (`planarize.anodize`); ``options`` replace its arguments for this call (e.g.
        ``snapshots``, ``observer``, ``max_seconds``)."""
        return anodize(self.build_surface(), progress=progress, **{**self.run.options(), **options})

    def replace(self, **changes) -> "PlanarizeScene":
        """A copy with top-level fields (or ``run`` settings given as a dict) replaced."""
        if isinstance(changes.get("run"), dict):
            changes["run"] = dataclasses.replace(self.run, **changes["run"])
        return dataclasses.replace(self, **changes)

    def quick(self, fraction: float) -> "PlanarizeScene":
        """A cheaper version for a first look: ``step / fraction``, refinement ``refine * fraction``
        (rounded, at least 1), and on the continuum engine a tolerance ``rtol / fraction`` (at most 1);
        thickness, records and snapshots unchanged.
        """
        fraction = real("quick fraction", fraction, 0.0, 1.0, low_open=True)
        params = dict(self.surface.params)
        if "refine" in params:
            params["refine"] = max(1, round(params["refine"] * fraction))
        run = {"step": float(f"{self.run.step / fraction:.12g}")}
        if self.run.engine == "continuum":
            rtol = Continuum().rtol if self.run.rtol is None else self.run.rtol
            run["rtol"] = min(1.0, float(f"{rtol / fraction:.12g}"))
        return self.replace(name=f"{self.name} quick {fraction:g}", surface=SurfaceSpec(self.surface.kind, params),
                            run=run)


# -- named scenes ------------------------------------------------------------------------------

#: The built-in scenes: the thesis's hill and depression (Figs 3-8, 3-9), its Ta film (Figs 3-11, 3-12),
#: and a tilted plane (which anodization must leave unchanged in shape).
SCENES = {
    "hill": PlanarizeScene("hill", surface=SurfaceSpec("hill"), run=RunSettings(thickness=1.0, step=0.01)),
    "depression": PlanarizeScene("depression", surface=SurfaceSpec("depression"),
                                 run=RunSettings(thickness=1.0, step=0.01)),
    "ta": PlanarizeScene("ta", surface=SurfaceSpec("random_roughness"),
                         run=RunSettings(thickness=200.0, step=0.5, record=40,
                                         snapshots=[0.0, 50.0, 100.0, 150.0, 200.0])),
    "tilted": PlanarizeScene("tilted", surface=SurfaceSpec("tilted_plane"), run=RunSettings(thickness=1.0, step=0.01)),
}


def get_scene(name: str) -> PlanarizeScene:
    """A built-in scene by name (`SCENES`)."""
    if name not in SCENES:
        raise InputError(f"unknown scene {name!r}; built-in scenes: {', '.join(SCENES)}")
    return SCENES[name]


__all__ = ["PlanarizeScene", "SurfaceSpec", "RunSettings", "SCENES", "SURFACES", "RUN", "TOP", "get_scene"]
