"""Micrographs: reading, scale, detection against synthetic truth, the real TEM image, outputs, bad input."""

from __future__ import annotations

import struct
import zlib
from pathlib import Path

import numpy as np
import pytest
from helpers import one_line_error, refused
from PIL import Image
from scipy import ndimage
from skimage.filters import threshold_otsu

from qdots.cli import main
from qdots.io import checkpoint
from qdots.micrograph.detect import detect_dots
from qdots.micrograph.film import complete_neighbourhood, film_metrics, film_state
from qdots.micrograph.measure import measure_image
from qdots.micrograph.read import MAX_PIXELS, read_micrograph
from qdots.micrograph.scale import find_scale_bar, parse_length, scale_from_bar
from qdots.micrograph.synthetic import dense_board, render_micrograph, score_detection, sparse_board

ROOT = Path(__file__).resolve().parents[2]
TEM = ROOT.parent / "shared" / "data" / "micrographs" / "nanoparticle_film_tem.png"


def score(detection, centres, diameters):
    """Recall, precision, median |diameter error| / d and median position error (px) (`score_detection`)."""
    s = score_detection(detection, centres, diameters)
    return s["recall"], s["precision"], s["diameter"], s["position"]


@pytest.mark.parametrize("board", [sparse_board, dense_board])
def test_dots_of_a_synthetic_micrograph_at_moderate_noise_are_found_and_sized(board):
    centres, diameters = board(384, 384, 15.0, 0.1, seed=3)
    image = render_micrograph(centres, diameters, (384, 384), noise=0.05, seed=4)
    detection = detect_dots(image)
    recall, precision, size, position = score(detection, centres, diameters)
    assert recall >= 0.98 and precision >= 0.98
    assert size <= 0.03 if board is dense_board else size <= 0.02
    assert position <= 0.5
    assert detection.dark and "automatic" in detection.polarity
    assert detection.shape == 0.5  # projected spheres recognised


def test_touching_dots_of_7_px_are_split_one_by_one():
    # 7.5 px dots touching (half the sites empty): the blur fills the necks the distance transform needs, so each dot
    # is seeded from its intensity (`blob_seeds`); measured recall 0.984, precision 1.000 (the distance transform's
    # maxima alone: 0.363, 0.652)
    centres, diameters = dense_board(160, 160, 7.5, 0.05, seed=4, vacancies=0.5)
    image = render_micrograph(centres, diameters, (160, 160), noise=0.03, blur=0.8, contrast=0.55, seed=5)
    recall, precision, _, position = score(detect_dots(image), centres, diameters)
    assert recall >= 0.9 and precision >= 0.95 and position <= 0.5


@pytest.mark.parametrize("dark", [True, False])
def test_dense_films_of_small_dots_get_their_polarity_from_the_dots_not_the_vacancies(dark):
    # 7.5 px dots touching, 30 % of the sites empty: the dot phase is one network touching the edge and the vacancies
    # are the only objects away from it, which made dark dots light (and light ones dark), recall 0.00 either way. The
    # Laplacian of Gaussian at the blobs' scale is skewed toward the dots, its sign flipping with the image's; measured
    # recall 0.97 (dark and light), precision 1.00
    centres, diameters = dense_board(160, 160, 7.5, 0.05, seed=2, vacancies=0.3)
    image = render_micrograph(centres, diameters, (160, 160), noise=0.05, blur=0.8, contrast=0.55, dark=dark, seed=1)
    detection = detect_dots(image)
    assert detection.dark == dark and "automatic" in detection.polarity
    recall, precision, _, _ = score(detection, centres, diameters)
    assert recall >= 0.8 and precision >= 0.9



