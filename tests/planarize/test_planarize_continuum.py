"""The continuum engine: its kernels against plain numpy, its physics on exact cases, its agreement with
the thesis's algorithm as that one's grid refines, and its stated error against the true one."""

from __future__ import annotations

import math

import numpy as np
import pytest
from helpers import refused

from planarize import Model, Surface, anodize, surfaces
from planarize.engines import Continuum
from planarize.engines.continuum import ContinuumEngine, resample
from planarize.engines.flow import GHOST, fill_ghosts, metal_rate
from planarize.engines.offset import coat, extremes, surface_moments

RNG = np.random.default_rng(5)


# -- kernels against numpy ----------------------------------------------------------------------

def moments_by_triangles(z, periodic):
    """Mean and RMS of the four-triangles-per-cell surface, by summing each triangle's exact integrals."""
    if periodic:
        z = np.pad(z, ((0, 1), (0, 1)), mode="wrap")
    a, b, c, d = z[:-1, :-1], z[1:, :-1], z[1:, 1:], z[:-1, 1:]
    m = (a + b + c + d) / 4
    first = second = 0.0
    for p, q, r in ((m, a, b), (m, b, c), (m, c, d), (m, d, a)):
        first += ((p + q + r) / 3).sum()
        second += ((p * p + q * q + r * r + p * q + q * r + r * p) / 6).sum()
    cells = 4 * a.size
    mean = first / cells
    return mean, np.sqrt(second / cells - mean ** 2)


@pytest.mark.parametrize("periodic", [False, True])
def test_surface_moments_are_the_integrals_over_the_triangles(periodic):
    z = 3.0 + RNG.normal(size=(7, 5))
    mean, rms = surface_moments(z, periodic)
    expected = moments_by_triangles(z, periodic)
    assert mean == pytest.approx(expected[0], rel=1e-12) and rms == pytest.approx(expected[1], rel=1e-10)
    assert surface_moments(np.full((4, 4), 2.5), periodic) == pytest.approx((2.5, 0.0))


def test_extremes_find_the_top_of_a_sampled_parabola():
    x = np.arange(9) * 0.5
    z = 1.0 - (x[:, None] - 2.2) ** 2 - 0.5 * (x[None, :] - 1.9) ** 2  # top 1.0 between grid points
    high, low = extremes(z, False)
    assert high == pytest.approx(1.0, abs=1e-12) and low == z.min()  # the low corner is no vertex


def brute_dilation(z, t, dx, dy):
    """max over grid points x of z(x) + sqrt(t^2 - |x - y|^2), an open grid mirrored about its edges."""
    nx, ny = z.shape
    r = int(np.ceil(t / min(dx, dy))) + 1
    mirrored = np.pad(z, r, mode="reflect")
    best = np.full(z.shape, -np.inf)
    for a in range(-r, r + 1):
        for b in range(-r, r + 1):
            d2 = (a * dx) ** 2 + (b * dy) ** 2
            if d2 <= t * t:
                best = np.maximum(best, mirrored[r + a:r + a + nx, r + b:r + b + ny] + np.sqrt(t * t - d2))
    return best


def dilate(z, t, dx, dy, periodic=False, window=None):
    nx, ny = z.shape
    ii, jj = np.indices(z.shape)
    out = np.empty_like(z)
    fi, fj = np.empty_like(ii), np.empty_like(jj)
    window = int(np.ceil(t / min(dx, dy))) + 1 if window is None else window
    coat(z, t, dx, dy, periodic, window, ii.astype(np.int64), jj.astype(np.int64), np.full(z.shape, -np.inf), out,
         fi, fj, 0, nx)
    return out


def analytic_dilation(f, x, t):
    """The dilation of the surface ``f(x, y)`` by a ball of radius ``t`` at the grid ``x`` x ``x``, by brute
    force on a grid of t / 24 (which the coat of the coarse samples must approach)."""
    h = t / 24
    r = int(np.ceil(t / h))
    offsets = np.arange(-r, r + 1) * h
    d2 = offsets[:, None] ** 2 + offsets[None, :] ** 2
    cap = np.where(d2 <= t * t, np.sqrt(np.maximum(t * t - d2, 0)), -np.inf)
    return np.array([[np.max(f(a + offsets[:, None], b + offsets[None, :]) + cap) for b in x] for a in x])


def test_coat_is_the_dilation_by_a_ball_to_sub_grid_accuracy():
    def f(x, y):
        return 0.3 * np.sin(x) * np.cos(0.7 * y)

    x = np.arange(21) * 0.25
    z = f(x[:, None], x[None, :])
    for t in (0.1, 0.6, 1.3):
        truth = analytic_dilation(f, x, t)
        inner = slice(6, -6)  # (the coat mirrors the grid about its edges, the analytic surface goes on)
        grid_error = np.abs(brute_dilation(z, t, 0.25, 0.25) - truth)[inner, inner].max()
        coat_error = np.abs(dilate(z, t, 0.25, 0.25) - truth)[inner, inner].max()
        assert coat_error < 2e-3 and coat_error < grid_error / 2, (t, coat_error, grid_error)
    plane = 4.0 + 0.3 * x[:, None] - 0.2 * x[None, :]
    found = dilate(plane, 0.8, 0.25, 0.25)
    inner = found[5:-5, 5:-5]  # away from the mirrored edges the coat of a plane is the plane moved out by t
    np.testing.assert_allclose(inner, plane[5:-5, 5:-5] + 0.8 * np.sqrt(1 + 0.3 ** 2 + 0.2 ** 2), atol=1e-12)


