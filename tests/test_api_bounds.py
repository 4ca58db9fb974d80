"""Every count, size, rate or interval a Python call implies is bounded before anything is allocated.

Each case asks for just more than a bound allows and expects `labrig.validate.InputError` at once, in one
line that names the key, the value and the bound: a call that got past its check would allocate gigabytes
or loop for hours, so a missing check shows as a failure (or a test that never ends), not as a pass.
"""

import functools
import math
from types import SimpleNamespace

import numpy as np
import pytest
from helpers import refused

import qdots
from labrig.figures import MAX_DPI
from qdots.analysis import lqe, lqe_thesis, packing, report, structure
from qdots.analysis.forster import TAU_NS, exciton_network
from qdots.deposition import deposit
from qdots.diagnostics import hard_cases
from qdots.engine import Chipmunk
from qdots.geometry import MAX_DISTANCES, MAX_PAIRS, segment_distances
from qdots.placement import MAX_CANDIDATES, MAX_LATTICE_SIZE, draw_candidates, hexagonal_lattice
from qdots.presets import get_preset
from qdots.render import save_png
from qdots.scene import MAX_DOTS, MAX_SEGMENTS, Scene, grating_segments
from qdots.simulation import MAX_STEPS


def board(positions, radii=7.5, box=None):
    positions = np.asarray(positions, dtype=float)
    fields = dict(positions=positions, radii=np.broadcast_to(np.asarray(radii, float), (len(positions),)).copy())
    if box is not None:
        fields["box"] = box
    return SimpleNamespace(**fields)


def grid(n, spacing=1.0):
    """``n`` points on a square grid, ``spacing`` px apart, from (1, 1)."""
    side = math.ceil(math.sqrt(n))
    return 1.0 + spacing * np.argwhere(np.ones((side, side)))[:n].astype(float)


