"""Hostile and malformed files: every reader refuses them in one line (an InputError), never with a traceback or a
huge allocation. By feature: TOML parameter files, JSON (archive metadata, sweep records, sweep.json), archives
(``.npz`` members with forged or inflating ``.npy`` headers), and printing names that hold control characters.

Every hostile input is built here, small: a header that declares 10**12 rows over 80 bytes, a member that
inflates to 160 MB from a few hundred kB.
"""

import io
import json
import tracemalloc
import zipfile

import numpy as np
import pytest

import qdots
from labrig.archive import MAX_METADATA_CHARS, read_archive, write_archive
from labrig.cli import Command, command_line, print_table
from labrig.jsonfile import MAX_CONTAINERS as JSON_MAX_CONTAINERS
from labrig.jsonfile import MAX_DEPTH as JSON_MAX_DEPTH
from labrig.jsonfile import parse_json, read_json
from labrig.sweeps import Sweep, run_sweep, summarize
from labrig.tomlfile import INT_RANGE, MAX_BYTES, MAX_CONTAINERS, MAX_DEPTH, parse_toml, read_toml
from labrig.validate import InputError, printable
from planarize.cli import main as planarize_main
from planarize.io.results import ARRAYS as RUN_ARRAYS
from planarize.io.results import load_run
from planarize.io.scenefile import load_scene
from qdots.cli import main as qdots_main
from qdots.io.checkpoint import MAX_ARRAY_BYTES
from qdots.io.experiment_file import load_experiment

SMALL_EXPERIMENT = """name = "small"
[board]
width = 80.0
height = 80.0
[deposition]
n_dots = 4
interval = 0.01
settle = 0.05
"""


def one_line_error(capsys, prog: str) -> str:
    """The one line ``PROG: error: ...`` a refused command printed (nothing else on stderr, no traceback)."""
    err = capsys.readouterr().err
    lines = [line for line in err.splitlines() if line.strip()]
    assert len(lines) == 1 and lines[0].startswith(f"{prog}: error: "), err[-2000:]
    assert "Traceback" not in err
    return lines[0]


# -- TOML ----------------------------------------------------------------------------------------

NESTED_TOML = {
    "arrays": lambda n: "a = " + "[" * n + "]" * n,
    "inline tables": lambda n: "a = " + "{b = " * n + "1" + "}" * n,
    "dotted keys": lambda n: "a" + ".a" * n + " = 1",
    "table headers": lambda n: "[a" + ".a" * n + "]\nb = 1",
    "arrays of tables": lambda n: "[[a" + ".a" * n + "]]\nb = 1",
}


@pytest.mark.parametrize("form", NESTED_TOML)
@pytest.mark.parametrize("depth", [500, 10_000])
def test_deeply_nested_toml_is_refused(form, depth):
    with pytest.raises(InputError, match=rf"^deep\.toml: invalid TOML: tables and arrays nested more than "
                                         rf"{MAX_DEPTH} deep"):
        parse_toml(NESTED_TOML[form](depth), "deep.toml")


def test_toml_nesting_up_to_the_limit_is_read():
    # the top-level table is the first level, then MAX_DEPTH - 1 arrays or tables
    node = parse_toml(NESTED_TOML["arrays"](MAX_DEPTH - 1))["a"]
    for _ in range(MAX_DEPTH - 2):
        node = node[0]
    assert node == []
    node = parse_toml(NESTED_TOML["dotted keys"](MAX_DEPTH - 1))["a"]
    for _ in range(MAX_DEPTH - 2):
        node = node["a"]
    assert node == {"a": 1}
    for form in ("arrays", "dotted keys"):
        with pytest.raises(InputError, match="nested more than"):
            parse_toml(NESTED_TOML[form](MAX_DEPTH))


def test_brackets_dots_and_quotes_inside_strings_and_comments_are_text():
    text = "\n".join([
        'a = "' + "[{." * 5000 + '\\"]"',
        "b = '" + "[[[" * 5000 + "'",
        'c = """\n' + "[." * 5000 + '\\""" ""still c"""""',
        "d = '''" + "{{" * 5000 + "''''",
        "# [[[[[[[ a comment " + "{" * 5000,
        '"e.f.g" = 1.5  # a quoted key: one key, not three tables',
        "h = [1.5, 2.5, 1979-05-27T07:32:00.999]",
    ])
    data = parse_toml(text)
    assert data["a"] == "[{." * 5000 + '"]' and data["b"] == "[[[" * 5000
    assert data["c"] == "[." * 5000 + '""" ""still c""' and data["d"] == "{{" * 5000 + "'"
    assert data["e.f.g"] == 1.5 and len(data["h"]) == 3