def numpy_rate(z, dx, dy, t, k_exp):
    """dM/dt of the thesis's rule (`planarize.engines.flow`) written with numpy, an open grid mirrored."""
    p = np.pad(z, 2, mode="reflect")
    c = p[2:-2, 2:-2]
    xm, xp, ym, yp = p[1:-3, 2:-2], p[3:-1, 2:-2], p[2:-2, 1:-3], p[2:-2, 3:-1]
    zx, zy = (xp - xm) / (2 * dx), (yp - ym) / (2 * dy)
    zxx, zyy = (xp - 2 * c + xm) / dx ** 2, (yp - 2 * c + ym) / dy ** 2
    zxy = (p[3:-1, 3:-1] - p[3:-1, 1:-3] - p[1:-3, 3:-1] + p[1:-3, 1:-3]) / (4 * dx * dy)
    g = 1 + zx ** 2 + zy ** 2
    mean = -((1 + zy ** 2) * zxx - 2 * zx * zy * zxy + (1 + zx ** 2) * zyy) / (2 * g ** 1.5)
    gauss = (zxx * zyy - zxy ** 2) / g ** 2
    root = np.sqrt(np.maximum(mean ** 2 - gauss, 0))
    k1, k2 = mean + root, mean - root
    jac = np.where(1 + t * k2 <= 0, 0.0, (1 + t * k1) * (1 + t * k2))
    total = jac + k_exp - 1
    speed = np.divide(jac, total, out=np.zeros_like(jac), where=total > 0)  # below a crease without expansion: 0

    def slope2(m2, m1, c, p1, p2, h):
        def minmod(a, b):
            return np.where(np.abs(a) < np.abs(b), a, b)
        dm = (c - m1) / h + 0.5 * minmod(c - 2 * m1 + m2, p1 - 2 * c + m1) / h
        dp = (p1 - c) / h - 0.5 * minmod(p1 - 2 * c + m1, p2 - 2 * p1 + c) / h
        return np.maximum(dm, 0) ** 2 + np.minimum(dp, 0) ** 2

    sx = slope2(p[:-4, 2:-2], xm, c, xp, p[4:, 2:-2], dx)
    sy = slope2(p[2:-2, :-4], ym, c, yp, p[2:-2, 4:], dy)
    return -speed * np.sqrt(1 + sx + sy)


def test_metal_rate_is_the_flow_written_with_numpy():
    z = 2.0 + 0.2 * RNG.normal(size=(9, 7))
    padded = np.zeros((9 + 2 * GHOST, 7 + 2 * GHOST))
    padded[GHOST:-GHOST, GHOST:-GHOST] = z
    fill_ghosts(padded, False)
    rate, stiff = np.empty(z.shape), np.zeros(9)
    metal_rate(padded, 0.3, 0.4, 0.7, 2.3, -1.0, rate, stiff, 0, 9)
    np.testing.assert_allclose(rate, numpy_rate(z, 0.3, 0.4, 0.7, 2.3), rtol=1e-12)
    metal_rate(padded, 0.3, 0.4, 6.0, 1.0, -1.0, rate, stiff, 0, 9)  # no expansion, creases where t k2 < -1
    assert np.isfinite(rate).all()
    np.testing.assert_allclose(rate, numpy_rate(z, 0.3, 0.4, 6.0, 1.0), rtol=1e-12)
    metal_rate(padded, 0.3, 0.4, 0.7, 2.3, 0.5, rate, stiff, 0, 9)  # the conformal rule: one normal speed
    assert np.all(rate <= -0.5)


# -- exact cases ------------------------------------------------------------------------------

@pytest.mark.parametrize("boundary", ["open", "periodic"])
def test_a_flat_film_grows_exactly(boundary):
    film = Surface(np.full((9, 9), 4.0), 0.5, boundary)
    run = anodize(film, 2.0, Model(k_exp=2.3), record=4)
    np.testing.assert_allclose(run.metal.z, 4.0 - 2.0 / 2.3, rtol=1e-13)
    np.testing.assert_allclose(run.oxide.z, 4.0 + 2.0 * 1.3 / 2.3, rtol=1e-13)
    assert np.all(run.history["metal_rms_nm"] < 1e-12) and abs(run.history["volume_error"][-1]) < 1e-12
    assert run.parameters["estimated_error"] == 0 and run.parameters["refine"] == 1


def test_a_tilted_plane_keeps_its_shape_away_from_the_edges():
    plane = surfaces.tilted_plane((0.2, -0.1), points=41, spacing=0.25)
    run = anodize(plane, 0.5, record=2, engine=Continuum(refine=1))
    drop = plane.z - run.metal.z
    inner = drop[12:-12, 12:-12]  # the mirrored edges are creases; their effect spreads ~ the thickness
    np.testing.assert_allclose(inner, 0.5 / 2.3 * np.sqrt(1 + 0.2 ** 2 + 0.1 ** 2), rtol=1e-10)


