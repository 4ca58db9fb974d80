"""The dock widget *Measure dots (qdots)*: measure a micrograph, correct the dots by hand, measure again, export.

It runs in napari's main thread (a measurement takes seconds; the window waits for it). What it shows:

* ``dots`` -- a points layer, one point per dot at its centre, its size the dot's diameter; yellow rims are whole
  dots, white ones dots cut by the edge or by what is left out, red ones dots stacked on a neighbour (left out of
  the sizes). Add points (their size is the layer's current point size: set it to the dot's diameter), delete
  them, move or resize them, then press *Measure the edited dots*.
* ``left out`` -- a shapes layer: the scale bar read (with its length in px), label boxes, data strips and frames.
* the summary table of ``qdots measure``, and a line that says what happened (a refusal, with why, and what the
  refused picture's objects were: they are shown in orange and can be measured anyway).

*Export* writes ``NAME.npz`` (a qdots state file), ``NAME_detections.png`` and ``NAME_summary.csv`` into the
folder given, as ``qdots measure`` does.
"""

from __future__ import annotations

import os
import tempfile
from collections.abc import Callable
from pathlib import Path

import numpy as np
from qtpy.QtWidgets import (
    QCheckBox,
    QComboBox,
    QFormLayout,
    QLabel,
    QLineEdit,
    QPushButton,
    QTableWidget,
    QTableWidgetItem,
    QVBoxLayout,
    QWidget,
)

from labrig.files import slug
from labrig.outputset import OutputSet
from labrig.validate import InputError

from ..cli.files import write_measurement
from ..micrograph.admit import NotAFilm
from ..micrograph.choices import MAX_NM_PER_PX, MIN_NM_PER_PX, POLARITIES, PROFILES
from ..micrograph.measure import MeasuredFilm, measure_image, summary_rows
from .layers import film_from_points, points_data, shapes_data

#: The names of the layers the widget makes (and replaces on each measurement).
DOTS, LEFT_OUT = "dots", "left out"


def slot(action: Callable[[], object]) -> Callable[[], None]:
    """A Qt slot that calls ``action`` and drops what it returns (a slot returns nothing)."""
    def called() -> None:
        action()

    return called


