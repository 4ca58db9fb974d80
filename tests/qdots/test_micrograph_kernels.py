"""The measurement's compiled kernels against numpy oracles written here: radial bins, region moments, the dots'
model, their neighbour-corrected profiles and their centres' shifts; the fits' model kept equal to its dots'."""

import math

import numpy as np
import pytest
from scipy import ndimage

from qdots.micrograph.profiles import BIN, profile_table, radial_profiles
from qdots.micrograph.refine import centre_shift, dot_profiles, model_image, refine_dots, second_image
from qdots.micrograph.segment import label_boxes, label_moments, region_properties, sequential_labels


def table_oracle(table, s, u):
    """`profile_table` read bilinearly at relative blur ``s`` and radii ``u`` (0 past the table), in numpy."""
    si = min(s * 100.0, 59.999) if s > 0 else 0.0
    i, a = int(si), si - int(si)
    ui = np.asarray(u, dtype=float) * 200.0
    inside = (ui >= 0) & (ui < 399.999)
    j = np.where(inside, ui, 0).astype(int)
    b = np.where(inside, ui, 0) - j
    value = (1 - a) * ((1 - b) * table[i, j] + b * table[i, j + 1]) + a * ((1 - b) * table[i + 1, j]
                                                                          + b * table[i + 1, j + 1])
    return np.where(inside, value, 0.0)


def dots(n=40, side=120, seed=0):
    rng = np.random.default_rng(seed)
    return (rng.uniform(-5, side + 5, (n, 2)), rng.uniform(2.0, 9.0, n), rng.uniform(0.05, 0.4, n),
            rng.uniform(0.5, 3.0, n))


def test_radial_bins_are_numpys_bincount():
    rng = np.random.default_rng(1)
    image = rng.random((150, 170))
    image[rng.random(image.shape) < 0.02] = np.nan  # pixels left out
    regions, n = ndimage.label(ndimage.binary_opening(rng.random(image.shape) < 0.6))
    centres = rng.uniform(0, 150, (n, 2))
    sums, counts, rhos = radial_profiles(image, regions, centres, 30)
    rows, cols = np.nonzero(regions)
    label = regions[rows, cols] - 1
    rho = np.hypot(cols + 0.5 - centres[label, 0], rows + 0.5 - centres[label, 1])
    b = (rho / BIN).astype(int)
    keep = (b < 30) & np.isfinite(image[rows, cols])
    index = label[keep] * 30 + b[keep]
    np.testing.assert_array_equal(sums.ravel(), np.bincount(index, image[rows, cols][keep], n * 30))
    np.testing.assert_array_equal(counts.ravel(), np.bincount(index, None, n * 30))
    np.testing.assert_array_equal(rhos.ravel(), np.bincount(index, rho[keep], n * 30))


def test_label_boxes_are_scipys_find_objects():
    rng = np.random.default_rng(4)
    labels, n = ndimage.label(rng.random((70, 91)) < 0.5)
    labels[labels == 3] = 0  # a label absent
    boxes = label_boxes(labels, n)
    for k, box in enumerate(ndimage.find_objects(labels, n)):
        expected = (0, 0, 0, 0) if box is None else (box[0].start, box[0].stop, box[1].start, box[1].stop)
        assert tuple(boxes[k]) == expected


def test_sequential_labels_are_skimages_relabelling():
    from skimage.segmentation import relabel_sequential

    rng = np.random.default_rng(5)
    labels, _ = ndimage.label(rng.random((50, 64)) < 0.5)
    labels = labels.astype(np.int32)
    gapped = labels * 3
    gapped[gapped % 7 == 0] = 0
    for field in (labels, gapped, np.zeros((4, 4), dtype=np.int32)):
        expected = relabel_sequential(field)[0]
        got = sequential_labels(field)
        assert got.dtype == expected.dtype
        np.testing.assert_array_equal(got, expected)


def test_region_moments_and_properties_are_numpys():
    rng = np.random.default_rng(2)
    labels, n = ndimage.label(ndimage.binary_opening(rng.random((90, 130)) < 0.55))
    rows, cols = np.indices(labels.shape)
    flat = labels.ravel()
    sums = label_moments(labels.astype(np.int64), n, 0.5)
    y, x = rows.ravel() + 0.5, cols.ravel() + 0.5
    for got, weights in zip(sums, (None, y, x, y * y, x * x, y * x)):
        np.testing.assert_allclose(got, np.bincount(flat, weights, n + 1)[1:], rtol=1e-12)
    props = region_properties(labels)
    area = np.bincount(flat, None, n + 1)[1:]
    np.testing.assert_array_equal(props["area"], area)
    np.testing.assert_allclose(props["centroid-0"], np.bincount(flat, rows.ravel(), n + 1)[1:] / area, rtol=1e-12)
    np.testing.assert_allclose(props["centroid-1"], np.bincount(flat, cols.ravel(), n + 1)[1:] / area, rtol=1e-12)


def test_the_dots_model_is_the_sum_of_their_blurred_profiles():
    table = profile_table(0.5)
    centres, radii, contrast, blurs = dots()
    model = model_image((120, 120), centres, radii, contrast, table, blurs)
    rows, cols = np.indices(model.shape)
    expected = np.zeros(model.shape)
    for (x, y), r, c, s in zip(centres, radii, contrast, blurs):
        rho = np.hypot(cols + 0.5 - x, rows + 0.5 - y)
        expected += np.where(rho < 2 * r, c * table_oracle(table, s / r, rho / r), 0.0)
    np.testing.assert_allclose(model, expected, rtol=0, atol=1e-13)


