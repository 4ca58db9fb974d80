"""What the micrograph commands accept -- file suffixes, choices, bounds and defaults -- in one light module.

The measuring and inferring modules import these from here; the command line reads them to build its
arguments and ``--help`` without importing numpy, numba, scipy or the simulator.
"""

from labrig.sweeps.spec import MAX_RUNS

#: Picture files qdots reads: TIFF (its own reader, with the microscopes' pixel-size tags), the formats Pillow
#: reads, and the microscopes' formats with rosettasciio's reader module for each.
TIFF = (".tif", ".tiff")
PILLOW = (".png", ".jpg", ".jpeg", ".bmp", ".gif")
MICROSCOPE = {".dm3": "digitalmicrograph", ".dm4": "digitalmicrograph", ".emd": "emd", ".ser": "tia"}
SUFFIXES = TIFF + PILLOW + tuple(MICROSCOPE)

#: Polarity choices: dots darker than the background (bright-field TEM), lighter, or decided from the image.
POLARITIES = ("auto", "dark", "light")
#: Dot profiles by name (the exponent p).
PROFILES = {"auto": None, "sphere": 0.5, "disc": 0.0}
#: Scales, nm per px: from 1 pm per pixel (finer than any electron microscope's pixel) to 1 mm per pixel.
MIN_NM_PER_PX, MAX_NM_PER_PX = 1e-3, 1e6

#: Most seeds, dots and worker processes of one comparison (``qdots compare``).
MAX_SEEDS, MAX_COMPARE_DOTS, MAX_WORKERS = 100, 5000, 64

#: Dots of a simulated film of the inference by default, and the most allowed.
FILM_DOTS, MAX_FILM_DOTS = 150, 2000
#: Posterior draws by default, and the films of the predictive check (and the most of those).
SAMPLES, CHECK_FILMS, MAX_CHECK_FILMS = 4000, 24, 1000
#: Films of a library by default (those of 150 dots are shipped with the package: `qdots.inference.library.SHIPPED`),
#: the fewest a posterior is trained on, and the most a library may hold.
LIBRARY_FILMS, MIN_TRAINING_FILMS, MAX_LIBRARY_FILMS = 3000, 20, MAX_RUNS
#: Most posterior samples drawn at once.
MAX_SAMPLES = 1_000_000


#: What ``qdots infer`` says when its extra is missing.
INFER_EXTRA = "qdots infer needs torch and sbi (the 'infer' extra): pip install torch==2.13.0 'nanodisorder[infer]'"


def missing_infer_extra() -> bool:
    """Whether torch or sbi is not installed (found without importing either)."""
    import importlib.util

    return any(importlib.util.find_spec(name) is None for name in ("torch", "sbi"))


def unknown_suffix(name: str) -> str | None:
    """The one-line reason a picture file's name is refused (its suffix is none qdots reads), or None."""
    suffix = name[name.rfind("."):].lower() if "." in name.lstrip(".") else ""
    if suffix in SUFFIXES:
        return None
    said = f"the suffix {suffix!r}" if suffix else "no suffix"
    return f"{name}: {said} is no picture format qdots reads ({', '.join(SUFFIXES)})"
