"""The napari plugin of ``qdots measure`` (the ``napari`` extra: ``pip install "nanodisorder[napari]"``).

* `reader` opens a micrograph as an image layer with its pixel size from the file (nm per px as the layer's
  scale, and where it was read in the layer's metadata);
* `widget` is the dock widget *Measure dots (qdots)*: it runs the measurement of ``qdots measure`` on an image
  layer and shows the dots as an editable points layer (each point's size its diameter), the scale bar and the
  regions left out as a shapes layer, and the summary as a table; after dots are added, deleted, moved or resized,
  *Measure the edited dots* measures the film again from the edited set (`qdots.micrograph.edit.edited_film`), and
  *Export* writes the same state file, overlay and CSV as the command line.
* `layers` turns a measurement into layer data and back, without Qt (tested on its own).

The manifest is ``napari.yaml`` (npe2), registered under the ``napari.manifest`` entry point.
"""