@pytest.mark.parametrize("dark", [True, False])
def test_dense_films_of_flat_discs_get_their_polarity_from_the_way_the_edges_bend(dark):
    # Notebook 06's film without the shared image: 30 px flat discs, 30 % of the sites empty. The vacancies, light
    # blobs of a dot's size ringed by dots, skewed the Laplacian of Gaussian toward light (-0.36): the gaps were
    # measured as 150 dots of 36 px, refused as not a film. The edges still curve around the dots (86 %)
    centres, diameters = dense_board(300, 300, 30.0, 0.1, seed=1, vacancies=0.3)
    image = render_micrograph(centres, diameters, (300, 300), profile=0.0, noise=0.05, dark=dark, seed=2)
    detection = detect_dots(image)
    assert detection.dark == dark and "edge pixels curve" in detection.polarity
    recall, precision, size, _ = score(detection, centres, diameters)
    assert recall >= 0.9 and precision >= 0.95 and size <= 0.03

def test_a_noisy_film_saved_as_8_bit_is_measured_and_clipped_noise_alone_is_not():
    # 16 px dots at noise 0.3 of the background, clipped to [0, 1] and rounded to 8 bits (half the background pixels
    # flattened at white): each dot scores 11-18 noise deviations of its mean (noise alone: about 1, at most 5.0 of
    # 63,696 candidates), but the old median-contrast gate (2.5 pixel-noise deviations) read 2.4 and found no dots
    def eight_bit(image):
        return np.round(np.clip(image, 0.0, 1.0) * 255.0)

    centres, diameters = dense_board(160, 160, 16.0, 0.05, seed=2, vacancies=0.5)
    image = render_micrograph(centres, diameters, (160, 160), noise=0.3, blur=0.8, contrast=0.55, seed=1)
    recall, precision, _, _ = score(detect_dots(eight_bit(image)), centres, diameters)
    assert recall >= 0.9 and precision >= 0.95
    noise = eight_bit(1.0 + 0.3 * np.random.default_rng(3).standard_normal((160, 160)))
    assert detect_dots(noise).n_dots == 0


def test_pixel_noise_is_not_taken_from_small_dots():
    from qdots.micrograph.segment import pixel_noise

    # a superlattice of 6 px dots: their structure is at the scale of a pixel or two, yet the estimate is the noise's
    # (measured within 3 %; the residual of a 1 px Gaussian gave 2.8 times it)
    centres, diameters = dense_board(160, 160, 6.0, 0.05, seed=2, vacancies=0.3)
    noisy, clean = (render_micrograph(centres, diameters, (160, 160), noise=noise, blur=0.8, seed=3)
                    for noise in (0.03, 0.0))
    assert np.std(noisy - clean) > 0.01
    assert pixel_noise(noisy, np.zeros(noisy.shape, dtype=bool)) == pytest.approx(np.std(noisy - clean), rel=0.1)


def test_light_dots_flat_discs_and_uneven_light_are_measured():
    centres, diameters = sparse_board(320, 320, 18.0, 0.12, seed=5)
    image = render_micrograph(centres, diameters, (320, 320), profile=0.0, dark=False, illumination=0.5,
                              noise=0.03, seed=6)
    detection = detect_dots(image)
    assert not detection.dark and detection.polarity.startswith("light dots (automatic")
    assert detection.shape == 0.0
    recall, precision, size, position = score(detection, centres, diameters)
    assert recall >= 0.98 and precision >= 0.98 and size <= 0.03 and position <= 0.5
    given = detect_dots(image, polarity="light", profile="disc")
    assert given.polarity == "light dots (given)" and given.profile == "disc (given)"


def test_cut_dots_are_flagged_and_kept_out_of_neighbourhood_metrics():
    centres = np.array([[5.0, 50.0], [60.0, 60.0], [75.0, 60.0], [67.5, 73.0]])
    diameters = np.full(4, 15.0)
    detection = detect_dots(render_micrograph(centres, diameters, (120, 120), noise=0.01, seed=1))
    assert detection.n_dots == 4
    order = np.argsort(detection.centres[:, 0])
    assert detection.cut[order].tolist() == [True, False, False, False]
    state = film_state(detection.centres, detection.diameters, detection.image_shape)
    complete = complete_neighbourhood(state)
    assert not complete[order[0]] and complete[order[1:]].all()
    metrics = film_metrics(state, measured=~detection.cut, complete=complete)
    assert metrics["dots_sized"] == 3 and metrics["dots_complete"] == 3
    assert metrics["mean_neighbours"] == pytest.approx(2.0)  # the triangle; the cut dot is far from it