def test_runs_do_not_depend_on_what_they_record_or_on_threads():
    s = surfaces.random_roughness(8.0, thickness=4.0, scales=((2.0, 0.5),), refine=2, boundary="periodic", seed=3)
    settings = Continuum(refine=2)
    a = anodize(s, 0.6, engine=settings, record=3)
    b = anodize(s, 0.6, engine=settings, record=12, snapshots=np.linspace(0, 0.6, 11).tolist())
    c = anodize(s, 0.6, engine=Continuum(refine=2, threads=1), record=3)
    assert a.metal == b.metal == c.metal and a.oxide == b.oxide == c.oxide
    np.testing.assert_array_equal(a.history["oxide_rms_nm"], b.history["oxide_rms_nm"][::4])


def test_resampling_keeps_the_piecewise_linear_surface():
    hill = surfaces.hill()  # 17 x 17: subsampled by 2 it is the hill refined 2x
    assert resample(hill, 0.5) == surfaces.hill(refine=2)
    odd = Surface(RNG.normal(size=(6, 6)), 1.0, "open")  # 5 cells: resampled onto 3 cells of 5/3 nm
    coarse = resample(odd, 0.5)
    assert coarse.shape == (4, 4) and coarse.spacing == pytest.approx((5 / 3, 5 / 3))
    assert coarse.z[0, 0] == odd.z[0, 0] and coarse.z[-1, -1] == odd.z[-1, -1]
    assert resample(hill, 2) == hill.refine(2)


# -- the thesis's algorithm converges to it ------------------------------------------------------

def thesis_gap(refine: int, shape="hill", boundary="open") -> float:
    """Largest relative difference of metal and oxide RMS between the fast engine at ``refine`` and the
    continuum engine (rtol 0.5 %), at every 0.2 nm to 1 nm."""
    cont = anodize(surfaces.bump(4.5 if shape == "hill" else 3.5, boundary=boundary), 1.0, record=5,
                   engine=Continuum(rtol=0.005))
    fine = anodize(surfaces.bump(4.5 if shape == "hill" else 3.5, refine=refine, boundary=boundary), 1.0,
                   Model(step=0.01 if refine < 16 else 0.005), "fast", record=5)
    gap = 0.0
    for column in ("metal_rms_nm", "oxide_rms_nm"):
        gap = max(gap, float(np.max(np.abs(fine.history[column][1:] / cont.history[column][1:] - 1))))
    return gap


def test_the_thesis_algorithm_approaches_it_as_its_grid_refines():
    gaps = [thesis_gap(r) for r in (4, 8)]
    assert gaps[1] < gaps[0] / 2 and gaps[1] < 0.08, gaps


@pytest.mark.slow
@pytest.mark.parametrize("shape", ["hill", "depression"])
@pytest.mark.parametrize("boundary", ["open", "periodic"])
def test_the_thesis_algorithm_agrees_with_it_on_fine_grids(shape, boundary):
    gaps = [thesis_gap(r, shape, boundary) for r in (8, 16)]
    assert gaps[1] < gaps[0] and gaps[1] < 0.04, gaps  # 16x: 65 x 65 points, step 0.005 nm


# -- the error it states --------------------------------------------------------------------

def largest_relative(run, truth, column):
    values = np.asarray(truth[column])
    scale = np.maximum(np.abs(values), 0.01 * abs(values[0]))
    true = np.max(np.abs(run.history[column] - values) / scale)
    stated = np.max(run.history[column.replace("_nm", "_error_nm")] / scale)
    return true, stated


def history_at(surface, thickness, factor, record):
    """An independent run of one resolution (`ContinuumEngine` directly, outside the driver)."""
    from planarize.recording import record_run

    engine = ContinuumEngine(surface, None, Model(), Continuum(), factor)
    rows = np.linspace(0.0, thickness, record + 1)
    return record_run(engine, thickness, rows, np.zeros(0), max_sweeps=10 ** 7)[0]


def test_the_stated_error_is_richardsons_at_the_order_observed_over_three_grids():
    """The hill's default run (4x here): its error columns recomputed by hand from runs at 1/2, 1x, 2x and 4x made
    outside the driver: the observed order from the three finest, Richardson's estimate from the two finest at 1.8
    where that order and the one a grid coarser both reach 1.2 (the hill's `pixel_curvature` is 1.07: a map its
    pixels resolve), else at most 1.5 where both reach 1.5, else at most 1."""
    from planarize.metrics import pixel_curvature

    hill = surfaces.hill()
    run = anodize(hill, 1.0, record=10)
    p = run.parameters
    assert p["refine"] == 4 and p["rtol_met"] and p["asymptotic"] and p["not_asymptotic"] == []
    assert pixel_curvature(hill) == pytest.approx(1.071, abs=1e-3) and p["smooth"]
    assert [level["factor"] for level in p["levels"]] == [0.25, 0.5, 1, 2, 4]
    half, coarse, middle, fine = (history_at(hill, 1.0, f, 10) for f in (0.5, 1, 2, 4))
    taken = []
    for column in ("metal_rms_nm", "oxide_rms_nm", "metal_zrange_nm", "oxide_zrange_nm"):
        np.testing.assert_allclose(run.history[column], fine[column], rtol=1e-12)
        order = np.log2(np.linalg.norm(middle[column] - coarse[column]) / np.linalg.norm(fine[column] - middle[column]))
        before = np.log2(np.linalg.norm(coarse[column] - half[column]) / np.linalg.norm(middle[column] - coarse[column]))
        assert 0.7 <= order <= 3.0 and order == pytest.approx(p["orders"][column], rel=1e-9)
        q = 1.8 if min(order, before) >= 1.2 else min(order, 1.5) if min(order, before) >= 1.5 else min(order, 1.0)
        taken.append(q)
        np.testing.assert_allclose(run.history[column.replace("_nm", "_error_nm")],
                                   np.abs(fine[column] - middle[column]) / (2 ** q - 1), rtol=1e-9, atol=1e-15)
    assert 1.8 in taken and min(taken) < 1.8  # (both branches: the metal RMS observed 0.39 at 2x)