def test_too_many_tables_are_refused():
    parse_toml("".join(f"[t{i}]\nx = 1\n" for i in range(1000)))
    with pytest.raises(InputError, match=f"more than {MAX_CONTAINERS:,} tables and arrays"):
        parse_toml("".join(f"[t{i}]\n" for i in range(MAX_CONTAINERS + 1)))
    with pytest.raises(InputError, match=f"more than {MAX_CONTAINERS:,} tables and arrays"):
        parse_toml("a = [" + "[]," * (MAX_CONTAINERS + 1) + "]")


def test_integers_beyond_64_bits_are_refused():
    with pytest.raises(InputError, match=r"^big\.toml: invalid TOML: Exceeds the limit .* 10000 digits$"):
        parse_toml("a = " + "7" * 10_000, "big.toml")
    with pytest.raises(InputError, match=r"invalid TOML: deposition\.sigma = an integer of 400 digits is outside"):
        parse_toml("[deposition]\nsigma = 1" + "0" * 399)
    with pytest.raises(InputError, match=rf"invalid TOML: b\[1\] = {2**63} is outside the 64-bit integers"):
        parse_toml(f"b = [1, {2**63}]")
    assert parse_toml(f"a = {INT_RANGE[0]}\nb = {INT_RANGE[1]}") == {"a": -2**63, "b": 2**63 - 1}


def test_a_byte_order_mark_is_skipped(tmp_path):
    assert parse_toml("\ufeffa = 1") == {"a": 1}
    path = tmp_path / "bom.toml"
    path.write_bytes(b"\xef\xbb\xbf" + SMALL_EXPERIMENT.encode())
    assert read_toml(path, "experiment file")["name"] == "small"
    assert load_experiment(path).name == "small"
    scene = tmp_path / "scene.toml"
    scene.write_bytes(b"\xef\xbb\xbfname = \"bom\"\n[surface]\nkind = \"hill\"\n")
    assert load_scene(scene).name == "bom"


def test_text_longer_than_a_parameter_file_is_refused(tmp_path):
    with pytest.raises(InputError, match=f"more than the {MAX_BYTES:,}"):
        parse_toml("#" * (MAX_BYTES + 1))
    path = tmp_path / "long.toml"
    path.write_text("#" * (MAX_BYTES + 1))
    with pytest.raises(InputError, match=f"more than the {MAX_BYTES:,}"):
        read_toml(path, "scene file")


def deep_toml(tmp_path, name="deep.toml"):
    path = tmp_path / name
    path.write_text(NESTED_TOML["arrays"](10_000))
    return path


@pytest.mark.parametrize("main, prog, command", [(qdots_main, "qdots", "run"), (planarize_main, "planarize", "run"),
                                                 (qdots_main, "qdots", "sweep"),
                                                 (planarize_main, "planarize", "sweep")])
def test_every_command_refuses_deep_toml_in_one_line(tmp_path, capsys, main, prog, command):
    path = deep_toml(tmp_path)
    assert main([command, str(path)]) == 2
    assert "nested more than" in one_line_error(capsys, prog)


@pytest.mark.parametrize("main, prog", [(qdots_main, "qdots"), (planarize_main, "planarize")])
def test_sweeps_refuse_a_deep_base_file_in_one_line(tmp_path, capsys, main, prog):
    deep_toml(tmp_path, "base.toml")
    sweep = tmp_path / "sweep.toml"
    sweep.write_text('base = "base.toml"\n[axes]\nseed = [1, 2]\n')
    assert main(["sweep", str(sweep)]) == 2
    line = one_line_error(capsys, prog)
    assert "base.toml: invalid TOML: tables and arrays nested more than" in line


@pytest.mark.parametrize("value", ["7" * 10_000, "1" + "0" * 400], ids=["10000 digits", "401 digits"])
def test_qdots_run_refuses_huge_integers_in_one_line(tmp_path, capsys, value):
    path = tmp_path / "big.toml"
    path.write_text(SMALL_EXPERIMENT + f"sigma = {value}\n")
    assert qdots_main(["run", str(path), "--out", str(tmp_path / "out")]) == 2
    assert "invalid TOML" in one_line_error(capsys, "qdots")


