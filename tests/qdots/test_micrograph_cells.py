"""Particles as the cells of a network (`qdots.micrograph.cells`): close-packed light spheres with dark gaps."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import ndimage

from qdots.micrograph.admit import film_verdict
from qdots.micrograph.cells import MIN_CELL, lattice_spacing, network_cells, split_merged, whole_outlines


def packed_spheres(diameter: float = 40.0, gap: float = 3.0, shape=(300, 360), seed: int = 1, joined=()) -> tuple:
    """Light flat discs of ``diameter`` px on a hexagonal lattice ``diameter + gap`` apart, on a dark ground, blurred
    by 1 px, with noise; the pairs of lattice sites in ``joined`` are bridged (their gap filled). Returns the image and
    the discs' centres (x, y)."""
    spacing = diameter + gap
    rows = np.arange(-spacing, shape[0] + spacing, spacing * np.sqrt(3) / 2)
    centres = [(x + (k % 2) * spacing / 2, y) for k, y in enumerate(rows) for x in np.arange(-spacing, shape[1] + spacing,
                                                                                              spacing)]
    yy, xx = np.mgrid[:shape[0], :shape[1]]
    image = np.full(shape, 0.2)
    for x, y in centres:
        image[(xx - x) ** 2 + (yy - y) ** 2 <= (diameter / 2) ** 2] = 0.8
    for a, b in joined:
        (xa, ya), (xb, yb) = centres[a], centres[b]
        t = np.clip(((xx - xa) * (xb - xa) + (yy - ya) * (yb - ya)) / ((xb - xa) ** 2 + (yb - ya) ** 2), 0, 1)
        image[(xx - xa - t * (xb - xa)) ** 2 + (yy - ya - t * (yb - ya)) ** 2 <= (diameter / 4) ** 2] = 0.8
    image = ndimage.gaussian_filter(image, 1.0) + 0.02 * np.random.default_rng(seed).standard_normal(shape)
    return image, np.array(centres)


def test_close_packed_light_spheres_are_the_cells_of_their_gaps_network():
    """Each whole sphere is one cell, measured at the threshold halfway between gap and sphere: within 1 px of its
    drawn diameter; the darker phase's cells (the gaps' triangles) are not a film of them."""
    image, centres = packed_spheres()
    found = network_cells(image, None, (0, 0, image.shape[1], image.shape[0]), dark=False)
    assert found is not None and not found.dark and np.isnan(found.shape)
    whole = ~found.cut
    inside = ((centres[:, 0] > 25) & (centres[:, 0] < 335) & (centres[:, 1] > 25) & (centres[:, 1] < 275)).sum()
    assert abs(int(whole.sum()) - int(inside)) <= 3
    assert np.median(found.diameters[whole]) == pytest.approx(40.0, abs=1.0)
    assert np.all(np.abs(found.diameters[whole] - 40.0) < 2.0)
    assert found.widths is not None and np.array_equal(found.widths, found.diameters)
    not_a_film(network_cells(image, None, (0, 0, image.shape[1], image.shape[0]), dark=True))


def not_a_film(found) -> None:
    """``found`` is nothing, or refused as a film of round particles."""
    assert found is None or film_verdict(found)[0]


def test_touching_spheres_are_parted_along_their_broken_gaps():
    """Spheres touching in a hexagonal lattice leave only the interstices between them dark: no phase is one network
    (the gaps are broken at every contact). Each whole sphere is still one cell, parted at the interstices and the
    thin gaps a top-hat finds, within 1 px of its drawn diameter; the interstices are not a film."""
    for gap in (0.0, 1.0):
        image, centres = packed_spheres(gap=gap)
        found = network_cells(image, None, (0, 0, image.shape[1], image.shape[0]), dark=False)
        assert found is not None and "touching in a lattice" in found.polarity
        whole = ~found.cut
        inside = ((centres[:, 0] > 25) & (centres[:, 0] < 335) & (centres[:, 1] > 25) & (centres[:, 1] < 275)).sum()
        assert abs(int(whole.sum()) - int(inside)) <= 6
        assert np.all(np.abs(found.diameters[whole] - 40.0) < 1.0)
        not_a_film(network_cells(image, None, (0, 0, image.shape[1], image.shape[0]), dark=True))


