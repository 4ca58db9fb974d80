"""Micrographs as microscopes write them: size spread and diameter on dense and ordered films, data strips and ruled bars, pictures that are not films.

Three tables, every number against a known truth:

* **Dense films**: square and hexagonal superlattices with 1 and 2 nm ligand gaps, a touching random film
  (10 % vacancies) and a touching superlattice without any, each at size spreads of 3, 5 and 10 %; 10 nm
  dots at 0.6 nm/px (16.7 px), projected spheres, uneven focus (blur 0.6 px at the left edge to 1.2 px at
  the right), uneven contrast (0.55, 15 % dot to dot, +-20 % top to bottom), illumination falling 30 %
  across, the support's grain (2 % of the background, correlated over 1.5 px) and noise (5 %). Beside
  ``qdots measure``'s diameters, those of a threshold-based measurement as published tools make it
  (`threshold_tool`: Otsu's threshold on the image flattened by a broad Gaussian, a watershed of the distance
  transform, each region's area-equivalent diameter), against the same truth.
* **As microscopes write them**: films laid out with a data strip (black or white, along any side, with
  text) or a box over the film, and a scale bar solid, ruled, checkered or as a ruler line, labelled under,
  over or beside it (`qdots.micrograph.labelled`), written as JPEG (quality 85) and measured with the bar's
  length given (``--scale-bar``): the bar found, the scale, the dots in the strip, the diameters.
* **Not films**: a plot, text and a drawing (drawn, and with noise as a scan has), and a board picture
  as ``qdots render`` draws it: each must be refused with its reason.

Run: ``python -m benchmarks.micrograph_films [--quick]``
"""

from __future__ import annotations

import tempfile
import time
from pathlib import Path

import numpy as np
from scipy import ndimage

from qdots.micrograph.detect import detect_dots
from qdots.micrograph.film import film_metrics, film_state
from qdots.micrograph.synthetic import dense_board, render_micrograph, superlattice_board

from .report import Headline, Note, Table, cli

#: The code this benchmark measures (besides itself): a commit to it after a run marks the run's section as
#: older than its code (`benchmarks.staleness`).
MEASURED_CODE = ("qdots/micrograph", "qdots/analysis")

#: 10 nm dots at 0.6 nm/px; the film types: (lattice, ligand gap in nm) or a random touching film.
NM_PER_PX, DIAMETER_NM = 0.6, 10.0
FILMS = {"square superlattice, 1 nm gaps": ("square", 1.0), "square superlattice, 2 nm gaps": ("square", 2.0),
         "hexagonal superlattice, 1 nm gaps": ("hexagonal", 1.0), "hexagonal superlattice, 2 nm gaps": ("hexagonal", 2.0),
         "touching, random (10 % vacancies)": ("random", 0.0), "touching superlattice, no vacancies": ("hexagonal", 0.0)}
SPREADS = (0.03, 0.05, 0.10)
#: How the dense films are imaged (`qdots.micrograph.synthetic.render_micrograph`).
IMAGING = {"noise": 0.05, "blur": (0.6, 1.2), "contrast": 0.55, "contrast_spread": 0.15, "contrast_tilt": 0.2,
           "texture": 0.02, "illumination": 0.3}
#: The requirements of issue 52: sigma within 1.5 percentage points, mean diameter within 2 %, g(r)'s first peak
#: at one diameter or more when the dots do not overlap.
GOALS = {"sigma_pp": 1.5, "diameter": 0.02, "gr": 1.0}


def film(kind: str, gap_nm: float, sigma: float, side: int, seed: int = 1):
    """Centres and diameters (px) of one film type."""
    d = DIAMETER_NM / NM_PER_PX
    if kind == "random":
        return dense_board(side, side, d, sigma, seed=seed)
    return superlattice_board(side, side, d, sigma, gap_nm / NM_PER_PX, kind, seed=seed,
                              jitter=0.05 if gap_nm == 0 else 0.02)


