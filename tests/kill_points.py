"""Kill a command at every step of its output set's switch, and say what each kill left on disk.

Run as a script (``python kill_points.py OUT NAME PROG ARG...``) by ``test_output_sets.py``; ``OUT`` holds the
earlier set ``OUT/NAME`` (and, for qdots, ``OUT/summary.csv``). The command ``PROG ARG...`` runs in this
process until its set's switch begins (everything staged). There, for k = 1, 2, ..., a forked child carries
on with the switch and the rest of the command, and SIGKILLs itself just before the k-th change to the disk
that it makes (a rename, an exchange, a link, a removal, a new file); this process then compares what is on
disk, byte for byte, with the earlier set and with the new one (as the switch began), and puts ``OUT`` back
as it was for the next k. The first child that is not killed ran past the last step. Prints one JSON list:
per k, whether the child was killed, its exit status, and what the set and the summary table were ("old",
"new" or "mixed").
"""

import json
import os
import shutil
import signal
import sys
from pathlib import Path


def snapshot(directory: Path) -> dict:
    """Every visible file under ``directory`` (hidden staging directories and temporaries left out): bytes by
    relative path."""
    found = {}
    for root, dirs, files in os.walk(directory):
        dirs[:] = [d for d in dirs if not d.startswith(".")]
        for name in files:
            if not name.startswith("."):
                path = Path(root) / name
                found[str(path.relative_to(directory))] = path.read_bytes()
    return found


def verdict(now, old, new) -> str:
    return "old" if now == old else "new" if now == new else "mixed"


def count_steps(out: Path, expected: Path, k: int) -> None:
    """From now on, SIGKILL this process just before its k-th change to the disk (and keep a copy of the new
    summary table as it is put in place)."""
    import labrig.staging as staging

    steps = [0]

    def step():
        steps[0] += 1
        if steps[0] == k:
            os.kill(os.getpid(), signal.SIGKILL)

    def counted(function, created_only=False):
        def wrapper(*args, **kwargs):
            if not created_only or (len(args) > 1 and args[1] & os.O_CREAT):
                step()
            return function(*args, **kwargs)
        return wrapper

    replace = os.replace

    def replace_noting_the_table(source, target, *args, **kwargs):
        if Path(target) == out / "summary.csv":
            shutil.copyfile(source, expected / "summary.csv")
        step()
        return replace(source, target, *args, **kwargs)

    for name in ("rename", "unlink", "rmdir", "link", "symlink", "remove"):
        setattr(os, name, counted(getattr(os, name)))
    os.replace = replace_noting_the_table
    os.open = counted(os.open, created_only=True)
    staging.exchange = counted(staging.exchange)


def main(out: Path, name: str, prog: str, argv: list) -> None:
    import labrig.staging as staging
    from labrig.launch import launch

    stdout = os.dup(1)
    os.dup2(os.open(os.devnull, os.O_WRONLY), 1)  # the command's own output; its errors stay on stderr
    switch = staging.Staging.switch
    table = out / "summary.csv"
    old_set = snapshot(out / name)
    old_table = table.read_bytes() if table.exists() else None

    def tried_at_every_step(self, then=None):
        new_set = snapshot(self.path)
        pristine = out.with_name(out.name + ".pristine")
        shutil.copytree(out, pristine)
        results = []
        for k in range(1, 200):
            expected = out.with_name(f"{out.name}.expected")
            expected.mkdir()
            pid = os.fork()
            if pid == 0:  # the child goes on with the switch and the command, to its end or the k-th step
                count_steps(out, expected, k)
                return switch(self, then)
            _, status = os.waitpid(pid, 0)
            killed = os.WIFSIGNALED(status) and os.WTERMSIG(status) == signal.SIGKILL
            new_table = (expected / "summary.csv").read_bytes() if (expected / "summary.csv").exists() else None
            results.append({"k": k, "killed": killed,
                            "status": os.WEXITSTATUS(status) if os.WIFEXITED(status) else None,
                            "set": verdict(snapshot(out / name), old_set, new_set),
                            "table": verdict(table.read_bytes() if table.exists() else None, old_table, new_table),
                            "visible": sorted(p.name for p in out.iterdir() if not p.name.startswith("."))})
            shutil.rmtree(expected)
            shutil.rmtree(out)
            shutil.copytree(pristine, out)
            if not killed:
                break
        shutil.rmtree(pristine)
        os.write(stdout, json.dumps(results).encode())
        os._exit(0)

    staging.Staging.switch = tried_at_every_step
    os._exit(launch(prog, f"{prog}.cli", argv))  # a child's exit status; this process ends in the switch


if __name__ == "__main__":
    main(Path(sys.argv[1]), sys.argv[2], sys.argv[3], sys.argv[4:])