def test_a_frame_around_the_image_is_not_picture():
    centres, diameters = sparse_board(200, 200, 15.0, 0.05, seed=2)
    image = render_micrograph(centres, diameters, (200, 200), noise=0.02, seed=2)
    framed = np.pad(image, 4, constant_values=0.0)
    detection = detect_dots(framed)
    assert detection.window == (4, 4, 204, 204)
    recall, precision, _, position = score(detection, centres + 4.0, diameters)
    assert recall >= 0.98 and precision >= 0.98 and position <= 0.5


def test_a_scale_bar_is_found_measured_and_left_out():
    centres, diameters = sparse_board(300, 300, 15.0, 0.05, seed=7)
    image = render_micrograph(centres, diameters, (300, 300), noise=0.02, seed=7)
    image[270:276, 180:280] = image.min() - 0.2  # a solid black bar 100 px long
    bar = find_scale_bar(image)
    assert bar.length_px == pytest.approx(100, abs=0.2) and bar.box == (180, 270, 280, 276) and bar.dark
    nm_per_px = scale_from_bar(bar, "0.5um")
    assert nm_per_px == pytest.approx(5.0, rel=1e-3)
    assert parse_length("200 nm") == 200.0 and parse_length("2µm") == 2000.0 and parse_length("15A") == 1.5
    detection = detect_dots(image, ignore=bar.mask(image.shape))
    x, y = detection.centres.T
    assert not np.any((x > 178) & (x < 282) & (y > 268) & (y < 278))  # the bar is not a row of dots
    clear = np.hypot(np.clip(centres[:, 0], 180, 280) - centres[:, 0], np.clip(centres[:, 1], 270, 276)
                     - centres[:, 1]) > diameters
    recall = score(detection, centres[clear], diameters[clear])[0]
    assert recall >= 0.98


@pytest.mark.parametrize("seed", range(6))
def test_bright_noise_near_saturation_is_no_scale_bar_and_a_drawn_bar_on_it_is_one(seed):
    """An 8-bit film whose bright background (238 +- 8) saturates: the pixels near the lightest value, joined by the
    closing of a ruled bar's cuts, made 10-11 px "bars" of noise on 3 of these 6 (and on two real pictures without a
    bar, 13 and 16 px). A bar stands out of its surroundings by many noise deviations; noise does not."""
    centres, diameters = sparse_board(300, 300, 15.0, 0.25, coverage=0.1, seed=seed)
    clean = render_micrograph(centres, diameters, (300, 300), noise=0.0, seed=seed + 10)
    noise = np.random.default_rng(seed).normal(0.0, 8.0, clean.shape)
    image = np.clip(np.round(40 + 198 * (clean - clean.min()) / np.ptp(clean) + noise), 0, 255)
    assert find_scale_bar(image) is None
    image[280:284, 200:260] = 255  # a white bar drawn on it
    bar = find_scale_bar(image)
    assert bar is not None and bar.box == (200, 280, 260, 284) and bar.length_px == pytest.approx(60, abs=1)


def bar_on_film(shape: tuple[int, int], seed: int, rows: slice, cols: slice):
    """`find_scale_bar` on a sparse film of ``shape`` with a block darker than every dot drawn at ``rows``, ``cols``."""
    centres, diameters = sparse_board(shape[1], shape[0], 15.0, 0.05, seed=seed)
    image = render_micrograph(centres, diameters, shape, noise=0.02, seed=seed)
    image[rows, cols] = image.min() - 0.2
    return find_scale_bar(image)


def test_an_upright_bar_is_no_scale_bar_and_a_thick_one_along_the_rows_is_one():
    """Scale bars are drawn along the rows: on 88 real pictures of the development halves every one is, and the three
    upright "bars" taken before were a panel label's "1" and two dark gaps between touching particles. A solid bar
    4.5 times longer than thick (a journal figure's "1 um" bar, 72 x 16 px) was missed while a bar had to be 5 times."""
    assert bar_on_film((300, 300), 7, slice(150, 230), slice(20, 28)) is None
    bar = bar_on_film((300, 300), 7, slice(270, 286), slice(180, 252))
    assert bar is not None and bar.box == (180, 270, 252, 286) and bar.length_px == pytest.approx(72, abs=0.5)