#: The fewest dots whose pairs can exceed `MAX_PAIRS`: a pair search over them with a reach that takes
#: every pair asks for more than the bound.
CROWD = next(n for n in range(14_000, 15_000) if n * (n - 1) // 2 > MAX_PAIRS)
#: Just above `packing.MAX_ALL_PAIRS` pairs.
ALL_PAIRS_DOTS = next(n for n in range(99_990, 100_010) if n * (n - 1) // 2 > packing.MAX_ALL_PAIRS)


@functools.cache
def crowd(big: float = 0.0):
    """`CROWD` dots of radius 0.4 on a 1 px grid in a 200 px box (every pair within 170 px); the last one of
    radius ``big`` if given."""
    radii = np.full(CROWD, 0.4)
    radii[-1] = big or 0.4
    return board(grid(CROWD), radii, box=(200.0, 200.0))


@functools.cache
def network():
    return exciton_network(board(hexagonal_lattice(3, 15.0, origin=(50.0, 50.0))), seed=0)


@functools.cache
def nine_dots():
    return qdots.State(time=0.0, positions=hexagonal_lattice(3, 15.0, origin=(50.0, 50.0)), velocities=np.zeros((9, 2)),
                       radii=np.full(9, 7.5), masses=np.ones(9), box=(200.0, 200.0), walls=np.zeros((0, 4)))


def one_dot_sim():
    return qdots.Simulation(Scene(box=(400.0, 400.0), positions=[[200.0, 200.0]], radii=[7.5]), [], seed=1)


def live_run(queued: int = 0):
    from qdots.interactive.live import LiveRun

    live = LiveRun(Scene(box=(400.0, 400.0), positions=[[200.0, 200.0], [100.0, 100.0]], radii=[7.5, 7.5]), seed=1)
    if queued:
        live.drop(queued, interval=0.0)
    return live


def live_board(**kwargs):
    from qdots.interactive.board import LiveBoard

    return LiveBoard(live_run(), **kwargs)


def crowded_scene():
    """One dot of radius 20,000 px among `CROWD` small ones: the overlap check would list every pair."""
    side = math.ceil(math.sqrt(CROWD))
    small = 50_000.0 + 300.0 * np.argwhere(np.ones((side, side)))[:CROWD].astype(float)
    return Scene(box=(100_000.0, 100_000.0), positions=np.vstack([small, [[20_001.0, 20_001.0]]]),
                 radii=np.r_[np.full(CROWD, 0.5), 20_000.0])


def long_case():
    """100,000 samples of 1,000 s: at the default 20 ms step each is 50,000 steps, the case 5e9."""
    def build():
        return Scene(box=(100.0, 100.0), positions=[[50.0, 50.0]], radii=[7.5]), []

    return hard_cases.check(hard_cases.HardCase("long", build, 1e8, 1.0, sample=1000.0))


THESIS_DT = 0.999e-3 * TAU_NS  # n_excitons = MAX_EXCITONS at this dt: just above MAX_THESIS_STEPS
DEPOSITS = MAX_STEPS // round(1e4 / Chipmunk().dt) + 1  # dots 1e4 s apart: just above MAX_STEPS
RNG = np.random.default_rng(0)

#: (call, words its one-line message holds): each asks for just more than one bound.
CASES = {
    # analysis: pair searches (qdots.geometry.MAX_PAIRS)
    "radial_distribution r_max": (lambda: structure.radial_distribution(crowd(), r_max=150.0),
                                  ["r_max = 150 px", f"{MAX_PAIRS:,}"]),
    "neighbour_edges mean_radius": (lambda: packing.neighbour_edges(crowd(), mean_radius=200.0),
                                    ["mean_radius = 200 px", f"{MAX_PAIRS:,}"]),
    "hexatic_order mean_radius": (lambda: structure.hexatic_order(crowd(), mean_radius=200.0),
                                  ["mean_radius = 200 px", f"{MAX_PAIRS:,}"]),
    "clusters mean_radius": (lambda: structure.clusters(crowd(), mean_radius=200.0),
                             ["mean_radius = 200 px", f"{MAX_PAIRS:,}"]),
    "neighbour_edges rule code": (lambda: packing.neighbour_edges(crowd(150.0), rule="code"),
                                  ["rule 'code'", "150 px", f"{MAX_PAIRS:,}"]),
    "overlaps": (lambda: packing.overlaps(crowd(150.0)), ["largest radius, 150 px", f"{MAX_PAIRS:,}"]),
    "fill_within_radius overlaps": (lambda: packing.fill_within_radius(crowd(150.0), [10.0]),
                                    ["largest radius, 150 px", f"{MAX_PAIRS:,}"]),
    # analysis: sizes
    "radial_distribution bins": (
        lambda: structure.radial_distribution(board(grid(50, 10.0), 2.0, box=(100.0, 100.0)), r_max=50.0,
                                              bins=structure.MAX_BINS + 1),
        ["bins", f"{structure.MAX_BINS:,}", str(structure.MAX_BINS + 1)]),
    "fill_within_radius circles": (
        lambda: packing.fill_within_radius(nine_dots(), np.linspace(1, 100, packing.MAX_CIRCLES + 1)),
        ["radius", f"{packing.MAX_CIRCLES:,}", f"{packing.MAX_CIRCLES + 1:,}"]),
    "fill_within_radius lens areas": (  # 5,001 dots x 10,000 circles that reach them all
        lambda: packing.fill_within_radius(board(grid(5001, 20.0), 5.0, box=(2000.0, 2000.0)),
                                           np.linspace(3000, 4000, packing.MAX_CIRCLES)),
        ["radius", "5,001 dots", f"{packing.MAX_FILL_TERMS:,}"]),
    "size_separation_correlation all": (
        lambda: packing.size_separation_correlation(board(grid(ALL_PAIRS_DOTS, 20.0), 5.0), pairs="all"),
        ["pairs='all'", f"{ALL_PAIRS_DOTS:,} dots", f"{packing.MAX_ALL_PAIRS:,}"]),
    # LQE
    "lqe_monte_carlo n_excitons": (lambda: lqe.lqe_monte_carlo(network(), lqe.MAX_EXCITONS + 1),
                                   ["n_excitons", f"{lqe.MAX_EXCITONS:,}", str(lqe.MAX_EXCITONS + 1)]),
    "lqe_monte_carlo thesis steps": (
        lambda: lqe.lqe_monte_carlo(network(), lqe.MAX_EXCITONS, method="thesis", dt=THESIS_DT),
        ["n_excitons = 10,000,000", f"dt = {THESIS_DT:g} ns", f"{lqe_thesis.MAX_THESIS_STEPS:,}"]),
    "thesis_walks steps": (
        lambda: lqe_thesis.thesis_walks(network(), np.zeros(lqe.MAX_EXCITONS, dtype=np.intp), THESIS_DT, RNG),
        ["starts = 10,000,000", f"{lqe_thesis.MAX_THESIS_STEPS:,}"]),
    "lqe_exact dt low": (lambda: lqe.lqe_exact(network(), scheme="thesis", dt=0.999e-6 * TAU_NS),
                         ["dt must be in", "1e-6 to 1000 radiative lifetimes", repr(0.999e-6 * TAU_NS)]),
    "lqe_exact dt high": (lambda: lqe.lqe_exact(network(), scheme="thesis", dt=1.001e3 * TAU_NS),
                          ["dt must be in", "1e-6 to 1000 radiative lifetimes", repr(1.001e3 * TAU_NS)]),
    "lqe_monte_carlo dt low": (lambda: lqe.lqe_monte_carlo(network(), 10, method="thesis", dt=0.999e-6 * TAU_NS),
                               ["dt must be in", "1e-6 to 1000 radiative lifetimes"]),
    "thesis_walks dt high": (
        lambda: lqe_thesis.thesis_walks(network(), np.zeros(10, dtype=np.intp), 1.001e3 * TAU_NS, RNG),
        ["dt must be in", "1e-6 to 1000 radiative lifetimes"]),
    "step_probabilities block": (
        lambda: lqe_thesis.step_probabilities(network(), 0.26, block=lqe_thesis.MAX_BLOCK + 1),
        ["block", f"{lqe_thesis.MAX_BLOCK:,}"]),
    "thesis_walks block": (
        lambda: lqe_thesis.thesis_walks(network(), np.zeros(10, dtype=np.intp), 0.26, RNG,
                                        block=lqe_thesis.MAX_BLOCK + 1),
        ["block", f"{lqe_thesis.MAX_BLOCK:,}"]),
    "film_lqe draws": (lambda: lqe.film_lqe(nine_dots(), draws=lqe.MAX_DRAWS + 1),
                       ["draws", f"{lqe.MAX_DRAWS:,}", str(lqe.MAX_DRAWS + 1)]),
    "board_report draws": (lambda: report.board_report(nine_dots(), draws=lqe.MAX_DRAWS + 1),
                           ["draws", f"{lqe.MAX_DRAWS:,}"]),
    # pictures
    "save_png dpi": (lambda: save_png(nine_dots(), "unwritten.png", dpi=MAX_DPI + 1), ["dpi", "1200", "1201.0"]),
    "save_report_png dpi": (
        lambda: report.save_report_png(nine_dots(), report.board_report(nine_dots(), lqe=False), "unwritten.png",
                                       dpi=MAX_DPI + 1),
        ["dpi", "1200", "1201.0"]),
    # placement
    **{f"hexagonal_lattice {layout}": (lambda layout=layout, m=m: hexagonal_lattice(m + 1, 15.0, layout),
                                       ["m", f"{m:,}", str(m + 1)])
       for layout, m in MAX_LATTICE_SIZE.items()},
    "draw_candidates m": (lambda: draw_candidates(RNG, MAX_CANDIDATES + 1, (0, 0, 100, 100), 15.0, 0.1),
                          ["m", f"{MAX_CANDIDATES:,}"]),
    # scene
    "grating_segments pitch": (lambda: grating_segments((600.0, 600.0), 600.0 / (MAX_SEGMENTS + 2)),
                               [f"grating pitch = {600.0 / (MAX_SEGMENTS + 2):g} px", f"{MAX_SEGMENTS:,}"]),
    "grating_segments tiny pitch": (lambda: grating_segments((600.0, 600.0), 1e-300), ["grating pitch = 1e-300 px"]),
    "grating_segments infinite pitch": (lambda: grating_segments((600.0, 600.0), math.inf), ["grating pitch", "inf"]),
    "grating_segments offset": (lambda: grating_segments((600.0, 600.0), 10.0, offset=math.nan), ["offset", "nan"]),
    "grating_segments box": (lambda: grating_segments((600.0, 1e9), 10.0), ["box", "1e6"]),
    "segment_distances": (lambda: segment_distances(np.zeros((2001, 2)), np.tile([0.0, 0.0, 1.0, 1.0], (10_000, 1))),
                          ["2,001 points x 10,000 segments", f"{MAX_DISTANCES:,}"]),
    "Scene overlap check": (crowded_scene, ["radii", "20000 px", f"{MAX_PAIRS:,}"]),
    # deposition
    "deposit dots": (lambda: deposit(one_dot_sim(), MAX_DOTS, interval=0.0),
                     ["n_dots = 1,000,000", "1,000,001 dots", f"{MAX_DOTS:,}"]),
    "deposit steps": (lambda: deposit(one_dot_sim(), DEPOSITS, interval=1e4),
                      [f"n_dots = {DEPOSITS:,} dots 10000 s apart", f"{MAX_STEPS:,}"]),
    # interactive
    "LiveRun.drop n_dots": (lambda: live_run().drop(MAX_DOTS + 1), ["n_dots", f"{MAX_DOTS:,}"]),
    "LiveRun.drop board": (lambda: live_run().drop(MAX_DOTS - 1),
                           ["n_dots = 999,999", "1,000,001 dots", f"{MAX_DOTS:,}"]),
    "LiveRun.drop queue": (lambda: live_run(10).drop(MAX_DOTS - 11), ["999,989", "1,000,001 dots", "10 queued"]),
    "LiveRun.add_grating": (lambda: live_run().add_grating(1e-4), ["grating pitch", f"{MAX_SEGMENTS:,}"]),
    "LiveBoard size": (lambda: live_board(size=20.02), ["size must be in (0, 20] in", "20.02"]),
    "LiveBoard frame_pause": (lambda: live_board(frame_pause=60.5), ["frame_pause", "60", "60.5"]),
    "LiveBoard infinite frame_pause": (lambda: live_board(frame_pause=math.inf), ["frame_pause", "inf"]),
    # hard cases, presets
    "centre_pack n": (lambda: hard_cases.centre_pack(1.0, n=hard_cases.CENTRE_PACK_SITES + 1), ["n", "529", "530"]),
    "loose_film n": (lambda: hard_cases.loose_film(MAX_DOTS + 1), ["n", f"{MAX_DOTS:,}"]),
    "mixture masses": (lambda: hard_cases.mixture("heavy"), ["masses", "'heavy'"]),
    "HardCase sample": (
        lambda: hard_cases.HardCase("x", hard_cases.falling_gas(), 1.0, 1.0,
                                    sample=1 / (hard_cases.MAX_SAMPLES + 1)),
        ["sample", f"{hard_cases.MAX_SAMPLES:,}"]),
    "HardCase seconds": (lambda: hard_cases.HardCase("x", hard_cases.falling_gas(), 0.0, 1.0), ["seconds", "0.0"]),
    "hard case run": (long_case, [f"{MAX_STEPS:,}"]),
    "get_preset quick": (lambda: get_preset("fig2-2", quick=1.5), ["quick must be in (0, 1]", "1.5"]),
}


@pytest.mark.parametrize("name", list(CASES))
def test_refused_at_once_in_one_line(name, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)  # nothing may be written
    call, words = CASES[name]
    refused(call, *words)
    assert list(tmp_path.iterdir()) == []


def test_the_same_inputs_at_their_bounds_are_measured():
    assert packing.neighbour_counts(crowd()).max() == 4  # the crowd at an ordinary reach
    assert structure.radial_distribution(crowd(), r_max=2.0).counts.sum() > 0
    board50 = board(grid(50, 10.0), 2.0, box=(100.0, 100.0))
    assert len(structure.radial_distribution(board50, r_max=50.0, bins=structure.MAX_BINS).g) == structure.MAX_BINS
    for layout, m in MAX_LATTICE_SIZE.items():
        assert len(hexagonal_lattice(m, 1.0, layout)) <= MAX_DOTS
    assert len(grating_segments((600.0, 600.0), 600.0 / (MAX_SEGMENTS + 1) * (1 + 1e-9))) == MAX_SEGMENTS
    assert segment_distances(np.zeros((20, 2)), np.tile([0.0, 0.0, 1.0, 1.0], (10_000, 1))).shape == (20, 10_000)
    assert len(hard_cases.centre_pack(1.0, n=hard_cases.CENTRE_PACK_SITES)()[0].radii) == hard_cases.CENTRE_PACK_SITES


def test_the_bounds_sit_just_below_the_cases_that_exceed_them():
    assert CROWD * (CROWD - 1) // 2 > MAX_PAIRS >= (CROWD - 1) * (CROWD - 2) // 2
    assert 5001 * packing.MAX_CIRCLES > packing.MAX_FILL_TERMS >= 5000 * packing.MAX_CIRCLES
    assert 2001 * 10_000 > MAX_DISTANCES >= 2000 * 10_000


def test_deposition_refusal_leaves_the_board_as_it_was():
    sim = one_dot_sim()
    refused(lambda: deposit(sim, DEPOSITS, interval=1e4), f"{MAX_STEPS:,}")
    assert sim.n_dots == 1 and sim.steps_taken == 0