def test_on_a_map_with_pixel_scale_features_the_estimate_takes_the_observed_order_at_most_1_or_1_5():
    """Noise of 0.3 nm on 9 x 9 points smoothed over 0.6 of a pixel (`pixel_curvature` 3.4, a rough map, as measured AFM
    maps are): the default run (8x here) recomputed by hand from runs at 1x, 2x, 4x and 8x: the order at 8x and 4x
    observed, Richardson's estimate at most 1.5 where both reach 1.5 (`ORDER_CAP`) and at most 1 otherwise
    (`ROUGH_ORDER`)."""
    from scipy.ndimage import gaussian_filter

    from planarize.metrics import pixel_curvature

    z = gaussian_filter(np.random.default_rng(1).standard_normal((9, 9)), 0.6)
    rough = Surface(5.0 + 0.3 * z / z.std(), 1.0)
    run = anodize(rough, 1.0, record=10)
    p = run.parameters
    assert 1.3 < pixel_curvature(rough) < 4 and not p["smooth"] and not p["noisy"] and p["refine"] == 8
    assert p["not_asymptotic"] == []
    half, coarse, middle, fine = (history_at(rough, 1.0, f, 10) for f in (1, 2, 4, 8))
    taken = []
    for column in ("metal_rms_nm", "oxide_rms_nm", "metal_zrange_nm", "oxide_zrange_nm"):
        order = np.log2(np.linalg.norm(middle[column] - coarse[column]) / np.linalg.norm(fine[column] - middle[column]))
        before = np.log2(np.linalg.norm(coarse[column] - half[column]) / np.linalg.norm(middle[column] - coarse[column]))
        assert order == pytest.approx(p["orders"][column], rel=1e-9)
        q = min(order, 1.5) if order >= 1.5 and before >= 1.5 else min(order, 1.0)
        taken.append(q)
        np.testing.assert_allclose(run.history[column.replace("_nm", "_error_nm")],
                                   np.abs(fine[column] - middle[column]) / (2 ** q - 1), rtol=1e-9, atol=1e-15)
    assert 1.0 in taken and min(taken) < 1.0  # (both: orders of 0.78-1.4 observed)


def test_on_a_map_whose_pixels_bend_as_noise_does_no_error_is_stated_and_the_grid_refines_only_while_cheap(
        tmp_path, capsys):
    """White noise (pixel curvature 4.9) and a one-pixel pit (sqrt(20) = 4.47) reach `NOISE_CURVATURE`: their
    features are one pixel wide and no affordable grid is asymptotic (on 17 x 17 points the orders of one refinement
    wandered between -1.5 and 4.5 from 1x to 8x), so no error is stated and the run does not claim to meet rtol. A
    finer grid is computed only while it is predicted to take at most `SETTLE_S`; the command line says why no number
    is given."""
    from planarize.cli import main as planarize_main
    from planarize.engines.resolution import NOISE_CURVATURE, SETTLE_S, predicted_seconds
    from planarize.metrics import pixel_curvature

    noise = 5.0 + 0.3 * np.random.default_rng(1).standard_normal((9, 9))
    pit = np.full((9, 9), 4.0)
    pit[4, 4] = 3.0
    for z, spacing in ((noise, 1.0), (pit, 0.25)):
        surface = Surface(z, spacing)
        run = anodize(surface, 1.0, record=10)
        p = run.parameters
        assert pixel_curvature(surface) >= NOISE_CURVATURE and p["noisy"] and not p["smooth"]
        assert p["not_asymptotic"] == ["metal_rms_nm", "metal_zrange_nm", "oxide_rms_nm", "oxide_zrange_nm"]
        assert np.isnan(p["estimated_error"]) and not p["rtol_met"] and not p["asymptotic"]
        assert all(np.isnan(run.history[c]).all() for c in run.history if c.endswith("_error_nm"))
        levels = p["levels"]
        assert levels[-1]["factor"] == p["refine"] >= 2
        if p["refine"] < 8:  # it stopped where the next grid was predicted to take longer than SETTLE_S
            assert predicted_seconds(levels[-2], levels[-1], 4 * levels[-1]["points"], measured=False) > SETTLE_S
    np.save(tmp_path / "pit.npy", pit)
    assert planarize_main(["import", str(tmp_path / "pit.npy"), "--thickness", "1", "--unit", "nm", "--spacing",
                           "0.25", "--out", str(tmp_path / "out")]) == 0
    printed = " ".join(capsys.readouterr().out.split())
    assert ("not stated: the map bends from pixel to pixel as white noise does (pixel curvature 4.5, at least 4)"
            in printed), printed


