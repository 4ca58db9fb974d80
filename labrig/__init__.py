"""labrig: the physics-free rig that `qdots` and `planarize` stand on.

One module per job, no physics, no knowledge of either package:

* `labrig.validate` -- checks of values people give, errors that name the key and the range
  (`InputError`);
* `labrig.files` -- atomic writes, streamed writers, output sets, CSV tables, safe file names;
* `labrig.staging` -- the staging directories, locks and one-step switch behind output sets;
* `labrig.archive` -- ``.npz`` archives of arrays and JSON metadata, checked before they are loaded;
* `labrig.tomlfile` -- TOML parameter files: read, write exactly, check keys;
* `labrig.jsonfile` -- JSON read back (records, metadata), bounded in size and depth before it is parsed;
* `labrig.cli` -- the command-line contract (one-line errors, exit status 2) and argument types;
* `labrig.launch` -- the console entry points (a Ctrl-C at any moment of a command is one line);
* `labrig.progress` -- progress bars that say when numba compiles and keep it out of their ETA;
* `labrig.figures` -- figures saved atomically at a bounded resolution;
* `labrig.sweeps` -- parameter sweeps on local cores or a Dask cluster, resumable, one table;
* `labrig.movies` -- MP4 movies drawn with matplotlib, playable in browsers and slide decks;
* `labrig.widgets` -- ipympl canvases for notebook widgets.
"""

#: The version of the distribution (qdots, planarize and labrig are released together).
__version__ = "0.3.0"
