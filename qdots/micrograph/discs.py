"""Discs on a pixel grid: which pixels the dots cover, and which dots cover given pixels.

A pixel ``(row, col)`` is inside the disc of centre ``(x, y)`` and radius ``r`` (px) when its centre
``(col + 0.5, row + 0.5)`` is within ``r`` of it (`qdots.micrograph.detect`'s coordinates).
"""

from __future__ import annotations

from labrig.compiled import jit


@jit
def discs_cover(mask, centres, radii, out):
    """Set ``out[k]`` where dot k's disc holds a pixel of ``mask`` (each disc looked at whole, whatever its
    neighbours cover)."""
    h, w = mask.shape
    for k in range(len(radii)):
        x, y, r = centres[k, 0], centres[k, 1], radii[k]
        for row in range(max(0, int(y - r)), min(h, int(y + r) + 2)):
            for col in range(max(0, int(x - r)), min(w, int(x + r) + 2)):
                if mask[row, col] and (col + 0.5 - x) ** 2 + (row + 0.5 - y) ** 2 <= r * r:
                    out[k] = True
                    break
            if out[k]:
                break


@jit
def paint_discs(covered, centres, radii):
    """Set the pixels of ``covered`` whose centres lie inside any disc (``centres`` (x, y), ``radii``, px)."""
    h, w = covered.shape
    for k in range(len(radii)):
        x, y, r = centres[k, 0], centres[k, 1], radii[k]
        for row in range(max(0, int(y - r)), min(h, int(y + r) + 2)):
            for col in range(max(0, int(x - r)), min(w, int(x + r) + 2)):
                if (col + 0.5 - x) ** 2 + (row + 0.5 - y) ** 2 <= r * r:
                    covered[row, col] = True
