"""`EngineSettings`: the speed/accuracy knobs of a `qdots.Simulation`, validated."""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass

import numpy as np

from labrig.validate import InputError

#: Fraction of an overlap corrected per sub-step by default. Measured on a dense pack under
#: centre gravity at dt = 1 ms: 10 % leaves 0.60 % worst overlap (5.9 % at 10x gravity), 30 %
#: leaves 0.32 % (1.5 %) at the same cost; 50 % starts to jitter (rms speed x1.7 at 10x gravity).
OVERLAP_CORRECTION = 0.3


@dataclass(frozen=True)
class EngineSettings:
    """The speed/accuracy knobs of the engine (see `Simulation` for their meaning)."""

    dt: float = 1e-3
    substeps: int = 1
    iterations: int = 10
    collision_slop: float = 0.01
    collision_bias: float | None = None
    spatial_hash: tuple[float, int] | None = None
    threads: int = 1

    def __post_init__(self) -> None:
        if isinstance(self.dt, bool) or not (isinstance(self.dt, (int, float)) and math.isfinite(self.dt)
                                             and self.dt > 0):
            raise InputError(f"dt must be > 0 s, got {self.dt!r}")
        for name in ("substeps", "iterations"):
            value = getattr(self, name)
            if not (isinstance(value, (int, np.integer)) and not isinstance(value, bool) and value >= 1):
                raise InputError(f"{name} must be an integer >= 1, got {value!r}")
        if isinstance(self.collision_slop, bool) or not (
                isinstance(self.collision_slop, (int, float)) and math.isfinite(self.collision_slop)
                and self.collision_slop >= 0):
            raise InputError(f"collision_slop must be >= 0 px, got {self.collision_slop!r}")
        if self.collision_bias is not None and not (0.0 <= self.collision_bias < 1.0):
            raise InputError(f"collision_bias must be in [0, 1), got {self.collision_bias!r}")
        if isinstance(self.threads, bool) or self.threads not in (1, 2):
            raise InputError(f"threads must be 1 or 2, got {self.threads!r}")
        if self.spatial_hash is not None:
            ok = isinstance(self.spatial_hash, (tuple, list)) and len(self.spatial_hash) == 2
            if ok:
                cell, count = self.spatial_hash
                ok = (isinstance(cell, (int, float)) and not isinstance(cell, bool) and cell > 0
                      and isinstance(count, (int, np.integer)) and not isinstance(count, bool) and count >= 1)
            if not ok:
                raise InputError(f"spatial_hash must be (cell_size_px > 0, integer count >= 1), "
                                 f"got {self.spatial_hash!r}")
            object.__setattr__(self, "spatial_hash", (float(self.spatial_hash[0]), int(self.spatial_hash[1])))

    @property
    def bias(self) -> float:
        """pymunk's collision_bias: given, or `OVERLAP_CORRECTION` per sub-step."""
        if self.collision_bias is not None:
            return float(self.collision_bias)
        return (1.0 - OVERLAP_CORRECTION) ** (self.substeps / self.dt)

    def to_dict(self) -> dict:
        """Plain-data form (JSON/TOML friendly)."""
        return {k: (list(v) if isinstance(v, tuple) else v) for k, v in asdict(self).items()}