# -- JSON ----------------------------------------------------------------------------------------

def test_deep_json_is_refused():
    for text in ["[" * 10_000 + "]" * 10_000, '{"a": ' * 10_000 + "1" + "}" * 10_000]:
        with pytest.raises(InputError, match=rf"^x\.json: invalid JSON: arrays and objects nested more than "
                                             rf"{JSON_MAX_DEPTH} deep"):
            parse_json(text, "x.json")
    assert parse_json("[" * JSON_MAX_DEPTH + "]" * JSON_MAX_DEPTH) == eval("[" * JSON_MAX_DEPTH + "]" * JSON_MAX_DEPTH)
    assert parse_json('{"a": "[[[[{{{{\\"]]"}') == {"a": '[[[[{{{{"]]'}  # brackets in strings are text


def test_big_json_is_refused(tmp_path):
    with pytest.raises(InputError, match="an integer of 10,000 digits"):
        parse_json("7" * 10_000)
    assert parse_json(str(2**128)) == 2**128  # a generator state: 39 digits
    with pytest.raises(InputError, match=f"more than {JSON_MAX_CONTAINERS:,} arrays and objects"):
        parse_json("[" + "[]," * JSON_MAX_CONTAINERS + "[]]")
    path = tmp_path / "x.json"
    path.write_text("[1, 2, 3]")
    assert read_json(path, "record") == [1, 2, 3]
    with pytest.raises(InputError, match=r"x\.json: the record is 9 bytes, more than the 8 read"):
        read_json(path, "record", max_bytes=8)
    with pytest.raises(FileNotFoundError):
        read_json(tmp_path / "absent.json", "record")


def write_npz(path, members: dict) -> None:
    """An .npz of ``members``: arrays (saved with np.save) or raw ``.npy`` bytes."""
    with zipfile.ZipFile(path, "w") as archive:
        for name, value in members.items():
            if isinstance(value, bytes):
                archive.writestr(f"{name}.npy", value)
            else:
                buffer = io.BytesIO()
                np.save(buffer, value, allow_pickle=True)
                archive.writestr(f"{name}.npy", buffer.getvalue())


def state_arrays(n=3):
    return {"positions": np.full((n, 2), 20.0), "velocities": np.zeros((n, 2)), "radii": np.full(n, 4.0),
            "masses": np.ones(n), "segments": np.zeros((0, 4))}


@pytest.fixture
def state(tmp_path):
    """A small, valid qdots state file."""
    scene = qdots.Scene(box=(100, 100), positions=[[20, 20], [50, 50], [80, 30]], radii=[4, 4, 5])
    return qdots.save(qdots.Simulation(scene, [qdots.ThermalKicks()], seed=1), tmp_path / "good.npz")


def saved_members(path) -> dict:
    with zipfile.ZipFile(path) as archive:
        return {info.filename[:-4]: archive.read(info) for info in archive.infolist()}


def test_state_metadata_and_forces_nested_deep_are_refused(tmp_path, state, capsys):
    metadata = json.loads(str(np.load(state)["metadata"]))
    deep = "[" * 10_000 + "]" * 10_000
    forces = json.dumps({**metadata, "forces": []}).replace('"forces": []', f'"forces": {deep}')
    for where, text in [("metadata", deep), ("forces", forces)]:
        bad = tmp_path / f"deep-{where}.npz"
        write_npz(bad, {**saved_members(state), "metadata": np.array(text)})
        with pytest.raises(InputError, match=r"is not a readable qdots state file: metadata: invalid JSON: arrays "
                                             r"and objects nested more than"):
            qdots.read_state(bad)
        for command in (["render", str(bad), "--out", str(tmp_path / "x.png")], ["analyze", str(bad)],
                        ["resume", str(bad), "--seconds", "0.01", "--out", str(tmp_path / "out")]):
            assert qdots_main(command) == 2
            assert "nested more than" in one_line_error(capsys, "qdots")


def test_planarize_run_metadata_nested_deep_is_refused(tmp_path):
    bad = tmp_path / "run.npz"
    write_npz(bad, {"metadata": np.array('{"format": "planarize-run", "version": 1, "parameters": '
                                         + "[" * 10_000 + "]" * 10_000 + "}")})
    with pytest.raises(InputError, match="is not a readable planarize run file: metadata: invalid JSON: arrays and "
                                         "objects nested more than"):
        load_run(bad)


