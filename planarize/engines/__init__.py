"""The planarization engines: one model (`planarize.engines.base`), three ways to compute it.

* `planarize.engines.reference` -- the thesis's sequential algorithm (and its Matlab shortcuts);
* `planarize.engines.fast` -- batched sweeps with incremental updates, compiled with numba;
* `planarize.engines.features` -- which features are compared (the slot layout), and the sets;
* `planarize.engines.kernels`, `bookkeeping`, `pyramid`, `closer` -- the fast engine's compiled parts.
"""
