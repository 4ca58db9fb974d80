"""Micrographs as microscopes write them (issue 52): dense and ordered films measured honestly, data strips and
ruled scale bars, the scale checks, and pictures that are not films refused."""

from __future__ import annotations

import re

import numpy as np
import pytest
from helpers import one_line_error, refused
from PIL import Image

from qdots.analysis.structure import radial_distribution
from qdots.cli import main
from qdots.micrograph.annotations import find_annotations
from qdots.micrograph.detect import detect_dots
from qdots.micrograph.film import film_metrics, film_state, first_peak, size_spread
from qdots.micrograph.labelled import label_micrograph, not_a_film
from qdots.micrograph.measure import measure_image, scale_check
from qdots.micrograph.overlay import save_overlay
from qdots.micrograph.scale import find_scale_bar
from qdots.micrograph.synthetic import dense_board, render_micrograph, superlattice_board

#: 10 nm dots at 0.6 nm/px, imaged with uneven focus and contrast, the support's grain and noise.
D = 10.0 / 0.6
IMAGING = {"noise": 0.05, "blur": (0.6, 1.2), "contrast": 0.55, "contrast_spread": 0.15, "contrast_tilt": 0.2,
           "texture": 0.02, "illumination": 0.3}


def first_shell(centres, diameters, shape) -> float:
    """Where g(r) peaks within 1.6 mean diameters, in mean diameters."""
    state = film_state(centres, diameters, shape)
    mean = float(np.mean(diameters))
    rdf = radial_distribution(state, r_max=1.6 * mean, bins=64)
    return float(rdf.r[int(np.nanargmax(rdf.g))] / mean)


def inside(centres, diameters, shape) -> np.ndarray:
    h, w = shape
    r = diameters / 2
    return (centres[:, 0] >= r) & (centres[:, 1] >= r) & (centres[:, 0] + r <= w) & (centres[:, 1] + r <= h)


@pytest.mark.parametrize("lattice, gap_nm", [("hexagonal", 1.5), ("square", 1.0)])
def test_a_superlattice_with_ligand_gaps_is_measured_honestly(lattice, gap_nm):
    centres, diameters = superlattice_board(288, 288, D, 0.05, gap_nm / 0.6, lattice, seed=1)
    image = render_micrograph(centres, diameters, (288, 288), seed=2, **IMAGING)
    detection = detect_dots(image)
    true = diameters[inside(centres, diameters, image.shape)]
    metrics = film_metrics(film_state(detection.centres, detection.diameters, image.shape), ~detection.cut,
                           errors=detection.errors)
    assert abs(metrics["size_spread"] - true.std(ddof=1) / true.mean()) <= 0.015
    # the goal is 2 % (met on the benchmark's 512 px films); this small film settles its focus on ~150 dots
    assert abs(metrics["mean_diameter_px"] / true.mean() - 1) <= 0.025
    whole = ~detection.cut
    assert first_shell(detection.centres[whole], detection.diameters[whole], image.shape) >= 1.0  # no overlap
    assert 0 < metrics["size_spread_error"] < metrics["size_spread_measured"]


def test_the_spread_takes_the_measurement_error_out():
    rng = np.random.default_rng(3)
    d = rng.normal(20.0, 1.0, 4000)
    errors = np.abs(rng.normal(0.0, 0.6, 4000))
    s = size_spread(d, errors)
    measured = d.std(ddof=1) / d.mean()
    error = np.sqrt(np.mean(errors**2)) / d.mean()
    assert s["size_spread_measured"] == pytest.approx(measured)
    assert s["size_spread_error"] == pytest.approx(error)
    assert s["size_spread"] ** 2 == pytest.approx(measured**2 - error**2)
    assert size_spread(d)["size_spread"] == pytest.approx(measured)  # no errors given: nothing taken out
    assert size_spread(d, np.full(4000, 50.0))["size_spread"] == 0.0  # errors larger than the spread
    outliers = np.concatenate([d, np.full(80, 40.0)])  # 2 % fused pairs or false dots: left out of the SD
    with_them = size_spread(outliers)
    assert with_them["size_outliers"] == 80 and with_them["size_spread_measured"] == pytest.approx(measured)
    assert with_them["size_mean"] == pytest.approx(d.mean())
    tail = np.concatenate([d, rng.normal(24.0, 1.0, 400)])  # a tail within reach is kept: the SD grows, the IQR hardly
    assert size_spread(tail)["size_spread_measured"] > 1.2 * size_spread(tail)["size_spread_robust"]


