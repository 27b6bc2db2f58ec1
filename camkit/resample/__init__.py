"""Resampling: interpolation kernels, remap, warps, resize and lens maps."""

from camkit.resample.kernels import DEFAULT_BICUBIC_A, INTERPOLATIONS, kernel, kernel_support
from camkit.resample.remap import BORDERS, remap

__all__ = ["BORDERS", "DEFAULT_BICUBIC_A", "INTERPOLATIONS", "kernel", "kernel_support", "remap"]
