"""Resampling: interpolation kernels, remap, warps, resize and lens maps."""

from camkit.resample.chromatic import apply_chromatic, correct_chromatic
from camkit.resample.kernels import DEFAULT_BICUBIC_A, INTERPOLATIONS, kernel, kernel_support
from camkit.resample.maps import optimal_pinhole, reproject_map, undistort_map
from camkit.resample.remap import BORDERS, remap, undistort_image
from camkit.resample.resize import RESIZE_INTERPOLATIONS, resize, resize_weights
from camkit.resample.warp import warp_affine, warp_perspective

__all__ = [
    "BORDERS",
    "DEFAULT_BICUBIC_A",
    "INTERPOLATIONS",
    "RESIZE_INTERPOLATIONS",
    "apply_chromatic",
    "correct_chromatic",
    "kernel",
    "kernel_support",
    "optimal_pinhole",
    "remap",
    "reproject_map",
    "resize",
    "resize_weights",
    "undistort_image",
    "undistort_map",
    "warp_affine",
    "warp_perspective",
]
