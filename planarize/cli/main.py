"""The ``planarize`` command line.

``planarize run SCENE.toml`` runs a scene file, ``planarize scene NAME``
runs (or saves) a built-in scene and ``planarize import FILE`` runs a
measured height map. Each subcommand is a `labrig.cli.Command` in `COMMANDS`:
its ``_add_<name>`` function adds its arguments when it is the command chosen,
and the function that runs it has the command's description as its docstring.
`main` dispatches and turns bad input into a one-line error with exit code 2.
Nothing here imports the engines before a command's arguments are built, so
``planarize --help`` answers at once.
"""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

from labrig.cli import Command, UsageError, command_line, float_in, fraction, param_help, param_type
from labrig.sweeps.command import plot_command, sweep_command

_positive = float_in(0.0, math.inf, low_open=True)


def _add_outputs(p, out_default: str) -> None:
    """Options shared by the commands that run: output directory, engine, quick mode, movie."""
    from ..engines import NAMES as ENGINES
    from ..engines import PARAMS, RTOL
    from ..model import RULES

    p.add_argument("--out", type=Path, default=Path(out_default), metavar="DIR",
                   help=f"output directory, created if missing (default ./{out_default})")
    p.add_argument("--engine", choices=list(ENGINES), default=None,
                   help="override the scene's engine: continuum (the thesis rule's converged limit, with its "
                        "error; the default), fast (the thesis algorithm, batched) or reference (the thesis "
                        "algorithm, slow)")
    p.add_argument("--rtol", type=param_type(PARAMS["continuum"]["rtol"]), default=None, metavar="R",
                   help=param_help(PARAMS["continuum"]["rtol"], RTOL))
    p.add_argument("--rule", choices=list(RULES), default=None,
                   help="where the oxide grows: thesis (each bit of metal turns into oxide at its nearest oxide "
                        "point) or conformal (the metal recedes at one speed, the oxide is its conformal coat); "
                        "conformal needs the continuum engine")
    p.add_argument("--quick", type=fraction, default=None, metavar="F",
                   help="a first look: steps 1/F times larger, refinement F times smaller")
    p.add_argument("--movie", action="store_true",
                   help="also write an MP4 of the oxide growing (a frame every 1/40 of the thickness)")


def _add_run(p) -> None:
    p.add_argument("scene", type=Path, metavar="SCENE.toml", help="scene file")
    _add_outputs(p, "planarize-run")


def _add_scene(p) -> None:
    from ..scene import SCENES

    p.description = ("The built-in scenes: " + ", ".join(SCENES) + " (hill and depression: thesis Figs 3-8/3-9; "
                     "ta: the Ta film of Figs 3-11/3-12).")
    p.add_argument("name", choices=list(SCENES), metavar="NAME", help=f"one of: {', '.join(SCENES)}")
    p.add_argument("--save", type=Path, default=None, metavar="FILE.toml",
                   help="only write the scene file to edit, do not run")
    _add_outputs(p, "planarize-run")


def _add_import(p) -> None:
    from ..model import Model

    p.add_argument("file", type=Path, metavar="FILE", help="height map")
    p.add_argument("--thickness", type=float_in(0.0, math.inf), required=True, metavar="NM",
                   help="oxide thickness to grow, nm")
    p.add_argument("--unit", default=None, help="lateral (and height) unit if the file does not say: nm, um, m, A")
    p.add_argument("--z-unit", default=None, help="height unit, if different from --unit")
    p.add_argument("--spacing", type=_positive, nargs="+", default=None, metavar="D",
                   help="grid spacing DX [DY] in --unit (.npy and plain matrices)")
    p.add_argument("--level", nargs="?", const="plane", default=None, metavar="WHAT",
                   help="levelling: auto, none, or corrections joined by commas from lines, spikes, scars, plane, "
                        "poly2, poly3 (default: auto for instruments' files and .gwy, none for others; "
                        "--level alone: plane)")
    p.add_argument("--channel", default=None,
                   help="channel: a .gwy channel's number or title, an instrument file's channel name "
                        "(default: the height channel)")
    p.add_argument("--step", type=param_type(Model.PARAMS["step"]), default=None, metavar="NM",
                   help=param_help(Model.PARAMS["step"]) + " (default: z-range / 100)")
    p.add_argument("--k-exp", type=param_type(Model.PARAMS["k_exp"]), default=2.3, metavar="K",
                   help=param_help(Model.PARAMS["k_exp"], 2.3))
    p.add_argument("--distance", choices=Model.PARAMS["distance"].choices, default="thesis",
                   help=param_help(Model.PARAMS["distance"]) + " (default thesis)")
    p.add_argument("--save", type=Path, default=None, metavar="FILE.toml",
                   help="only write the scene file for this import, do not run")
    _add_outputs(p, "planarize-import")


