"""A parameter sweep as plain data, and its expansion into runs.

A `Sweep` is base parameters (a nested dict), axes (dotted keys such as
``"deposition.sigma"``, each with a list of values or a range), explicit
points (dicts of dotted keys, each optionally ``label``-led) and seeds. Its
runs are ``points x product(axes) x seeds``, in that order (the last seed
varies fastest). Nothing here knows any physics: a runner's ``canonical``
function validates and completes each run's parameters, and a run is
identified by a hash of those full, canonical parameters, so two spellings
of the same run (a default written out or left implicit) are one run.

>>> sweep = Sweep(base={"x": 1.0, "seed": 10}, axes={"x": [1.0, 2.0]}, seeds=2)
>>> [run.columns for run in sweep.runs()]                       # doctest: +NORMALIZE_WHITESPACE
[{'x': 1.0, 'seed': 10}, {'x': 1.0, 'seed': 11}, {'x': 2.0, 'seed': 10}, {'x': 2.0, 'seed': 11}]
"""

from __future__ import annotations

import copy
import hashlib
import itertools
import json
import math
from dataclasses import dataclass, field
from typing import Callable, Mapping

from ..validate import MAX_SEED, InputError, count

#: Keys of a range axis: ``{start, stop, num}`` (evenly spaced, both ends) or ``{start, stop, step}``.
RANGE_KEYS = ("start", "stop", "num", "step")
#: Largest number of values one range may expand to (a typo guard).
MAX_RANGE = 100_000
#: Most runs in one sweep (points x axes x seeds), checked before any run is expanded.
MAX_RUNS = 100_000
#: Most runs a sweep starts unless the caller raises its ``max_runs`` (up to `MAX_RUNS`): a typo in a range
#: should not start a week of runs.
DEFAULT_MAX_RUNS = 1_000
#: Significant digits kept by range values (0.1 * 3 is 0.3, not 0.30000000000000004).
RANGE_DIGITS = 12


@dataclass(frozen=True)
class Run:
    """One run of a sweep.

    Attributes
    ----------
    id : str
        16 hex digits: SHA-256 of the runner's kind and the canonical parameters.
    index : int
        Position in the sweep's expansion order.
    params : dict
        Full, canonical parameters (what the runner receives).
    columns : dict
        What sets this run apart: its point's ``label`` (if any), then each
        swept key (point keys, axes, seed) with its canonical value.
    """

    id: str
    index: int
    params: dict
    columns: dict


def canonical_json(params) -> str:
    """``params`` as JSON with sorted keys and no spaces: equal parameters give equal text."""
    try:
        return json.dumps(params, sort_keys=True, separators=(",", ":"), ensure_ascii=False, allow_nan=False)
    except (TypeError, ValueError) as exc:
        raise InputError(f"parameters must be JSON data (tables, lists, strings, finite numbers, "
                         f"booleans): {exc}") from None


def run_id(kind: str, params) -> str:
    """Identifier of a run: the first 16 hex digits of SHA-256 over ``kind`` and `canonical_json`."""
    return hashlib.sha256(f"{kind}\n{canonical_json(params)}".encode()).hexdigest()[:16]


def _parts(key: str) -> list[str]:
    if not isinstance(key, str) or not key or any(not part for part in key.split(".")):
        raise InputError(f"a parameter key must be a dotted name such as 'deposition.sigma', got {key!r}")
    return key.split(".")


def get_path(tree, key: str, default=KeyError):
    """The value at dotted ``key`` in nested dicts/lists (list items by index: ``forces.0.r0``)."""
    node = tree
    for part in _parts(key):
        if isinstance(node, Mapping) and part in node:
            node = node[part]
        elif isinstance(node, list) and part.isdigit() and int(part) < len(node):
            node = node[int(part)]
        elif default is KeyError:
            raise KeyError(key)
        else:
            return default
    return node


