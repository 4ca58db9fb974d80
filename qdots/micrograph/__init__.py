"""Micrographs of real films: read them, find their dots, and measure them as a simulated board is measured.

This package measures pictures; it needs neither pymunk nor torch (``tests/test_layout.py`` checks). What a
measured film says about the conditions that made it (simulating, comparing, inferring) is `qdots.inference`.
The names below are imported when first used, so that the command line's ``--help`` loads none of them.

>>> from qdots.micrograph import dense_board, measure_image, render_micrograph
"""

from labrig.lazy import exports

#: Where each public name lives.
_NAMES = {
    "Micrograph": "read", "read_micrograph": "read",
    "MeasuredFilm": "measure", "measure_image": "measure", "summary_rows": "measure",
    "Detection": "detection", "detect_dots": "detect",
    "ScaleBar": "scale", "find_scale_bar": "scale", "parse_length": "scale", "scale_from_bar": "scale",
    "Annotations": "annotations", "find_annotations": "annotations",
    "NotAFilm": "admit", "check_picture": "admit",
    "film_state": "film", "film_metrics": "film",
    "edited_film": "edit",
    "overlay_figure": "overlay", "save_overlay": "overlay",
    "render_micrograph": "synthetic", "dense_board": "synthetic", "sparse_board": "synthetic",
    "superlattice_board": "synthetic", "score_detection": "synthetic",
    "label_micrograph": "labelled",
}

__all__ = list(_NAMES)
__getattr__, __dir__ = exports(__name__, _NAMES)
