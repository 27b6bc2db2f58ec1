"""Calibration: targets, homographies, Zhang's closed form and nonlinear refinement."""

from camkit.calib.calibrate import (
    DEFAULT_FIX,
    CalibrationResult,
    calibrate,
    calibrate_images,
    default_fix,
    held_parameters,
)
from camkit.calib.detect import CornerDetection, detect_corners
from camkit.calib.homography import find_homography
from camkit.calib.pnp import PnPResult, solve_pnp
from camkit.calib.targets import Checkerboard
from camkit.calib.zhang import intrinsics_from_homographies, poses_from_homographies

__all__ = [
    "DEFAULT_FIX",
    "CalibrationResult",
    "Checkerboard",
    "CornerDetection",
    "PnPResult",
    "calibrate",
    "calibrate_images",
    "default_fix",
    "detect_corners",
    "find_homography",
    "held_parameters",
    "intrinsics_from_homographies",
    "poses_from_homographies",
    "solve_pnp",
]
