"""`labrig.threads.by_rows` and the measurement's kernels built on it, against the same function on the whole image."""

import numpy as np
import pytest
from scipy import ndimage
from skimage.segmentation import expand_labels

from labrig.threads import by_rows
from qdots.micrograph.segment import grow_labels, inside_distance


@pytest.mark.parametrize("rows", [5, 700, 1030, 1537])
def test_a_local_filter_by_rows_is_the_filter(rows):
    image = np.random.default_rng(rows).random((rows, 90))
    for sigma in (1.0, 2.5):
        whole = ndimage.gaussian_filter(image, sigma)
        np.testing.assert_array_equal(by_rows(lambda part, s=sigma: ndimage.gaussian_filter(part, s), image,
                                              int(4 * sigma + 1), band=256), whole)


def test_a_margin_too_short_is_seen():
    """The check that by_rows needs the footprint: a filter reaching further than the margin differs at the seams."""
    image = np.random.default_rng(1).random((1024, 40))
    banded = by_rows(lambda part: ndimage.uniform_filter(part, 21), image, 3, band=256)
    assert not np.array_equal(banded, ndimage.uniform_filter(image, 21))


def test_inside_distance_is_the_euclidean_distance_transform():
    rng = np.random.default_rng(2)
    mask = ndimage.binary_opening(rng.random((1100, 300)) < 0.8, iterations=2)
    np.testing.assert_array_equal(inside_distance(mask, 30.0), ndimage.distance_transform_edt(mask))
    mask[200:900, 50:250] = True  # a region deeper than the margin: computed whole
    np.testing.assert_array_equal(inside_distance(mask, 10.0), ndimage.distance_transform_edt(mask))


def test_grown_labels_are_skimages():
    rng = np.random.default_rng(3)
    labels, _ = ndimage.label(ndimage.binary_opening(rng.random((1200, 260)) < 0.45))
    np.testing.assert_array_equal(grow_labels(labels, 4.0), expand_labels(labels, distance=4.0))
