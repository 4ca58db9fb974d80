"""TOML scene files for planarize: a starting surface and the anodization to run on it.

A scene file holds top-level ``name`` and ``seed``, a ``[surface]`` table
(``kind`` and that kind's parameters) and a ``[run]`` table (the arguments
of `planarize.anodize`). Every key but ``surface.path`` of a ``"file"``
surface is optional: a missing key takes its default (the surface kinds'
defaults are those of the `planarize.surfaces` functions). `scene_to_toml`
writes every key with units and allowed ranges in comments; floats are
written with ``repr`` and read back exactly, so ``load_scene(save_scene(s))
== s``. Unknown keys, wrong types and out-of-range values raise a
`labrig.validate.InputError` naming the file and the full key (e.g. ``run.step``); the TOML
reading, writing and key checks are `labrig.tomlfile`'s.

Surface kinds: ``"hill"``, ``"depression"``, ``"bump"``, ``"tilted_plane"``,
``"random_roughness"`` (seeded by the top-level ``seed``) and ``"file"``
(a measured height map, `planarize.io.load_heights`; a relative ``path`` is
relative to the scene file's directory).
"""

from __future__ import annotations

import dataclasses
import inspect
import math
import os
from dataclasses import dataclass, field
from pathlib import Path

from labrig.files import write_text_atomic
from labrig.tomlfile import check_keys, from_source, parse_toml, read_toml, toml_line
from labrig.validate import InputError, typed

from .. import surfaces
from ..anodize import Anodization, anodize, engines
from ..engines.base import INTERACTING, VOLUME_RULES
from ..engines.features import DISTANCES
from ..surface import Surface
from .heights import FORMATS, LENGTH_UNITS, load_heights

_BUMP = {
    "base": ("float", "nm, film thickness around the bump, >= 0"),
    "points": ("int", "grid points per side before refinement, odd integer >= 3"),
    "spacing": ("float", "nm, grid spacing before refinement, > 0"),
    "refine": ("int", "refinement factor, integer >= 1 (thesis 4: 17 x 17 points)"),
    "method": ("str", '"linear" (the thesis) | "cubic" refinement'),
    "boundary": ("str", '"open" | "periodic"'),
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
        "scales": ("scales", "[[width, height], ...] nm, widest first, each width dividing the previous"),
        "refine": ("int", "final refinement factor, integer >= 1"),
        "method": ("str", '"linear" | "cubic" final refinement'),
        "boundary": ("str", '"open" | "periodic"'),
    }),
    "file": (load_heights, {
        "path": ("str", "height map: .xyz, .csv/.txt/.asc/.dat matrix, .npy or .gwy; relative to this file"),
        "unit": ("str?", f"unit of lateral sizes (and heights), for files that do not state it: "
                         f"{' | '.join(repr(u) for u in ('nm', 'um', 'm', 'A'))}"),
        "z_unit": ("str?", "unit of the heights if different from unit"),
        "spacing": ("spacing?", "grid spacing in unit, number or [dx, dy]; .npy and plain matrices only"),
        "level": ("bool", "remove the least-squares plane's tilt"),
        "channel": ("channel?", ".gwy channel number or title; unset: the first height channel"),
        "format": ("str?", f"{' | '.join(repr(f) for f in FORMATS)}; unset: from the suffix"),
        "boundary": ("str", '"open" | "periodic"'),
        "max_aspect": ("float", "largest pixel aspect ratio accepted, >= 1"),
    }),
}
#: Run settings: key -> (type, comment).
RUN = {
    "thickness": ("float", "nm, oxide thickness to grow, >= 0"),
    "step": ("float", "nm, metal height consumed per oxidation, > 0 (thesis: 0.01 hill, 0.5 Ta)"),
    "k_exp": ("float", "oxide volume per metal volume consumed, >= 1 (Ta 2.3, Al ~1.3)"),
    "engine": ("str", " | ".join(f'"{e}"' for e in engines()) + ' ("reference": the thesis algorithm, slow)'),
    "distance": ("str", '"thesis" (points and segments) | "exact" (the triangulated surfaces)'),
    "volume": ("str", '"exact" | "thesis" (equal point weights)'),
    "tolerance": ("float?", "nm, fast engine batch tolerance, >= 0; unset: step / 10"),
    "interacting": ("str", '"wait" | "together" (fast engine: interacting candidates of a batch; together is faster, '
                           'changes the result by what the tolerance lets in)'),
    "record": ("record", "history rows: a count n (n + 1 evenly spaced) or [thicknesses nm]"),
    "snapshots": ("floats?", "[thicknesses nm] at which both surfaces are kept, in [0, thickness]; unset: [0, thickness]"),
}
#: Top-level keys.
TOP = {"name": ("str", "label of the run"), "seed": ("int", "integer >= 0, seeds random_roughness")}


