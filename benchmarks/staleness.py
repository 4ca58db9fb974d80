"""Which sections of the performance report are older than the code they measure, from git.

Each benchmark module names the code it measures in ``MEASURED_CODE`` (paths in the repository, files or folders); its
own module counts too. A section is *older than its code* when a commit that touched one of those paths is dated
after the section's run (the commit's author date, which a rebase keeps, against the run's date in the report's
data). The report's summary table marks such sections, so a figure measured on code that has changed since says so.
Where git or the repository is not there (an installed copy), the status is unknown and nothing is marked.
"""

from __future__ import annotations

import datetime
import subprocess
from pathlib import Path

#: The repository the benchmarks live in.
ROOT = Path(__file__).resolve().parent.parent
#: Longest a git query may take, s.
GIT_TIMEOUT = 30
#: The files of each qdots engine (those they share in both), for benchmarks that measure one engine only.
CHIPMUNK_ENGINE = tuple(f"qdots/engine/{name}.py" for name in (
    "__init__", "allocator", "bodies", "chipmunk", "chipmunk_backend", "chipmunk_step", "contacts", "pair_scheme",
    "protocol", "pymunk_adapter", "settings"))
EVENT_ENGINE = tuple(f"qdots/engine/{name}.py" for name in (
    "__init__", "allocator", "contacts", "event", "event_backend", "event_calendar", "event_loop", "pair_scheme",
    "protocol", "settings"))


def last_change(paths, root: Path = ROOT) -> str | None:
    """The author date (ISO 8601) of the last commit that touched any of ``paths`` (relative to ``root``), or None
    when git cannot tell (no git, no repository, no such commit)."""
    try:
        run = subprocess.run(["git", "log", "-1", "--format=%aI", "--", *map(str, paths)], cwd=root,
                             capture_output=True, text=True, timeout=GIT_TIMEOUT)
    except (OSError, subprocess.SubprocessError):
        return None
    date = run.stdout.strip()
    return date if run.returncode == 0 and date else None


def parse(date: str) -> datetime.datetime:
    """An ISO 8601 date with its offset (a date without one is taken as UTC)."""
    value = datetime.datetime.fromisoformat(date)
    return value if value.tzinfo else value.replace(tzinfo=datetime.timezone.utc)


def is_stale(run_date: str, changed: str | None) -> bool:
    """True when the code was changed (``changed``, ISO 8601) after the section was run (``run_date``)."""
    return changed is not None and parse(changed) > parse(run_date)


def measured_paths(name: str) -> list[str]:
    """The paths ``benchmarks.<name>`` measures: its ``MEASURED_CODE`` and its own module."""
    import importlib

    module = importlib.import_module(f"benchmarks.{name}")
    return [f"benchmarks/{name}.py", *getattr(module, "MEASURED_CODE", ())]


def status(name: str, run_date: str, root: Path = ROOT) -> str:
    """``""`` when the section of ``name`` run on ``run_date`` is not older than its code, else what changed when."""
    changed = last_change(measured_paths(name), root)
    if not is_stale(run_date, changed):
        return ""
    return f"older than its code (changed {parse(changed).date().isoformat()})"
