"""What the ``planarize`` subcommands do; `planarize.cli` parses arguments and calls these.

`run_scene` writes, into its output directory, for a scene named ``NAME``, the folder ``NAME/`` of
``NAME.toml`` (the scene it ran, for provenance, with the levelling of an imported map spelled out),
``NAME_levelling.csv`` (an imported map's artefacts: size, and whether each was removed), ``NAME.npz`` (the run,
`planarize.io.results`), ``NAME_history.csv``, ``NAME_fig3-8.png`` (centre
slice before/after), ``NAME_fig3-9.png`` (RMS and z-range against oxide
thickness), ``NAME_surfaces.png`` (3-D oxide at the snapshots, Fig 3-11) and
optionally ``NAME.mp4`` (the oxide growing): one `labrig.outputset.OutputSet`, switched into place in one
atomic step. Runs of different names may share a directory; nothing in it is shared between them (no
summary table), so concurrent runs of different names never touch each other's files.
"""

from __future__ import annotations

import math
import os
import sys
from pathlib import Path

import numpy as np

from labrig.cli import print_table
from labrig.files import slug
from labrig.outputset import OutputSet
from labrig.validate import InputError

from .. import render
from ..anodize import Anodization
from ..engines.resolution import ASYMPTOTIC_CHANGE, NOISE_CURVATURE, ORDER_HIGH, ORDER_LOW
from ..io.heights import load_levelled
from ..io.results import save_history_csv, save_run
from ..io.scenefile import save_scene
from ..levelling import applied_corrections, detect, report_rows
from ..metrics import z_range
from ..model import MAX_STEP
from ..scene import PlanarizeScene, RunSettings, SurfaceSpec

#: Movie frames (oxide thicknesses evenly spaced from 0 to the target, plus the scene's snapshots).
MOVIE_FRAMES = 40
#: At most this many snapshots go into the 3-D surfaces figure.
MAX_SURFACE_PANELS = 9


def run_scene(scene: PlanarizeScene, out: Path, *, movie: bool = False, progress: bool = True,
              source: Path | None = None) -> dict:
    """Run ``scene`` and write its files into ``out``; returns the summary (also printed as a table).

    The files are one `labrig.outputset.OutputSet`, locked before the run starts (a second run of the same name
    into the same directory is refused) and switched in all at once when it has finished, so a failed or
    killed run leaves the earlier folder of the same name as it was; ``source``, the scene file the scene was
    read from, is never written over (its provenance copy is then ``NAME.ran.toml``). An earlier
    ``NAME.mp4`` or ``NAME_surfaces.png`` that this run does not write is removed in the same switch (it
    showed the run this one replaces), and a line says so.
    """
    out = Path(out)
    stem = slug(scene.name)
    settings = scene.run
    shown = settings.snapshots if settings.snapshots is not None else [0.0, settings.thickness]
    snapshots = shown
    if movie:
        snapshots = sorted({*shown, *np.linspace(0.0, settings.thickness, MOVIE_FRAMES + 1).tolist()})
    with OutputSet(out, stem) as files:  # locks the set before anything is computed
        found = levelling(scene)
        run = scene.anodize(progress=progress, snapshots=snapshots)
        save_run(run, files.stage(f"{stem}.npz"))
        save_history_csv(run, files.stage(f"{stem}_history.csv"))
        render.save_figure(render.slice_figure(run, scene.name), files.stage(f"{stem}_fig3-8.png"))
        render.save_figure(render.history_figure(run, scene.name), files.stage(f"{stem}_fig3-9.png"))
        panels = _panels(run, shown)
        if panels.snapshots:  # (a scene may keep none)
            render.save_figure(render.snapshots_figure(panels), files.stage(f"{stem}_surfaces.png"))
        else:
            files.drop(f"{stem}_surfaces.png")
        if movie:
            render.save_movie(run, files.stage(f"{stem}.mp4"))
        else:
            files.drop(f"{stem}.mp4")
        save_scene(scene, files.stage(files.name_beside(f"{stem}.toml", source)))
        if found:
            save_levelling_csv(found, files.stage(f"{stem}_levelling.csv"))
        else:
            files.drop(f"{stem}_levelling.csv")
    for path in files.removed:
        print(f"removed the earlier {path.name}: it showed the run that this one replaces"
              + (" (add --movie to make one)" if path.suffix == ".mp4" else ""))
    summary = summarize(scene, run)
    print_table(f"{scene.name}: {summary['grid']}, k_exp {summary['k_exp']:g}, {_method(summary)}", [
        ("oxide thickness", f"{summary['thickness_nm']:.4g} nm (mean {summary['distance_mean_nm']:.4g} "
                            f"+- {summary['distance_std_nm']:.2g} nm)"),
        *[(f"{surface} {label}", _change(summary, f"{surface}_{key}")) for surface in ("metal", "oxide")
          for key, label in (("rms", "RMS"), ("zrange", "z-range"))],
        *[(f"levelling: {label}", sentence) for label, sentence in report_rows(found)],
        ("discretization error", _accuracy(summary)),
        ("volume balance error", f"{summary['volume_error']:.2g}"),
        ("wall time", f"{summary['wall_s']:.2f} s ({summary['point_updates_per_s']:,.0f} point updates/s)"),
        ("files", f"{files.path}{os.sep}: " + ", ".join(path.name for path in files.written)),
    ])
    return summary