def bar_image(style: str) -> tuple[np.ndarray, int]:
    """A grey field with a 120 px bar drawn by hand (no matplotlib): ``style`` ruled (cut by 2 px gaps), checkered
    (blocks in an outline), ruler (a line with ticks), or boxed (a white box holding the bar and a 'label')."""
    image = np.full((80, 200), 0.5) + 0.02 * np.random.default_rng(0).standard_normal((80, 200))
    x, y, length = 40, 40, 120
    if style == "ruled":
        image[y:y + 6, x:x + length] = 0.0
        for k in range(1, 5):
            image[y:y + 6, x + 24 * k - 1:x + 24 * k + 1] = 0.5
        image[y - 4:y + 10, x:x + 2] = image[y - 4:y + 10, x + length - 2:x + length] = 0.0
    elif style == "checkered":
        image[y:y + 8, x:x + length] = 0.0
        image[y + 1:y + 7, x + 1:x + length - 1] = 1.0
        for k in range(0, 5, 2):
            image[y:y + 8, x + 24 * k:x + 24 * (k + 1)] = 0.0
    elif style == "ruler":
        image[y + 4:y + 6, x:x + length] = 0.0
        for k in range(6):
            tip = y - 6 if k in (0, 5) else y
            image[tip:y + 6, min(x + 24 * k, x + length - 2):min(x + 24 * k, x + length - 2) + 2] = 0.0
    else:
        image[y - 14:y + 30, x - 10:x + length + 10] = 1.0
        image[y:y + 6, x:x + length] = 0.0
        image[y + 12:y + 24, x + 40:x + 46] = image[y + 12:y + 24, x + 60:x + 70] = 0.0  # 'letters'
    return image, length


@pytest.mark.parametrize("style", ["ruled", "checkered", "ruler", "boxed"])
def test_ruled_checkered_and_boxed_bars_are_measured_whole(style):
    image, length = bar_image(style)
    bar = find_scale_bar(image)
    assert bar is not None and bar.length_px == pytest.approx(length, abs=0.5) and bar.ruled == (style != "boxed")


LAYOUTS = [dict(strip="bottom", colour="black", style="ruled", boxed=True, label="under"),
           dict(strip="top", colour="white", style="checkered", label="over"),
           dict(strip="right", colour="black", style="ruler", label="beside", strip_px=150, bar_nm=40),
           dict(strip="left", colour="white", style="solid", label="under", strip_px=150, bar_nm=40),
           dict(strip=None, colour="white", style="ruled", boxed=True, label="under"),
           dict(strip=None, colour="black", style="solid", label="beside")]


@pytest.fixture(scope="module")
def picture():
    centres, diameters = superlattice_board(330, 260, D, 0.05, 2.5, "hexagonal", seed=4)
    film = render_micrograph(centres, diameters, (260, 330), seed=5, **IMAGING)
    return np.clip(film / np.percentile(film, 99.9) * 0.85, 0, 1)


@pytest.mark.parametrize("layout", LAYOUTS, ids=lambda k: f"{k['strip']}-{k['colour']}-{k['style']}-{k['label']}")
def test_data_strips_and_bars_are_found_whatever_their_side_colour_and_style(picture, layout):
    labelled = label_micrograph(picture, 0.6, **{"bar_nm": 60, **layout})
    found = find_annotations(labelled.image)
    assert found.window == labelled.window
    assert found.bar is not None and abs(found.bar.length_px - labelled.bar_px) <= 1
    assert [s.side for s in found.strips] == ([layout["strip"]] if layout["strip"] else [])