def square(params):
    return {"y": params["x"] ** 2}


def test_a_deep_or_huge_sweep_record_is_run_again(tmp_path):
    sweep = Sweep(base={"x": 1.0}, axes={"x": [1.0, 2.0]})
    first = run_sweep(sweep, square, tmp_path / "s", workers=1, progress=False)
    records = sorted((tmp_path / "s" / "runs").iterdir())
    records[0].write_text("[" * 10_000 + "]" * 10_000)
    records[1].write_text('{"id": ' + "7" * 10_000 + "}")
    again = run_sweep(sweep, square, tmp_path / "s", workers=1, progress=False)
    assert again.ran == 2 and [r["y"] for r in again.rows] == [r["y"] for r in first.rows] == [1.0, 4.0]


@pytest.mark.parametrize("change, message", [
    (lambda meta: "[" * 10_000 + "]" * 10_000, "invalid JSON: arrays and objects nested more than"),
    (lambda meta: json.dumps({**meta, "swept": [["x"]]}), r"swept must be a list of column names, got \[\['x'\]\]"),
    (lambda meta: json.dumps({**meta, "seed_key": {"a": 1}}), "seed_key must be a column name or null"),
    (lambda meta: json.dumps([meta]), "swept must be a list of column names, got None"),
], ids=["deep", "swept of lists", "seed_key of a table", "not an object"])
def test_a_malformed_sweep_json_is_refused_by_sweep_plot(tmp_path, capsys, change, message):
    result = run_sweep(Sweep(base={"x": 1.0}, axes={"x": [1.0, 2.0]}), square, tmp_path / "s", workers=1,
                       progress=False)
    assert [s["n"] for s in summarize(result.table, "y", "x")] == [1, 1]
    meta_path = tmp_path / "s" / "sweep.json"
    meta_path.write_text(change(json.loads(meta_path.read_text())))
    with pytest.raises(InputError, match=message):
        summarize(result.table, "y", "x")
    assert qdots_main(["sweep-plot", str(result.table), "--metric", "y", "--x", "x"]) == 2
    assert "sweep.json: " in one_line_error(capsys, "qdots")


# -- archives ------------------------------------------------------------------------------------

def npy_header(shape, dtype="<f8") -> bytes:
    """The ``.npy`` header (format 1.0) of an array of ``shape`` and ``dtype``, without its data."""
    buffer = io.BytesIO()
    np.lib.format.write_array_header_1_0(buffer, {"descr": dtype, "fortran_order": False, "shape": shape})
    return buffer.getvalue()


@pytest.mark.parametrize("shape, declared", [
    ((10**12, 2), r"1000000000000 x 2 float64 values \(16,000,000,000,000 bytes\) but holds 80 bytes"),
    ((1, 2), r"1 x 2 float64 values \(16 bytes\) but holds 80 bytes"),
], ids=["10**12 rows", "1 row"])
def test_a_state_whose_header_lies_about_its_size_is_refused(tmp_path, state, capsys, shape, declared):
    bad = tmp_path / "forged.npz"
    write_npz(bad, {**saved_members(state), "positions": npy_header(shape) + bytes(80)})
    with pytest.raises(InputError, match=rf"forged\.npz is not a readable qdots state file: positions\.npy declares "
                                         rf"{declared}"):
        qdots.read_state(bad)
    for command in (["render", str(bad), "--out", str(tmp_path / "x.png")], ["analyze", str(bad)],
                    ["resume", str(bad), "--seconds", "0.01", "--out", str(tmp_path / "out")]):
        assert qdots_main(command) == 2
        assert "declares" in one_line_error(capsys, "qdots")


def test_a_planarize_run_declaring_a_huge_grid_is_refused(tmp_path):
    bad = tmp_path / "run.npz"
    write_npz(bad, {"metadata": np.array('{"format": "planarize-run", "version": 1}'),
                    **{name: np.zeros((2, 2)) for name in RUN_ARRAYS}, "metal": npy_header((10**6, 10**6)) + bytes(80)})
    with pytest.raises(InputError, match=r"metal\.npy declares 1000000 x 1000000 float64 values "
                                         r"\(8,000,000,000,000 bytes\) but holds 80 bytes"):
        load_run(bad)


