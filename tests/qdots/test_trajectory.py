"""GSD trajectories read back with gsd and freud."""

import numpy as np
import pytest

import qdots

gsd_hoomd = pytest.importorskip("gsd.hoomd")
from qdots.io.trajectory import GSDWriter  # noqa: E402


def small_run():
    grid = np.array([(x, y) for x in range(20, 200, 20) for y in range(20, 100, 20)], float)
    scene = qdots.Scene(box=(200, 120), positions=grid, radii=np.full(len(grid), 7.0))
    return qdots.Simulation(scene, [qdots.ThermalKicks()], seed=2, dt=1e-3)


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


def test_a_viewer_gets_sizes_colours_heavy_dots_and_walls(tmp_path):
    scene = qdots.Scene(box=(200, 120), positions=[[40, 60], [100, 60], [160, 60]], radii=[5.0, 7.5, 10.0],
                        masses=[1.0, 2.0, 1.0], segments=qdots.scene.grating_segments((200, 120), 40.0))
    state = qdots.Simulation(scene, seed=1).state()
    path = tmp_path / "traj.gsd"
    with GSDWriter(path, every=1) as writer:
        writer.write(state)
    with gsd_hoomd.open(path, "r") as traj:
        frame = traj[0]
    assert list(frame.particles.types) == ["dot", "heavy"]
    np.testing.assert_array_equal(frame.particles.typeid, [0, 1, 0])
    np.testing.assert_allclose(frame.log["particles/Color"], qdots.render.size_colours(state.radii), atol=1e-7)
    walls = frame.log["qdots/walls"].reshape(-1, 4) + [100, 60, 100, 60]
    np.testing.assert_allclose(walls, state.walls)
    assert len(walls) == len(state.walls) > 4  # the board's four sides and the grating lines
    np.testing.assert_array_equal(frame.log["qdots/periodic"], [0, 0])


def test_ovito_reads_what_the_state_file_holds(tmp_path):
    ovito_io = pytest.importorskip("ovito.io")
    sim = small_run()
    sim.run(0.02)
    state = sim.state()
    path = tmp_path / "traj.gsd"
    with GSDWriter(path, every=1) as writer:
        writer.write(state)
    data = ovito_io.import_file(str(path)).compute()
    xy = np.asarray(data.particles["Position"])[:, :2] + [100.0, 60.0]
    np.testing.assert_allclose(xy, state.positions, atol=1e-4)
    np.testing.assert_allclose(np.asarray(data.particles["Radius"]), state.radii, rtol=1e-6)
    np.testing.assert_allclose(np.asarray(data.particles["Color"]), qdots.render.size_colours(state.radii), atol=1e-7)
    assert data.attributes["qdots/periodic"] == (0, 0)
