"""The thesis's runs as `Experiment` presets (Appendix A, ``FileDepositer``).

==================  ============================================================================
``fig2-2``          300 free dots on 600 x 600 px, sigma 0 and 0.15, equal masses
                    (``runAttractionComparison``: ``runRandomAttraction(15, s, 300, false)``).
``fig2-3``          150 dots in a grating 6 lattice spacings wide (77.94 px), sigma 0 and 0.15,
                    masses ~ d^3 (``runAttractionGrating``: ``runRandomAttractionGrating(..., true)``).
``fig2-6``          equal vs d^3 masses at sigma 0, 0.05, 0.10, 0.15 (Fig 2-6a), and uniform size
                    with half the dots twice as heavy (Fig 2-6b, Table 2.1,
                    ``runRandomAttractionBimodal(15, 0, 15, 0, 2.0, 300, false)``).
``centre-gravity``  ``runCentralSuite(500)``: 500 dots dropped on a ring around the centre, pulled
                    in at 750 px/s^2 (``setGravity(25)`` x 30 px), drag ``setFriction(0.1, 0.1)``;
                    sigma 0 and 0.15, 0.5 s between dots, 15 s to settle (``advance(15000)``;
                    the Java comment says 100 s).
==================  ============================================================================

Figure runs set gravity and friction to zero (``setGravity(0)``,
``setFriction(0, 0)``): only van der Waals attraction and thermal kicks act.
Every run uses the Java's seed, ``new Random(154)``, as its root seed.

`NAMES` is known at import; the experiments (`PRESETS`) are made when first
used, so that the command line lists the presets without loading the
simulators.
"""

from __future__ import annotations

import functools
import math
from typing import TYPE_CHECKING

from labrig.validate import InputError, real

if TYPE_CHECKING:
    from .experiment import Experiment

#: Root seed of every preset (the Java's ``new Random(154)``).
THESIS_SEED = 154
#: Mean dot diameter, px.
MEAN_DIAMETER = 15.0
#: Width of the thesis's grating channel: 6 lattice row spacings, ``6 d sqrt(3)/2`` px.
GRATING_WIDTH = 6.0 * MEAN_DIAMETER * math.sqrt(3.0) / 2.0
#: Size factor of ``get_preset(name, quick=True)``.
QUICK_FACTOR = 0.1


def _film(name: str, sigma: float, *, n_dots: int = 300, mass_model: str = "equal", grating: float = 0.0,
          heavy_mass: float = 2.0) -> Experiment:
    """A ``runRandomAttraction*`` run: random deposition, 1 s apart, 100 s to settle, vdW + kicks."""
    from .experiment import Board, Deposition, Experiment, default_forces

    deposition = Deposition(protocol="random", n_dots=n_dots, mean_diameter=MEAN_DIAMETER, sigma=sigma,
                            mass_model=mass_model, heavy_mass=heavy_mass, interval=1.0, settle=100.0)
    return Experiment(name=name, seed=THESIS_SEED, board=Board(600.0, 600.0, True), grating=grating,
                      deposition=deposition, forces=default_forces())


def _central(name: str, sigma: float, n_dots: int = 500) -> Experiment:
    """A ``runRandomCenterGravity`` run: ring deposition 0.5 s apart, centre gravity and drag."""
    from .experiment import Board, Deposition, Experiment, default_forces
    from .forces import CentreGravity, Drag

    deposition = Deposition(protocol="centre", n_dots=n_dots, mean_diameter=MEAN_DIAMETER, sigma=sigma,
                            mass_model="equal", interval=0.5, settle=15.0)
    forces = default_forces() + (CentreGravity((300.0, 300.0), 750.0).to_dict(),
                                 Drag(0.1, 0.1 / 30.0).to_dict())
    return Experiment(name=name, seed=THESIS_SEED, board=Board(600.0, 600.0, True), deposition=deposition,
                      forces=forces)


def _fig2_6() -> tuple[Experiment, ...]:
    runs = []
    for sigma in (0.0, 0.05, 0.10, 0.15):
        runs.append(_film(f"fig2-6a equal masses sigma={sigma:g}", sigma))
        runs.append(_film(f"fig2-6a volume masses sigma={sigma:g}", sigma, mass_model="volume"))
    runs.append(_film("fig2-6b bimodal masses sigma=0", 0.0, mass_model="bimodal", heavy_mass=2.0))
    return tuple(runs)


#: How each preset's experiments are made, by name, in the thesis's order.
_MAKERS = {
    "fig2-2": lambda: (_film("fig2-2a sigma=0", 0.0), _film("fig2-2b sigma=0.15", 0.15)),
    "fig2-3": lambda: (_film("fig2-3a grating sigma=0", 0.0, n_dots=150, mass_model="volume", grating=GRATING_WIDTH),
                       _film("fig2-3b grating sigma=0.15", 0.15, n_dots=150, mass_model="volume",
                             grating=GRATING_WIDTH)),
    "fig2-6": _fig2_6,
    "centre-gravity": lambda: (_central("central sigma=0", 0.0), _central("central sigma=0.15", 0.15)),
}
#: The presets' names, in the thesis's order.
NAMES = tuple(_MAKERS)


@functools.cache
def _presets() -> dict[str, tuple[Experiment, ...]]:
    return {key: make() for key, make in _MAKERS.items()}


def __getattr__(name: str):
    if name == "PRESETS":  # every preset by name: a tuple of experiments, made once, when first asked for
        return _presets()
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def get_preset(name: str, quick: bool | float = False) -> list[Experiment]:
    """The experiments of a preset.

    Parameters
    ----------
    name : str
        One of `NAMES` (``"fig2-2"``, ``"fig2-3"``, ``"fig2-6"``, ``"centre-gravity"``).
    quick : bool or float
        False: the thesis's sizes. True: `Experiment.quick` with `QUICK_FACTOR`
        (0.1). A number in (0, 1]: that factor.

    Returns
    -------
    list of Experiment

    Raises
    ------
    ValueError
        On an unknown name (the message lists the known ones) or a bad ``quick``.
    """
    if name not in NAMES:
        raise InputError(f"unknown preset {name!r} (known: {', '.join(NAMES)})")
    runs = _presets()[name]
    if quick is False:
        return list(runs)
    factor = QUICK_FACTOR if quick is True else real("quick", quick, 0.0, 1.0, low_open=True)
    return [exp.quick(factor) for exp in runs]