def test_a_bar_shorter_than_a_twentieth_of_the_picture_is_no_scale_bar():
    """A scale bar is drawn to be read (a tenth to a quarter of the picture's side on the real pictures measured):
    a bright 10 px run on a sphere's rim and a particle cut by the edge were taken for bars before. On a 544 x 512
    film a drawn bar of 26 px (under 27.2) is none, one of 28 px is; on a 200 px picture the 10 px floor holds."""
    from qdots.micrograph.scale import shortest_bar

    assert shortest_bar((512, 544)) == pytest.approx(27.2) and shortest_bar((150, 200)) == 10.0
    assert bar_on_film((512, 544), 3, slice(490, 494), slice(500, 526)) is None
    bar = bar_on_film((512, 544), 3, slice(490, 494), slice(500, 528))
    assert bar is not None and bar.box == (500, 490, 528, 494)
    refused(lambda: scale_from_bar(None, "20nm"), "0.05 of the picture's longer side")


@pytest.mark.parametrize("text", ["200", "nm", "-5nm", "0nm", "200 parsec", "1e999nm", "1e-300nm", "1e300 um"])
def test_bad_scale_bar_lengths_are_refused(text):
    refused(lambda: parse_length(text), "scale_bar")


def test_tiff_pages_depths_and_imagej_scale_are_read(tmp_path):
    tifffile = pytest.importorskip("tifffile")
    centres, diameters = sparse_board(160, 160, 15.0, 0.05, seed=8)
    image = render_micrograph(centres, diameters, (160, 160), noise=0.02, seed=8)
    as16 = np.clip(image * 40000, 0, 65535).astype(np.uint16)
    path = tmp_path / "film.tif"
    tifffile.imwrite(path, np.stack([as16, as16[::-1]]), imagej=True, resolution=(1 / 0.8, 1 / 0.8),
                     metadata={"unit": "nm"})
    first = read_micrograph(path)
    assert first.pages == 2 and first.nm_per_px == pytest.approx(0.8) and first.shape == (160, 160)
    np.testing.assert_array_equal(read_micrograph(path, page=1).pixels, as16[::-1].astype(float))
    plain = tmp_path / "plain8.tif"
    tifffile.imwrite(plain, (image * 200).clip(0, 255).astype(np.uint8))
    assert read_micrograph(plain).nm_per_px is None
    refused(lambda: read_micrograph(path, page=2), "page")
    film = measure_image(path, nm_per_px=2.0, lqe=False)  # the file's own scale wins, and the table says so
    assert film.nm_per_px == pytest.approx(0.8) and "not used" in film.summary["scale"]
    refused(lambda: measure_image(path, nm_per_px=-1.0, lqe=False), "nm_per_px")


@pytest.mark.parametrize("tag, text, words", [
    (34682, "[User]\nDate=01/01/2020\n[Scan]\nPixelWidth=4.466e-09\nPixelHeight=4.466e-09\n", "FEI/Thermo tag"),
    (34118, "0\n1\nAP_IMAGE_PIXEL_SIZE\nImage Pixel Size = 4.466 nm\nDP_DETECTOR_TYPE\nDetector = SE2\n",
     "Zeiss SEM tag (Image Pixel Size 4.466 nm)")])
def test_the_pixel_size_an_instrument_writes_in_its_tiff_tag_is_read_and_named(tmp_path, tag, text, words):
    tifffile = pytest.importorskip("tifffile")
    pixels = (np.random.default_rng(0).random((40, 40)) * 255).astype(np.uint8)
    tifffile.imwrite(tmp_path / "sem.tif", pixels, extratags=[(tag, "s", 0, text, True)])
    m = read_micrograph(tmp_path / "sem.tif")
    assert m.nm_per_px == pytest.approx(4.466) and words in m.scale_source


