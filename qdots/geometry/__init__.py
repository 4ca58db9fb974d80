"""Geometry of a board of discs: pair searches, overlaps, clashes and clearances, each written once.

* `qdots.geometry.pairs` -- which dots are near which: the engine's compiled cell-grid search
  (`pairs_within`, `VerletPairs`, `pairs_closer`, `pair_separation`) and the analysis's KD-tree search
  with distances (`pairs_with_distances`), bounded by `MAX_PAIRS` (`pair_bound`);
* `qdots.geometry.discs` -- discs against discs (`relative_overlap`, `overlapping_pairs`, `worst_overlap`,
  `nested_pairs`, `clashing_pairs`, `nearest_ratio`, `nearest_centre`, `DiscTree`) and against wall segments (`segment_distances`,
  `wall_clearances`, `worst_wall_overlap`, `clear_of_walls`).

Every scene check, deposition, analysis and hard case measures with these: no other module has its own
pair search or overlap formula.
"""

from .discs import (
    MAX_DISTANCES,
    NESTING_SLACK,
    REACH_SLACK,
    DiscTree,
    clashing_pairs,
    clear_of_walls,
    nearest_centre,
    nearest_ratio,
    nested_pairs,
    overlapping_pairs,
    relative_overlap,
    segment_distances,
    wall_clearances,
    worst_overlap,
    worst_wall_overlap,
)
from .pairs import (
    MAX_GRID_CELLS,
    MAX_PAIRS,
    MAX_SKIN,
    VerletPairs,
    extent,
    moved_beyond,
    pair_bound,
    pair_separation,
    pairs_closer,
    pairs_with_distances,
    pairs_within,
)

__all__ = [
    "MAX_PAIRS", "MAX_GRID_CELLS", "MAX_SKIN", "MAX_DISTANCES", "NESTING_SLACK", "REACH_SLACK",
    "pair_separation", "pairs_within", "pairs_with_distances", "pair_bound", "pairs_closer", "VerletPairs",
    "moved_beyond", "extent",
    "relative_overlap", "overlapping_pairs", "worst_overlap", "nested_pairs", "clashing_pairs", "nearest_ratio", "nearest_centre",
    "DiscTree",
    "segment_distances", "wall_clearances", "worst_wall_overlap", "clear_of_walls",
]
