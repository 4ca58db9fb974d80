"""GSD trajectories read back with gsd and freud."""

import numpy as np
import pytest

import qdots

gsd_hoomd = pytest.importorskip("gsd.hoomd")
from qdots.io.trajectory import GSDWriter  # noqa: E402


def small_run():
    grid = np.array([(x, y) for x in range(20, 200, 20) for y in range(20, 100, 20)], float)
    scene = qdots.Scene(box=(200, 120), positions=grid, radii=np.full(len(grid), 7.0))
    return qdots.Simulation(scene, [qdots.ThermalKicks()], seed=2)


def test_frames_round_trip(tmp_path):
    sim = small_run()
    path = tmp_path / "traj.gsd"
    with GSDWriter(path, every=10, dt=sim.dt) as writer:
        sim.attach(writer)
        final = sim.run(0.05)
    assert writer.frames == 6
    with gsd_hoomd.open(path, "r") as traj:
        assert len(traj) == 6
        last = traj[-1]
        assert last.configuration.dimensions == 2
        np.testing.assert_allclose(last.configuration.box[:2], [200, 120])
        assert last.configuration.step == 50
        xy = last.particles.position[:, :2] + np.array([100.0, 60.0])
        np.testing.assert_allclose(xy, final.positions, atol=1e-4)  # float32
        np.testing.assert_allclose(last.particles.diameter, 14.0)
        assert last.log["qdots/time"][0] == pytest.approx(0.05)


def test_interrupted_run_leaves_no_file(tmp_path):
    sim = small_run()
    path = tmp_path / "traj.gsd"
    with pytest.raises(RuntimeError):
        with GSDWriter(path, every=5) as writer:
            sim.attach(writer)
            sim.run(0.02)
            raise RuntimeError("user interrupt")
    assert list(tmp_path.iterdir()) == []


def test_freud_reads_the_frames(tmp_path):
    freud = pytest.importorskip("freud")
    sim = small_run()
    path = tmp_path / "traj.gsd"
    with GSDWriter(path, every=1) as writer:
        writer.write(sim.state())
    with gsd_hoomd.open(path, "r") as traj:
        frame = traj[0]
        box = freud.box.Box.from_box(frame.configuration.box, dimensions=2)
        query = freud.locality.AABBQuery(box, frame.particles.position)
        pairs = query.query(frame.particles.position, {"r_max": 20.5, "exclude_ii": True}).toNeighborList()
    # the 9 x 4 grid at 20 px pitch: 2 (9 - 1) * 4 + 9 (4 - 1) * 2 = 118 directed neighbour pairs
    assert len(pairs) == 118


def test_bad_every():
    with pytest.raises(ValueError, match="every must be an integer"):
        GSDWriter("x.gsd", every=0)