def _load_sweep(path: Path):
    from .sweep import load_sweep

    return load_sweep(path)


def _sweep_runner(quick: float | None):
    from .sweep import AnodizeRunner

    return AnodizeRunner(quick)


def _prepare(scene, args):
    """The scene with the command-line overrides applied."""
    if args.engine is not None and args.engine != scene.engine.name:  # another engine, at its defaults
        scene = scene.replace(engine=args.engine)
    if args.rtol is not None:
        scene = scene.replace(engine={"rtol": args.rtol})
    if args.rule is not None:
        scene = scene.replace(run={"rule": args.rule})
    if args.quick is not None:
        scene = scene.quick(args.quick)
    return scene


def _run_file(args: argparse.Namespace) -> int:
    """Run a scene file (see `planarize scene NAME --save FILE` for examples) and write the run (.npz),
    its history (CSV), Figs 3-8 and 3-9, the 3-D surfaces at the snapshots, the scene file and
    optionally a movie."""
    from ..io.scenefile import load_scene
    from .commands import run_scene

    run_scene(_prepare(load_scene(args.scene), args), args.out, movie=args.movie, source=args.scene)
    return 0


def _run_named(args: argparse.Namespace) -> int:
    from ..io.scenefile import save_scene
    from ..scene import get_scene
    from .commands import run_scene

    scene = _prepare(get_scene(args.name), args)
    if args.save is not None:
        print(save_scene(scene, args.save))
        return 0
    run_scene(scene, args.out, movie=args.movie)
    return 0


def _run_import(args: argparse.Namespace) -> int:
    """Import a height map (.xyz, .csv/.txt/.asc/.dat matrix, .npy, .gwy, or an AFM instrument's .spm, .ibw,
    .jpk, .stp, .top, .nid, Park .tiff, .mi) and anodize it. Units and sizes stated in the file are used; give the others with
    --unit and --spacing. Artefacts are reported and levelled as --level says."""
    from ..io.scenefile import save_scene
    from .commands import import_scene, run_scene

    if args.spacing is not None and len(args.spacing) > 2:
        raise UsageError(f"--spacing takes DX or DX DY, got {len(args.spacing)} values")
    spacing = None if args.spacing is None else (args.spacing[0] if len(args.spacing) == 1 else args.spacing)
    channel = int(args.channel) if args.channel is not None and args.channel.isdigit() else args.channel
    scene = import_scene(args.file, thickness=args.thickness, step=args.step, unit=args.unit, z_unit=args.z_unit,
                         spacing=spacing, level=args.level, channel=channel, k_exp=args.k_exp,
                         distance=args.distance)
    scene = _prepare(scene, args)
    if args.save is not None:
        print(save_scene(scene, args.save))
        return 0
    run_scene(scene, args.out, movie=args.movie)
    return 0


#: The subcommands, in the order `--help` lists them.
COMMANDS = [
    Command("run", "run a TOML scene file", _run_file, _add_run),
    Command("scene", "run or save a built-in scene", _run_named, _add_scene),
    Command("import", "anodize a measured height map (AFM)", _run_import, _add_import),
    sweep_command("planarize", "planarize runs", _load_sweep, _sweep_runner,
                  "a first look: steps 1/F times larger, refinement F times smaller"),
    plot_command("planarize"),
]
build_parser, main = command_line("planarize", "Anodization planarization of rough metal surfaces.", COMMANDS)


if __name__ == "__main__":
    sys.exit(main())
