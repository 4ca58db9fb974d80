"""A film measured again from dots edited by hand (`qdots.micrograph.edit`), and the napari plugin's layer data
(`qdots.napari_plugin.layers`, which needs no Qt)."""

import numpy as np
import pytest
from helpers import disc_film_png, refused

from qdots.micrograph.edit import edited_film
from qdots.micrograph.measure import measure_image
from qdots.napari_plugin.layers import film_from_points, points_data, shapes_data


@pytest.fixture(scope="module")
def film(tmp_path_factory):
    folder = tmp_path_factory.mktemp("edit")
    disc_film_png(folder / "film.png", n=50, size=220, seed=5)
    return measure_image(folder / "film.png", nm_per_px=0.5, lqe=False)


def test_the_same_set_measures_the_same_film(film):
    det = film.detection
    again = edited_film(film, det.centres, det.diameters)
    assert again.summary["dots_edited"] == 0 and again.summary["dots_deleted"] == 0
    for key, value in film.summary.items():
        assert again.summary[key] == value or (value != value and again.summary[key] != again.summary[key]), key


def test_deleted_and_added_dots_change_the_film_and_are_counted(film):
    det = film.detection
    whole = np.flatnonzero(~det.cut)
    keep = np.setdiff1d(np.arange(det.n_dots), whole[:5])
    centres = np.vstack([det.centres[keep], [[110.0, 3.0]], [[60.0, 60.0]]])
    diameters = np.append(det.diameters[keep], [16.0, 40.0])
    edited = edited_film(film, centres, diameters)
    s = edited.summary
    assert s["dots"] == det.n_dots - 5 + 2 and s["dots_edited"] == 2 and s["dots_deleted"] == 5
    assert edited.detection.cut[-2]  # the added dot at the top edge is cut by it
    assert not edited.detection.cut[-1] and np.isnan(edited.detection.contrast[-1])
    assert np.isclose(2 * np.asarray(edited.state.radii), 40.0).sum() == 1  # the board holds the dot as given
    assert "edited by hand: 2 dots added" in s["doubts"]


@pytest.mark.parametrize("centres, diameters, said", [
    (np.zeros((0, 2)), np.zeros(0), "1 to"),
    ([[10.0, 10.0]], [0.0], "positive"),
    ([[10.0, 10.0]], [np.nan], "positive"),
    ([[-1.0, 10.0]], [5.0], "outside"),
    ([[10.0, 1e9]], [5.0], "outside"),
    ([[10.0, 10.0]], [5.0, 6.0], "must be (N, 2)"),
])
def test_an_edited_set_that_cannot_be_a_film_is_refused_in_one_line(film, centres, diameters, said):
    refused(lambda: edited_film(film, centres, diameters), said)


def test_layer_data_goes_round_in_napari_coordinates(film):
    data, attributes = points_data(film)
    assert np.allclose(data[:, ::-1], film.detection.centres) and np.allclose(attributes["size"],
                                                                             film.detection.diameters)
    assert set(attributes["features"]["kind"]) <= {"whole", "cut", "stacked"}
    again = film_from_points(film, data, attributes["size"])
    assert again.summary["dots_edited"] == 0 and again.summary["mean_diameter_px"] == film.summary["mean_diameter_px"]
    boxes, shape_attributes = shapes_data(film)
    assert len(boxes) == len(shape_attributes["edge_color"]) == len(shape_attributes["features"]["what"])