def test_the_estimate_takes_a_high_order_only_where_it_was_observed_twice_running():
    from planarize.engines.resolution import estimate_order

    assert estimate_order(2.2, 1.8) == 1.5  # a smooth surface in its asymptotic regime
    assert estimate_order(2.2, 1.2) == estimate_order(1.3, 2.5) == 1.0
    assert estimate_order(2.2, math.nan) == 1.5 and estimate_order(1.3, math.nan) == 1.3  # no order one grid coarser
    assert estimate_order(0.8, 2.0) == 0.8  # a low order is taken as it is
    # on a map its pixels resolve, an order of 1.2 or more twice running (once on the reported grid) is taken as 1.8
    assert estimate_order(1.25, 1.3, smooth=True) == estimate_order(2.9, math.nan, smooth=True) == 1.8
    assert estimate_order(1.25, 1.1, smooth=True) == 1.0 and estimate_order(0.9, math.nan, smooth=True) == 0.9


def test_a_quantity_that_changed_by_more_than_a_tenth_is_not_asymptotic_whatever_its_order():
    """Richardson's expansion is one of small changes: a quantity the last refinement moved by more than
    `ASYMPTOTIC_CHANGE` (0.1) of its value gets no number even at a steady order (a one-pixel checkerboard stated
    117-125 % where the truth was 30-46 %); one moved by less keeps its estimate."""
    from planarize.engines.resolution import ASYMPTOTIC_CHANGE, error_columns
    from planarize.metrics import ESTIMATED

    assert ASYMPTOTIC_CHANGE == 0.1
    fine = {c: np.array([10.0, 8.0]) for c in ESTIMATED}
    middle = {c: np.array([10.0, 8.0 + d]) for c, d in zip(ESTIMATED, (0.4, 0.79, 0.81, 3.0))}
    orders = dict.fromkeys(ESTIMATED, 1.0)
    errors = error_columns(fine, middle, orders, 2.0)
    np.testing.assert_allclose(errors["metal_rms_error_nm"], [0.0, 0.4])
    np.testing.assert_allclose(errors["metal_zrange_error_nm"], [0.0, 0.79])  # (9.9 % of 8)
    assert np.isnan(errors["oxide_rms_error_nm"]).all() and np.isnan(errors["oxide_zrange_error_nm"]).all()
    steep = error_columns(fine, middle, dict.fromkeys(ESTIMATED, 3.5), 2.0)  # an order past ORDER_HIGH: none either
    assert all(np.isnan(column).all() for column in steep.values())


def test_pixel_curvature_tells_a_map_its_pixels_resolve_from_one_with_pixel_scale_features():
    """About 1 on the thesis's surfaces, 2 on a step, about 4.5 on noise and on a one-pixel pit, inf on a one-pixel
    checkerboard (curvature without slope) and on a map with no interior point, 0 on a plane; a map and its copy
    scaled in all three directions agree, and an anisotropic spacing enters as the geometric mean of the two."""
    from planarize.metrics import pixel_curvature

    assert 1.0 < pixel_curvature(surfaces.hill()) < 1.1 and 1.0 < pixel_curvature(surfaces.depression()) < 1.1
    step = np.full((17, 17), 4.0)
    step[:, 8:] = 7.0
    assert pixel_curvature(Surface(step.T, 0.25)) == pytest.approx(2.0)
    pit = np.full((17, 17), 4.0)
    pit[8, 8] = 0.0
    assert pixel_curvature(Surface(pit, 0.25)) == pytest.approx(np.sqrt(20.0))
    checkerboard = 4.0 + 0.5 * (np.add.outer(np.arange(17), np.arange(17)) % 2)
    assert pixel_curvature(Surface(checkerboard, 0.25)) == math.inf
    assert pixel_curvature(Surface(np.array([[4.0, 0.0], [0.0, 0.0]]))) == math.inf
    x, y = np.meshgrid(np.arange(9.0), np.arange(9.0), indexing="ij")
    assert pixel_curvature(Surface(0.3 * x + 0.2 * y, 1.0)) < 1e-12
    bowl = x ** 2 + y ** 2
    assert pixel_curvature(Surface(bowl, 1.0)) == pytest.approx(pixel_curvature(Surface(100 * bowl, 10.0)))
    stretched = Surface(np.add.outer(np.arange(9.0) ** 2, np.zeros(12)), (1.0, 3.0))
    assert pixel_curvature(stretched) == pytest.approx(pixel_curvature(Surface(np.arange(9.0)[:, None] ** 2
                                                                                + np.zeros((9, 12)), 1.0)) * np.sqrt(3))


