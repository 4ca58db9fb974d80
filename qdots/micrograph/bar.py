"""A scale bar found on a micrograph: where it lies, how it is drawn, and how long it is."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: Shortest scale bar, px.
MIN_BAR = 10


@dataclass(frozen=True)
class ScaleBar:
    """A scale bar found on an image.

    Attributes
    ----------
    length_px : float
        Its length, px (along its long side), as ``measured`` says.
    box : (int, int, int, int)
        ``(x0, y0, x1, y1)`` of the bar, px (x the column, y the row; ``x1``, ``y1`` exclusive).
    dark : bool
        Whether it is drawn in the image's darkest colour (else its lightest).
    ruled : bool
        Whether it is divided or ticked (cuts, blocks in an outline, ticks, end caps) rather than a plain bar.
    thickness : int
        The thickness of its spine, px (ticks and end caps aside).
    at_edge : bool
        Whether it reaches the picture's edge (its length may then be cut, and is that of what is shown).
    extent : (int, int, int, int) or None
        ``(x0, y0, x1, y1)`` of all it was found with and is left out with (`mask`): a letter of its label that touches
        it (the tail of a "µ") as well; None: ``box``.
    measured : str
        How its length was measured: between its ends' half-contrast points
        (`qdots.micrograph.bar_profile.half_contrast_length`), between the middles of its end marks
        (`qdots.micrograph.strip_bars.band_bar`), or from its first tick to its last
        (`qdots.micrograph.strip_bars.band_ruler`).
    """

    length_px: float
    box: tuple[int, int, int, int]
    dark: bool
    ruled: bool = False
    thickness: int = 0
    at_edge: bool = False
    measured: str = "at half contrast"
    extent: tuple[int, int, int, int] | None = None

    @property
    def found_box(self) -> tuple[int, int, int, int]:
        """``extent``, or ``box`` where it is None: what is left out with the bar."""
        return self.box if self.extent is None else self.extent

    def mask(self, shape: tuple[int, int], margin: int = 2) -> np.ndarray:
        """The bar's pixels (its `found_box`) and ``margin`` px around them, as a boolean image of ``shape``."""
        out = np.zeros(shape, dtype=bool)
        x0, y0, x1, y1 = self.found_box
        out[max(0, y0 - margin):y1 + margin, max(0, x0 - margin):x1 + margin] = True
        return out
