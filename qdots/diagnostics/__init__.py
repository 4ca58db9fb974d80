"""Diagnostics of the engines, apart from the simulators they examine.

* `qdots.diagnostics.hard_cases` -- the scenes an engine must survive (stability, lost or escaped dots,
  overlap) and their check, asserted by the tests and timed by ``python -m benchmarks.qdots_hard_cases``;
* `qdots.diagnostics.energy_budget` -- the kinetic-energy budget of each time step by mass class, measured
  from outside either engine through the forces' hook.
"""
