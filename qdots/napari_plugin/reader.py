"""napari reader: a micrograph as an image layer with its pixel size from the file."""

from __future__ import annotations

import os
from collections.abc import Callable

from ..micrograph.choices import unknown_suffix


def get_reader(path: str | list[str]) -> Callable | None:
    """The reader of ``path`` (one file of a format qdots reads), else None (napari then asks another plugin)."""
    if isinstance(path, list):
        if len(path) != 1:
            return None
        path = path[0]
    if not isinstance(path, (str, os.PathLike)) or unknown_suffix(os.path.basename(os.fspath(path))) is not None:
        return None
    return read_layers


def read_layers(path: str | list[str]) -> list[tuple]:
    """``[(pixels, attributes, "image")]``: the first page, grey, with ``scale`` (nm per px, both axes) when the file
    states it, and ``metadata`` holding the path (``qdots_path``), the pixel size (``nm_per_px``) and where it was
    read (``scale_source``)."""
    from ..micrograph.read import read_micrograph

    if isinstance(path, list):
        path = path[0]
    image = read_micrograph(path)
    scale = (image.nm_per_px, image.nm_per_px) if image.nm_per_px else (1.0, 1.0)
    metadata = {"qdots_path": os.path.abspath(path), "nm_per_px": image.nm_per_px, "page": image.page,
                "scale_source": image.scale_source or "none in the file"}
    attributes = {"name": os.path.basename(os.fspath(path)), "scale": scale, "metadata": metadata,
                  "colormap": "gray", **({"units": "nm"} if image.nm_per_px else {})}
    return [(image.pixels, attributes, "image")]