def test_a_microscope_file_is_read_with_its_calibration(tmp_path):
    pytest.importorskip("h5py")
    emd = pytest.importorskip("rsciio.emd")
    data = np.random.default_rng(0).random((64, 80)).astype(np.float32)
    axes = [{"name": name, "size": size, "scale": 0.025, "offset": 0.0, "units": "µm", "navigate": False}
            for name, size in (("y", 64), ("x", 80))]
    emd.file_writer(str(tmp_path / "film.emd"), {"data": data, "axes": axes, "metadata": {"General": {"title": "f"}, "Signal": {"signal_type": ""}},
                                                  "original_metadata": {}})
    m = read_micrograph(tmp_path / "film.emd")
    assert m.shape == (64, 80) and m.nm_per_px == pytest.approx(25.0)
    np.testing.assert_allclose(m.pixels, data)


def test_colour_jpeg_is_read_as_grey(tmp_path):
    rgb = np.zeros((40, 50, 3), dtype=np.uint8)
    rgb[..., 0], rgb[..., 1], rgb[..., 2] = 30, 60, 90
    rgb[10:20, 10:20] = 200
    Image.fromarray(rgb).save(tmp_path / "c.jpg", quality=95)
    m = read_micrograph(tmp_path / "c.jpg")
    assert m.shape == (40, 50) and abs(m.pixels[0, 0] - 60) < 3 and abs(m.pixels[15, 15] - 200) < 3


def png_declaring(width: int, height: int) -> bytes:
    """A PNG header that declares ``width`` x ``height`` grey pixels and holds none."""
    def chunk(kind: bytes, data: bytes) -> bytes:
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF)
    return (b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", width, height, 8, 0, 0, 0, 0))
            + chunk(b"IEND", b""))


def test_bad_images_are_refused_in_one_line(tmp_path):
    (tmp_path / "text.png").write_text("not an image")
    refused(lambda: read_micrograph(tmp_path / "text.png"), "not a readable image")
    good = tmp_path / "good.png"
    Image.fromarray((np.random.default_rng(0).random((64, 64)) * 255).astype(np.uint8)).save(good)
    (tmp_path / "cut.png").write_bytes(good.read_bytes()[:200])
    refused(lambda: read_micrograph(tmp_path / "cut.png"), "not a readable image")
    (tmp_path / "zero.png").write_bytes(png_declaring(0, 0))
    refused(lambda: read_micrograph(tmp_path / "zero.png"), "not a readable image")
    Image.fromarray(np.zeros((1, 30), dtype=np.uint8)).save(tmp_path / "line.png")
    refused(lambda: read_micrograph(tmp_path / "line.png"), "30 x 1 px", "at least 16 x 16")
    Image.fromarray(np.array([[0, 255], [128, 30]], dtype=np.uint8)).save(tmp_path / "two.png")
    refused(lambda: read_micrograph(tmp_path / "two.png"), "2 x 2 px", "at least 16 x 16")
    Image.fromarray(np.full((20, 20), 7, dtype=np.uint8)).save(tmp_path / "flat.png")
    refused(lambda: read_micrograph(tmp_path / "flat.png"), "every pixel has the value 7")
    for side, words in ((100_000, ("more than",)), (9000, ("9000 x 9000",))):
        (tmp_path / "huge.png").write_bytes(png_declaring(side, side))
        refused(lambda: read_micrograph(tmp_path / "huge.png"), *words)
    assert 9000 * 9000 > MAX_PIXELS
    tifffile = pytest.importorskip("tifffile")
    tifffile.imwrite(tmp_path / "nan.tif", np.full((20, 20), np.nan, dtype=np.float32))
    refused(lambda: read_micrograph(tmp_path / "nan.tif"), "every pixel is NaN")
    with pytest.raises(FileNotFoundError, match="missing.png"):
        read_micrograph(tmp_path / "missing.png")


