"""The dots found in one image (`Detection`): what `qdots.micrograph.detect.detect_dots` returns and every
measure of a film reads."""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from .discs import paint_discs
from .profiles import half_depth_radius


@dataclass(frozen=True)
class Detection:
    """The dots found in one image.

    Attributes
    ----------
    centres : ndarray, shape (N, 2)
        ``(x, y)`` = (column, row) of each centre, image px (see `qdots.micrograph.detect`).
    diameters : ndarray, shape (N,)
        Fitted diameter of each dot, px.
    cut : ndarray of bool, shape (N,)
        Dots whose disc crosses the edge of the picture (`window`) or pixels left out (``ignore``), measured on
        their visible part.
    contrast : ndarray, shape (N,)
        Fitted contrast ``C`` of each dot, in units of the background level.
    dark : bool
        Whether the dots are darker than the background.
    polarity : str
        How the polarity was decided, in words.
    shape : float
        The profile shape ``p`` chosen (0 flat disc, 0.5 projected sphere).
    profile : str
        How it was chosen, in words.
    blur : float
        The blur width ``s`` chosen, px.
    rejected : int
        Objects of the image that are not dots (text, scale-bar strokes, debris) or that the fit refused.
    image_shape : (int, int)
        ``(H, W)`` of the image, px.
    window : (int, int, int, int)
        ``(x0, y0, x1, y1)``: the part of the image that is picture, px (a frame or data strips that
        acquisition programs draw along its sides are left out, `qdots.micrograph.annotations.find_strips`).
    errors : ndarray, shape (N,)
        Each diameter's measurement error, px, from measuring the film again with another draw of its own noise
        (`qdots.micrograph.refine.repeat_errors`).
    shapes : ndarray, shape (N, 3)
        The elongation, outline and neck of the region each dot was found in (`qdots.micrograph.shapes`; NaN for
        the faint dots found in the fit's residual).
    widths : ndarray, shape (N,), optional
        Each dot's full width at half depth read on its own profile, px (`half_widths`; NaN where it could not be
        read; None: not read, the fitted profile's is used).
    """

    centres: np.ndarray
    diameters: np.ndarray
    cut: np.ndarray
    contrast: np.ndarray
    dark: bool
    polarity: str
    shape: float
    profile: str
    blur: float
    rejected: int
    image_shape: tuple[int, int]
    window: tuple[int, int, int, int]
    errors: np.ndarray
    shapes: np.ndarray
    widths: np.ndarray | None = None

    @property
    def n_dots(self) -> int:
        return len(self.diameters)

    def half_widths(self) -> np.ndarray:
        """Each dot's full width at half depth, px, what a line profile by hand measures: read on the dot's own
        profile, its neighbours taken out, halfway from its core to its crest (`widths`,
        `qdots.micrograph.profiles.measured_half_widths`); where that could not be read, where its fitted profile
        (`shape`, blurred by `blur`) has lost half its central contrast (`qdots.micrograph.profiles.half_depth_radius`;
        a flat disc's is its diameter, a projected sphere's 0.87 of it unblurred)."""
        if not np.isfinite(self.shape):
            fitted = self.diameters.copy()
        else:
            fitted = self.diameters * half_depth_radius(self.shape, self.blur / np.maximum(0.5 * self.diameters, 1e-9))
        if self.widths is None:
            return fitted
        return np.where(np.isfinite(self.widths), self.widths, fitted)

    def take(self, keep) -> Detection:
        """The dots where ``keep`` (booleans, one per dot, or indices) is true, everything else as it is."""
        keep = np.asarray(keep)
        return replace(self, centres=self.centres[keep], diameters=self.diameters[keep], cut=self.cut[keep],
                       contrast=self.contrast[keep], errors=self.errors[keep], shapes=self.shapes[keep],
                       widths=None if self.widths is None else self.widths[keep])

    def coverage(self) -> float:
        """Fraction of the image inside the fitted discs (their union, on the pixel grid)."""
        covered = np.zeros(self.image_shape, dtype=np.bool_)
        paint_discs(covered, np.ascontiguousarray(self.centres, dtype=float), 0.5 * np.asarray(self.diameters, float))
        return float(covered.mean())
