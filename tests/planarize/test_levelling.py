"""Levelling of measured height maps (`planarize.levelling`): each artefact put on a known surface is found with
its size and removed, and the thesis's surfaces and hard cases are left alone."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.ndimage import gaussian_filter

from labrig.validate import InputError
from planarize import Surface, anodize, surfaces
from planarize.engines import Continuum
from planarize.levelling import (
    CORRECTIONS,
    align_lines,
    applied_corrections,
    detect,
    level_surface,
    parse_corrections,
    report_rows,
    scar_mask,
    spike_mask,
)


def film(n: int = 96, seed: int = 0, rms: float = 3.0, spacing: float = 5.0) -> Surface:
    """A smooth random film (correlation length 3 pixels), RMS ``rms`` nm."""
    z = gaussian_filter(np.random.default_rng(seed).normal(size=(n, n)), 3.0, mode="wrap")
    return Surface(100.0 + rms * z / z.std(), spacing)


def found(artefacts, name):
    return next(a for a in artefacts if a.name == name)


def test_the_corrections_are_parsed_in_their_order_and_bad_words_are_refused_in_one_line():
    assert parse_corrections("plane, lines") == ("lines", "plane")
    assert parse_corrections(["spikes", "poly2"]) == ("spikes", "poly2")
    assert parse_corrections(True) == ("plane",) and parse_corrections(False) == ()
    assert parse_corrections(None, "auto") == "auto" and parse_corrections("none") == ()
    for bad, match in (("planes", "unknown correction 'planes'"), ("poly2,poly3", "alternatives"),
                       (3, "level must be")):
        with pytest.raises(InputError, match=match) as error:
            parse_corrections(bad)
        assert "\n" not in str(error.value)


def test_a_tilt_is_found_with_its_angle_and_removed_keeping_the_mean():
    base = film()
    x, y = np.meshgrid(base.x, base.y, indexing="ij")
    slope = math.tan(math.radians(2.0))
    tilted = base.with_heights(base.z + slope * (0.6 * x + 0.8 * y))
    levelled, artefacts = level_surface(tilted, "plane")
    tilt = found(artefacts, "tilt")
    # the angle found is that of the tilted film's least-squares plane, fitted here independently
    design = np.column_stack([np.ones(x.size), x.ravel(), y.ravel()])
    _, gx, gy = np.linalg.lstsq(design, tilted.z.ravel(), rcond=None)[0]
    assert tilt.found and tilt.applied
    assert tilt.detail.startswith(f"{math.degrees(math.atan(math.hypot(gx, gy))):.3g} deg")
    assert levelled.z.mean() == pytest.approx(tilted.z.mean())
    # a fit is linear: the tilted film levels to the film levelled, to rounding
    reference = level_surface(base, "plane")[0].z
    np.testing.assert_allclose(levelled.z - levelled.z.mean(), reference - reference.mean(), atol=1e-9)


def test_scan_line_offsets_are_found_with_their_size_and_removed():
    base = film(seed=1)
    offsets = np.random.default_rng(2).normal(0.0, 2.0, base.shape[1])  # one offset per scan line (y)
    shifted = base.with_heights(base.z + offsets[None, :])
    artefacts = detect(shifted)
    lines = found(artefacts, "line offsets")
    assert lines.found and not lines.applied
    assert lines.size == pytest.approx(np.std(offsets), rel=0.25)
    aligned = align_lines(shifted.z)
    # each line moves as a whole; the jumps between lines are gone (what stays is a slow drift: the median
    # of each line's differences is a noisy estimate, and their sum wanders; the plane takes its trend)
    moved = np.mean(aligned - base.z, axis=0)
    assert np.std(aligned - base.z - moved) < 1e-9
    assert np.std(np.diff(moved)) < 0.1 * np.std(np.diff(offsets))
    assert not found(detect(base), "line offsets").found  # a film without offsets has none


def test_one_pixel_spikes_are_found_counted_and_replaced():
    base = film(64, seed=3)
    rng = np.random.default_rng(4)
    where = rng.choice(64 * 64, 8, replace=False)
    spiky = base.z.copy().ravel()
    spiky[where] += rng.choice([-1, 1], 8) * rng.uniform(30, 60, 8)  # 10-20 x the film's RMS
    spiky = base.with_heights(spiky.reshape(64, 64))
    mask, _ = spike_mask(spiky.z)
    assert sorted(np.flatnonzero(mask)) == sorted(where)
    levelled, artefacts = level_surface(spiky, "spikes")
    spikes = found(artefacts, "spikes")
    assert spikes.count == 8 and spikes.applied and spikes.size > 25
    assert np.abs(levelled.z - base.z).max() < 3.0  # each replaced by its window's median


def test_scars_along_a_scan_line_are_found_and_bridged():
    base = film(96, seed=5)
    scarred = base.z.copy()
    scarred[10:40, 20] += 15.0  # a 30-pixel scar on one line
    scarred[50:90, 60:62] -= 12.0  # a 40-pixel scar two lines wide, below
    mask, repaired = scar_mask(scarred)
    assert mask[10:40, 20].all() and mask[50:90, 60:62].all()
    assert mask.sum() <= 30 + 80 + 8  # (a few pixels at the scars' ends at most)
    levelled, artefacts = level_surface(base.with_heights(scarred), "scars")
    scars = found(artefacts, "scars")
    assert scars.count == 2 and scars.applied
    assert np.abs(levelled.z - base.z).max() < 2.0


def test_a_bow_is_reported_by_auto_and_removed_only_when_asked():
    base = film(seed=6)
    x, y = np.meshgrid(base.x, base.y, indexing="ij")
    bowed = base.with_heights(base.z + 4e-4 * ((x - x.mean()) ** 2 + (y - y.mean()) ** 2))
    kept, auto = level_surface(bowed, "auto")
    bow = found(auto, "bow")
    assert bow.found and not bow.applied and "poly2" in bow.sentence()
    removed, asked = level_surface(bowed, "poly2")
    assert found(asked, "bow").applied
    reference = level_surface(base, "poly2")[0].z  # (a fit is linear: the bow comes off exactly)
    np.testing.assert_allclose(removed.z - removed.z.mean(), reference - reference.mean(), atol=1e-9)
    assert applied_corrections(asked) == ("plane", "poly2")
    assert np.std(kept.z - base.z) > 1.0


def test_auto_on_a_clean_film_changes_nothing_and_none_measures_nothing():
    base = film(seed=7)
    levelled, artefacts = level_surface(base, "auto")
    assert not any(a.found for a in artefacts[:3])  # no offsets, spikes or scars on a clean film
    assert report_rows(artefacts) == [(a.name, a.sentence()[len(a.name) + 1:]) for a in artefacts if a.found]
    assert level_surface(base, "none") == (base, [])


@pytest.mark.parametrize("name, surface", [
    ("hill", surfaces.hill()), ("depression", surfaces.depression()), ("Ta film", surfaces.random_roughness(seed=1)),
    ("checkerboard of 1 um steps", Surface(((np.arange(68)[:, None] // 4 + np.arange(68)[None, :] // 4) % 2)
                                           * 1000.0, 50.0)),
    ("cone", Surface(100 * (1 - np.hypot(*np.meshgrid(np.linspace(-1, 1, 65), np.linspace(-1, 1, 65)))), 10.0)),
    ("noise of 100 nm", Surface(np.random.default_rng(1).normal(0, 100, (128, 128)), 10.0)),
])
def test_the_hard_cases_and_the_thesis_surfaces_have_no_spikes(name, surface):
    """A step's edge, a cone's tip and white noise are no spikes (the spread test of the module docstring)."""
    assert not spike_mask(surface.z)[0].any(), name


def test_a_spike_no_longer_decides_the_grid_once_removed():
    """Issue 63's case: eight one-pixel spikes on a 64 x 64 map forced the finest grid. Removed by levelling,
    the run chooses the grid the map without them chooses."""
    base = film(64, seed=8, rms=2.0, spacing=10.0)
    spiky = base.z.copy()
    rng = np.random.default_rng(9)
    spiky.ravel()[rng.choice(spiky.size, 8, replace=False)] += 40.0
    levelled, artefacts = level_surface(base.with_heights(spiky), "auto")
    assert found(artefacts, "spikes").count == 8
    settings = Continuum(max_refine=4)
    chosen = [anodize(s, 5.0, engine=settings, record=2).parameters["refine"] for s in (base, levelled)]
    assert chosen[0] == chosen[1]


def test_every_correction_is_named_in_the_module_docstring():
    import planarize.levelling as module

    for correction in CORRECTIONS:
        assert f'``"{correction}"``' in module.__doc__
