"""What a measured film says about the conditions that made it: the thesis's deposition simulated as a forward
model, a film compared with its simulation, and the conditions inferred (simulation-based inference).

The pictures themselves are measured by `qdots.micrograph`; this package drives the simulator, and its posterior
needs the ``infer`` extra (torch and sbi). The names below are imported when first used.
"""

from labrig.lazy import exports

#: Where each public name lives.
_NAMES = {
    "Inference": "infer", "infer_image": "infer", "infer_film": "infer",
    "Comparison": "compare", "compare_film": "compare",
    "Parameter": "forward", "simulate_film": "forward", "FilmTooSlow": "forward",
    "Library": "library", "build_library": "library",
    "Posterior": "posterior", "load_or_train": "posterior", "credible_intervals": "posterior",
    "IntervalCalibration": "conformal",
    "calibration_films": "calibration", "coverage_table": "calibration",
    "corner_figure": "plots", "best_film_figure": "plots", "check_figure": "plots", "side_by_side_figure": "plots",
    "save_side_by_side": "plots",
}

__all__ = list(_NAMES)
__getattr__, __dir__ = exports(__name__, _NAMES)
