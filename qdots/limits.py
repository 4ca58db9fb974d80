"""The bounds of what a board may hold and a run may ask for, in one light module.

Every count and size is checked against these before anything is allocated. They live apart from the
classes that check them (`qdots.Scene`, `qdots.geometry.VerletPairs`, the engines' settings) so that the
command line can state and check them without importing the simulators (numba, scipy, pymunk).
"""

from labrig.params import Param

#: Most dots a scene holds (Chipmunk needs about 1 kB per dot).
MAX_DOTS = 1_000_000
#: Most static segments besides the box edges.
MAX_SEGMENTS = 100_000
#: Largest board side and largest coordinate, px.
MAX_LENGTH = 1e6
#: Smallest mean dot diameter a deposition takes, px: ten thousandths of the thesis's 15 px (below it a dot moves
#: many radii per step under any force, and sizes near 1e-300 px overflow the motion's checks).
MIN_DIAMETER = 0.01
#: Largest mass, in mean dot masses (and smallest: its inverse).
MAX_MASS = 1e6
#: Largest speed given as input, px/s (a mean dot crosses the thesis's board in 0.6 ms).
MAX_SPEED = 1e6
#: Largest Verlet skin of a pair list, px.
MAX_SKIN = 1000.0
#: Largest Förster radius, in mean radii (as ``forster_radii``, and for ``forster_radius`` in px): far
#: beyond any dot film (the thesis uses 2).
MAX_FORSTER_RADII = 1000.0
#: Largest ``forster_radius`` on any board, px: `MAX_FORSTER_RADII` radii of the largest dot a scene may
#: hold (`MAX_LENGTH`). Its sixth power (1e54) is far within a float.
MAX_FORSTER_PX = MAX_FORSTER_RADII * MAX_LENGTH
#: Most trap draws `qdots.analysis.lqe.film_lqe` averages (as ``qdots analyze --draws``).
MAX_DRAWS = 10_000
#: Declaration of a deposition's size spread (`qdots.experiment.Deposition`'s ``sigma``, ``qdots demo --sigma``).
SIGMA = Param("float", 0.0, 1.0, high_open=True, doc="standard deviation of the diameter as a fraction of the mean")
