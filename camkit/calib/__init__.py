"""Calibration (estimation only): homographies, Zhang's closed form, PnP and nonlinear refinement.

Targets and their detectors live in :mod:`camkit.target`."""

from camkit.calib.calibrate import (
    DEFAULT_FIX,
    CalibrationResult,
    calibrate,
    calibrate_detections,
    calibrate_images,
    default_fix,
    held_parameters,
)
from camkit.calib.homography import find_homography
from camkit.calib.pnp import PnPResult, solve_pnp
from camkit.calib.refine import LMOptions, RefineReport
from camkit.calib.rig import CameraRig, RigResult, calibrate_rig
from camkit.calib.uncertainty import projection_uncertainty
from camkit.calib.zhang import intrinsics_from_homographies, poses_from_homographies

__all__ = [
    "DEFAULT_FIX",
    "CalibrationResult",
    "CameraRig",
    "LMOptions",
    "PnPResult",
    "RefineReport",
    "RigResult",
    "calibrate",
    "calibrate_detections",
    "calibrate_images",
    "calibrate_rig",
    "default_fix",
    "find_homography",
    "held_parameters",
    "intrinsics_from_homographies",
    "poses_from_homographies",
    "projection_uncertainty",
    "solve_pnp",
]