def levelling(scene: PlanarizeScene) -> list:
    """The artefacts found and removed on a ``"file"`` scene's map as its ``level`` says (empty for the other
    kinds, and for maps read as they are), `planarize.levelling.Artefact`."""
    if scene.surface.kind != "file":
        return []
    params = dict(scene.surface.params)
    return load_levelled(params.pop("path"), **params)[1]


def save_levelling_csv(found: list, path: Path) -> Path:
    """The artefacts of a run's map, one row each: what was found, its size and whether it was removed."""
    rows = ["artefact,correction,size_nm,count,found,removed,detail"]
    rows += [f"{a.name},{a.correction},{a.size!r},{a.count},{str(a.found).lower()},{str(a.applied).lower()},"
             f"\"{a.detail}\"" for a in found]
    Path(path).write_text("\n".join(rows) + "\n", encoding="utf-8")
    return Path(path)


def _method(summary: dict) -> str:
    if summary["engine"] == "continuum":
        return f"{summary['rule']} rule, continuum engine at {summary['resolution']}"
    return f"step {summary['step_nm']:g} nm, {summary['engine']} engine"


def _change(summary: dict, key: str) -> str:
    """``start -> end nm``, with the end's estimated error where the run states one."""
    error = summary.get(f"{key}_error_nm")
    tail = "" if error is None or not math.isfinite(error) else f" +- {error:.2g}"
    return f"{summary[f'{key}_initial_nm']:.4g} -> {summary[f'{key}_nm']:.4g}{tail} nm"


def _accuracy(summary: dict) -> str:
    error = summary.get("estimated_error")
    if summary["engine"] != "continuum":
        return "not estimated (the thesis's algorithm: compare with engine continuum, or refine the grid)"
    cost = f"; the next finer grid, {summary['finer_grid']}" if summary.get("finer_grid") else ""
    if summary.get("noisy"):
        return (f"not stated: the map bends from pixel to pixel as white noise does (pixel curvature "
                f"{summary['pixel_curvature']:.2g}, at least {NOISE_CURVATURE:g}): its features are one pixel wide, as "
                f"on a grid too coarse for them, on noise, or at one-pixel spikes and pits (--level spikes removes "
                f"those), and no affordable grid converges steadily; its "
                f"last refinement, to {summary['resolution']}, changed RMS and z-range by up to "
                f"{100 * summary['last_change']:.3g} %{cost}")
    if summary.get("own_grid"):
        return ("not stated: the run stopped at the map's own grid, whose two coarser companions sample the map at half "
                "and a quarter of its resolution per side: their changes hold what the map loses by sampling, not only the flow's "
                "error, so they cannot estimate this grid's error (a finer grid would: [engine] refine = 2 in the "
                f"scene file); its last refinement changed RMS and z-range by up to {100 * summary['last_change']:.3g} "
                f"%{cost}")
    if summary.get("not_asymptotic"):
        return (f"not stated: {summary['not_asymptotic']} not yet converging at a steady order at the finest grid "
                f"tried, {summary['resolution']} (observed order outside [{ORDER_LOW:g}, {ORDER_HIGH:g}], or a change of "
                f"more than {100 * ASYMPTOTIC_CHANGE:g} %); its last "
                f"refinement changed RMS and z-range by up to {100 * summary['last_change']:.3g} %{cost}")
    if error is None or not math.isfinite(error):
        return "not estimated (the run stopped before its error estimate)"
    rule = ("taken as 1.8 where it was 1.2 or more twice running, on a map its pixels resolve" if summary.get("smooth")
            else "taken at most as 1 unless it was 1.5 or more twice running")
    text = (f"at most {100 * error:.2g} % of RMS and z-range (Richardson's estimate at the order observed over the "
            f"three finest grids, {rule})")
    if summary["rtol_met"]:
        return f"{text}; meets rtol {100 * summary['rtol']:.2g} %"
    return (f"{text}, volume balance off by up to {100 * summary['volume_error_largest']:.2g} %; does NOT meet rtol "
            f"{100 * summary['rtol']:.2g} % at the finest grid tried"
            + (cost or ": a finer one (Continuum(max_refine=...)) or engine fast"))


def _panels(run: Anodization, targets) -> Anodization:
    """``run`` with only the snapshots at ``targets`` (at most `MAX_SURFACE_PANELS`, evenly picked)."""
    wanted = {round(float(t), 9) for t in targets}
    shots = [s for s in run.snapshots if round(s.target, 9) in wanted]
    if len(shots) > MAX_SURFACE_PANELS:
        shots = [shots[k] for k in np.linspace(0, len(shots) - 1, MAX_SURFACE_PANELS).round().astype(int)]
    return Anodization(run.parameters, run.history, shots, run.initial, run.metal, run.oxide, run.distances)