@pytest.mark.parametrize("scale", [0.0, -1.0, float("nan"), float("inf"), 1e-300, 1e300])
def test_bad_scales_are_refused(tmp_path, scale):
    centres, diameters = sparse_board(100, 100, 12.0, 0.05, seed=1)
    path = tmp_path / "f.png"
    Image.fromarray((render_micrograph(centres, diameters, (100, 100), seed=1) * 200).clip(0, 255)
                    .astype(np.uint8)).save(path)
    refused(lambda: measure_image(path, nm_per_px=scale, lqe=False), "nm_per_px")


def test_an_image_without_dots_or_scale_bar_writes_nothing(tmp_path, capsys):
    noise = (np.random.default_rng(1).normal(128, 5, (128, 128))).clip(0, 255).astype(np.uint8)
    Image.fromarray(noise).save(tmp_path / "empty.png")
    out = tmp_path / "out"
    assert main(["measure", str(tmp_path / "empty.png"), "--out", str(out)]) == 2
    assert "no dots found" in one_line_error(capsys)
    assert not out.exists()
    assert main(["measure", str(tmp_path / "empty.png"), "--out", str(out), "--scale-bar", "100nm"]) == 2
    assert "no scale bar found" in one_line_error(capsys)
    assert not out.exists()


def test_measure_writes_a_state_analyze_and_render_read(tmp_path, capsys):
    centres, diameters = dense_board(240, 200, 14.0, 0.1, seed=9)
    image = render_micrograph(centres, diameters, (200, 240), noise=0.04, seed=9)
    Image.fromarray((image * 220).clip(0, 255).astype(np.uint8)).save(tmp_path / "film.png")
    out = tmp_path / "out"
    printed = capsys.readouterr() if main(["measure", str(tmp_path / "film.png"), "--out", str(out),
                                           "--nm-per-px", "0.5"]) == 0 else pytest.fail("measure failed")
    assert "interior fraction" in printed.out and "0.5 nm/px (given)" in printed.out
    out = out / "film"  # the measurement's folder
    assert sorted(p.name for p in out.iterdir()) == ["film.npz", "film_detections.png", "film_summary.csv"]
    state = checkpoint.read_state(out / "film.npz")
    metadata = checkpoint.read_metadata(out / "film.npz")["micrograph"]
    assert metadata["nm_per_px"] == 0.5 and metadata["image"] == "film.png"
    assert np.all(state.velocities == 0) and state.box == (240.0, 200.0)
    assert main(["analyze", str(out / "film.npz")]) == 0
    assert main(["render", str(out / "film.npz"), "--out", str(tmp_path / "r.png")]) == 0
    assert (tmp_path / "r.png").stat().st_size > 0


def test_compare_runs_the_matching_experiment(tmp_path, capsys):
    from qdots.io.experiment_file import load_experiment

    centres, diameters = sparse_board(200, 200, 15.0, 0.1, coverage=0.3, seed=10)
    image = render_micrograph(centres, diameters, (200, 200), noise=0.03, seed=10)
    Image.fromarray((image * 220).clip(0, 255).astype(np.uint8)).save(tmp_path / "film.png")
    args = [str(tmp_path / "film.png"), "--nm-per-px", "2", "--dots", "12", "--seeds", "2", "--engine", "event"]
    assert main(["compare", *args, "--out", str(tmp_path / "one"), "--workers", "1"]) == 0
    out = tmp_path / "cmp"
    assert main(["compare", *args, "--out", str(out), "--workers", "2"]) == 0  # each seed in its own process
    printed = capsys.readouterr().out
    assert "image" in printed and "simulation" in printed and "+-" in printed
    out = out / "film_compare"  # the comparison's folder
    names = sorted(p.name for p in out.iterdir())
    assert names == ["film.npz", "film_compare.csv", "film_compare.png", "film_compare.toml", "film_detections.png",
                     "film_sim-154.npz", "film_sim-155.npz", "film_summary.csv"]
    for name in names:  # the same files, byte for byte, whether the seeds ran in one process or two
        assert (out / name).read_bytes() == (tmp_path / "one" / "film_compare" / name).read_bytes(), name
    exp = load_experiment(out / "film_compare.toml")
    assert exp.deposition.n_dots == 12 and exp.deposition.mass_model == "volume" and exp.engine.kind == "event"
    assert exp.deposition.sigma == pytest.approx(0.1, abs=0.03)
    assert checkpoint.load(out / "film_sim-155.npz").state().n_dots == 12


