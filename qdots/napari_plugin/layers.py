"""A measurement as napari layer data and back, without Qt: what the dock widget (`qdots.napari_plugin.widget`)
shows and reads.

napari's coordinates are ``(row, column)``; a measurement's centres are ``(x, y)`` = (column, row), image px. The
layers keep image px as their data (the layers' ``scale`` puts them in nm beside the image)."""

from __future__ import annotations

import numpy as np

from ..micrograph.edit import edited_film
from ..micrograph.measure import MeasuredFilm

#: Edge colours of the dots: whole, cut by the edge or by what is left out, stacked on a neighbour (left out of
#: the sizes), and what a refusal found.
DOT_COLOURS = {"whole": "yellow", "cut": "white", "stacked": "red", "refused": "orangered"}


def points_data(film: MeasuredFilm, refused: bool = False) -> tuple[np.ndarray, dict]:
    """``(data, attributes)`` of the points layer of ``film``'s dots: ``(row, column)`` centres and, in the
    attributes, ``size`` (each dot's diameter, px), ``features`` (``kind``: whole, cut or stacked; ``diameter_px``)
    and ``border_color``."""
    det = film.detection
    stacked = film.stacked if film.stacked is not None else np.zeros(det.n_dots, dtype=bool)
    kind = np.where(det.cut, "cut", np.where(stacked, "stacked", "refused" if refused else "whole"))
    data = np.asarray(det.centres, dtype=float)[:, ::-1].reshape(-1, 2)
    attributes = {"size": np.asarray(det.diameters, dtype=float), "face_color": "transparent",
                  "border_color": [DOT_COLOURS[k] for k in kind], "border_width": 0.08,
                  "border_width_is_relative": True, "features": {"kind": kind, "diameter_px": det.diameters}}
    return data, attributes


def film_from_points(film: MeasuredFilm, data, sizes, lqe: bool = False) -> MeasuredFilm:
    """``film`` measured again from a points layer's ``data`` (``(row, column)``, px) and ``sizes`` (diameters, px):
    `qdots.micrograph.edit.edited_film`."""
    data = np.asarray(data, dtype=float).reshape(-1, 2)
    return edited_film(film, data[:, ::-1], np.asarray(sizes, dtype=float).reshape(-1), lqe=lqe)


def rectangle(box) -> np.ndarray:
    """The four ``(row, column)`` corners of the box ``(x0, y0, x1, y1)``, px."""
    x0, y0, x1, y1 = (float(v) for v in box)
    return np.array([[y0, x0], [y0, x1], [y1, x1], [y1, x0]])


def shapes_data(film: MeasuredFilm) -> tuple[list[np.ndarray], dict]:
    """``(rectangles, attributes)`` of what the measurement left out or read: the scale bar (with its length), label
    boxes, data strips and frames (the parts of the image outside the picture's window)."""
    found = film.annotations
    boxes, labels, colours = [], [], []
    if film.bar is not None:
        boxes.append(rectangle(film.bar.box))
        labels.append(f"scale bar {film.bar.length_px:.1f} px")
        colours.append("magenta")
    if found is not None:
        for box in found.boxes:
            boxes.append(rectangle(box))
            labels.append("label box")
            colours.append("orange")
        h, w = film.image.shape
        x0, y0, x1, y1 = found.window
        for part in ((0, 0, w, y0), (0, y1, w, h), (0, y0, x0, y1), (x1, y0, w, y1)):  # outside the window
            if part[2] > part[0] and part[3] > part[1]:
                boxes.append(rectangle(part))
                labels.append("strip or frame")
                colours.append("orange")
    attributes = {"shape_type": "rectangle", "edge_color": colours, "face_color": "transparent", "edge_width": 2,
                  "features": {"what": labels}, "text": {"string": "{what}", "color": "white", "size": 9}}
    return boxes, attributes
