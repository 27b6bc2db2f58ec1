"""Resampling: interpolation kernels, remap, warps, resize and lens maps."""

from camkit.resample.kernels import DEFAULT_BICUBIC_A, INTERPOLATIONS, kernel, kernel_support
from camkit.resample.maps import optimal_pinhole, reproject_map, undistort_map
from camkit.resample.remap import BORDERS, remap, undistort_image
from camkit.resample.warp import warp_affine, warp_perspective

__all__ = [
    "BORDERS",
    "DEFAULT_BICUBIC_A",
    "INTERPOLATIONS",
    "kernel",
    "kernel_support",
    "optimal_pinhole",
    "remap",
    "reproject_map",
    "undistort_image",
    "undistort_map",
    "warp_affine",
    "warp_perspective",
]