def _defaults(kind: str) -> dict:
    builder, schema = SURFACES[kind]
    params = inspect.signature(builder).parameters
    if kind in ("hill", "depression"):
        params = inspect.signature(surfaces.bump).parameters
    return {key: _plain(params[key].default) for key in schema if params[key].default is not inspect.Parameter.empty}


def _plain(value):
    """Tuples (of tuples) as lists: the form TOML reads back."""
    return [_plain(v) for v in value] if isinstance(value, (list, tuple)) else value


def _check_type(key: str, value, kind: str):
    """``value`` as ``kind``; ValueError naming the full ``key`` otherwise."""
    if value is None and kind.endswith("?"):
        return None
    plain = kind.rstrip("?")
    number = (int, float)

    def is_number(v):
        return isinstance(v, number) and not isinstance(v, bool)

    if plain == "float2":
        if isinstance(value, (list, tuple)) and len(value) == 2 and all(map(is_number, value)):
            return [float(v) for v in value]
        raise InputError(f"{key} must be a list of two numbers, got {value!r}")
    if plain == "scales":
        if isinstance(value, (list, tuple)) and value and all(
                isinstance(p, (list, tuple)) and len(p) == 2 and all(map(is_number, p)) for p in value):
            return [[float(w), float(h)] for w, h in value]
        raise InputError(f"{key} must be a non-empty list of [width, height] pairs (nm), got {value!r}")
    if plain == "floats":
        if isinstance(value, (list, tuple)) and all(map(is_number, value)):
            return [float(v) for v in value]
        raise InputError(f"{key} must be a list of numbers (nm), got {value!r}")
    if plain == "record":
        if isinstance(value, int) and not isinstance(value, bool):
            return value
        if isinstance(value, (list, tuple)) and all(map(is_number, value)):
            return [float(v) for v in value]
        raise InputError(f"{key} must be an integer count or a list of thicknesses (nm), got {value!r}")
    if plain == "spacing":
        if is_number(value):
            return float(value)
        return _check_type(key, value, "float2")
    if plain == "channel":
        if isinstance(value, str) or (isinstance(value, int) and not isinstance(value, bool)):
            return value
        raise InputError(f"{key} must be a channel number or title, got {value!r}")
    return typed(key, value, plain)


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
        given = {key: _check_type(f"surface.{key}", value, schema[key][0]) for key, value in self.params.items()}
        full = {**_defaults(self.kind), **given}
        object.__setattr__(self, "params", {key: full[key] for key in schema if key in full})
        if self.kind == "file":
            for key in ("unit", "z_unit"):
                if full.get(key) is not None and full[key] not in LENGTH_UNITS:
                    raise InputError(f"surface.{key} must be one of {', '.join(LENGTH_UNITS)}, got {full[key]!r}")
            if full.get("format") is not None and full["format"] not in FORMATS:
                raise InputError(f"surface.format must be one of {FORMATS}, got {full['format']!r}")
            if not full["max_aspect"] >= 1:
                raise InputError(f"surface.max_aspect must be >= 1, got {full['max_aspect']!r}")
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
    """What `planarize.anodize` is asked to do (see its docstring for each argument)."""

    thickness: float = 1.0
    step: float = 0.01
    k_exp: float = 2.3
    engine: str = "fast"
    distance: str = "thesis"
    volume: str = "exact"
    tolerance: float | None = None
    interacting: str = "wait"
    record: int | list = 50
    snapshots: list | None = None

    def __post_init__(self):
        for key, (kind, _) in RUN.items():
            object.__setattr__(self, key, _check_type(key, getattr(self, key), kind))
        _at_least("thickness", self.thickness, 0.0, "nm")
        _at_least("step", self.step, 0.0, "nm", open_=True)
        _at_least("k_exp", self.k_exp, 1.0, "")
        if self.tolerance is not None:
            _at_least("tolerance", self.tolerance, 0.0, "nm")
        for key, allowed in (("engine", tuple(engines())), ("distance", DISTANCES), ("volume", VOLUME_RULES),
                             ("interacting", INTERACTING)):
            if getattr(self, key) not in allowed:
                raise InputError(f"{key} must be one of {', '.join(map(repr, allowed))}, got {getattr(self, key)!r}")
        if isinstance(self.record, int) and self.record < 1:
            raise InputError(f"record must be a count >= 1 or a list of thicknesses, got {self.record!r}")
        for key in ("record", "snapshots"):
            values = getattr(self, key)
            if isinstance(values, list) and not all(0 <= v <= self.thickness for v in values):
                raise InputError(f"{key} must lie in [0, thickness = {self.thickness!r}] nm, got {values!r}")

    def options(self) -> dict:
        """Keyword arguments of `planarize.anodize` (all but the surface and ``progress``)."""
        out = {key: getattr(self, key) for key in RUN if key not in ("tolerance", "interacting")}
        if self.engine == "fast":  # the reference engine has no batches
            out["interacting"] = self.interacting
            if self.tolerance is not None:
                out["tolerance"] = self.tolerance
        return out