def test_a_film_with_a_black_data_strip_is_measured_without_it(picture, tmp_path, capsys):
    labelled = label_micrograph(picture, 0.6, bar_nm=60, strip="bottom", colour="black", style="ruled", boxed=True)
    path = tmp_path / "strip.jpg"
    Image.fromarray((255 * labelled.image).astype(np.uint8)).save(path, quality=85)
    assert main(["measure", str(path), "--scale-bar", "60nm", "--out", str(tmp_path / "out"), "--no-lqe"]) == 0
    printed = capsys.readouterr().out
    over = re.search(r"over ([0-9.]+) px at half contrast \(a ruled bar", printed)
    assert over and abs(float(over.group(1)) - labelled.bar_px) <= 1 and "data strip" in printed and "bottom" in printed
    film = measure_image(path, scale_bar="60nm", lqe=False)
    assert film.nm_per_px == pytest.approx(0.6, rel=0.01)
    assert film.detection.centres[:, 1].max() < labelled.window[3]  # no dot in the strip
    assert film.detection.n_dots > 100 and 8.5 < film.summary["mean_diameter_nm"] < 10.5
    overlay = save_overlay(film, tmp_path / "overlay.png")
    with Image.open(overlay) as shown:
        rgb = np.asarray(shown.convert("RGB"), dtype=int)
    magenta = (rgb[..., 0] > 200) & (rgb[..., 1] < 80) & (rgb[..., 2] > 200)
    assert magenta.sum() > 100  # the bar used is outlined


def test_a_scale_that_makes_the_dots_implausible_is_said_so():
    plausible = {"nm_per_px": 0.6, "mean_diameter_nm": 9.8}
    assert "within the 1-100 nm" in scale_check(plausible)
    assert "outside the 1-100 nm" in scale_check({"nm_per_px": 5.0, "mean_diameter_nm": 83.0 * 5})
    assert "outside" in scale_check({"nm_per_px": 0.01, "mean_diameter_nm": 0.2})
    assert "no scale" in scale_check({"nm_per_px": float("nan")})


def board_png(path):
    from qdots.render import save_png

    centres, diameters = dense_board(200, 200, 15.0, 0.05, seed=4, vacancies=0.3)
    return save_png(film_state(centres, diameters, (200, 200)), path)


@pytest.mark.parametrize("kind", ["plot", "text", "drawing", "board", pytest.param("noisy text", marks=pytest.mark.slow),
                                  "noisy drawing"])
def test_pictures_that_are_not_films_are_refused_in_one_line(kind, tmp_path, capsys):
    path = tmp_path / "picture.png"
    if kind == "board":
        board_png(path)
    else:
        drawn = not_a_film(kind.split()[-1], (240, 320))
        if kind.startswith("noisy"):
            drawn = np.clip(drawn + 0.03 * np.random.default_rng(1).standard_normal(drawn.shape), 0, 1)
        Image.fromarray((255 * drawn).astype(np.uint8)).save(path)
    out = tmp_path / "out"
    assert main(["measure", str(path), "--out", str(out), "--no-lqe"]) == 2
    message = one_line_error(capsys)
    assert "not a micrograph" in message or "not a film" in message
    if "not a micrograph" in message:  # drawn: refused before anything is sought, nothing written
        assert not out.exists()
    else:  # what was found is shown, and nothing else written
        assert sorted(p.relative_to(out).as_posix() for p in out.rglob("*") if p.is_file()) == [
            "picture-refused/picture_refused.png"]
        assert "picture_refused.png" in message and "--force" in message


@pytest.mark.slow
@pytest.mark.release
def test_enlarged_scanned_text_is_refused_as_lines_of_text(tmp_path, capsys):
    """Regression: text drawn at 3x with noise passed every other look (its letters fitted as 6 px discs, alike
    within 20-30 %, measured the same twice within 1.6 %). Its objects lie in lines: a third of the bands between
    its rows are empty, none of its columns' (films: at most 4 %)."""
    from scipy import ndimage

    drawn = ndimage.zoom(not_a_film("text", (240, 320), seed=1), 3, order=1)
    drawn = np.clip(drawn + 0.05 * np.random.default_rng(2).standard_normal(drawn.shape), 0, 1)
    path = tmp_path / "page.png"
    Image.fromarray((255 * drawn).astype(np.uint8)).save(path)
    assert main(["measure", str(path), "--out", str(tmp_path / "out"), "--no-lqe"]) == 2
    assert "lie in lines, as text does" in one_line_error(capsys)
    assert [p.name for p in (tmp_path / "out").rglob("*") if p.is_file()] == ["page_refused.png"]