def test_an_inflating_member_is_refused_before_it_is_read(tmp_path, state):
    """160 MB of positions deflated to a few hundred kB: refused from the size the archive declares."""
    bad = tmp_path / "bomb.npz"
    rows = 10 * MAX_ARRAY_BYTES["positions"] // 16
    members = saved_members(state)
    header = npy_header((rows, 2))
    with zipfile.ZipFile(bad, "w", zipfile.ZIP_DEFLATED) as archive:
        for name, data in members.items():
            if name != "positions":
                archive.writestr(f"{name}.npy", data)
        with archive.open("positions.npy", "w", force_zip64=True) as stream:
            stream.write(header)
            chunk = bytes(10**6)
            for _ in range(rows * 16 // len(chunk)):
                stream.write(chunk)
    assert bad.stat().st_size < 2**20
    tracemalloc.start()
    try:
        with pytest.raises(InputError, match=rf"its array 'positions' is {rows * 16 + len(header):,} bytes, more "
                                             rf"than the {MAX_ARRAY_BYTES['positions']:,} this format holds"):
            qdots.read_state(bad)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak < 50 * 2**20


def test_members_that_are_not_arrays_of_numbers_are_refused(tmp_path, state):
    members = saved_members(state)
    cases = [
        ({"positions": np.array([None, {"a": 1}], dtype=object)}, r"positions\.npy holds object values, not numbers"),
        ({"positions": np.array(["a", "b"])}, r"positions\.npy holds <U1 values, not numbers"),
        ({"positions": b"\x93NUMPY\x01\x00\x76\x00{'descr': '<f8', 'fortran_order': False, 'shape': (((("}, "damaged"),
        ({"extra": np.zeros(2)}, "it holds an array 'extra', which this format has not"),
        ({"metadata": np.array(["{}", "{}"])}, r"its metadata is an array of shape \(2,\), not one string"),
        ({"metadata": npy_header((), "<U100000000") + bytes(8)},
         r"metadata\.npy declares one <U100000000 values \(400,000,000 bytes\) but holds 8 bytes"),
        ({"positions": npy_header((2,), "<U1000000000") + bytes(8)}, "damaged .npy header .*not a valid dtype"),
    ]
    for change, message in cases:
        bad = tmp_path / "bad.npz"
        write_npz(bad, {**members, **change})
        with pytest.raises(InputError, match=message):
            qdots.read_state(bad)
    with zipfile.ZipFile(bad, "a") as archive:
        archive.writestr("notes.txt", "hello")
    with pytest.raises(InputError, match="its member 'notes.txt' is not a .npy array"):
        qdots.read_state(bad)


def test_metadata_longer_than_the_limit_is_refused(tmp_path, state):
    bad = tmp_path / "long.npz"
    text = json.dumps({"format": "qdots-state", "pad": "x" * MAX_METADATA_CHARS})
    long_metadata = io.BytesIO()
    np.save(long_metadata, np.array(text))
    with zipfile.ZipFile(bad, "w", zipfile.ZIP_DEFLATED) as archive:  # 4 MB of text in a few kB
        for name, data in {**saved_members(state), "metadata": long_metadata.getvalue()}.items():
            archive.writestr(f"{name}.npy", data)
    with pytest.raises(InputError, match=rf"metadata\.npy holds {4 * len(text):,} bytes of values, more than the "
                                         rf"{4 * MAX_METADATA_CHARS:,} this format holds"):
        qdots.read_state(bad)


def test_arrays_up_to_the_callers_limit_are_read(tmp_path):
    """The limit counts the values, not the .npy header: an array of exactly the limit is read, one value more
    is refused, an array the limits do not name is refused."""
    path = tmp_path / "x.npz"
    limits = {"grid": 10 * 8, "series_*": 3 * 8}
    write_archive(path, {"format": "test", "version": 1}, {"grid": np.ones((2, 5)), "series_a": np.arange(3)})
    metadata, arrays = read_archive(path, "test", 1, ["grid"], max_bytes=limits)
    assert metadata == {"format": "test", "version": 1} and arrays["grid"].shape == (2, 5)
    assert arrays["series_a"].tolist() == [0, 1, 2]
    for extra, message in [({"grid": np.ones(11)}, r"grid\.npy holds 88 bytes of values, more than the 80"),
                           ({"series_b": np.ones(4)}, r"series_b\.npy holds 32 bytes of values, more than the 24"),
                           ({"other": np.ones(1)}, "it holds an array 'other', which this format has not")]:
        write_archive(path, {"format": "test", "version": 1}, {"grid": np.ones((2, 5)), **extra})
        with pytest.raises(InputError, match=message):
            read_archive(path, "test", 1, ["grid"], max_bytes=limits)


# -- printing control characters -----------------------------------------------------------------

def test_printable_escapes_control_characters_only():
    escaped = "dots\\x1b[2J\\x07\\r\\n\\t\\x00\\x7f\\x9b é ✓ \\x"
    assert printable("dots\x1b[2J\x07\r\n\t\x00\x7f\x9b é ✓ \\x") == escaped
    assert printable(ValueError("a\x1bb")) == "a\\x1bb"


def test_print_table_escapes_what_it_prints(capsys):
    print_table("scene \x1b[31mred\r:", [("name\x07", "a\x1b[2Jb"), ("k", "v")])
    out = capsys.readouterr().out
    assert "\x1b" not in out and "\x07" not in out and "\r" not in out
    assert out.splitlines() == ["scene \\x1b[31mred\\r:", "  name\\x07  a\\x1b[2Jb", f"  {'k':<8}  v"]


def test_the_error_line_escapes_control_characters(capsys):
    def fail(args):
        raise InputError("name 'a\x1b[2J\rb' is\nbad")

    _, main = command_line("prog", "a test", [Command("go", "fail", fail)])
    assert main(["go"]) == 2
    assert one_line_error(capsys, "prog") == "prog: error: name 'a\\x1b[2J\\rb' is\\nbad"


def test_a_name_with_control_characters_is_kept_and_printed_escaped(tmp_path, capsys):
    path = tmp_path / "esc.toml"
    path.write_text(SMALL_EXPERIMENT.replace('name = "small"', 'name = "fu\\u001b[31mzz\\u0007x\\r"'))
    assert load_experiment(path).name == "fu\x1b[31mzz\x07x\r"  # names are data
    assert qdots_main(["run", str(path), "--out", str(tmp_path / "out")]) == 0  # no glyph warning (an error here)
    out = capsys.readouterr().out
    assert "fu\\x1b[31mzz\\x07x\\r" in out and "\x1b" not in out and "\x07" not in out and "\r" not in out
    table = (tmp_path / "out" / "summary.csv").read_text()  # written escaped, read back as written
    assert "fu\\x1b[31mzz\\x07x\\r" in table and not any(c in table for c in "\x1b\x07\r")
    assert len(table.splitlines()) == 2


def test_control_characters_are_escaped_in_sweep_tables_and_planarize_stderr(tmp_path, capsys):
    pytest.importorskip("pyarrow")
    import pyarrow.parquet as pq

    name = "a\x1b[2Jb\nc"
    result = run_sweep(Sweep(base={"name": name, "x": 1}, axes={"x": [1, 2]}), lambda p: {"y": p["x"], "tag": name},
                       tmp_path / "sweep", workers=1, progress=False)
    text = result.table.read_text()
    assert "a\\x1b[2Jb\\nc" in text and "\x1b" not in text and len(text.splitlines()) == 3
    for column in pq.read_table(result.parquet).to_pydict().values():
        assert not any(isinstance(v, str) and "\x1b" in v for v in column)
    assert pq.read_table(result.parquet).to_pydict()["tag"] == ["a\\x1b[2Jb\\nc"] * 2
    scene = tmp_path / "hill.toml"
    assert planarize_main(["scene", "hill", "--quick", "0.25", "--save", str(scene)]) == 0
    text = scene.read_text()
    scene.write_text(text.replace('name = "hill quick 0.25"', 'name = "h\\u001b[31mill"'))
    assert scene.read_text() != text
    assert planarize_main(["run", str(scene), "--out", str(tmp_path / "out")]) == 0  # no glyph warning
    captured = capsys.readouterr()
    assert "\x1b" not in captured.out + captured.err and "h\\x1b[31mill" in captured.out


def test_an_empty_complex_array_in_a_state_file_is_an_empty_float_array():
    """A case the state-file fuzzer found: empty arrays of any kind hold no bad value and load as float
    (casting an empty complex array warned, and warnings are errors)."""
    from labrig.validate import array

    segments = array("segments", np.zeros((0, 4), dtype=complex), (None, 4))
    assert segments.shape == (0, 4) and segments.dtype == np.float64
