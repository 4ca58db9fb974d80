"""Rounding jitter of qdots measure on real micrographs: each picture measured three times, its pixels times 1, 1 + 1e-13 and 1 - 1e-13.

No picture can tell those three apart, so a measurement that is a smooth function of the picture gives the same
result for all three, to about 1e-13. Where the three results differ by more, a discrete choice made inside the
measurement (which radius of a search is best, which pixels a window holds, which trial of the settling has the
least residual) amplified the change of the last bit into a change of the result: that spread is a floor under
the result's error that no goal can be met within, and a verdict that differs between the three sits on its rule's
threshold. Each copy is a float64 TIFF of the pixels as read (`qdots.micrograph.read_micrograph`: the same
measurement as of the file itself, to the last bit, at factor 1), measured as `benchmarks.micrograph_real` measures
the file (the file's own scale, else the bar with its written length).

Run: ``python -m benchmarks.micrograph_jitter [--half dev|test|all] [--only ID ...]``.
"""

from __future__ import annotations

import math
import tempfile
import time
from pathlib import Path

import numpy as np

from .real_data import cache_folder, entries, halves_main
from .report import Headline, Note, Table

MEASURED_CODE = ("qdots/micrograph", "qdots/analysis")
#: The factors the pixels are multiplied by.
FACTORS = (1.0, 1.0 + 1e-13, 1.0 - 1e-13)
#: EMPS pictures measured beside the real micrographs of the development half: a film whose verdict sits on the
#: outline rule's threshold (docs/micrograph.md, rounding jitter).
EDGE_CASES = ("891f96f60d",)


def measure_copy(pixels: np.ndarray, nm_per_px: float | None, bar: str | None) -> dict:
    """qdots measure on a float64 TIFF of ``pixels``: what it reports, or its refusal."""
    import tifffile

    from labrig.validate import InputError
    from qdots.micrograph.measure import measure_image

    start = time.perf_counter()
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "copy.tif"
        tifffile.imwrite(path, np.asarray(pixels, dtype=np.float64))
        try:
            try:
                film = measure_image(path, nm_per_px=nm_per_px, scale_bar=bar, lqe=False)
            except InputError as exc:  # as micrograph_real does: measured again without the bar, sizes in px
                if bar is None or not str(exc).startswith("scale_bar: no scale bar found"):
                    raise
                film = measure_image(path, lqe=False)
        except InputError as exc:
            return {"verdict": "refused", "why": str(exc).split(": ", 2)[-1], "seconds": time.perf_counter() - start}
    s = film.summary
    return {"verdict": "measured", "mean": s["mean_diameter_px"], "half_width": s["mean_half_width_px"],
            "spread": s["size_spread"], "blur": film.detection.blur, "dots": int(np.count_nonzero(~film.detection.cut)),
            "seconds": time.perf_counter() - start}


def jitter_row(name: str, path: Path, bar_nm: float | None) -> dict:
    """One picture measured at every factor of `FACTORS`, and the spread of its results."""
    from qdots.micrograph.read import read_micrograph

    image = read_micrograph(path)
    bar = f"{bar_nm:g}nm" if bar_nm is not None and image.nm_per_px is None else None
    runs = [measure_copy(image.pixels * factor, image.nm_per_px, bar) for factor in FACTORS]
    row = {"id": name, "verdicts": [r["verdict"] for r in runs], "seconds": float(np.mean([r["seconds"] for r in runs])),
           "why": next((r["why"] for r in runs if r["verdict"] == "refused"), "")}
    measured = [r for r in runs if r["verdict"] == "measured"]
    if len(measured) >= 2:
        for key in ("mean", "half_width"):
            values = [r[key] for r in measured]
            row[key] = float(np.mean(values))
            row[f"{key}_spread"] = float(max(values) / min(values) - 1.0)
        row["spread_pp"] = 100.0 * float(np.ptp([r["spread"] for r in measured]))
        row["spread"] = float(np.mean([r["spread"] for r in measured]))
        row["blurs"] = [r["blur"] for r in measured]
        row["dots"] = [r["dots"] for r in measured]
    return row


