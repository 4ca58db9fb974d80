"""Parameter sweeps that scale from a laptop to a cluster; no physics, usable by any package.

>>> from labrig.sweeps import Sweep, run_sweep, plot_sweep
>>> def run_one(params):                            # module level, so worker processes can import it
...     return {"y": params["x"] ** 2 + params["seed"]}
>>> sweep = Sweep(base={"x": 0.0, "seed": 0}, axes={"x": {"start": 0, "stop": 1, "num": 5}}, seeds=3)
>>> result = run_sweep(sweep, run_one, "out")       # doctest: +SKIP
>>> plot_sweep(result.rows, "y", x="x")             # doctest: +SKIP

* `Sweep` (`labrig.sweeps.spec`): base parameters, axes (lists or ranges over
  dotted keys), explicit points, seeds; expanded into runs identified by a
  hash of their full parameters. Sweep files (TOML): `labrig.sweeps.files`.
* `run_sweep` (`labrig.sweeps.execute`): local process pool (default: all
  cores) or a Dask cluster (``scheduler=``); one record file per run,
  resumable, failed runs recorded with their error; one progress bar.
* `read_table`, `summarize`, `plot_sweep`, `save_sweep_plot`: the gathered
  table (CSV, Parquet with pyarrow) and mean +- standard error figures.

Reproducible: a run's result depends only on its parameters (its seed is one
of them), so equal sweeps give equal tables whatever the executor, the
number of workers and the order in which runs finish. Physics lives in the
runners: `qdots.cli.sweep` and `planarize.cli.sweep`.
"""

from ..lazy import exports

#: Where each public name lives (imported when first used: the command lines register the sweep commands
#: without loading the sweep machinery).
_NAMES = {"SweepResult": "execute", "run_sweep": "execute", "SweepFile": "files", "load_sweep_file": "files",
          "sweep_from_dict": "files", "plot_sweep": "plot", "save_sweep_plot": "plot", "summarize": "plot",
          "Run": "spec", "Sweep": "spec", "run_id": "spec", "read_table": "table"}

__all__ = ["Sweep", "Run", "run_id", "run_sweep", "SweepResult", "SweepFile", "load_sweep_file", "sweep_from_dict",
           "read_table", "summarize", "plot_sweep", "save_sweep_plot"]


__getattr__, __dir__ = exports(__name__, _NAMES)