# -- the real micrograph ---------------------------------------------------------------------------------------------
# Tolerances established by hand once, on the image itself (no ground truth comes with it):
# * Count: two 300 x 300 px crops counted by eye on an enlarged picture: x 600-900, y 0-300 px holds 54
#   particles, x 300-600, y 400-700 px holds 41 (fused pairs counted as two where a waist shows).
# * Diameter: ten particles with background on both sides, picked by eye in the first crop; each one's
#   half-contrast width (halfway between its core and the background, both read off the Gaussian-smoothed
#   image) measured along a row and a column, and the width along the line that crosses no neighbour kept.
# * Scale: the bar is 127 px long (read off the image).
HAND_COUNTS = {(600, 900, 0, 300): 54, (300, 600, 400, 700): 41}
HAND_WIDTHS = {(691, 236): 29.0, (680, 264): 31.9, (818, 154): 30.9, (850, 242): 29.85, (763, 250): 30.4,
               (628, 138): 31.0, (705, 87): 32.7, (678, 39): 28.95, (647, 42): 28.3, (708, 206): 33.8}


@pytest.fixture(scope="module")
def tem_film():
    if not TEM.exists():
        pytest.skip(f"the shared test micrograph is not beside the project ({TEM.name})")
    return measure_image(TEM, scale_bar="200nm")


def test_the_real_micrograph_matches_counts_and_sizes_taken_by_hand(tem_film):
    film = tem_film
    assert film.bar.length_px == pytest.approx(127.5, abs=0.5) and film.nm_per_px == pytest.approx(200 / 127.5, rel=0.005)
    assert film.detection.dark and film.detection.shape == 0.0  # flat dark discs
    centres = film.detection.centres
    for (x0, x1, y0, y1), hand in HAND_COUNTS.items():
        found = int(np.sum((centres[:, 0] >= x0) & (centres[:, 0] < x1) & (centres[:, 1] >= y0) & (centres[:, 1] < y1)))
        assert abs(found - hand) <= 0.1 * hand, (found, hand)
    measured = []
    for (x, y), width in HAND_WIDTHS.items():
        distance = np.hypot(centres[:, 0] - x, centres[:, 1] - y)
        k = int(np.argmin(distance))
        assert distance[k] < 3.0
        assert abs(film.detection.diameters[k] - width) <= 0.06 * width, ((x, y), film.detection.diameters[k], width)
        measured.append(film.detection.diameters[k])
    assert np.mean(measured) == pytest.approx(np.mean(list(HAND_WIDTHS.values())), rel=0.03)
    s = film.summary
    assert s["mean_diameter_nm"] == pytest.approx(np.mean(list(HAND_WIDTHS.values())) * 200 / 127, rel=0.06)
    assert s["dots_cut_by_edge"] > 20
    # coverage against an independent measure: the share of pixels (above the scale bar's rows) darker than halfway
    # between the background and the particles' cores, which is a flat disc's edge; the union of the fitted discs
    # covers a little less (irregular and fused particles stick out of their discs)
    picture = ndimage.gaussian_filter(film.image.pixels[:820], 1.0)
    split = threshold_otsu(picture)
    half = 0.5 * (np.median(picture[picture > split]) + np.median(picture[picture < split]))
    assert 0.8 * np.mean(picture < half) < s["coverage"] < 1.05 * np.mean(picture < half)


def test_the_real_micrograph_overlay_is_written(tem_film, tmp_path):
    from qdots.micrograph.overlay import save_overlay

    path = save_overlay(tem_film, tmp_path / "tem_detections.png")
    with Image.open(path) as picture:
        assert picture.size[0] >= 900 and picture.size[1] >= 900
        grey = np.asarray(picture.convert("RGB"), dtype=float)
    assert grey.std() > 20  # a picture, not a blank page