def test_films_in_rows_are_not_text():
    from qdots.micrograph.admit import LINE_FILLED, LINE_GAPS, LINE_RUNS, text_lines

    def text(centres, diameter):
        lines, across, runs = text_lines(centres, diameter)
        return lines >= LINE_GAPS and across <= LINE_FILLED and runs >= LINE_RUNS

    for lattice in ("hexagonal", "square"):  # rows and columns aligned with the picture
        centres, diameters = superlattice_board(300, 300, 10.0, 0.05, 3.0, lattice, seed=1)
        assert not text(centres, float(np.median(diameters))), lattice
    rows = np.column_stack([np.tile(np.arange(10.0, 300, 8), 8), np.repeat(np.arange(8) * 36.0 + 10, 37)])
    assert text(rows, 8.0)  # lines of 8 px objects 36 px apart: text's layout
    # regression: a sparse film of the thesis's kind, two clusters one above the other with a wide gap between them
    # (a third of the rows' bands empty, none of the columns'), was refused as text
    grid = np.array([(x + 0.5 * (y % 2), y * 0.87) for y in range(8) for x in range(9)]) * 16.0
    clusters = np.vstack([grid + [40.0, 40.0], grid + [48.0, 400.0]])
    lines, across, runs = text_lines(clusters, 15.0)
    assert lines >= LINE_GAPS and across <= LINE_FILLED and runs == 2
    assert not text(clusters, 15.0)


def test_the_refusal_names_its_reason():
    flat = np.zeros((200, 200))
    flat[50:150, 50:150] = 1.0
    from qdots.micrograph.admit import check_picture

    refused(lambda: check_picture(flat, find_annotations(flat), "square.png"), "square.png", "flat colour")


def test_a_micrograph_whose_background_is_clipped_flat_is_not_a_drawing():
    """Particles on a background clipped to one value (an EMPS development film of raspberry-like particles on black,
    33 % of it flat) were refused as "flat colour, as in a drawing". What is not flat in a micrograph is its particles,
    with noise inside them; in a drawing, strokes and edges. Here a sparse film's light background is clipped flat
    (over 30 % of the picture) and the picture is taken; the drawings, plots and text of `not_a_film` still are not."""
    from qdots.micrograph.admit import FLAT_SHARE, check_picture
    from qdots.micrograph.synthetic import sparse_board

    centres, diameters = sparse_board(400, 300, 24.0, 0.1, seed=3)
    image = render_micrograph(centres, diameters, (300, 400), noise=0.03, seed=3)
    clipped = np.minimum(image, np.percentile(image, 40))  # the light background, clipped to one value
    assert (clipped == clipped.max()).mean() > FLAT_SHARE
    check_picture(clipped, find_annotations(clipped), "clipped.png")  # taken: no error
    for kind in ("plot", "text", "drawing"):
        picture = not_a_film(kind)
        refused(lambda p=picture, k=kind: check_picture(p, find_annotations(p), f"{k}.png"), f"{kind}.png", "flat colour")


@pytest.mark.slow
def test_a_touching_superlattice_without_vacancies_is_measured_to_two_percent():
    """No background shows anywhere but between three touching dots: the faint dots the threshold misses
    (`qdots.micrograph.missed`) and a background field that followed each dot's neighbours pulled the mean
    diameter 6.3 % low on this film before."""
    from benchmarks.micrograph_films import dense_case

    row = dense_case("touching superlattice, no vacancies", 0.05, 512)
    assert abs(row["d"]) <= 0.02, row
    assert abs(row["measured"] - row["sigma"]) <= 0.015, row


@pytest.mark.slow
def test_a_change_of_the_pictures_last_bit_hardly_moves_the_diameters():
    """Rounding jitter: the same film with its pixels times 1 and 1 +- 1e-13, which no picture can tell apart. The
    settling's last pattern of blurs and backgrounds, a quarter of its first steps apart, let the fits' own jitter
    choose its minimum: these two films' mean diameters moved by 0.010 % and 0.035 %; without it, by 0.004 % and
    0.007 % (`python -m benchmarks.micrograph_jitter` measures the same on real micrographs)."""
    from benchmarks.micrograph_films import FILMS, IMAGING, film

    for name in ("hexagonal superlattice, 1 nm gaps", "touching superlattice, no vacancies"):
        kind, gap = FILMS[name]
        centres, diameters = film(kind, gap, 0.05, 384)
        image = render_micrograph(centres, diameters, (384, 384), seed=2, **IMAGING)
        means = []
        for factor in (1.0, 1.0 + 1e-13, 1.0 - 1e-13):
            found = detect_dots(image * factor)
            means.append(float(np.mean(found.diameters[~found.cut])))
        assert max(means) / min(means) - 1.0 < 2e-4, (name, means)