def set_path(tree: dict, key: str, value) -> None:
    """Set dotted ``key`` in ``tree`` in place, creating missing tables on the way."""
    parts = _parts(key)
    node = tree
    for depth, part in enumerate(parts):
        last = depth == len(parts) - 1
        where = ".".join(parts[:depth]) or "the parameters"
        if isinstance(node, list):
            if not (part.isdigit() and int(part) < len(node)):
                raise InputError(f"cannot set {key!r}: {where} is a list of {len(node)}, "
                                 f"{part!r} is not an index in it")
            part = int(part)
        elif not isinstance(node, dict):
            raise InputError(f"cannot set {key!r}: {where} is {node!r}, not a table")
        if last:
            node[part] = copy.deepcopy(value)
        else:
            if isinstance(node, dict) and part not in node:
                node[part] = {}
            node = node[part]


def _number(where: str, value) -> float | int:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise InputError(f"{where} must be a finite number, got {value!r}")
    return value


def _round(value: float) -> float:
    return float(f"{value:.{RANGE_DIGITS}g}")


def range_values(key: str, spec: Mapping) -> tuple:
    """The values of a range axis ``{start, stop, num}`` or ``{start, stop, step}``, both ends included.

    Integers stay integers when ``start`` and ``step`` (or every ``num`` value) are whole;
    floats are rounded to `RANGE_DIGITS` significant digits.
    """
    where = f"axes.{key}"
    extra = [k for k in spec if k not in RANGE_KEYS]
    if extra:
        raise InputError(f"unknown key {extra[0]!r} in the range {where} (allowed: {', '.join(RANGE_KEYS)})")
    missing = [k for k in ("start", "stop") if k not in spec]
    if missing:
        raise InputError(f"the range {where} needs {' and '.join(missing)}")
    if ("num" in spec) == ("step" in spec):
        raise InputError(f"the range {where} needs exactly one of num (count) or step")
    start, stop = _number(f"{where}.start", spec["start"]), _number(f"{where}.stop", spec["stop"])
    if "num" in spec:
        num = spec["num"]
        if isinstance(num, bool) or not isinstance(num, int) or not 1 <= num <= MAX_RANGE:
            raise InputError(f"{where}.num must be an integer in [1, {MAX_RANGE}], got {num!r}")
        values = [start + (stop - start) * k / (num - 1) for k in range(num)] if num > 1 else [start]
        whole = all(isinstance(v, int) for v in (start, stop)) and all(float(v).is_integer() for v in values)
    else:
        step = _number(f"{where}.step", spec["step"])
        if step == 0 or (stop - start) / step < 0:
            raise InputError(f"{where}.step must be nonzero and lead from start ({start!r}) to stop ({stop!r}), "
                             f"got {step!r}")
        count = math.floor((stop - start) / step + 1e-9) + 1
        if count > MAX_RANGE:
            raise InputError(f"the range {where} has {count} values, more than {MAX_RANGE}")
        values = [start + k * step for k in range(count)]
        whole = isinstance(start, int) and isinstance(step, int)
    return tuple(int(round(v)) if whole else _round(float(v)) for v in values)


def axis_values(key: str, spec) -> tuple:
    """The values of one axis: a non-empty list of distinct values, or a range table."""
    _parts(key)
    if isinstance(spec, Mapping):
        return range_values(key, spec)
    if not isinstance(spec, (list, tuple)) or not spec:
        raise InputError(f"axes.{key} must be a non-empty list of values or a range table "
                         f"{{start, stop, num | step}}, got {spec!r}")
    values = tuple(spec)
    texts = [canonical_json(v) for v in values]
    if len(set(texts)) < len(texts):
        twice = next(v for v, t in zip(values, texts) if texts.count(t) > 1)
        raise InputError(f"axes.{key} lists {twice!r} twice")
    return values


