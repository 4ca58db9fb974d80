"""planarize on real AFM maps: instruments' own files read, their artefacts found and levelled, and the continuum
engine's stated error against the true one.

The maps are the public sample scans of `benchmarks/afm_real.toml` (Bruker, Asylum, JPK, WSxM, NanoSurf, Park
Systems and PicoView files, and a Bruker scan saved by Gwyddion), fetched by ``python -m benchmarks.afm_files``; no
one on this project made them. The NanoSurf scans, then the Park and PicoView scans (`HELD_OUT`), were added after
the estimator's rules were chosen: both crops of each are held out, each group scored once on the code of its day.

* **Reading and levelling.** Each file read by `planarize.io.load_levelled` at its defaults (``"auto"``): its
  size and pixel, the artefacts found (and removed), the time to read and level it.
* **Stated against true error.** The continuum engine at its defaults (``rtol`` 0.02) on ``CROP`` x ``CROP``
  pixels of each levelled map (a crop: the refinements to 16x of a whole map would take days), grown to the
  crop's z-range in oxide thickness: the error it states beside its true error. Two crops per map, chosen
  before the estimator was changed: the **development half**, the centre crop, on which the estimator was
  examined, and the **test half**, the crop centred at a quarter of the map's width and height, reported here
  (its per-level numbers were printed once beside the development half's while the two candidate estimators
  were compared; the observed-order range the engine uses, [0.7, 3], was fixed before either was run). The
  true error is against the converged answer: the finest run corrected by Richardson's rule at the order of
  the last three refinements (the slope of their changes: `benchmarks.planarize_continuum.converged`, as on the
  thesis's surfaces). The finest run is 32x, or 16x where the 16x run cost more than `FINEST_AFTER` point steps,
  or 8x where the 8x run did. The goal of issue 63:
  stated within a factor 2 of the true error, and where the run is not in its asymptotic regime, no number
  stated.

Run: ``python -m benchmarks.afm_real [--quick]`` (the maps must be fetched first).
"""

from __future__ import annotations

import time

import numpy as np

from planarize import Surface
from planarize.engines import Continuum
from planarize.io.heights import load_levelled
from planarize.metrics import ESTIMATED, pixel_curvature, z_range

from .afm_files import manifest, present
from .planarize_continuum import case_results, level, point_steps
from .report import Headline, Note, Table, cli

#: The code this benchmark measures (besides itself).
MEASURED_CODE = ("planarize",)
#: Pixels a side of the crop the engine runs on, the refinements computed for its converged answer (the finest
#: four times the finest the default run may choose, `planarize.engines.Continuum`'s ``max_refine`` of 8), and
#: the default run's settings; quick: a smaller crop, and the default run capped at 2x.
CROP, FACTORS, SETTINGS = 32, (0.5, 1, 2, 4, 8, 16, 32), Continuum()
#: The converged answer leaves out a run finer than 8x where the one before it cost more than this many point steps
#: (time steps times grid points: about 10 s on 2 cores; each halving of the spacing costs 8-40x as much, up to half an
#: hour for one crop). Wall time decided this before, and a crop whose 8x run took 9-10 s had its truth from 16x on
#: one run and from 8x on the next. With a single 16x run, the order of one ratio of two changes scattered between
#: 0.4 and 2.5 on these crops and made the truth up to 2x off.
FINEST_AFTER = 1.5e8
#: A crop whose own grid (1x) takes more than this many point steps is not run: its converged answer, from grids up
#: to 8x that each cost 8-40 times the one before, would take hours (the crops run cost 1e3-1.3e5 at 1x; a Bruker D3100
#: scan's, 60 nm of relief over 0.59 nm pixels, 5.5e5-3.8e6). Decided from the 1x cost alone, before any estimate.
MOST_POINT_STEPS = 2e5
#: The two halves: where each crop is centred, as fractions of the map's rows and columns.
HALVES = {"development": (0.5, 0.5), "test": (0.25, 0.25)}
QUICK_CROP, QUICK_FACTORS, QUICK_SETTINGS = 16, (0.5, 1, 2, 4), Continuum(max_refine=2)
#: Scans added after the rules of the estimate were chosen, by group: both their crops are held out, each group scored
#: once. The NanoSurf scans were scored first; the Park Systems and PicoView scans (read through SurfaceTopography)
#: after the noisy-map rule; the last group after the rule for the map's own grid, chosen on every scan before it
#: (the calibration grid, grid.nid, is read but not run: its steps make the flow stiff).
HELD_OUT = {"NanoSurf scans": ("sapphire.nid", "MoS2.nid", "SBS-PMMA.nid"),
            "Park Systems and PicoView scans": ("example_ps.tiff", "mi-1.mi"),
            "Bruker, Asylum, NanoSurf and WSxM scans of SurfaceTopography": (
                "di-2.di", "di-3.di", "di-5.di", "spot_1-1000nm.ibw", "nid-1.nid", "stp-1.stp")}