def test_each_dots_profile_is_the_image_plus_its_neighbours_model_in_radial_bins():
    table = profile_table(0.0)
    centres, radii, contrast, blurs = dots(seed=3)
    rng = np.random.default_rng(3)
    image = rng.random((120, 120))
    image[rng.random(image.shape) < 0.02] = np.nan
    model = model_image(image.shape, centres, radii, contrast, table, blurs)
    reach = 1.4 * radii + 4.0
    n_bins = math.ceil(reach.max() / BIN) + 1
    sums, counts, rhos = dot_profiles(image, model, centres, radii, contrast, table, blurs, reach, n_bins, BIN, -1)
    rows, cols = np.indices(image.shape)
    for k, ((x, y), r, c, s) in enumerate(zip(centres, radii, contrast, blurs)):
        rho = np.hypot(cols + 0.5 - x, rows + 0.5 - y)
        own = np.where(rho < 2 * r, c * table_oracle(table, s / r, rho / r), 0.0)
        value = image + model - own
        take = (rho < reach[k]) & np.isfinite(value)
        b = (rho[take] / BIN).astype(int)
        np.testing.assert_allclose(sums[k], np.bincount(b, value[take], n_bins), rtol=0, atol=1e-9)
        np.testing.assert_array_equal(counts[k], np.bincount(b, None, n_bins))
        np.testing.assert_allclose(rhos[k], np.bincount(b, rho[take], n_bins), rtol=0, atol=1e-9)


@pytest.mark.parametrize("shape", [(7, 5), (1, 4), (64, 64), (300, 41)])
@pytest.mark.parametrize("shift", [(0, 0), (1, 2), (-2, 5), (37, 61), (7, -11)])
def test_the_second_image_is_the_clean_film_plus_its_residual_rolled(shape, shift):
    rng = np.random.default_rng(1)
    image, level_map, model = rng.random(shape), 1.0 + rng.random(shape), 0.3 * rng.random(shape)
    image[rng.random(shape) < 0.1] = np.nan
    image.flat[::13] = np.inf
    clean = level_map - model
    expected = clean + np.nan_to_num(np.roll(image - clean, shift, axis=(0, 1)))
    expected[np.isnan(image)] = np.nan
    for threads in (1, 2, 3):  # the same to the bit, in bands of rows or whole
        np.testing.assert_array_equal(second_image(image, level_map, model, shift, threads), expected)


def test_the_dots_model_is_the_same_to_the_bit_painted_in_bands_of_rows():
    centres, radii, contrast, blurs = dots(n=400, seed=6, side=300)
    whole = model_image((300, 300), centres, radii, contrast, profile_table(0.5), blurs, threads=1)
    assert whole.any()
    for threads in (2, 3, 5):
        np.testing.assert_array_equal(model_image((300, 300), centres, radii, contrast, profile_table(0.5), blurs,
                                                  threads=threads), whole)


def test_a_centres_shift_is_the_balance_of_its_darkness_within_nine_tenths_of_its_radius():
    rng = np.random.default_rng(4)
    image = rng.random((60, 70))
    model = rng.normal(0.0, 0.1, image.shape)
    image[rng.random(image.shape) < 0.03] = np.nan  # pixels left out count no darkness
    rows, cols = np.indices(image.shape)
    for x, y, r in [(30.3, 25.7, 9.0), (35.0, 30.0, 4.2), (12.6, 40.1, 11.0)]:
        dx_, dy_ = cols + 0.5 - x, rows + 0.5 - y
        dark = np.nan_to_num(np.maximum(0.8 - (image + model), 0.0)) * (dx_**2 + dy_**2 < (0.9 * r) ** 2)
        expected = np.clip([np.sum(dark * dx_) / dark.sum(), np.sum(dark * dy_) / dark.sum()], -0.25 * r, 0.25 * r)
        np.testing.assert_allclose(centre_shift(image, model, x, y, r, 0.8), expected, rtol=1e-12)
    assert centre_shift(image, model, 3.0, 30.0, 9.0, 0.8) == (0.0, 0.0)  # its window crosses the edge


@pytest.mark.parametrize("move", [False, True])
def test_the_fits_leave_the_model_of_the_dots_they_found(move):
    """Each fit takes its dot's model out and puts the new one in: at the end the model is the fitted dots' model
    painted afresh, whatever moved."""
    table = profile_table(0.5)
    centres, radii, contrast, blurs = dots(n=30, side=100, seed=5)
    image = 1.0 - model_image((100, 100), centres, radii, contrast, table, blurs)
    image += np.random.default_rng(5).normal(0.0, 0.02, image.shape)
    start = centres + np.random.default_rng(6).normal(0.0, 0.7, centres.shape)
    fitted = refine_dots(image, start, 1.1 * radii, contrast, 5.0, 0.5, blurs, np.ones(len(radii)), move=move)
    assert move or np.array_equal(fitted.centres, start)
    assert not move or np.abs(fitted.centres - start).max() > 0.1
    again = model_image(image.shape, fitted.centres, np.nan_to_num(fitted.radius), fitted.contrast, table, blurs)
    np.testing.assert_allclose(fitted.model, again, rtol=0, atol=1e-12)


def test_the_trimmed_misfit_leaves_out_the_largest_squares_and_nothing_else():
    from qdots.micrograph.settle import trimmed_sum

    rng = np.random.default_rng(4)
    squares = rng.random(1000) ** 2
    squares[::97] = np.nan  # pixels left out of the picture
    finite = np.sort(squares[np.isfinite(squares)])
    keep = int(round(0.97 * finite.size))
    assert trimmed_sum(squares, 0.03) == pytest.approx(float(finite[:keep].sum()))
    assert trimmed_sum(squares, 0.0) == pytest.approx(float(finite.sum()))
    assert trimmed_sum(np.array([4.0, 1.0]), 0.5) == 1.0
    assert trimmed_sum(np.array([np.nan]), 0.03) == 0.0