def test_a_quantity_that_does_not_converge_steadily_gets_no_number():
    """On the hill at its own grid the metal RMS changes more from 1x to 2x than from 1/2 to 1x (observed order
    0.39 at 2x): pinned at 2x, the run states no error for it, says which quantity and why, and does not claim
    to meet rtol; the quantities that do converge steadily keep theirs."""
    run = anodize(surfaces.hill(), 1.0, record=10, engine=Continuum(refine=2))
    p = run.parameters
    assert p["not_asymptotic"] == ["metal_rms_nm"] and not p["asymptotic"] and not p["rtol_met"]
    assert p["orders"]["metal_rms_nm"] < 0.7 and np.isnan(p["estimated_error"])
    assert np.isnan(run.history["metal_rms_error_nm"]).all() and np.isfinite(run.history["oxide_rms_error_nm"]).all()


def test_rtol_chooses_the_resolution():
    hill = surfaces.hill()
    loose = anodize(hill, 0.5, record=5, engine=Continuum(rtol=0.5))
    tight = anodize(hill, 0.5, record=5, engine=Continuum(rtol=0.005))
    assert loose.parameters["refine"] < tight.parameters["refine"]
    assert tight.parameters["estimated_error"] <= 0.005 < max(level.get("estimated_error", 0) for level in
                                                               loose.parameters["levels"]) <= 0.5
    capped = anodize(hill, 0.5, record=5, engine=Continuum(rtol=1e-4, max_refine=2))
    assert capped.parameters["refine"] == 2 and not capped.parameters["rtol_met"]


def test_a_grid_with_no_coarser_companion_estimates_its_error_from_the_next_refinement():
    # Found by the height-map fuzz test: on 2 x 2 points the half-resolution grid is the grid itself,
    # and the estimate divided 0 by 0. It now comes from the 2x grid against the surface's own.
    spike = Surface(np.array([[4.0, 0.0], [0.0, 0.0]]), spacing=1.0)
    with np.errstate(all="raise"):
        run = anodize(spike, 0.5, engine=Continuum())
    first = next(level for level in run.parameters["levels"] if level["factor"] == 1)
    assert run.parameters["refine"] >= 2 and "estimated_error" not in first
    assert np.isfinite(run.oxide.z).all() and "orders" in run.parameters["levels"][-1]  # estimated from 1x, 2x, 4x ...
    assert np.isfinite(run.parameters["estimated_error"]) != bool(run.parameters["not_asymptotic"])
    pinned = anodize(spike, 0.5, engine=Continuum(refine=1))  # no finer level allowed: no estimate, said so
    assert np.isnan(pinned.parameters["estimated_error"]) and not pinned.parameters["rtol_met"]

# -- the conformal rule -----------------------------------------------------------------------

def test_the_conformal_rule_equals_the_thesis_rule_on_a_flat_film_and_planarizes_less():
    film = Surface(np.full((5, 5), 4.0), 0.5, "periodic")
    flat = [anodize(film, 1.0, Model(rule=r), record=2).metal.z for r in ("thesis", "conformal")]
    np.testing.assert_allclose(flat[0], flat[1], rtol=1e-14)
    hill = surfaces.hill(boundary="periodic")
    thesis = anodize(hill, 1.0, Model(rule="thesis"), record=2).history
    conformal = anodize(hill, 1.0, Model(rule="conformal"), record=2).history
    assert conformal["metal_rms_nm"][-1] > 1.3 * thesis["metal_rms_nm"][-1]


# -- inputs ------------------------------------------------------------------------------------

def test_bad_settings_are_refused_in_one_line():
    refused(lambda: Continuum(rtol=0), "rtol must be in [0.0001, 1]")
    refused(lambda: Continuum(refine=3), "refine must be a power of 2 in [1, 16], got 3")
    refused(lambda: Continuum(max_refine=32), "max_refine must be an integer in [1, 16]")
    refused(lambda: Continuum(stability=1.5), "stability must be in (0, 1]")
    hill = surfaces.hill()
    refused(lambda: anodize(hill, 1.0, oxide=hill.shifted(0.1)), "the continuum engine starts from bare metal")
    refused(lambda: anodize(hill, 1.0, Model(rule="conformal"), "fast"),
            "the fast engine computes the thesis's rule only")
    refused(lambda: ContinuumEngine(hill.z), "metal must be a planarize.Surface")


def converged_history(surface, thickness, factors, record):
    """Each estimated column's converged values: the finest run plus Richardson's correction at the order of the
    last three refinements, the least-squares slope of the logarithms of their changes over the four runs
    ``factors`` (coarse to fine; of three runs, their one ratio: one ratio scatters where the grids are
    coarse, `benchmarks.planarize_continuum`)."""
    runs = [anodize(surface, thickness, record=record, engine=Continuum(refine=f)).history for f in factors]
    truth = {}
    for column in ("metal_rms_nm", "oxide_rms_nm", "metal_zrange_nm", "oxide_zrange_nm"):
        values = [np.asarray(h[column]) for h in runs]
        changes = [np.linalg.norm(b - a) for a, b in zip(values, values[1:])]
        p = np.clip(-np.polyfit(np.arange(len(changes)), np.log2(changes), 1)[0], 0.5, 4.0)
        truth[column] = values[-1] + (values[-1] - values[-2]) / (2 ** p - 1)
    return truth


@pytest.mark.slow
@pytest.mark.timeout(1800)
@pytest.mark.parametrize("name", ["hill", "depression", "random",
                                  pytest.param("ta", marks=pytest.mark.release)])  # (3 minutes: not in CI)
