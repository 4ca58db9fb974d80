"""The command lines answer ``--help``, ``--version`` and argument errors without loading the simulators (numba,
scipy, pymunk, matplotlib: seconds of imports); how fast that is, is measured by ``python -m benchmarks.cold_start``.
"""

import json
import subprocess
import sys
import textwrap

#: What no answer of `CASES` may import; the top level's answers import no numpy either.
HEAVY = ("numba", "scipy", "pymunk", "matplotlib", "tqdm", "qdots.simulation", "qdots.geometry",
         "planarize.engines.continuum", "planarize.engines.fast", "planarize.anodize")
#: (program, arguments, exit status, numpy allowed): the answers that must come at once, those that import no numpy
#: first (they run in turn in one process).
CASES = [
    ("qdots", ["--help"], 0, False), ("qdots", ["--version"], 0, False), ("qdots", [], 2, False),
    ("qdots", ["nosuch"], 2, False), ("qdots", ["demo", "--dots", "0"], 2, False),
    ("planarize", ["--help"], 0, False), ("planarize", ["--version"], 0, False), ("planarize", ["nosuch"], 2, False),
    ("qdots", ["run"], 2, True), ("qdots", ["run", "x.toml", "--engine", "verlet"], 2, True),
    ("qdots", ["run", "--help"], 0, True), ("qdots", ["preset", "nosuch"], 2, True), ("qdots", ["resume"], 2, True),
    ("qdots", ["render"], 2, True), ("qdots", ["analyze", "--traps", "2"], 2, True), ("qdots", ["sweep"], 2, True),
    ("qdots", ["sweep-plot"], 2, True), ("planarize", ["sweep-plot"], 2, True),
    ("qdots", ["measure", "--help"], 0, True), ("qdots", ["compare", "--help"], 0, True),
    ("qdots", ["infer", "--help"], 0, True), ("planarize", ["import", "--help"], 0, True),
    ("planarize", ["run", "--help"], 0, True), ("qdots", ["measure", "nofile.png"], 2, True),
    ("qdots", ["measure", "film.xyz"], 2, True), ("qdots", ["mesure"], 2, False),
    ("qdots", ["measure", "--scalebar", "5nm", "x.png"], 2, True),
]
PROBE = textwrap.dedent("""
    import contextlib, io, json, sys
    from labrig.launch import launch

    found = []
    for prog, argv, status, numpy in json.loads(sys.argv[1]):
        with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()) as err:
            got = launch(prog, f"{prog}.cli", argv)
        loaded = [name for name in (*json.loads(sys.argv[2]), *(() if numpy else ("numpy",))) if name in sys.modules]
        found.append([prog, argv, got, loaded, err.getvalue().strip().splitlines()[-1:]])
    print(json.dumps(found))
""")


def test_help_version_and_argument_errors_load_no_simulator():
    done = subprocess.run([sys.executable, "-c", PROBE, json.dumps(CASES), json.dumps(HEAVY)], capture_output=True,
                          text=True, timeout=120)
    assert done.returncode == 0, done.stderr[-2000:]
    found = json.loads(done.stdout)
    assert len(found) == len(CASES)
    for (prog, argv, status, _), (_, _, got, loaded, last) in zip(CASES, found):
        assert got == status and loaded == [], (prog, argv, got, loaded, last)
        if status == 2:  # one line naming the program, never a traceback
            assert last and last[0].startswith(f"{prog}: error: "), (prog, argv, last)