def whole(centres, diameters, shape) -> np.ndarray:
    """The dots whose disc lies inside the picture."""
    h, w = shape
    r = 0.5 * diameters
    return (centres[:, 0] >= r) & (centres[:, 1] >= r) & (centres[:, 0] + r <= w) & (centres[:, 1] + r <= h)


def threshold_tool(image: np.ndarray, flatten: bool = True) -> np.ndarray:
    """Diameters (px) of the dots as a threshold-based tool measures them: the image flattened by a broad
    Gaussian (an eighth of its side; or, with ``flatten`` False, as it is, with the regions' holes filled, as
    ImageJ's particle analysis is used on real pictures), smoothed by 1 px, cut at Otsu's threshold; the distance
    transform's maxima at least 0.6 typical radii apart seed a watershed; each region not touching the edge, of 10
    px or more, gives the diameter of the disc of its area."""
    from skimage.feature import peak_local_max
    from skimage.filters import threshold_otsu
    from skimage.segmentation import watershed

    smooth = ndimage.gaussian_filter(image, 1.0)
    flat = smooth / ndimage.gaussian_filter(image, max(image.shape) / 8.0) if flatten else smooth
    mask = flat < threshold_otsu(flat)
    if not flatten:
        mask = ndimage.binary_fill_holes(mask)
    distance = ndimage.distance_transform_edt(mask)
    tops = (distance == ndimage.maximum_filter(distance, 5)) & (distance >= 2)
    if not tops.any():
        return np.zeros(0)
    radius = float(np.median(distance[tops]))
    peaks = peak_local_max(distance, min_distance=max(2, int(0.6 * radius)), labels=ndimage.label(mask)[0])
    markers = np.zeros(image.shape, dtype=int)
    markers[tuple(peaks.T)] = np.arange(1, len(peaks) + 1)
    labels = watershed(-distance, markers, mask=mask)
    area = np.bincount(labels.ravel())[1:]
    edge = np.unique(np.concatenate([labels[0], labels[-1], labels[:, 0], labels[:, -1]]))
    keep = ~np.isin(np.arange(1, len(area) + 1), edge) & (area >= 10)
    return 2.0 * np.sqrt(area[keep] / np.pi)


def first_peak(state) -> float:
    """Where g(r) peaks within 1.6 mean diameters (the first shell of neighbours), in mean diameters."""
    from qdots.analysis.structure import radial_distribution

    mean = 2.0 * float(np.mean(state.radii))
    rdf = radial_distribution(state, r_max=1.6 * mean, bins=64)
    return float(rdf.r[int(np.nanargmax(rdf.g))] / mean)


def dense_case(name: str, sigma: float, side: int) -> dict:
    """One dense film measured: sigma, diameter and g(r) against the truth, and the threshold tool's diameter."""
    kind, gap = FILMS[name]
    centres, diameters = film(kind, gap, sigma, side)
    image = render_micrograph(centres, diameters, (side, side), seed=2, **IMAGING)
    start = time.perf_counter()
    detection = detect_dots(image)
    seconds = time.perf_counter() - start
    true = diameters[whole(centres, diameters, image.shape)]
    state = film_state(detection.centres, detection.diameters, image.shape)
    metrics = film_metrics(state, measured=~detection.cut, errors=detection.errors)
    true_sigma = float(true.std(ddof=1) / true.mean())
    inside = whole(centres, diameters, image.shape)
    true_gr = first_peak(film_state(centres[inside], diameters[inside], image.shape))
    measured_gr = first_peak(film_state(detection.centres[~detection.cut], detection.diameters[~detection.cut],
                                        image.shape))
    return {"film": name, "sigma": true_sigma, "dots": int(len(true)), "measured": metrics["size_spread"],
            "true_gr": true_gr,
            "raw": metrics["size_spread_measured"], "error": metrics["size_spread_error"],
            "d": metrics["mean_diameter_px"] / true.mean() - 1.0,
            "threshold": float(np.mean(threshold_tool(image))) / true.mean() - 1.0,
            "gr": measured_gr, "p": detection.shape, "seconds": seconds}


