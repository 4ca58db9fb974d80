"""Micrograph measurement against known boards: recall, precision, size, position and interior-fraction
errors against noise, and the time to measure an image.

Synthetic micrographs (`qdots.micrograph.synthetic.render_micrograph`): dark projected spheres
(contrast 0.6 of the light, spread 12 % dot to dot), blur 1 px, illumination falling 30 % across the
image, Gaussian noise of 0 to 0.3 of the background level; mean diameter 15 px, size spread 10 %;
two boards: a dense touching film (hexagonal lattice 1.02 diameters apart, 10 % vacancies, each dot
shifted within its site) and a sparse one (15 % coverage). A true dot is found when a detection lies
within 0.3 of its diameter; errors are over the dots the image edge does not cut (median |d - d_true|
/ d_true, median centre distance); the interior-fraction error is the measured film's against the true
board's, both with `complete_neighbourhood`'s edge rule. Time is the whole `detect_dots` (the first
call's compilation excluded), and for 2048 x 2048 also `measure_image` with and without the film LQE.

Run: ``python -m benchmarks.micrograph [--quick]``
"""

from __future__ import annotations

import time

import numpy as np

from qdots.micrograph.detect import detect_dots
from qdots.micrograph.synthetic import dense_board, render_micrograph, score_detection, sparse_board

from .report import Figure, Headline, Table, cli

#: The code this benchmark measures (besides itself): a commit to it after a run marks the run's section as
#: older than its code (`benchmarks.staleness`).
MEASURED_CODE = ("qdots/micrograph", "qdots/analysis")

NOISES = (0.0, 0.02, 0.05, 0.1, 0.2, 0.3)
#: The goals of the issue at moderate noise (0.05): recall, precision, diameter error, position error (px),
#: interior-fraction error, seconds for 2048 x 2048.
GOALS = {"recall": 0.98, "precision": 0.98, "diameter": 0.03, "position": 0.5, "interior": 0.02, "seconds": 5.0}


def case(board: str, noise: float, side: int, seed: int = 1) -> dict:
    make = dense_board if board == "dense" else sparse_board
    centres, diameters = make(side, side, 15.0, 0.1, seed=seed)
    image = render_micrograph(centres, diameters, (side, side), noise=noise, seed=seed + 1)
    start = time.perf_counter()
    detection = detect_dots(image)
    seconds = time.perf_counter() - start
    return {"board": board, "noise": noise, "dots": len(diameters), "seconds": seconds, "p": detection.shape,
            **score_detection(detection, centres, diameters)}


def timing_2048(repeats: int) -> dict:
    """measure_image on a dense 2048 x 2048 film written as a 16-bit PNG: best of ``repeats``."""
    import tempfile
    from pathlib import Path

    from PIL import Image

    from qdots.micrograph.measure import measure_image

    centres, diameters = dense_board(2048, 2048, 15.0, 0.1, seed=5)
    image = render_micrograph(centres, diameters, (2048, 2048), noise=0.05, seed=6)
    with tempfile.TemporaryDirectory() as directory:
        path = Path(directory) / "film.png"
        Image.fromarray(np.clip(image * 50000, 0, 65535).astype(np.uint16)).save(path)
        times = {"detect": [], "measure": [], "measure_lqe": []}
        for _ in range(repeats):
            start = time.perf_counter()
            detection = detect_dots(image)
            times["detect"].append(time.perf_counter() - start)
            start = time.perf_counter()
            film = measure_image(path, nm_per_px=1.0, lqe=False)
            times["measure"].append(time.perf_counter() - start)
            start = time.perf_counter()
            measure_image(path, nm_per_px=1.0, lqe=True)
            times["measure_lqe"].append(time.perf_counter() - start)
    return {"dots": len(diameters), "found": detection.n_dots, "film_dots": film.summary["dots"],
            **{k: min(v) for k, v in times.items()}, **score_detection(detection, centres, diameters)}


