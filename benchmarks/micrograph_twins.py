"""The hand line profiles that score qdots measure on real micrographs, checked on each film's synthetic twin.

The reference of most real micrographs (`benchmarks.real_data.half_depth_widths`) is the full width at half depth
of a line profile by hand through each particle: its background is the crest beside the particle, which on a
close-packed film is the narrow gap to the next one. When the particles are small against their blur, that gap never
rises to the background, and the hand width reads narrow. How much, no real picture can say: its true widths are
unknown. So each film is rendered again (`qdots.micrograph.synthetic.render_micrograph`) with the centres,
diameters, shape, blur and contrast qdots measure found on it and its pixel noise: its **twin**, whose true
half-depth widths are known. On the twin the same hand profiles (at the same particles, with the same reach) and qdots
measure are each set against the truth; their ratio on the twin is set beside their ratio on the real picture.
Where the two ratios agree, the real picture's difference between qdots measure and its reference is what the
geometry makes of a line profile by hand, not a fault of either; where they differ, something on the real picture
(stacked particles, facets, a fringe) is not in the twin.

Run: ``python -m benchmarks.micrograph_twins [--half dev|test|all] [--only ID ...]``.
"""

from __future__ import annotations

import math

import numpy as np

from .real_data import CREST_INSIDE, cache_folder, entries, half_depth_widths, halves_main, reference
from .report import Note, Table

MEASURED_CODE = ("qdots/micrograph",)


def twin_row(entry: dict) -> dict | None:
    """One picture and its twin: qdots measure's half-depth width over the hand profiles' on the same particles, on
    the picture and on the twin, and each against the twin's truth. None where the picture has no hand profiles or
    is refused."""
    from scipy import ndimage
    from scipy.spatial import cKDTree

    from labrig.validate import InputError
    from qdots.micrograph.detect import detect_dots
    from qdots.micrograph.measure import measure_image
    from qdots.micrograph.profiles import half_depth_radius
    from qdots.micrograph.read import read_micrograph
    from qdots.micrograph.synthetic import render_micrograph

    ref = reference(entry) if entry.get("expect") == "measure" else None
    if ref is None or ref.widths is None:
        return None
    path = cache_folder() / entry["file"]
    bar = f"{entry['scale_bar_nm']:g}nm" if "scale_bar_nm" in entry else None
    try:
        try:
            film = measure_image(path, scale_bar=bar, lqe=False)
        except InputError:
            film = measure_image(path, lqe=False)
    except InputError:
        return None
    det = film.detection
    image = read_micrograph(path).pixels.astype(float)
    reach = entry["profile_reach"] if entry["reference"] == "profiles" else 1.5 * float(np.median(ref.diameters)) / 2 + 3
    ok = np.isfinite(ref.widths)
    centres, widths = ref.width_centres[ok], ref.widths[ok]
    distance, index = cKDTree(det.centres).query(centres)
    near = distance <= 0.5 * widths
    real = float(np.median(det.half_widths()[index[near]] / widths[near]))
    # the twin: every dot found, rendered as found, with the picture's pixel noise (relative to its level)
    good = np.isfinite(det.diameters)
    dots, diameters = det.centres[good], det.diameters[good]
    noise = 1.25 * float(np.std(image - ndimage.median_filter(image, 3))) / max(abs(float(np.median(image))), 1e-12)
    contrast = float(np.clip(np.median(det.contrast[good]), 0.05, 0.9))
    twin = render_micrograph(dots, diameters, image.shape, profile=det.shape, blur=det.blur, contrast=contrast,
                             illumination=0.0, noise=min(noise, 0.2), seed=1)
    truth = diameters * half_depth_radius(det.shape, det.blur / (0.5 * diameters))
    gap, which = cKDTree(dots).query(centres[near])
    same = np.unique(which[gap < 0.5 * widths[near]])  # the twin's particles at the reference's
    outlines = None if entry["reference"] == "profiles" else CREST_INSIDE * diameters[same] / 2  # as the reference reads
    hand = half_depth_widths(twin, dots[same], True, reach, outlines)
    found = detect_dots(twin, polarity="dark")
    miss, at = cKDTree(found.centres).query(dots[same])
    ours = found.half_widths()[at]
    use = np.isfinite(hand) & (miss < 3.0)
    if not use.any():
        return None
    return {"id": entry["id"], "particles": int(use.sum()), "real": real,
            "hand": float(np.median(hand[use] / truth[same][use])), "ours": float(np.median(ours[use] / truth[same][use])),
            "twin": float(np.median(ours[use] / hand[use])), "diameter": float(np.median(diameters)),
            "blur": float(det.blur), "shape": float(det.shape), "noise": noise}


def table(rows: list[dict], half: str) -> Table:
    def pct(v: float) -> str:
        return f"{100 * (v - 1.0):+.1f} %" if math.isfinite(v) else ""

    return Table(f"Real micrographs, {half} half: the hand line profiles and qdots measure on each film's twin",
                 ["picture", "d (px)", "blur (px)", "shape p", "noise", "particles", "qdots / hand, real picture",
                  "qdots / hand, twin", "hand / truth, twin", "qdots / truth, twin"],
                 [[r["id"], f"{r['diameter']:.1f}", f"{r['blur']:.2f}", f"{r['shape']:g}", f"{r['noise']:.3f}",
                   r["particles"], pct(r["real"]), pct(r["twin"]), pct(r["hand"]), pct(r["ours"])] for r in rows],
                 note="Half-depth widths, the median ratio over the reference's particles. The twin is each picture "
                      "rendered again from what qdots measure found on it (centres, diameters, shape, blur, median "
                      "contrast, pixel noise; `python -m benchmarks.micrograph_twins`); its truth is each rendered "
                      "dot's half-depth width. Where 'qdots / hand' is alike on the real picture and on its twin, their "
                      "difference on the real picture is the hand profile's reading of that geometry.")


def results(halves: tuple[str, ...], only: list[str] | None = None, most: int | None = None) -> list:
    chosen = [e for e in entries() if e["half"] in halves and (not only or e["id"] in only)][:most]
    missing = [e["file"] for e in chosen if not (cache_folder() / e["file"]).exists()]
    if missing:
        return [Note(f"{len(missing)} of the {len(chosen)} real micrographs are not in {cache_folder().name}/ (the "
                     "cache folder): fetch them with `python -m benchmarks.micrograph_real --fetch`.")]
    out: list = []
    for half in halves:
        rows = [row for row in (twin_row(e) for e in chosen if e["half"] == half) if row is not None]
        if rows:
            out.append(table(rows, half))
    return out


def run(quick: bool) -> list:
    """The development half (quick: its first 3 pictures)."""
    return results(("dev",), most=3 if quick else None)


def main(argv: list[str] | None = None) -> int:
    return halves_main(results, __doc__.splitlines()[0], argv)


if __name__ == "__main__":
    raise SystemExit(main())