class MeasureWidget(QWidget):
    """The dock widget (see the module). ``viewer`` is the napari viewer it works in."""

    def __init__(self, napari_viewer) -> None:
        super().__init__()
        self.viewer = napari_viewer
        #: The last measurement (or what a refusal found), None before the first.
        self.film: MeasuredFilm | None = None
        self.refused = False
        self.image_layer = QComboBox()
        self.scale_bar = QLineEdit()
        self.scale_bar.setPlaceholderText("e.g. 200nm (read off the bar)")
        self.nm_per_px = QLineEdit()
        self.nm_per_px.setPlaceholderText("from the file, or the bar")
        self.polarity = QComboBox()
        self.polarity.addItems(list(POLARITIES))
        self.profile = QComboBox()
        self.profile.addItems(list(PROFILES))
        self.force = QCheckBox("measure a picture that is refused anyway")
        self.lqe = QCheckBox("film LQE (slow on large films)")
        self.lqe.setChecked(True)
        self.out = QLineEdit(str(Path("qdots-measure").absolute()))
        self.measure_button = QPushButton("Measure")
        self.edited_button = QPushButton("Measure the edited dots")
        self.export_button = QPushButton("Export (state file, overlay, CSV)")
        self.status = QLabel("Open a micrograph, then press Measure.")
        self.status.setWordWrap(True)
        self.table = QTableWidget(0, 2)
        self.table.setHorizontalHeaderLabels(["measure", "value"])
        header, rows = self.table.horizontalHeader(), self.table.verticalHeader()
        assert header is not None and rows is not None  # a table widget is made with both
        header.setStretchLastSection(True)
        rows.setVisible(False)
        self.table.setWordWrap(True)
        self.setMinimumWidth(420)
        form = QFormLayout()
        for label, field in (("image", self.image_layer), ("scale bar", self.scale_bar), ("nm per px", self.nm_per_px),
                             ("polarity", self.polarity), ("profile", self.profile)):
            form.addRow(label, field)
        layout = QVBoxLayout(self)
        layout.addLayout(form)
        for widget in (self.force, self.lqe, self.measure_button, self.edited_button, QLabel("export into"),
                       self.out, self.export_button, self.status, self.table):
            layout.addWidget(widget)
        for button, action in ((self.measure_button, self.measure), (self.edited_button, self.measure_edited),
                               (self.export_button, self.export)):
            button.clicked.connect(slot(action))
        self.viewer.layers.events.inserted.connect(self.list_images)
        self.viewer.layers.events.removed.connect(self.list_images)
        self.list_images()

    # -- what the user sees -----------------------------------------------------------------------------------

    def list_images(self, event=None) -> None:
        """Offer every image layer, the newest first."""
        from napari.layers import Image

        names = [layer.name for layer in self.viewer.layers if isinstance(layer, Image)][::-1]
        current = self.image_layer.currentText()
        self.image_layer.clear()
        self.image_layer.addItems(names)
        if current in names:
            self.image_layer.setCurrentText(current)

    def say(self, text: str) -> None:
        self.status.setText(text)

    def show_film(self, film: MeasuredFilm, refused: bool = False) -> None:
        """Show ``film``: its dots, what was left out, its summary."""
        self.film, self.refused = film, refused
        layer = self.viewer.layers[self.image_layer.currentText()]
        for name in (DOTS, LEFT_OUT):
            if name in self.viewer.layers:
                self.viewer.layers.remove(name)
        boxes, attributes = shapes_data(film)
        if boxes:
            self.viewer.add_shapes(boxes, name=LEFT_OUT, scale=layer.scale, **attributes)
        data, attributes = points_data(film, refused)
        dots = self.viewer.add_points(data, name=DOTS, scale=layer.scale, **attributes)
        dots.current_size = float(np.median(film.detection.diameters)) if film.detection.n_dots else 10.0
        rows = summary_rows(film.summary)
        self.table.setRowCount(len(rows))
        for k, (label, text) in enumerate(rows):
            self.table.setItem(k, 0, QTableWidgetItem(label))
            item = QTableWidgetItem(text)
            item.setToolTip(text)  # the whole text, where the column cuts it
            self.table.setItem(k, 1, item)
        self.table.resizeColumnToContents(0)
        self.table.resizeRowsToContents()

    # -- the buttons -------------------------------------------------------------------------------------------

    def measure(self) -> MeasuredFilm | None:
        """Measure the chosen image layer as ``qdots measure`` does; a refusal shows what was found."""
        try:
            path, page, cleanup = self._picture()
            try:
                film = measure_image(path, nm_per_px=self._scale(), scale_bar=self.scale_bar.text().strip() or None,
                                     polarity=self.polarity.currentText(), profile=self.profile.currentText(),
                                     page=page, lqe=self.lqe.isChecked(), force=self.force.isChecked())
            finally:
                cleanup()
        except NotAFilm as refusal:
            if refusal.found is not None:
                self.show_film(refusal.found, refused=True)
            self.say(f"Refused: {refusal}. Tick 'measure a picture that is refused anyway' to measure it, or correct "
                     "the dots and press 'Measure the edited dots'.")
            return None
        except (InputError, OSError) as exc:
            self.say(f"Not measured: {exc}")
            return None
        self.show_film(film)
        self.say(f"{film.summary['dots']} dots measured ({film.scale}). Correct them if needed, then press "
                 "'Measure the edited dots'.")
        return film

    def measure_edited(self) -> MeasuredFilm | None:
        """Measure the film again from the ``dots`` layer as edited."""
        if self.film is None or DOTS not in self.viewer.layers:
            self.say("Measure first: there are no dots to edit.")
            return None
        dots = self.viewer.layers[DOTS]
        try:
            film = film_from_points(self.film, dots.data, dots.size, lqe=self.lqe.isChecked())
        except InputError as exc:
            self.say(f"Not measured: {exc}")
            return None
        self.show_film(film)
        self.say(f"{film.summary['dots']} dots measured from the edited set ({film.summary['dots_edited']} added, "
                 f"moved or resized; {film.summary['dots_deleted']} deleted or changed).")
        return film

    def export(self) -> Path | None:
        """Write the last measurement as ``qdots measure`` does; returns the folder written."""
        if self.film is None or self.refused:
            self.say("Nothing to export: measure a film first (a refused picture is exported once it is measured).")
            return None
        stem = slug(Path(self.film.image.source).stem)
        try:
            with OutputSet(Path(self.out.text().strip() or "qdots-measure"), stem) as files:
                write_measurement(self.film, files, stem)
        except (InputError, OSError) as exc:
            self.say(f"Not exported: {exc}")
            return None
        self.say(f"Wrote {files.path}{os.sep}: " + ", ".join(p.name for p in files.written))
        return files.path

    # -- helpers -----------------------------------------------------------------------------------------------

    def _scale(self) -> float | None:
        text = self.nm_per_px.text().strip()
        if not text:
            return None
        try:
            value = float(text)
        except ValueError:
            raise InputError(f"nm per px must be a number in [{MIN_NM_PER_PX:g}, {MAX_NM_PER_PX:g}], got {text!r}") from None
        return value

    def _picture(self):
        """``(path, page, cleanup)`` of the chosen image layer: its file when it was opened from one, else its pixels
        written to a temporary TIFF (then the scale comes from the layer's scale, or the fields)."""
        name = self.image_layer.currentText()
        if not name or name not in self.viewer.layers:
            raise InputError("no image layer: open a micrograph first")
        layer = self.viewer.layers[name]
        path = layer.metadata.get("qdots_path") or getattr(layer.source, "path", None)
        if path:
            return path, int(layer.metadata.get("page", 0)), lambda: None
        from PIL import Image

        pixels = np.asarray(layer.data, dtype=np.float32)
        if pixels.ndim == 3:  # colour: the mean of its channels, as the reader does
            pixels = pixels[..., :3].mean(axis=-1)
        if pixels.ndim != 2:
            raise InputError(f"the layer {name!r} is not a 2-D picture (shape {pixels.shape})")
        folder = tempfile.mkdtemp(prefix="qdots-napari-")
        path = os.path.join(folder, f"{slug(name)}.tif")
        Image.fromarray(pixels).save(path)

        def cleanup() -> None:
            os.unlink(path)
            os.rmdir(folder)

        if not self.nm_per_px.text().strip() and not self.scale_bar.text().strip() and layer.scale[-1] != 1:
            self.nm_per_px.setText(f"{float(layer.scale[-1]):g}")
        return path, 0, cleanup
