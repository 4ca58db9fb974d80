"""The anodization model (thesis section 3.3): what happens to the surfaces, apart from how it is computed.

A `Model` is the physics every engine computes: the metal point closest to the oxide is lowered by
``step`` and its closest oxide points raised by ``(k_exp - 1) step`` shared by Eq 3.9, distances
measured between the features ``distance`` names, volume accounted by ``volume``. The engines
(`planarize.engines`) differ only in how they find and update those distances.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import ClassVar

from labrig.params import Param, check_fields

#: Distance kinds: the thesis's point/segment pairs, or the exact surface distance (`planarize.engines.features`).
DISTANCES = ("thesis", "exact")
#: Volume accounting: exact for the piecewise-linear surface, or the thesis's equal weights.
VOLUME_RULES = ("exact", "thesis")
#: Where the oxide grows: the thesis's rule (each bit of metal becomes oxide at its nearest oxide point,
#: so the volume balances at every point), or "conformal" (the metal recedes at one speed everywhere and
#: the oxide is its conformal coat: the volume balances over the whole surface). Only the continuum
#: engine computes "conformal".
RULES = ("thesis", "conformal")
#: Oxide volume per metal volume: at least 1 (an oxide that takes less room than its metal does not
#: planarize), at most 5 (the Pilling-Bedworth ratios of real metals lie between about 0.5 and 4;
#: Ta2O5 2.3, Nb2O5 2.7, WO3 3.4, Al2O3 ~1.3).
K_EXP_RANGE = (1.0, 5.0)
#: Largest metal height consumed per oxidation, nm.
MAX_STEP = 1e3


@dataclass(frozen=True)
class Model:
    """The physics of a run (thesis section 3.3).

    Parameters
    ----------
    k_exp : float
        Oxide volume per metal volume consumed, in `K_EXP_RANGE` (Ta 2.3, Al ~1.3).
    step : float
        Metal height consumed per oxidation of one point, nm, in (0, `MAX_STEP`] (thesis 0.01 for the
        hill, 0.5 for the Ta film).
    distance : {"thesis", "exact"}
        Feature pairs compared (`planarize.engines.features`): the thesis's points and segments, or
        the exact distance to the triangulated surfaces.
    volume : {"exact", "thesis"}
        Volume accounting: exact for the piecewise-linear surface (edge points of an open grid
        carry half the area), or the thesis's equal weights (exact on periodic grids only).
    rule : {"thesis", "conformal"}
        Where the oxide grows (`RULES`): the thesis's rule, or the plain reading of "metal preserved,
        oxide conformal" (uniform recession of the metal; continuum engine only).

    ``step``, ``distance`` and ``volume`` are numerical choices of the thesis's discrete algorithm
    (the reference, Matlab and fast engines); the continuum engine computes their common limit.
    """

    k_exp: float = 2.3
    step: float = 0.01
    distance: str = "thesis"
    volume: str = "exact"
    rule: str = "thesis"

    #: Each field's declaration (`labrig.params.Param`), also the scene file's ``[run]`` keys of the model.
    PARAMS: ClassVar[dict[str, Param]] = {
        "step": Param("float", 0.0, MAX_STEP, low_open=True, unit="nm", doc="metal height consumed per oxidation",
                      rule="at most the thickness (thesis: 0.01 hill, 0.5 Ta; the thesis's engines only)"),
        "k_exp": Param("float", *K_EXP_RANGE, doc="oxide volume per metal volume consumed (Ta 2.3, Al ~1.3)"),
        "distance": Param("str", choices=DISTANCES, doc="distance between the thesis's points and segments, "
                                                        "or between the triangulated surfaces"),
        "volume": Param("str", choices=VOLUME_RULES, doc="volume accounting: exact, or the thesis's equal weights"),
        "rule": Param("str", choices=RULES, doc='where the oxide grows ("conformal": continuum engine only)'),
    }

    def __post_init__(self) -> None:
        check_fields(self, self.PARAMS)

    def replace(self, **changes) -> Model:
        """A copy with some fields changed, validated again."""
        return dataclasses.replace(self, **changes)