def dense_table(side: int, names, spreads) -> tuple[Table, list[dict]]:
    rows = [dense_case(name, sigma, side) for name in names for sigma in spreads]
    table = Table(f"Dense and ordered films, {side} x {side} px, 10 nm dots at {NM_PER_PX} nm/px, uneven focus and "
                  "contrast: size spread and diameter against the truth",
                  ["film", "true sigma", "measured sigma", "sigma error (pp)", "of it: measurement error",
                   "sigma before the error is taken out", "mean diameter error", "threshold tool's diameter error",
                   "g(r) first peak (d), true / measured", "dots", "time (s)"],
                  [[r["film"], f"{100 * r['sigma']:.2f} %", f"{100 * r['measured']:.2f} %",
                    f"{100 * (r['measured'] - r['sigma']):+.2f}", f"{100 * r['error']:.2f} %", f"{100 * r['raw']:.2f} %",
                    f"{100 * r['d']:+.2f} %", f"{100 * r['threshold']:+.1f} %", f"{r['true_gr']:.2f} / {r['gr']:.2f}",
                    r["dots"], r["seconds"]]
                   for r in rows],
                  note="sigma is SD / mean over the dots whose disc lies inside the picture (true) and those the edge "
                       "does not cut (measured), the measurement error (`repeat_errors`) taken out; g(r)'s first peak "
                       "is its highest point within 1.6 mean diameters, each film's own mean; the threshold "
                       "tool's diameters are its regions' area-equivalent diameters, against the same truth. Goals "
                       "(issue 52): sigma within 1.5 pp, mean diameter within 2 %, g(r) first peak >= 1 diameter. "
                       "Time measured on a 2-core machine shared with other work.")
    return table, rows


def written_cases(quick: bool) -> list[dict]:
    """The layouts of the second table: (strip side or None, colour, bar style, boxed, label place)."""
    layouts = [("bottom", "black", "ruled", True, "under"), ("bottom", "white", "checkered", False, "beside"),
               ("top", "white", "solid", False, "over"), ("right", "black", "ruler", False, "under"),
               ("left", "white", "ruled", False, "under"), (None, "white", "solid", True, "under"),
               (None, "black", "checkered", False, "under")]
    return [dict(zip(("strip", "colour", "style", "boxed", "label"), layout)) for layout in layouts[:3 if quick else None]]


def written_table(quick: bool) -> Table:
    from PIL import Image

    from qdots.micrograph.labelled import label_micrograph
    from qdots.micrograph.measure import measure_image

    h, w = (360, 440) if quick else (560, 700)
    centres, diameters = film("hexagonal", 1.5, 0.05, max(h, w))
    keep = (centres[:, 0] < w + diameters) & (centres[:, 1] < h + diameters)
    centres, diameters = centres[keep], diameters[keep]
    picture = render_micrograph(centres, diameters, (h, w), seed=3, **IMAGING)
    picture = np.clip(picture / np.percentile(picture, 99.9) * 0.85, 0, 1)
    true = diameters[whole(centres, diameters, (h, w))]
    rows = []
    with tempfile.TemporaryDirectory() as directory:
        for case in written_cases(quick):
            side = case["strip"] in ("left", "right")
            bar_nm = 60.0 if side else 100.0
            labelled = label_micrograph(picture, NM_PER_PX, bar_nm=bar_nm, strip_px=170 if side else None, **case)
            path = Path(directory) / "film.jpg"
            Image.fromarray((255 * labelled.image).astype(np.uint8)).save(path, quality=85)
            measured = measure_image(path, scale_bar=f"{bar_nm:g}nm", lqe=False)
            x0, y0, x1, y1 = labelled.window
            c = measured.detection.centres
            outside = int(np.sum((c[:, 0] < x0) | (c[:, 0] > x1) | (c[:, 1] < y0) | (c[:, 1] > y1)))
            s = measured.summary
            rows.append([f"{case['strip'] or 'none'}", case["colour"], case["style"], "yes" if case["boxed"] else "no",
                         case["label"], labelled.bar_px, measured.bar.length_px,
                         f"{100 * (s['nm_per_px'] / NM_PER_PX - 1):+.2f} %", outside,
                         f"{100 * (s['mean_diameter_nm'] / (true.mean() * NM_PER_PX) - 1):+.2f} %",
                         f"{100 * s['size_spread']:.2f} %", f"{100 * true.std(ddof=1) / true.mean():.2f} %"])
    return Table(f"Films as microscopes write them ({w} x {h} px film, 10 nm dots, 1.5 nm gaps, hexagonal, "
                 "spread 5 %, JPEG quality 85), measured with the bar's length given",
                 ["strip", "colour", "bar", "boxed", "label", "bar (px, true)", "bar found (px)", "scale error",
                  "dots outside the picture", "mean diameter error", "sigma measured", "sigma true"], rows,
                 note="The strip, its text and the bar are drawn with matplotlib (`qdots.micrograph.labelled`); "
                      "'none' is a bar drawn over the film's corner, boxed or not.")