def _seeds(seeds) -> int | tuple | None:
    if seeds is None:
        return None
    if isinstance(seeds, int) and not isinstance(seeds, bool):
        return count("seeds", seeds, 1, MAX_RUNS)
    if isinstance(seeds, (list, tuple)) and seeds and all(
            isinstance(s, int) and not isinstance(s, bool) and 0 <= s <= MAX_SEED for s in seeds):
        if len(seeds) > MAX_RUNS:
            raise InputError(f"seeds lists {len(seeds):,} seeds, more than the {MAX_RUNS:,} runs a sweep may have")
        if len(set(seeds)) < len(seeds):
            raise InputError(f"seeds lists a seed twice: {list(seeds)!r}")
        return tuple(seeds)
    raise InputError(f"seeds must be a count in [1, {MAX_RUNS:,}] or a non-empty list of integers in "
                     f"[0, {MAX_SEED}], got {seeds!r}")


def _point(k: int, point) -> dict:
    if not isinstance(point, Mapping):
        raise InputError(f"points[{k}] must be a table of parameter values, got {point!r}")
    point = dict(point)
    if "label" in point and not (isinstance(point["label"], str) and point["label"].strip()):
        raise InputError(f"points[{k}].label must be a non-empty string, got {point['label']!r}")
    for key in point:
        if key != "label":
            _parts(key)
    return point


def _identity(params: dict) -> dict:
    return json.loads(canonical_json(params))


def _describe(columns: dict) -> str:
    return ", ".join(f"{k}={v!r}" for k, v in columns.items()) or "the base"


