"""The README's Python examples run as they are written, pasted into a script (not only in a REPL), and print what
their comments say."""

import ast
import re
import subprocess
import sys
from pathlib import Path

import pytest

README = Path(__file__).resolve().parent.parent / "README.md"


def python_blocks() -> list[str]:
    return re.findall(r"```python\n(.*?)```", README.read_text(encoding="utf-8"), flags=re.S)


def test_the_readme_has_python_examples():
    assert len(python_blocks()) >= 2


@pytest.mark.parametrize("index", range(len(python_blocks())))
def test_each_readme_example_runs_as_a_script(tmp_path, index):
    code = python_blocks()[index]
    script = tmp_path / "example.py"
    script.write_text(code, encoding="utf-8")
    done = subprocess.run([sys.executable, str(script)], cwd=tmp_path, capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stderr[-3000:]
    lost = [ast.unparse(node) for node in ast.parse(code).body
            if isinstance(node, ast.Expr) and not isinstance(node.value, ast.Call)]
    assert not lost, f"lines whose value a script never shows (print them): {lost}"
    for said in re.findall(r"print\(.*\)\s+#\s*(.+)$", code, flags=re.M):  # what the comment says is printed
        assert said.strip() in done.stdout, (said, done.stdout)