def test_the_spacing_of_a_lattice_and_of_none():
    """The autocorrelation's peak beyond its central lobe: a hexagonal lattice of 43 px (within the 2 px its radial
    average's first shell spreads over); none in noise."""
    image, _ = packed_spheres(gap=3.0)
    assert lattice_spacing(image - image.mean(), np.zeros(image.shape, dtype=bool)) == pytest.approx(43.0, abs=2.0)
    noise = ndimage.gaussian_filter(np.random.default_rng(3).standard_normal((200, 200)), 1.0)
    assert lattice_spacing(noise, np.zeros(noise.shape, dtype=bool)) is None


def test_two_spheres_whose_gap_the_cut_misses_are_split_and_a_clump_is_left_whole():
    image, _ = packed_spheres(joined=[(60, 49)])  # neighbours near the middle
    found = network_cells(image, None, (0, 0, image.shape[1], image.shape[0]), dark=False)
    assert found is not None
    whole = found.diameters[~found.cut]
    assert whole.max() < 1.3 * 40.0  # the bridged pair is two cells, not one of 1.4 diameters
    labels = np.zeros((40, 200), dtype=int)
    labels[5:35, 5:35] = 1
    labels[5:35, 45:75] = 2
    labels[5:35, 85:115] = 3
    labels[2:38, 120:198] = 4  # 2.8 times a cell's area: two or three particles
    assert split_merged(labels).max() >= 5
    labels[2:38, 120:198] = 0
    labels[0:40, 120:200] = 4  # a clump of 4.4 cells' area, at the edge: left whole
    assert split_merged(labels).max() == 4


def test_small_cells_and_noise_are_no_network():
    """Cells are measured at a threshold, which moves each edge by up to a pixel: under `MIN_CELL` px they are not
    taken. Noise alone has no network whose cells are particles."""
    image, _ = packed_spheres(diameter=10.0, gap=2.0)
    assert MIN_CELL > 10 and network_cells(image, None, (0, 0, 360, 300), dark=False) is None
    noise = np.random.default_rng(2).standard_normal((200, 200))
    assert network_cells(noise, None, (0, 0, 200, 200), dark=False) is None


def test_a_cell_is_whole_with_its_own_holes_and_a_crescent_its_hull():
    """A ring's core (a particle's darker middle) joins it; a crescent (an SEM sphere lit on one side) becomes its
    convex hull, near the disc it was cut from; a gap between two cells is left to neither, and a convex cell is left
    as it is."""
    yy, xx = np.mgrid[:80, :200]
    disc = lambda x, y, r: (xx - x) ** 2 + (yy - y) ** 2 <= r ** 2  # noqa: E731
    cells = np.zeros((80, 200), dtype=np.int64)
    cells[disc(30, 40, 15) & ~disc(30, 40, 7)] = 1  # a ring
    cells[disc(80, 40, 15) & ~disc(86, 40, 12)] = 2  # a crescent open to the right
    cells[disc(140, 40, 15)] = 3  # a whole disc
    cells[20:60, 165:175] = 4  # two bars with a gap between them, closed at the ends by neither
    cells[20:60, 185:195] = 5
    out = whole_outlines(cells)
    assert np.array_equal(out == 1, disc(30, 40, 15))
    crescent, hull = int((cells == 2).sum()), int((out == 2).sum())
    assert crescent < 0.6 * disc(80, 40, 15).sum() and hull > 0.85 * disc(80, 40, 15).sum()
    assert not ((out == 2) & ~disc(80, 40, 16)).any()  # the hull of a piece of a disc lies in it (within a pixel)
    assert np.array_equal(out == 3, cells == 3)
    assert np.array_equal(out == 4, cells == 4) and np.array_equal(out == 5, cells == 5)
