"""Run files (.npz) and history tables: exact round trips, atomic writes, bad files."""

import csv
import json
import zipfile

import numpy as np
import pytest
from helpers import refused_file

import planarize
from planarize.io.results import history_json, load_run, save_history_csv, save_history_json, save_run


@pytest.fixture(scope="module")
def run():
    return planarize.anodize(planarize.surfaces.hill(refine=2), 0.5, planarize.Model(step=0.05), record=5, snapshots=[0.0, 0.25, 0.5])


def assert_same_run(a, b):
    # (compared as JSON: a NaN, an error the run does not state, equals itself there and not in Python)
    assert json.dumps(a.parameters, sort_keys=True) == json.dumps(b.parameters, sort_keys=True)
    assert list(a.history) == list(b.history)
    for key in a.history:
        assert np.array_equal(a.history[key], b.history[key], equal_nan=True) and a.history[key].dtype == b.history[key].dtype, key
    assert (a.initial, a.metal, a.oxide) == (b.initial, b.metal, b.oxide)
    assert np.array_equal(a.distances, b.distances)
    assert len(a.snapshots) == len(b.snapshots)
    for s, t in zip(a.snapshots, b.snapshots):
        assert (s.target, s.thickness, s.metal, s.oxide) == (t.target, t.thickness, t.metal, t.oxide)
        assert np.array_equal(s.distances, t.distances)


def test_run_round_trips_exactly(run, tmp_path):
    back = load_run(save_run(run, tmp_path / "run.npz"))
    assert_same_run(run, back)
    assert back.thickness == run.thickness and len(back.snapshots) == 3
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run.npz"]
    with np.load(tmp_path / "run.npz") as saved:  # the file says which version of planarize wrote it
        assert json.loads(str(saved["metadata"]))["planarize"] == planarize.__version__
    periodic = planarize.anodize(planarize.surfaces.bump(4.5, points=5, refine=1, boundary="periodic"), 0.2, planarize.Model(step=0.05),
                                 snapshots=[])
    assert_same_run(periodic, load_run(save_run(periodic, tmp_path / "periodic.npz")))


def finite_or_none(value):
    if isinstance(value, dict):
        return {key: finite_or_none(v) for key, v in value.items()}
    if isinstance(value, list):
        return [finite_or_none(v) for v in value]
    return None if isinstance(value, float) and not np.isfinite(value) else value


def test_history_csv_and_json(run, tmp_path):
    with open(save_history_csv(run, tmp_path / "h.csv"), newline="") as stream:
        rows = list(csv.DictReader(stream))
    assert len(rows) == len(run.history["thickness_nm"]) == 6
    for key, values in run.history.items():
        assert [float(r[key]) for r in rows] == pytest.approx(values.tolist(), rel=1e-15)
    data = json.loads(save_history_json(run, tmp_path / "h.json").read_text())
    assert data["parameters"] == finite_or_none(run.parameters)  # (an error not stated, NaN, is null in JSON)
    assert data["history"]["oxide_rms_nm"] == run.history["oxide_rms_nm"].tolist()
    assert "Eq 3.8" in data["columns"]["metal_rms_nm"]


def test_json_is_strict_with_non_finite_values(run):
    history = {**run.history, "volume_error": np.array([np.inf] * 6)}
    strange = planarize.Anodization(run.parameters, history, [], run.initial, run.metal, run.oxide)
    assert history_json(strange)["history"]["volume_error"] == [None] * 6


def test_failed_write_keeps_the_previous_file(run, tmp_path, monkeypatch):
    path = save_run(run, tmp_path / "run.npz")
    before = path.read_bytes()

    def broken(*args, **kwargs):
        raise OSError("disk full")

    monkeypatch.setattr(np, "savez", broken)
    with pytest.raises(OSError, match="disk full"):
        save_run(run, path)
    assert path.read_bytes() == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run.npz"]


def test_bad_run_files(tmp_path):
    with pytest.raises(FileNotFoundError):
        load_run(tmp_path / "absent.npz")
    refused_file(load_run, tmp_path / "junk.npz", b"junk", "junk.npz is not a readable planarize run file")
    np.savez(tmp_path / "other.npz", metadata=np.array(json.dumps({"format": "qdots-state"})))
    with pytest.raises(ValueError, match="not a planarize run file"):
        load_run(tmp_path / "other.npz")
    with pytest.raises(ValueError, match="Anodization"):
        save_run("not a run", tmp_path / "x.npz")


def test_damaged_run_files_are_one_line_errors(tmp_path):
    run = planarize.anodize(planarize.surfaces.hill(points=3, refine=1), 0.05, record=2)
    good = save_run(run, tmp_path / "run.npz")
    data = good.read_bytes()
    (tmp_path / "truncated.npz").write_bytes(data[: len(data) // 2])
    with zipfile.ZipFile(good) as archive:  # a byte of the metal heights (after its local header)
        info = archive.getinfo("metal.npy")
    local = data[info.header_offset:info.header_offset + 30]
    start = info.header_offset + 30 + int.from_bytes(local[26:28], "little") + int.from_bytes(local[28:30], "little")
    flipped = bytearray(data)
    flipped[start + info.file_size - 3] ^= 0xFF
    (tmp_path / "flipped.npz").write_bytes(bytes(flipped))
    for name in ("truncated.npz", "flipped.npz"):
        with pytest.raises(ValueError, match="run"):
            load_run(tmp_path / name)
    with np.load(good) as archive:
        arrays = {k: archive[k] for k in archive.files}
    metadata = json.loads(str(arrays["metadata"]))
    for name, change in (("list", lambda a: {**a, "metadata": np.array(json.dumps([1]))}),
                         ("shape", lambda a: {**a, "metal": np.zeros((2, 2))}),
                         ("spacing", lambda a: {**a, "metadata": np.array(json.dumps({**metadata, "spacing": "x"}))})):
        with open(tmp_path / f"{name}.npz", "wb") as stream:
            np.savez(stream, **change(arrays))
        with pytest.raises(ValueError, match="run"):
            load_run(tmp_path / f"{name}.npz")
