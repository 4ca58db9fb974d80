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


def test_tasks_run_once_each_and_give_their_results_in_order():
    from labrig.threads import by_chunks, run_tasks

    calls = []
    results = run_tasks([lambda k=k: calls.append(k) or k * k for k in range(37)], threads=2)
    assert results == [k * k for k in range(37)]
    assert sorted(calls) == list(range(37))
    assert run_tasks([], threads=2) == []
    assert by_chunks(lambda start, stop: (start, stop), 2500, chunk=1024) == [(0, 1024), (1024, 2048), (2048, 2500)]


def test_a_failing_task_raises_and_the_others_stop_taking_tasks():
    from labrig.threads import run_tasks

    done = []

    def task(k):
        if k == 0:
            raise ValueError("task 0 failed")
        done.append(k)

    with pytest.raises(ValueError, match="task 0 failed"):
        run_tasks([lambda k=k: task(k) for k in range(200)], threads=2)
    assert len(done) < 199


def test_work_nested_in_a_pools_thread_runs_there_without_waiting_for_the_pool():
    """A task that itself runs tasks (a fit that profiles its dots in chunks) inside the pool's only other thread:
    before, it waited for that pool, which could never run it."""
    from labrig.threads import run_tasks

    inner = lambda: run_tasks([lambda k=k: k for k in range(5)], threads=2)  # noqa: E731
    assert run_tasks([inner, inner, inner], threads=2) == [[0, 1, 2, 3, 4]] * 3


def test_flooding_the_masks_pieces_by_bands_gives_one_floods_labels(monkeypatch):
    """Seeds at distinct heights: each piece of the mask gets the labels of one watershed of the whole, whatever the
    number of threads."""
    from skimage.segmentation import watershed

    import labrig.threads as threads
    from qdots.micrograph.segment import watershed_parts

    rng = np.random.default_rng(4)
    mask = ndimage.gaussian_filter(rng.random((1300, 400)), 3) > 0.5
    surface = rng.random(mask.shape)  # no two heights equal
    markers = np.zeros(mask.shape, dtype=np.int32)
    seeds = np.argwhere(mask)[rng.choice(int(mask.sum()), 900, replace=False)]
    markers[tuple(seeds.T)] = np.arange(1, 901)
    assert ndimage.label(mask)[1] > 50
    whole = watershed(surface, markers, mask=mask)
    np.testing.assert_array_equal(watershed_parts(surface, markers, mask), whole)
    monkeypatch.setattr(threads, "available_threads", lambda: 1)
    np.testing.assert_array_equal(watershed_parts(surface, markers, mask), whole)
    small = (slice(0, 300), slice(None))  # under two bands of rows: flooded whole
    np.testing.assert_array_equal(watershed_parts(surface[small], markers[small], mask[small]),
                                  watershed(surface[small], markers[small], mask=mask[small]))