def _at_least(key: str, value: float, low: float, unit: str, open_: bool = False) -> None:
    if not (math.isfinite(value) and (value > low if open_ else value >= low)):
        raise InputError(f"{key} must be {'>' if open_ else '>='} {low:g}{' ' + unit if unit else ''}, got {value!r}")


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
        _check_type("name", self.name, "str")
        if isinstance(self.seed, bool) or not isinstance(self.seed, int) or self.seed < 0:
            raise InputError(f"seed must be an integer >= 0, got {self.seed!r}")
        if not isinstance(self.surface, SurfaceSpec) or not isinstance(self.run, RunSettings):
            raise InputError("surface must be a SurfaceSpec and run a RunSettings")

    def build_surface(self) -> Surface:
        """The starting metal surface."""
        return self.surface.build(self.seed)

    def anodize(self, *, progress: bool = False, **overrides) -> Anodization:
        """Run the scene (`planarize.anodize`); ``overrides`` replace run settings for this call."""
        return anodize(self.build_surface(), progress=progress, **{**self.run.options(), **overrides})

    def replace(self, **changes) -> "PlanarizeScene":
        """A copy with top-level fields (or ``run`` settings given as a dict) replaced."""
        if isinstance(changes.get("run"), dict):
            changes["run"] = dataclasses.replace(self.run, **changes["run"])
        return dataclasses.replace(self, **changes)

    def quick(self, fraction: float) -> "PlanarizeScene":
        """A cheaper version for a first look: ``step / fraction``, refinement ``refine * fraction``
        (rounded, at least 1); thickness, records and snapshots unchanged.
        """
        if not (isinstance(fraction, (int, float)) and 0 < fraction <= 1):
            raise InputError(f"quick fraction must be in (0, 1], got {fraction!r}")
        params = dict(self.surface.params)
        if "refine" in params:
            params["refine"] = max(1, round(params["refine"] * fraction))
        return self.replace(name=f"{self.name} quick {fraction:g}", surface=SurfaceSpec(self.surface.kind, params),
                            run={"step": float(f"{self.run.step / fraction:.12g}")})