def run(quick: bool) -> list:
    """The noise sweep on both boards (quick: 384 px, three noise levels, no 2048 timing)."""
    side = 384 if quick else 1024
    noises = (0.0, 0.05, 0.2) if quick else NOISES
    detect_dots(render_micrograph(*sparse_board(96, 96, 15.0, 0.1, seed=0), (96, 96), seed=0))  # compile first
    rows = [case(board, noise, side) for board in ("sparse", "dense") for noise in noises]
    table = Table(f"Synthetic micrographs, {side} x {side} px, mean diameter 15 px, sigma 10 %: detection against truth",
                  ["board", "noise", "dots", "recall", "precision", "median diameter error", "diameter bias",
                   "median position error (px)", "interior fraction (true)", "interior error", "shape p",
                   "time (s)"],
                  [[r["board"], r["noise"], r["dots"], r["recall"], r["precision"], f"{100 * r['diameter']:.2f} %",
                    f"{100 * r['bias']:+.2f} %", r["position"], r["true_interior"], f"{r['interior']:+.3f}",
                    r["p"], r["seconds"]] for r in rows],
                  note="Noise is the standard deviation of the added Gaussian noise in units of the mean background "
                       "level (moderate: 0.05). Goals at moderate noise: recall and precision >= 0.98, diameter error "
                       "<= 3 %, position error <= 0.5 px, interior fraction within 0.02.")
    results = [table, figure(rows)]
    moderate = [r for r in rows if r["noise"] == 0.05]
    results.insert(0, Headline("micrograph detection at moderate noise (sparse / dense)",
                               " / ".join(f"{r['seconds']:.2f} s" for r in moderate) + f" ({side}^2 px)",
                               " / ".join(f"recall {r['recall']:.3f}, d error {100 * r['diameter']:.1f} %"
                                          for r in moderate)))
    if not quick:
        t = timing_2048(3)
        results.append(Table("2048 x 2048 px dense film (16-bit PNG), noise 0.05: best of 3",
                             ["true dots", "found", "detect_dots (s)", "measure_image, no LQE (s)",
                              "measure_image with LQE (s)", "recall", "precision", "median diameter error",
                              "median position error (px)", "interior error"],
                             [[t["dots"], t["found"], t["detect"], t["measure"], t["measure_lqe"], t["recall"],
                               t["precision"], f"{100 * t['diameter']:.2f} %", t["position"],
                               f"{t['interior']:+.3f}"]],
                             note=f"Goal: a 2048 x 2048 image measured in <= {GOALS['seconds']:g} s on 2 cores."))
        results.insert(0, Headline("qdots measure, 2048 x 2048 dense film", f"{t['measure']:.2f} s "
                                   f"({t['measure_lqe']:.2f} s with the film LQE)",
                                   f"recall {t['recall']:.3f}, d error {100 * t['diameter']:.1f} %"))
    return results


def figure(rows: list[dict]) -> Figure:
    from matplotlib.figure import Figure as MplFigure

    fig = MplFigure(figsize=(11, 3.6))
    axes = fig.subplots(1, 3)
    for board, marker in (("sparse", "o"), ("dense", "s")):
        part = [r for r in rows if r["board"] == board]
        noise = [r["noise"] for r in part]
        axes[0].plot(noise, [r["recall"] for r in part], marker + "-", label=f"{board}: recall")
        axes[0].plot(noise, [r["precision"] for r in part], marker + "--", label=f"{board}: precision")
        axes[1].plot(noise, [100 * r["diameter"] for r in part], marker + "-", label=board)
        axes[2].plot(noise, [r["position"] for r in part], marker + "-", label=board)
    axes[0].axhline(GOALS["recall"], color="grey", lw=0.8, ls=":")
    axes[1].axhline(100 * GOALS["diameter"], color="grey", lw=0.8, ls=":")
    axes[2].axhline(GOALS["position"], color="grey", lw=0.8, ls=":")
    axes[0].set_ylabel("recall, precision")
    axes[1].set_ylabel("median diameter error (%)")
    axes[2].set_ylabel("median position error (px)")
    for ax in axes:
        ax.set_xlabel("noise (of the background level)")
        ax.legend(fontsize="small")
    fig.suptitle("Dots found in synthetic micrographs against noise (dotted: the goals)")
    fig.tight_layout()
    return Figure("micrograph_noise", fig, "Detection against noise on synthetic micrographs (sparse and dense films).")


def main(argv: list[str] | None = None) -> int:
    return cli(run, __doc__.splitlines()[0], argv)


if __name__ == "__main__":
    raise SystemExit(main())
