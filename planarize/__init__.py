"""Anodization planarization of metal surfaces on height grids (thesis chapter 3).

The engines arrive with later work; the package is importable so that the
project installs as one unit.
"""

__all__: list[str] = []