# -- TOML --------------------------------------------------------------------------------------

def scene_to_toml(scene: PlanarizeScene) -> str:
    """The scene file text: every key, with units and ranges in comments."""
    kind = scene.surface.kind
    lines = ["# planarize scene. Lengths in nm unless a unit is given. Every key is optional",
             "# (surface.path is required for kind = \"file\"). Load with planarize.io.scenefile.load_scene.", ""]
    lines += [toml_line(key, getattr(scene, key), note) for key, (_, note) in TOP.items()]
    lines += ["", "[surface]", toml_line("kind", kind, " | ".join(f'"{k}"' for k in SURFACES))]
    schema = SURFACES[kind][1]
    lines += [toml_line(key, scene.surface.params.get(key), note) for key, (_, note) in schema.items()]
    lines += ["", "[run]"] + [toml_line(key, getattr(scene.run, key), note) for key, (_, note) in RUN.items()]
    return "\n".join(lines) + "\n"


def save_scene(scene: PlanarizeScene, path: str | os.PathLike) -> Path:
    """Write ``scene`` to ``path`` as TOML, atomically; returns the path."""
    if not isinstance(scene, PlanarizeScene):
        raise TypeError(f"scene must be a PlanarizeScene, got {type(scene).__name__}")
    return write_text_atomic(path, scene_to_toml(scene))


def scene_from_dict(data: dict, base_dir: str | os.PathLike | None = None) -> PlanarizeScene:
    """A scene from parsed TOML; a relative ``surface.path`` is taken relative to ``base_dir``.

    Raises
    ------
    ValueError
        Naming the full key of an unknown key, a wrong type or an out-of-range value.
    """
    if not isinstance(data, dict):
        raise InputError(f"a scene must be a table, got {type(data).__name__}")
    check_keys("", data, [*TOP, "surface", "run"])
    top = {key: _check_type(key, data[key], kind) for key, (kind, _) in TOP.items() if key in data}
    surface = data.get("surface", {})
    run = data.get("run", {})
    for name, table in (("surface", surface), ("run", run)):
        if not isinstance(table, dict):
            raise InputError(f"{name} must be a table ([{name}]), got {table!r}")
    params = {k: v for k, v in surface.items() if k != "kind"}
    kind = _check_type("surface.kind", surface.get("kind", "hill"), "str")
    if kind not in SURFACES:
        raise InputError(f"surface.kind must be one of {', '.join(map(repr, SURFACES))}, got {kind!r}")
    if kind == "file" and isinstance(params.get("path"), str) and base_dir is not None:
        params["path"] = str(Path(base_dir, params["path"]))
    check_keys("run", run, list(RUN))
    try:
        run_settings = RunSettings(**run)
    except ValueError as exc:
        raise InputError(f"run.{exc}") from None
    return PlanarizeScene(**top, surface=SurfaceSpec(kind, params), run=run_settings)


def scene_from_toml(text: str, source: str = "<string>", base_dir=None) -> PlanarizeScene:
    """Parse scene-file text; errors are ValueErrors starting with ``source``."""
    return from_source(scene_from_dict, parse_toml(text, source), source, base_dir)


def load_scene(path: str | os.PathLike) -> PlanarizeScene:
    """Read a scene file (a relative ``surface.path`` is relative to its directory).

    Raises
    ------
    FileNotFoundError
        If ``path`` does not exist.
    ValueError
        If it cannot be read, is not valid TOML or holds a bad key or value;
        the message starts with the path.
    """
    path = Path(path)
    return from_source(scene_from_dict, read_toml(path, "scene file"), str(path), path.parent)


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


__all__ = ["PlanarizeScene", "SurfaceSpec", "RunSettings", "SCENES", "get_scene", "load_scene", "save_scene",
           "scene_from_toml", "scene_to_toml", "scene_from_dict"]