@pytest.mark.slow
@pytest.mark.parametrize("vacancies, within", [(0.0, 0.03), (0.1, 0.02)])
def test_a_blurred_superlattice_of_discs_is_measured_where_no_background_shows(vacancies, within):
    """Flat discs of 16.5 px, 2.5 px apart, blurred by 2 px: the gaps never rise to the background. With 10 % of the
    sites empty the background shows and the median diameter is right (-0.8 %). With none empty, six faint dots the
    threshold missed pulled the background the film is settled on down, and every diameter with it: -8.1 % before
    the misfit left out its largest squares there (`qdots.micrograph.settle.TRIM`), -2.7 % with two passes of each
    trial fit, -2.0 % with four (`qdots.micrograph.settle.TRIMMED_PASSES`) and the missed dots sized against the dots
    found; the goal is 2 %, and on twelve films alike the mean error is 2.1 %."""
    from scipy.spatial import cKDTree

    centres, diameters = superlattice_board(500, 500, 16.5, 0.07, 2.5, seed=1, vacancies=vacancies)
    image = render_micrograph(centres, diameters, (500, 500), profile=0.0, blur=2.0, noise=0.03, illumination=0.0,
                              contrast=0.5)
    detection = detect_dots(image)
    whole = ~detection.cut
    _, index = cKDTree(centres).query(detection.centres[whole])
    error = abs(float(np.median(detection.diameters[whole] / diameters[index])) - 1.0)
    assert error <= within
    if error > 0.02:
        pytest.xfail(f"open: {100 * error:.1f} % off, the goal is 2 %")


@pytest.mark.slow
def test_faint_dots_of_a_film_without_gaps_are_found():
    """Flat discs of 16.5 px, 1 px apart, blurred by 2 px, no site empty: the faint ones fall on the threshold's bright
    side. Found in the fitted model's residual, they were kept only when they fitted 0.8 typical radii wide, and the
    typical radius (of the first fits, as projected spheres) reads some 15 % over the discs' fitted radii: 28 of the
    780 dots inside the picture stayed missed, 10 since they are sized against the dots found
    (`qdots.micrograph.missed.ROUND`; the median diameter -6.4 % -> -3.5 %)."""
    from scipy.spatial import cKDTree

    centres, diameters = superlattice_board(500, 500, 16.5, 0.07, 1.0, seed=1, vacancies=0.0)
    image = render_micrograph(centres, diameters, (500, 500), profile=0.0, blur=2.0, noise=0.03, illumination=0.2,
                              contrast=0.5, seed=1)
    detection = detect_dots(image)
    inside = np.all((centres > 20) & (centres < 480), axis=1)
    distance, _ = cKDTree(detection.centres).query(centres[inside])
    assert np.count_nonzero(distance > 4.0) <= 15
    found, _ = cKDTree(centres).query(detection.centres[~detection.cut])
    assert np.count_nonzero(found > 4.0) <= 6


@pytest.mark.slow
def test_dense_and_ordered_films_meet_the_goals_of_issue_52():
    from benchmarks.micrograph_films import FILMS, SPREADS, dense_table

    _, rows = dense_table(512, list(FILMS), SPREADS)
    for row in rows:
        assert abs(row["measured"] - row["sigma"]) <= 0.015, row
        assert abs(row["d"]) <= 0.02, row
        assert row["gr"] >= 1.0 and row["true_gr"] >= 1.0, row
        assert row["threshold"] < -0.1 < row["d"], row  # a threshold under-sizes projected spheres; the fit does not


@pytest.mark.slow
def test_each_diameters_error_is_that_of_measuring_again():
    """The error from the film's own residual rolled aside (`repeat_errors`) against a true repeat: the same film
    imaged twice with independent noise. The estimate leaves out how the blur and background settled on each
    image differ (a true repeat settles them again), so it may come out lower, never much higher."""
    from scipy.spatial import cKDTree

    centres, diameters = superlattice_board(512, 512, D, 0.03, 1.0 / 0.6, "hexagonal", seed=1)
    a, b = (detect_dots(render_micrograph(centres, diameters, (512, 512), seed=s, **IMAGING)) for s in (2, 3))
    distance, nearest = cKDTree(b.centres).query(a.centres)
    same = (distance < 2) & ~a.cut & ~b.cut[nearest]
    true = np.std(a.diameters[same] - b.diameters[nearest[same]]) / np.sqrt(2)
    estimate = np.sqrt(np.nanmean(a.errors[same] ** 2))
    assert 0.5 * true <= estimate <= 1.2 * true