def summarize(scene: PlanarizeScene, run: Anodization) -> dict:
    """One flat dict describing a finished run (first and last history rows, speed)."""
    h = run.history
    nx, ny = run.initial.shape
    dx, dy = run.initial.spacing
    wall = run.wall_s
    updates = int(h["point_updates"][-1])
    p = run.parameters
    continuum = {}
    if p["engine"] == "continuum":
        factor = p["refine"]
        continuum = {"rule": p["rule"], "rtol": p["rtol"], "estimated_error": p["estimated_error"],
                     "rtol_met": p["rtol_met"], "volume_error_largest": p["volume_error"],
                     "resolution": "its own grid" if factor == 1 else f"{factor:g}x its grid",
                     "asymptotic": p["asymptotic"], "last_change": p["change"], "smooth": p.get("smooth", False),
                     "noisy": p.get("noisy", False), "own_grid": p.get("own_grid", False),
                     "pixel_curvature": p.get("pixel_curvature", math.nan),
                     "not_asymptotic": ", ".join(f"{c.replace('_nm', '').replace('_', ' ')} (order {p['orders'][c]:.2g})"
                                                 for c in p["not_asymptotic"]),
                     "finer_grid": p["finer"],
                     **{f"{s}_{m}_error_nm": float(h[f"{s}_{m}_error_nm"][-1]) for s in ("metal", "oxide")
                        for m in ("rms", "zrange")}}
    return {
        "name": scene.name, "grid": f"{nx} x {ny} points at {dx:g} x {dy:g} nm",
        "engine": p["engine"], "k_exp": p["k_exp"], "step_nm": p.get("step", math.nan), **continuum,
        "thickness_nm": run.thickness, "distance_mean_nm": float(h["distance_mean_nm"][-1]),
        "distance_std_nm": float(h["distance_std_nm"][-1]),
        **{f"{s}_{m}_initial_nm": float(h[f"{s}_{m}_nm"][0]) for s in ("metal", "oxide") for m in ("rms", "zrange")},
        **{f"{s}_{m}_nm": float(h[f"{s}_{m}_nm"][-1]) for s in ("metal", "oxide") for m in ("rms", "zrange")},
        "volume_error": float(h["volume_error"][-1]), "wall_s": wall, "point_updates": updates,
        "point_updates_per_s": updates / wall if wall > 0 else math.nan,
    }


def import_scene(path: Path, *, thickness: float, step: float | None = None, name: str | None = None,
                 **options) -> PlanarizeScene:
    """A ``"file"`` scene for the height map at ``path``, its levelling made explicit, and a line on stdout
    per artefact found or removed (`planarize.levelling`).

    ``options`` are `planarize.io.load_heights` arguments (``unit``,
    ``spacing``, ``level``, ...) and run settings (``k_exp``, ``distance``,
    ...); None values are left out. The scene's ``level`` is the list of
    corrections that were applied (``"auto"`` resolved), so that the scene
    file reproduces the same surface. Maps read as they are (``.npy``, text)
    are checked for artefacts too, and what is found is said, not removed.
    The default ``step`` is the imported surface's z-range / 100 (one
    significant digit), about the thesis's choice for its Ta film (0.5 nm
    steps for a ~50 nm z-range), and at most `planarize.model.MAX_STEP` and
    a tenth of ``thickness`` (a line on stderr says when it is capped).
    """
    surface_keys = ("unit", "z_unit", "spacing", "level", "channel", "format", "boundary", "max_aspect")
    params = {"path": os.path.abspath(path),  # not resolve(): a symbolic link loop is for load_heights to name
              **{k: v for k, v in options.items() if k in surface_keys and v is not None}}
    run = {k: v for k, v in options.items() if k not in surface_keys and v is not None}
    SurfaceSpec("file", params)  # the options checked before the file is read
    surface, found = load_levelled(params["path"], **{k: v for k, v in params.items() if k != "path"})
    params["level"] = ",".join(applied_corrections(found)) or "none"
    if not found:  # a map read as it is: say what looks like an artefact
        found = [a for a in detect(surface) if a.found]
        for artefact in found:
            print(f"{Path(path).name}: {artefact.name} {artefact.detail}: found, not removed (--level "
                  f"{artefact.correction} removes it)")
    else:
        for label, sentence in report_rows(found):
            print(f"{Path(path).name}: {label} {sentence}")
    spec = SurfaceSpec("file", params)
    if step is None:
        span = z_range(surface)
        if span <= 0:
            raise InputError(f"{path}: the surface is flat (z-range 0): pass a step")
        step = float(f"{span / 100:.0e}")
        cap = min(MAX_STEP, float(f"{thickness / 10:.0e}")) if thickness > 0 else MAX_STEP
        if step > cap:
            print(f"step: the default z-range / 100 = {step:g} nm is capped at {cap:g} nm (the largest step, "
                  "and a tenth of the thickness); pass --step to choose", file=sys.stderr)
            step = cap
    return PlanarizeScene(name or Path(path).stem, surface=spec, run=RunSettings(thickness=thickness, step=step, **run))
