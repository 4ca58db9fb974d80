"""Benchmarks: each reports wall time beside an error measure, measured in the same run.

``python -m benchmarks [--quick] [--only NAME ...]`` runs those listed in `BENCHMARKS` and writes
``docs/performance.md`` and ``docs/figures/*.png``; ``python -m benchmarks.<name>`` runs one.
"""

#: The registration point: modules of this package run by ``python -m benchmarks``, in report order.
#: Each exposes ``run(quick: bool) -> list[benchmarks.report.Result]`` (see `benchmarks.report`);
#: a module without ``run`` is run as ``main([])`` in full mode (its printout kept) and skipped by --quick.
BENCHMARKS = [
    "qdots_knobs",
    "qdots_model_cost",
    "qdots_peers",
    "qdots_hard_cases",
    "qdots_engines",
    "qdots_event_choices",
    "qdots_energy_budget",
    "engine_overhead",
    "fig2_2_realtime",
    "analysis",
    "lqe",
    "micrograph",
    "micrograph_films",
    "micrograph_real",
    "micrograph_emps",
    "micrograph_bars",
    "micrograph_twins",
    "micrograph_jitter",
    "qdots_identifiability",
    "qdots_infer",
    "qdots_infer_limits",
    "planarize_reference",
    "planarize_fast",
    "planarize_accuracy",
    "planarize_continuum",
    "planarize_hard",
    "afm_real",
    "sweeps",
    "cold_start",
]