#: The maps run through the engine (one per scan: the .top files repeat the .stp files' scans).
ENGINE_MAPS = ("sample_0.spm", "sample_0.ibw", "sample_0.jpk", "sample_0.gwy", "sample_0.stp",
               "sample_1_um_scale.stp", *(name for group in HELD_OUT.values() for name in group))


def crop(surface: Surface, n: int, centre: tuple[float, float] = (0.5, 0.5)) -> Surface:
    """``n`` x ``n`` points of ``surface`` centred at the fractions ``centre`` of its rows and columns."""
    i0 = min(max(int(surface.shape[0] * centre[0]) - n // 2, 0), surface.shape[0] - n)
    j0 = min(max(int(surface.shape[1] * centre[1]) - n // 2, 0), surface.shape[1] - n)
    return Surface(surface.z[i0:i0 + n, j0:j0 + n], surface.spacing)


def reading(maps: dict) -> tuple[Table, dict]:
    """Each file read and levelled at the defaults; the levelled surfaces by file."""
    table = Table("Reading and levelling each file (level \"auto\")",
                  ["file", "instrument", "points", "pixel (nm)", "z-range raw -> levelled (nm)", "artefacts found",
                   "read + level (s)"])
    levelled = {}
    for entry in manifest()["map"]:
        path = maps.get(entry["file"])
        if path is None:
            continue
        raw, _ = load_levelled(path, level="none", format=entry.get("format"))
        start = time.perf_counter()
        surface, artefacts = load_levelled(path, format=entry.get("format"))
        wall = time.perf_counter() - start
        levelled[entry["file"]] = surface
        found = "; ".join(f"{a.name} {a.detail}" + ("" if a.applied else " (kept)") for a in artefacts if a.found)
        table.rows.append([entry["file"], entry["instrument"], " x ".join(map(str, surface.shape)),
                           " x ".join(dict.fromkeys(f"{d:.3g}" for d in surface.spacing)),
                           f"{z_range(raw):.3g} -> {z_range(surface):.3g}", found or "none",
                           wall])
    return table, levelled


def errors(levelled: dict, size: int, factors, settings: Continuum, half: str) -> tuple[Table, list, dict]:
    """The default run's stated and true error on one crop of each map (``half``: `HALVES`); the ratios of stated to
    true error of the maps before `HELD_OUT`, and of each group of those."""
    table = Table(f"{half.capitalize()} half: stated against true error at the default (rtol 0.02), {size} x {size} "
                  f"crop centred at {HALVES[half][0]:g} of each levelled map: largest over the recorded thicknesses (%)",
                  ["file", "pixel curvature", "thickness (nm)", "refinement chosen", "wall (s)",
                   *[f"{c.replace('_nm', '').replace('_', ' ')} {what}" for c in ESTIMATED
                     for what in ("stated", "true", "ratio")]])
    ratios: list = []
    held_out: dict = {group: [] for group in HELD_OUT}
    for name in ENGINE_MAPS:
        if name not in levelled:
            continue
        surface = crop(levelled[name], size, HALVES[half])
        thickness = float(f"{z_range(surface):.1g}")
        cost = point_steps(level(surface, thickness, 1))
        if cost > MOST_POINT_STEPS:
            table.rows.append([name, pixel_curvature(surface), thickness,
                               f"not run: too steep ({cost:.2g} point steps at 1x)", "", *[""] * (3 * len(ESTIMATED))])
            continue
        rows, default, _ = case_results(name, lambda s=surface: s, thickness, factors, settings, FINEST_AFTER)
        finest = 2 * max(row[1] for row in rows)
        if default[1] >= finest:  # the converged answer comes from the run's own grids: no independent truth
            cells = [x if k % 3 == 0 else "(truth from the run's own grids)" for k, x in enumerate(default[3:])]
        else:
            cells = ["not asymptotic" if np.isnan(x) else x for x in default[3:]]
            group = next((g for g, names in HELD_OUT.items() if name in names), None)
            (ratios if group is None else held_out[group]).extend(default[5::3])
        table.rows.append([default[0], pixel_curvature(surface), thickness, *default[1:3], *cells])
    return table, ratios, held_out


def verdict(ratios: list) -> str:
    """How the stated errors of one half compare with the true ones."""
    ratios = np.asarray(ratios, dtype=float)
    stated = ratios[np.isfinite(ratios)]
    within = int(((stated >= 0.5) & (stated <= 2.0)).sum())
    text = (f"stated {len(stated)} of {len(ratios)} with an independent truth (the others: not asymptotic, no "
            f"number); within 2x: {within} of {len(stated)}")
    if len(stated):
        text += f"; ratios {stated.min():.2g}-{stated.max():.2g}, under 0.5: {int((stated < 0.5).sum())}"
    return text


def run(quick: bool = False) -> list:
    maps = present()
    if not maps:
        return [Note("The real AFM maps are not fetched: run `python -m benchmarks.afm_files` first.")]
    read, levelled = reading(maps)
    size, factors, settings = (QUICK_CROP, QUICK_FACTORS, QUICK_SETTINGS) if quick else (CROP, FACTORS, SETTINGS)
    if quick:
        levelled = {k: v for k, v in levelled.items() if k == "sample_0.jpk"}
    tables, verdicts, held_out = [], [], {group: [] for group in HELD_OUT}
    for half in HALVES if not quick else ("development",):
        table, ratios, new = errors(levelled, size, factors, settings, half)
        tables.append(table)
        verdicts.append(f"{half}: {verdict(ratios)}")
        for group in HELD_OUT:
            held_out[group] += new[group]
    verdicts += [f"{group} (both crops, held out): {verdict(ratios)}" for group, ratios in held_out.items() if ratios]
    return [
        Headline(f"planarize on real AFM files: {len(read.rows)} files read and levelled", "see table",
                 "; ".join(verdicts)),
        read, *tables,
        Note("Each engine run is on a crop, grown to the crop's z-range of oxide. The stated error is the run's own "
             "(history columns `*_error_nm`: Richardson's estimate at the order observed over its grid and the two "
             "coarser ones, where it lies in [0.7, 3], taken at most as 1.5 where the order one grid coarser reached "
             "1.5 too and at most as 1 otherwise (as 1.8 where it reached 1.2 twice running on a map its pixels resolve, "
             "pixel curvature under 1.3: of these crops, the Park scan's two); outside [0.7, 3], on a map whose pixel "
             "curvature reaches 4 (it bends from pixel to pixel as white noise does), or on the map's own grid (1x: "
             "its companions sample the map at fewer points than it has), the run states no number and says why); "
             "the true error its difference from the converged answer (the finest run, 32x "
             "where the runs before it were fast enough, corrected at the order of the last three refinements). These scans "
             "hold pixel-scale noise, whose z-range converges slowly and unevenly as the grid refines: that is "
             "where the runs state no number. A crop whose default run chose the finest grid the converged answer "
             "was computed from (8x, where its 8x run cost more than FINEST_AFTER point steps and 16x was left out) has no "
             "independent truth: its ratios are shown as such and not counted. A crop whose run at 1x alone costs "
             f"more than {MOST_POINT_STEPS:,.0f} point steps (too steep for its pixels: relief many times the pixel "
             "size) is not run, as its converged answer would take hours; that is decided from that cost alone. "
             + "; ".join(verdicts) + "."),
    ]


if __name__ == "__main__":
    raise SystemExit(cli(run, __doc__.splitlines()[0]))
