"""A board that runs live: `LiveRun` (no widget library needed) and `LiveBoard`, its notebook widget."""

from .live import Knobs, LiveRun


def __getattr__(name: str):
    if name == "LiveBoard":  # needs the widgets extra: imported on first use
        from .board import LiveBoard

        return LiveBoard
    raise AttributeError(f"module 'qdots.interactive' has no attribute {name!r}")


__all__ = ["LiveBoard", "LiveRun", "Knobs"]