def test_the_stated_error_is_near_the_true_error(name):
    """The goal is a factor 2. Measured with the estimate at 1.8 where the order reached 1.2 twice running on these
    maps its pixels resolve, and otherwise at most 1.5 where a high order was observed twice running and at most 1
    (`resolution.estimate_order`): the RMS's ratio of stated to true error on these four surfaces lies within
    0.6-1.9; the z-range's within 0.53-1.71 but for the random surface's oxide, whose order at 4x (1.30) followed
    1.15 one grid coarser and which is over-stated 3.5x (docs/planarize_continuum.md). So the bounds checked are
    0.5-2.5 for the RMS and 0.5-4 for the z-range."""
    surface, thickness, factors = {
        "hill": (surfaces.hill(), 1.0, (2, 4, 8, 16)),
        "depression": (surfaces.depression(), 1.0, (2, 4, 8, 16)),
        "random": (surfaces.random_roughness(8.0, thickness=4.0, scales=((2.0, 0.5),), boundary="periodic", seed=3),
                   1.0, (2, 4, 8, 16)),  # (its z-range converges irregularly below 8x)
        "ta": (surfaces.random_roughness(seed=1), 200.0, (1, 2, 4)),  # (three runs: one ratio)
    }[name]
    run = anodize(surface, thickness, record=10)
    truth = converged_history(surface, thickness, factors, 10)
    assert run.parameters["rtol_met"]
    for column in truth:
        true, stated = largest_relative(run, truth, column)
        over = 2.5 if "rms" in column else 4.0
        assert 0.5 * true < stated < over * true and true < 0.02, (column, true, stated)
    if name == "ta":  # the thesis's Ta film: within 0.5 % of the converged RMS from 40 nm on, 0.6 % at 20 nm
        for column in ("metal_rms_nm", "oxide_rms_nm"):
            error = np.abs(run.history[column] / truth[column] - 1)
            assert error[2:].max() < 0.005 and error.max() < 0.007, (column, error)


def test_a_time_budget_stops_a_continuum_run_at_its_reported_grid():
    run = anodize(surfaces.hill(), 1.0, max_seconds=1e-6)
    assert not run.complete and run.thickness < 1.0 and run.metal.shape == (17, 17)
    assert np.isnan(run.history["metal_rms_error_nm"]).all() and not run.parameters["rtol_met"]


def test_without_expansion_the_oxide_stays_where_the_metal_was_and_the_run_ends():
    """k_exp = 1 (no expansion): the continuum engine ran into a division by zero (its step bound and, below a crease,
    its speed J / (J + k_exp - 1)); the oxide's top is the initial metal surface, as the thesis's algorithm gives."""
    import planarize
    from planarize.metrics import z_range
    from planarize.model import Model

    hill = planarize.surfaces.hill()
    run = planarize.anodize(hill, 0.5, model=Model(k_exp=1.0))
    assert np.isfinite(run.metal.z).all() and np.isfinite(run.oxide.z).all()
    assert np.abs(run.oxide.z - hill.z).max() <= 0.05 * z_range(hill)
    assert abs(run.history["volume_error"][-1]) <= 0.02
    fast = planarize.anodize(hill, 0.5, model=Model(k_exp=1.0), engine="fast")
    assert np.abs(fast.oxide.z - hill.z).max() == 0.0


def test_a_run_that_stops_making_progress_says_so_in_one_line_with_what_to_try():
    """Gaussian noise of sigma 100 nm at 10 nm spacing: the continuum engine stalls (a traceback before); the error is
    one line that names the slope and the fast engine."""
    from labrig.validate import InputError
    from planarize.anodize import Stalled

    noise = Surface(np.random.default_rng(0).normal(0.0, 100.0, (12, 12)), 10.0, "open")
    with pytest.raises(Stalled) as caught:
        anodize(noise, 100.0)
    message = str(caught.value)
    assert isinstance(caught.value, InputError) and "\n" not in message
    assert "made no progress" in message and "slopes reach" in message and "--engine fast" in message


# -- what a run costs ---------------------------------------------------------------------------

def test_the_cost_of_the_next_grid_is_predicted_from_the_two_before():
    """Steps grow by their observed ratio (clipped to 2-16 per halving), points as given, at the measured speed
    but at most SECONDS_PER_POINT_STEP; the Ta film's own grid, predicted from 1/4 and 1/2, against its steps."""
    from planarize.engines import resolution

    quarter = {"points": 100, "steps": 10, "run_s": 1.0}
    half = {"points": 400, "steps": 40, "run_s": 1e-4}  # 6.25e-9 s per point and step: faster than the cap
    assert resolution.predicted_seconds(quarter, half, 1600) == pytest.approx(40 * 4 * 1600 * 1e-4 / (40 * 400))
    slow = dict(half, run_s=1.0)
    assert resolution.predicted_seconds(quarter, slow, 1600) == pytest.approx(160 * 1600 * resolution.SECONDS_PER_POINT_STEP)
    steep = dict(half, steps=10 * 40)
    assert resolution.predicted_seconds(quarter, steep, 1600) == pytest.approx(400 * 16 * 1600 * 1e-4 / (400 * 400))
    # not measured: at SECONDS_PER_POINT_STEP whatever the machine's speed (the cost SETTLE_S bounds)
    assert resolution.predicted_seconds(quarter, half, 1600, measured=False) == pytest.approx(
        160 * 1600 * resolution.SECONDS_PER_POINT_STEP)
    run = anodize(surfaces.random_roughness(seed=1), 200.0, record=2, engine=Continuum(refine=1))
    quarter, half, own = run.parameters["levels"]
    predicted_steps = half["steps"] * half["steps"] / quarter["steps"]
    assert 0.8 < own["steps"] / predicted_steps < 1.25, (quarter["steps"], half["steps"], own["steps"])


