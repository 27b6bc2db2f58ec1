"""Calibration: targets, homographies, Zhang's closed form and nonlinear refinement."""

from camkit.calib.calibrate import DEFAULT_FIX, CalibrationResult, calibrate
from camkit.calib.homography import find_homography
from camkit.calib.pnp import PnPResult, solve_pnp
from camkit.calib.targets import Checkerboard
from camkit.calib.zhang import intrinsics_from_homographies, poses_from_homographies

__all__ = [
    "DEFAULT_FIX",
    "CalibrationResult",
    "Checkerboard",
    "PnPResult",
    "calibrate",
    "find_homography",
    "intrinsics_from_homographies",
    "poses_from_homographies",
    "solve_pnp",
]