def refusal_table(quick: bool) -> Table:
    from PIL import Image

    from labrig.validate import InputError
    from qdots.micrograph.labelled import not_a_film
    from qdots.micrograph.measure import measure_image

    pictures = {}
    rng = np.random.default_rng(0)
    for kind in ("plot", "text", "drawing"):
        drawn = not_a_film(kind, (360, 480))
        pictures[kind] = drawn
        pictures[f"{kind}, scanned (noise 3 %)"] = np.clip(drawn + 0.03 * rng.standard_normal(drawn.shape), 0, 1)
    pictures["a board as qdots render draws it"] = board_picture()
    rows = []
    with tempfile.TemporaryDirectory() as directory:
        for name, picture in pictures.items():
            path = Path(directory) / "picture.png"
            Image.fromarray((255 * np.clip(picture, 0, 1)).astype(np.uint8)).save(path)
            try:
                film_ = measure_image(path, lqe=False)
                rows.append([name, "no", f"measured: {film_.summary['dots']} dots"])
            except InputError as exc:
                rows.append([name, "yes", str(exc).split(": ", 1)[1]])
    return Table("Pictures that are not films: refused, in one line", ["picture", "refused", "reason"], rows)


def board_picture() -> np.ndarray:
    """A simulated board as ``qdots render`` writes it (`qdots.render.save_png`: discs coloured by size, axes,
    title, key), in grey."""
    from qdots.micrograph.read import read_micrograph
    from qdots.render import save_png

    centres, diameters = dense_board(300, 300, 15.0, 0.05, seed=4, vacancies=0.3)
    with tempfile.TemporaryDirectory() as directory:
        path = save_png(film_state(centres, diameters, (300, 300)), Path(directory) / "board.png")
        pixels = read_micrograph(path).pixels
    return pixels / 255.0


def run(quick: bool) -> list:
    side = 256 if quick else 512
    names = list(FILMS)[::2] if quick else list(FILMS)
    spreads = (0.05,) if quick else SPREADS
    dense, rows = dense_table(side, names, spreads)
    worst_sigma = max(abs(r["measured"] - r["sigma"]) for r in rows)
    worst_d = max(abs(r["d"]) for r in rows)
    results = [Headline("qdots measure on dense and ordered films (sigma, mean diameter against truth)",
                        f"{np.mean([r['seconds'] for r in rows]):.1f} s per {side}^2 px film",
                        f"sigma within {100 * worst_sigma:.2f} pp, diameter within {100 * worst_d:.2f} %"),
               dense, written_table(quick), refusal_table(quick)]
    results.append(Note(f"Goals: sigma within {GOALS['sigma_pp']} pp and the mean diameter within "
                        f"{100 * GOALS['diameter']:g} % of the truth; worst over the films: "
                        f"{100 * worst_sigma:.2f} pp and {100 * worst_d:.2f} %."))
    return results


def main(argv: list[str] | None = None) -> int:
    return cli(run, __doc__.splitlines()[0], argv)


if __name__ == "__main__":
    raise SystemExit(main())