def test_the_grid_a_run_reports_does_not_depend_on_the_machines_speed(monkeypatch):
    """A finer grid asked for only to settle a quantity is bounded by its cost in point steps (`SETTLE_S` at
    `SECONDS_PER_POINT_STEP`), not by the measured speed: with a clock that makes the machine look a million times
    faster, white noise on 17 x 17 points still stops at 4x (its 8x grid would cost 31 s at that rate) with the same
    history. At the measured speed, a crop of a real Bruker scan ran to 4x on a busy machine and to 8x on a quiet one."""
    import itertools
    import types

    from planarize.engines import resolution

    noise = Surface(4.0 + 0.3 * np.random.default_rng(0).standard_normal((17, 17)), 0.25)
    run = anodize(noise, 1.0, record=4)
    ticks = itertools.count()
    monkeypatch.setattr(resolution, "time", types.SimpleNamespace(perf_counter=lambda: 1e-9 * next(ticks)))
    fast = anodize(noise, 1.0, record=4)
    assert run.parameters["refine"] == fast.parameters["refine"] == 4
    np.testing.assert_array_equal(run.history["metal_rms_nm"], fast.history["metal_rms_nm"])


def test_a_run_predicted_past_its_budget_is_refused_up_front_with_its_cost(monkeypatch):
    from labrig.validate import InputError
    from planarize.engines import resolution

    monkeypatch.setattr(resolution, "predicted_seconds", lambda before, last, points, measured=True: 3.6e5)
    with pytest.raises(resolution.TooCostly) as caught:
        anodize(surfaces.hill(), 1.0)
    message = str(caught.value)
    assert isinstance(caught.value, InputError) and "\n" not in message
    assert "about 4.2 days" in message and "17 x 17 map at its own grid" in message and "max_seconds" in message
    assert "--engine fast" in message
    run = anodize(surfaces.hill(), 1.0, max_seconds=0.5)  # a budget given: run until it, then stop
    assert run.metal.shape == (17, 17)


def test_a_finer_grid_that_outgrows_the_one_before_is_stopped_and_the_run_says_what_it_reached(monkeypatch):
    """A checkerboard of steps as high as 100 grid spacings (the issue's 1 um steps at 10 nm): its 2x grid's
    time steps shrink without end. The run ends with its own grid's answer, states no error for quantities that
    do not converge steadily, and names the finer grid it stopped (60 s at the defaults; 1 s here)."""
    from planarize.engines import resolution

    monkeypatch.setattr(resolution, "MIN_LEVEL_S", 1.0)
    z = 1000.0 * ((np.arange(17)[:, None] + np.arange(17)[None, :]) % 2)
    run = anodize(Surface(z, 10.0), 1000.0, record=4)
    p = run.parameters
    assert run.complete and p["refine"] == 1 and not p["rtol_met"] and run.thickness == 1000.0
    assert p["finer"].startswith("2x stopped after") and "too slow" in p["finer"]
    assert np.isnan(p["estimated_error"]) and p["not_asymptotic"]
    assert p["levels"][-1]["run_s"] < 5.0


def test_the_maps_own_grid_states_no_error_from_companions_coarser_than_the_map():
    """At 1x the companions (1/2 and 1/4) sample the map at fewer points, a smoother surface: on the smooth 129 x 129
    film of the accuracy benchmark the RMS error they gave was 8.6-9.4x the true one. The run states no number there;
    its 2x grid (2.7e8 point steps, 13 s at SECONDS_PER_POINT_STEP) is past SETTLE_S, so it stops at 1x and says what
    2x would take. The code before stated the RMS errors at 1x."""
    from scipy.ndimage import gaussian_filter

    from planarize.cli.commands import _accuracy
    from planarize.engines.resolution import SETTLE_S

    z = gaussian_filter(np.random.default_rng(0).normal(size=(129, 129)), sigma=4.0, mode="wrap")
    run = anodize(Surface(1000.0 + 6.0 * z / z.std(), 5.0, "periodic"), 200.0, record=4)
    p = run.parameters
    assert p["refine"] == 1 and p["own_grid"] and not p["noisy"] and not p["rtol_met"]
    for column in ("metal_rms_error_nm", "oxide_rms_error_nm", "metal_zrange_error_nm", "oxide_zrange_error_nm"):
        assert np.isnan(run.history[column]).all()
    assert p["finer"].startswith("2x not run: predicted to take about") and p["levels"][-1]["predicted_s"] > SETTLE_S
    summary = {"engine": "continuum", "own_grid": True, "last_change": p["change"], "finer_grid": p["finer"]}
    assert "the map's own grid" in _accuracy(summary) and "refine = 2" in _accuracy(summary)