def test_a_sparse_film_of_two_clusters_is_measured(tmp_path):
    """Regression (issue 61): films of the thesis's kind, 150 dots in a few clusters at coverage 0.08-0.13, were
    refused as text (4 of 38 of the inference's held-out films), their clusters one above the other."""
    rng = np.random.default_rng(5)
    grid = np.array([(x + 0.5 * (y % 2), y * 0.87) for y in range(8) for x in range(9)]) * 16.5
    centres = np.vstack([grid + [60.0, 50.0], grid + [80.0, 560.0], [[600.0, 300.0]]])
    diameters = 15.0 * (1.0 + 0.05 * rng.standard_normal(len(centres)))
    image = render_micrograph(centres, diameters, (720, 720), noise=0.04, seed=6)
    path = tmp_path / "clusters.png"
    Image.fromarray((255 * np.clip(image, 0, 1)).astype(np.uint8)).save(path)
    film = measure_image(path, lqe=False)
    assert film.summary["dots"] == len(centres)
    assert abs(film.summary["mean_diameter_px"] / float(np.mean(diameters)) - 1) < 0.03


def test_objects_not_round_are_refused_when_few_show_an_outline():
    """Regression: blood cells (SEM) gave 17 whole objects of which only 8 showed an outline (median 0.19; the others
    were found in the fit's residual and show none); the roundness check then asked for 10 outlines and the cells were
    measured as a film."""
    from qdots.micrograph.admit import MAX_OUTLINE, MIN_OUTLINES, film_verdict
    from qdots.micrograph.detect import Detection

    rng = np.random.default_rng(3)
    n = 17
    centres = np.column_stack([np.arange(n) % 5 * 120.0 + 80, np.arange(n) // 5 * 120.0 + 80])
    shapes = np.full((n, 3), np.nan)
    shapes[:8] = np.column_stack([rng.uniform(1.3, 1.8, 8), rng.uniform(0.17, 0.21, 8), np.zeros(8)])  # none touch
    detection = Detection(centres, np.full(n, 90.0), np.zeros(n, dtype=bool), np.full(n, 0.3), True, "dark",
                          0.0, "p = 0", 2.0, 0, (600, 700), (0, 0, 700, 600), np.full(n, 0.5), shapes)
    assert 8 >= MIN_OUTLINES
    refusals, _ = film_verdict(detection)
    assert any("not round" in r for r in refusals), refusals
    shapes[:8, 1] = 0.5 * MAX_OUTLINE  # the same film with round outlines is a film
    assert film_verdict(detection)[0] == []


def test_the_half_depth_width_is_of_the_dots_the_mean_diameter_is_of(tmp_path):
    """Regression: the mean half-depth width counted the size outliers the mean diameter leaves out (4 discs three
    times the others' size, detected in pieces: 9 outliers), so the two means described different dots (their ratio
    2.4 % above every dot's own)."""
    from qdots.micrograph.film import size_inliers
    from qdots.micrograph.synthetic import sparse_board

    centres, diameters = sparse_board(600, 600, 15.0, 0.05, coverage=0.12, seed=3)
    big = np.array([[100.0, 100.0], [500.0, 120.0], [120.0, 480.0], [480.0, 500.0]])
    away = np.min(np.hypot(*(centres[:, None, :] - big[None]).transpose(2, 0, 1)), axis=1) > 50
    centres, diameters = np.vstack([centres[away], big]), np.concatenate([diameters[away], np.full(4, 48.0)])
    path = tmp_path / "outliers.png"
    image = render_micrograph(centres, diameters, (600, 600), noise=0.03, seed=4)
    Image.fromarray((255 * np.clip(image, 0, 1)).astype(np.uint8)).save(path)
    film = measure_image(path, lqe=False)
    s, det = film.summary, film.detection
    assert s["size_outliers"] >= 4
    sized = ~det.cut & ~film.stacked
    inliers = size_inliers(det.diameters[sized])
    assert s["mean_diameter_px"] == pytest.approx(float(det.diameters[sized][inliers].mean()), rel=1e-12)
    assert s["mean_half_width_px"] == pytest.approx(float(det.half_widths()[sized][inliers].mean()), rel=1e-12)
    assert abs(float(det.half_widths()[sized].mean()) / s["mean_half_width_px"] - 1.0) > 0.01  # the outliers weigh


@pytest.mark.parametrize("shape", [0.0, 0.5])
def test_a_film_blurred_by_four_pixels_is_settled_at_its_blur(shape):
    """Regression: each pattern of the blur search trusted its surface within two steps of its centre and the next
    ones were narrower, so no blur past 2.55 px could be settled (`qdots.micrograph.settle.descend`): a film
    of 30 px dots blurred by 4 px (4.1 px with the detector's own smoothing) settled at 2.55 px, its discs 2.5 % too
    wide and its spheres taken for discs 10 % too narrow. Measured now: the blur within 1 %, diameters within 0.1 %."""
    from qdots.micrograph.synthetic import sparse_board

    centres, diameters = sparse_board(400, 400, 30.0, 0.07, coverage=0.2, seed=1)
    image = render_micrograph(centres, diameters, (400, 400), profile=shape, blur=4.0, noise=0.02, seed=2,
                              illumination=0.0)
    detection = detect_dots(image)
    assert detection.shape == shape
    assert detection.blur == pytest.approx(float(np.hypot(4.0, 1.0)), rel=0.05)
    whole = ~detection.cut
    inside = (centres.min(axis=1) > 15) & (centres.max(axis=1) < 385)
    assert float(np.mean(detection.diameters[whole])) == pytest.approx(float(np.mean(diameters[inside])), rel=0.02)


def test_where_blur_hides_the_shape_the_residual_chooses_and_says_so():
    """Small dots blurred by a third of their radius: a sphere and a flat disc both match the measured curvature at
    their own blurs. The lower residual chooses (before, the disc always did: these spheres' diameters 15 % low), the
    message says the shape is hardly seen, and the half-depth width, which does not depend on it, is right."""
    from scipy.spatial import cKDTree

    from qdots.micrograph.profiles import half_depth_radius
    from qdots.micrograph.synthetic import sparse_board

    centres, diameters = sparse_board(400, 400, 16.0, 0.15, coverage=0.12, seed=1)
    image = render_micrograph(centres, diameters, (400, 400), profile=0.5, blur=2.5, noise=0.03, seed=2,
                              illumination=0.0)
    detection = detect_dots(image)
    assert detection.shape == 0.5 and "hardly seen" in detection.profile
    distance, index = cKDTree(detection.centres).query(centres)
    found = distance < 3.0
    assert float(np.median(detection.diameters[index[found]] / diameters[found])) == pytest.approx(1.0, abs=0.02)
    truth = diameters * half_depth_radius(0.5, 2.5 / (0.5 * diameters))
    assert float(np.median(detection.half_widths()[index[found]] / truth[found])) == pytest.approx(1.0, abs=0.03)


def test_the_first_peak_of_g_is_the_nearest_neighbours_shell_on_an_ordered_film():
    """On a dense ordered board the shell at sqrt(7) spacings (12 neighbours) can rise above a first peak that
    straddles two bins: the reported peak is still the first shell's."""
    from scipy.spatial import cKDTree

    centres, diameters = dense_board(600, 600, 15.0, 0.1, seed=1)
    state = film_state(centres, diameters, (600, 600))
    spacing = float(np.median(cKDTree(centres).query(centres, k=2)[0][:, 1]))
    peak = film_metrics(state)["gr_peak_diameters"]
    assert peak == pytest.approx(spacing / np.mean(diameters), abs=0.06)


def test_first_peak_takes_the_first_local_maximum_that_reaches_half_the_largest():
    r = np.arange(10.0)
    assert first_peak(r, np.array([0, 0.2, 0.1, 0, 3, 5, 1, 0, 6, 2])) == 5.0  # the bump at 1 is under half of 6
    assert first_peak(r, np.array([0, 0, 9, 0, 0, 0, 0, 0, 9, 0])) == 2.0
    assert first_peak(r, np.array([np.nan, 4, 1, 0, 0, 0, 0, 0, 5, 0])) == 1.0
    assert np.isnan(first_peak(r, np.zeros(10)))
    assert np.isnan(first_peak(r, np.full(10, np.nan)))