@dataclass(frozen=True)
class Sweep:
    """Base parameters, axes, explicit points and seeds.

    Parameters
    ----------
    base : dict
        Parameters common to every run (nested tables).
    axes : dict
        Dotted key -> values: a non-empty list, or a range table
        ``{start, stop, num}`` / ``{start, stop, step}`` (`range_values`).
        Runs take the cartesian product of all axes.
    points : sequence of dict
        Explicit points: each a dict of dotted key -> value, optionally with a
        ``label`` (a string that becomes the table's ``label`` column). Runs
        take each point in turn, times the product of the axes. Default: one
        empty point (the base alone).
    seeds : int or sequence of int, optional
        A list of seeds, or a count ``n`` for the ``n`` seeds that start at the
        base's own seed (the canonical value at ``seed_key``, else 0). None:
        the base's seed only, no seed column.
    seed_key : str
        Where the seed goes in the parameters (qdots ``"seed"``, planarize
        ``"scene.seed"``).
    """

    base: dict
    axes: dict = field(default_factory=dict)
    points: tuple = ({},)
    seeds: int | tuple | None = None
    seed_key: str = "seed"

    def __post_init__(self) -> None:
        if not isinstance(self.base, Mapping):
            raise InputError(f"base must be a table of parameters, got {self.base!r}")
        if not isinstance(self.axes, Mapping):
            raise InputError(f"axes must be a table of key -> values, got {self.axes!r}")
        object.__setattr__(self, "base", copy.deepcopy(dict(self.base)))
        object.__setattr__(self, "axes", {key: axis_values(key, spec) for key, spec in self.axes.items()})
        points = self.points
        if isinstance(points, Mapping) or not isinstance(points, (list, tuple)) or not points:
            raise InputError(f"points must be a non-empty list of tables, got {points!r}")
        object.__setattr__(self, "points", tuple(_point(k, p) for k, p in enumerate(points)))
        labels = [p.get("label") for p in self.points]
        if any(labels) and (not all(labels) or len(set(labels)) < len(labels)):
            raise InputError(f"points must all have a label, each different, or none: got {labels!r}")
        object.__setattr__(self, "seeds", _seeds(self.seeds))
        if len(self) > MAX_RUNS:
            raise InputError(f"the sweep has {len(self):,} runs (points x axes x seeds), more than the {MAX_RUNS:,} "
                             f"a sweep may have")
        _parts(self.seed_key)
        if self.seeds is not None and (self.seed_key in self.axes or any(self.seed_key in p for p in self.points)):
            raise InputError(f"{self.seed_key!r} is set by seeds; do not also sweep it as an axis or point key")

    @property
    def swept(self) -> list[str]:
        """Column names that vary between runs: ``label``, point keys, axes, then the seed key."""
        keys = ["label"] if self.points[0].get("label") else []
        keys += [k for p in self.points for k in p if k != "label"]
        keys += list(self.axes)
        keys += [self.seed_key] if self.seeds is not None else []
        return list(dict.fromkeys(keys))

    def __len__(self) -> int:
        return math.prod(self.shape().values())

    def shape(self) -> dict:
        """How many values each factor of the run count has: ``points``, each axis, ``seeds``."""
        seeds = 1 if self.seeds is None else (self.seeds if isinstance(self.seeds, int) else len(self.seeds))
        return {"points": len(self.points), **{key: len(v) for key, v in self.axes.items()}, "seeds": seeds}

    def check_size(self, max_runs: int = DEFAULT_MAX_RUNS) -> int:
        """The number of runs; `InputError` when it exceeds ``max_runs`` (in [1, `MAX_RUNS`])."""
        max_runs = count("max_runs", max_runs, 1, MAX_RUNS)
        if len(self) > max_runs:
            factors = " x ".join(f"{n:,} {key}" for key, n in self.shape().items())
            raise InputError(f"the sweep has {len(self):,} runs ({factors}), more than the {max_runs:,} it may start: "
                             f"raise max_runs (--max-runs, at most {MAX_RUNS:,}) if that many are meant")
        return len(self)

    def runs(self, canonical: Callable[[dict], dict] | None = None, kind: str = "") -> list[Run]:
        """Every run, in order, with canonical parameters and ids.

        Parameters
        ----------
        canonical : callable, optional
            ``canonical(params) -> params``: validates a run's parameters and
            fills in every default; raises ValueError naming a bad key.
            Default: the parameters as JSON data, unchanged.
        kind : str
            Names the runner in each run's hash.

        Raises
        ------
        ValueError
            Naming the base, the axis, the point or the run whose parameters
            are bad, or two runs with identical parameters.
        """
        canonical = canonical or _identity

        def check(where: str, params: dict) -> dict:
            try:
                return canonical(params)
            except ValueError as exc:
                raise InputError(f"{where}: {exc}") from None

        base = check("base", copy.deepcopy(self.base))
        seeds = self.seeds
        if isinstance(seeds, int):
            first = get_path(base, self.seed_key, 0)
            if isinstance(first, bool) or not isinstance(first, int):
                raise InputError(f"seeds = {seeds} counts from the base's {self.seed_key!r}, "
                                 f"which must be an integer, got {first!r}")
            seeds = tuple(range(first, first + seeds))
        for k, point in enumerate(self.points):  # each point, then each axis, so an error names it
            check(f"points[{k}]", self._apply(self.base, point.items()))
        for key, values in self.axes.items():
            check(f"axes.{key}", self._apply(self.base, [*self.points[0].items(), (key, values[0])]))
        runs: list[Run] = []
        seen: dict[str, int] = {}
        grid = itertools.product(self.points, *self.axes.values(), seeds if seeds is not None else [None])
        for index, (point, *values) in enumerate(grid):
            seed = values.pop()
            changes = [*point.items(), *zip(self.axes, values)]
            if seed is not None:
                changes.append((self.seed_key, seed))
            raw = self._apply(self.base, changes)
            label = {"label": point["label"]} if "label" in point else {}
            where = f"run {index} ({_describe({**label, **dict((k, v) for k, v in changes if k != 'label')})})"
            params = check(where, raw)
            columns = {**label, **{key: get_path(params, key, None) for key in self.swept if key != "label"}}
            run = Run(run_id(kind, params), index, params, columns)
            if run.id in seen:
                raise InputError(f"{where} has the same parameters as run {seen[run.id]}: "
                                 f"every run of a sweep must differ")
            seen[run.id] = index
            runs.append(run)
        return runs

    @staticmethod
    def _apply(base: dict, changes) -> dict:
        params = copy.deepcopy(base)
        for key, value in changes:
            if key != "label":
                set_path(params, key, value)
        return params
