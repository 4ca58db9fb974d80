"""Measuring a board: every function takes a `qdots.State` (or a saved one, `qdots.read_state`).

* `qdots.analysis.packing` -- neighbours, interior dots, separation, fill within a radius, the
  packing summary (thesis Fig 2-4, Table 2.1); its names are also here, as ``qdots.analysis.*``;
* `qdots.analysis.structure` -- hexatic order, g(r), clusters, Voronoi coordination;
* `qdots.analysis.forster` -- the exciton hopping network (thesis Eq 2.3);
* `qdots.analysis.lqe` -- luminescence quantum efficiency, exact and Monte Carlo (Fig 2-5);
* `qdots.analysis.lqe_thesis` -- the thesis's fixed-step Monte Carlo, solved exactly;
* `qdots.analysis.report` -- the ``qdots analyze`` table and figure.
"""

from .packing import (
                      INTERIOR_MIN_NEIGHBOURS,
                      RULES,
                      FillCurve,
                      Separation,
                      escaped,
                      fill_within_radius,
                      neighbour_counts,
                      neighbour_edges,
                      overlaps,
                      packing_summary,
                      separation,
                      size_separation_correlation,
)

__all__ = ["RULES", "INTERIOR_MIN_NEIGHBOURS", "overlaps", "escaped", "neighbour_edges", "neighbour_counts", "Separation",
           "separation", "FillCurve", "fill_within_radius", "size_separation_correlation", "packing_summary"]
