"""Calibration: targets (the rest of the room is being built)."""

from camkit.calib.targets import Checkerboard

__all__ = ["Checkerboard"]