def test_coverage_is_the_union_of_the_discs_on_the_pixel_grid():
    from dataclasses import replace

    base = detect_dots(render_micrograph([[50.0, 50.0]], [20.0], (100, 100), noise=0.01, seed=1))
    one = replace(base, centres=np.array([[50.0, 50.0]]), diameters=np.array([20.0]))
    assert one.coverage() == pytest.approx(np.pi * 100 / 10_000, rel=0.02)
    twice = replace(base, centres=np.array([[50.0, 50.0], [50.0, 50.0], [0.0, 0.0]]),
                    diameters=np.array([20.0, 20.0, 20.0]))  # a repeat adds nothing; a corner disc a quarter
    assert twice.coverage() == pytest.approx(1.25 * np.pi * 100 / 10_000, rel=0.02)


def test_huge_spacings_and_radii_allocate_nothing_past_the_image():
    """Regression (a calibration film in the slow suite): a typical radius far past the image asked
    `spaced_maxima` for a footprint of billions of pixels (MemoryError). The spacing is now bounded by the image,
    and `missed_dots` does not search when the dots are that big."""
    from types import SimpleNamespace

    from qdots.micrograph.missed import missed_dots
    from qdots.micrograph.segment import spaced_maxima

    values = np.zeros((40, 50))
    values[10, 20] = 1.0
    assert spaced_maxima(values, 10**9, 0.5).tolist() == [[10, 20]]
    refined = SimpleNamespace(contrast=np.array([0.5]), radius=np.array([1e6]), centres=np.array([[20.0, 20.0]]),
                              model=np.zeros((40, 50)))
    assert missed_dots(np.ones((40, 50)), refined, np.ones((40, 50)), 1e6, 0.5, 1.0, 0.01).shape == (0, 2)


@pytest.mark.parametrize("shape", [(50, 70), (13, 17), (300, 5), (1, 9)])
def test_disc_maximum_is_the_footprint_maximum_filter(shape):
    from scipy import ndimage

    from qdots.micrograph.segment import disc_maximum

    rng = np.random.default_rng(sum(shape))
    for radius in (1, 2, 3, 5, 11, 22, 40):
        if radius >= min(shape):
            continue
        values = rng.normal(size=shape)
        values[rng.random(shape) < 0.1] = -np.inf
        y, x = np.ogrid[-radius:radius + 1, -radius:radius + 1]
        oracle = ndimage.maximum_filter(values, footprint=x * x + y * y <= radius * radius)
        np.testing.assert_array_equal(disc_maximum(values, radius), oracle)


def test_spaced_maxima_of_big_objects_need_no_footprint_memory():
    """Regression: a noisy drawing enlarged 5x (1200 x 1600 px, objects ~100 px across) made `missed_dots` ask
    for maxima 150 px apart, and scipy's footprint filter for gigabytes (MemoryError; a radius of 120 px over that
    image takes 116 s and 20 GB). `disc_maximum` needs memory for the pixels alone."""
    from qdots.micrograph.segment import spaced_maxima

    values = np.random.default_rng(3).normal(size=(600, 800))
    values[300, 400] = 10.0
    peaks = spaced_maxima(values, 150, 0.0)
    assert [300, 400] in peaks.tolist()
    gaps = np.hypot(*(peaks[:, None, :] - peaks[None, :, :]).T)
    assert gaps[np.triu_indices(len(peaks), 1)].min() > 150


def test_a_dot_under_another_that_covers_left_out_pixels_is_cut():
    """Regression: which dots cover pixels left out (a label's letters) was read off a picture of the discs painted in
    turn, so a small dot painted over by a larger neighbour was never flagged: two dots found on the "1.0 um" label of
    an SEM picture were taken as whole (stacked on the spheres beside them)."""
    from qdots.micrograph.detect import cut_dots

    ignore = np.zeros((100, 100), dtype=bool)
    ignore[40:45, 40:45] = True
    centres = np.array([[42.0, 42.0], [45.0, 45.0], [80.0, 80.0]])
    cut = cut_dots(centres, np.array([6.0, 30.0, 10.0]), (0, 0, 100, 100), ignore)
    np.testing.assert_array_equal(cut, [True, True, False])