def pictures(halves: tuple[str, ...], only: list[str] | None) -> list[tuple[str, str, Path, float | None]]:
    """(half, name, file, the bar's written length in nm or None) of each picture measured."""
    from .micrograph_emps import folder as emps_folder

    chosen = [(e["half"], e["id"], cache_folder() / e["file"], e.get("scale_bar_nm")) for e in entries()
              if e["half"] in halves]
    if "dev" in halves:
        chosen += [("dev", f"EMPS {name}", emps_folder() / f"{name}.png", None) for name in EDGE_CASES]
    return [c for c in chosen if not only or c[1] in only]


def table(rows: list[dict], half: str) -> Table:
    def pct(value: float) -> str:
        return f"{100 * value:.3f} %" if math.isfinite(value) else ""

    body = [[r["id"], " / ".join(r["verdicts"]) if len(set(r["verdicts"])) > 1 else r["verdicts"][0],
             f"{r['mean']:.2f}" if "mean" in r else "", pct(r.get("mean_spread", math.nan)),
             pct(r.get("half_width_spread", math.nan)),
             f"{100 * r['spread']:.2f} % ({r['spread_pp']:.2f})" if "spread" in r else "",
             "-".join(f"{b:.2f}" for b in (min(r["blurs"]), max(r["blurs"]))) if "blurs" in r else "",
             "-".join(str(n) for n in sorted({min(r["dots"]), max(r["dots"])})) if "dots" in r else "",
             f"{r['seconds']:.1f}"] for r in rows]
    return Table(f"Real micrographs, {half} half{' (and the EMPS edge case)' if half == 'dev' else ''}: the same "
                 "picture measured three times, its pixels times 1 and 1 +- 1e-13",
                 ["picture", "verdict", "mean d (px)", "mean d: spread", "half-depth width: spread",
                  "sigma (its spread, pp)", "blur (px)", "whole dots", "time per run (s)"], body,
                 note="Spread: the largest of the three results over the smallest, less 1 (for sigma, their range in "
                      "percentage points); a verdict is given three times where the three differ. Time measured on a "
                      "2-core machine.")


def results(halves: tuple[str, ...], only: list[str] | None = None, most: int | None = None) -> list:
    chosen = pictures(halves, only)[:most]
    missing = [str(path.name) for _, _, path, _ in chosen if not path.exists()]
    if missing:
        return [Note(f"{len(missing)} of the {len(chosen)} pictures are not in the cache folder: fetch them with "
                     "`python -m benchmarks.micrograph_real --fetch` and `python -m benchmarks.micrograph_emps --fetch`.")]
    out: list = []
    summary, seconds = [], []
    for half in halves:
        rows = [jitter_row(name, path, bar) for part, name, path, bar in chosen if part == half]
        if not rows:
            continue
        out.append(table(rows, half))
        seconds += [3 * r["seconds"] for r in rows]
        spreads = [r["mean_spread"] for r in rows if "mean_spread" in r]
        flips = [r["id"] for r in rows if len(set(r["verdicts"])) > 1]
        summary.append(f"{half}: mean d within {100 * max(spreads, default=0.0):.2f} % on {len(spreads)} films "
                       f"({sum(s > 1e-3 for s in spreads)} over 0.1 %); verdicts that differ: "
                       f"{', '.join(flips) if flips else 'none'}")
    out.insert(0, Headline("qdots measure's rounding jitter on real micrographs (pixels times 1 +- 1e-13)",
                           f"{sum(seconds):.0f} s for {len(seconds)} pictures, 3 runs each", "; ".join(summary)))
    return out


def run(quick: bool) -> list:
    """The development half and the EMPS edge cases (quick: the first 3 pictures, 3 runs each)."""
    return results(("dev",), most=3 if quick else None)


def main(argv: list[str] | None = None) -> int:
    return halves_main(results, __doc__.splitlines()[0], argv)


if __name__ == "__main__":
    raise SystemExit(main())
