"""Lateral chromatic aberration on images: red and blue resampled by the lens's radial maps
(:class:`camkit.lens.LateralChromaticAberration`)."""

from __future__ import annotations

import numpy as np

from camkit._validate import as_image
from camkit.errors import ParameterError, ShapeError
from camkit.lens.chromatic import LateralChromaticAberration
from camkit.resample.kernels import DEFAULT_BICUBIC_A
from camkit.resample.remap import remap

__all__ = ["apply_chromatic", "correct_chromatic"]


def _remap_channels(image: np.ndarray, aberration: LateralChromaticAberration, inverse: bool, interpolation: str,
                    bicubic_a: float) -> np.ndarray:
    if not isinstance(aberration, LateralChromaticAberration):
        raise ParameterError(f"aberration: expected a LateralChromaticAberration, got {type(aberration).__name__}")
    img = as_image(image, "image")
    if img.ndim != 3 or img.shape[2] not in (3, 4):
        raise ShapeError(f"image: expected an RGB(A) image (H, W, 3 or 4), got shape {img.shape}")
    h, w = img.shape[:2]
    out = img.copy()
    for name, ch in aberration.channels().items():
        m = aberration.map(name, w, h, inverse=inverse)
        out[:, :, ch] = remap(np.ascontiguousarray(img[:, :, ch]), m, interpolation=interpolation,
                              border="replicate", bicubic_a=bicubic_a)
    return out


def apply_chromatic(image: np.ndarray, aberration: LateralChromaticAberration, *, interpolation: str = "bicubic",
                    bicubic_a: float = DEFAULT_BICUBIC_A) -> np.ndarray:
    """Simulate the aberration on a sharp RGB(A) image (green and alpha are unchanged).

    Returns an image of the same shape and dtype.
    """
    return _remap_channels(image, aberration, True, interpolation, bicubic_a)


def correct_chromatic(image: np.ndarray, aberration: LateralChromaticAberration, *, interpolation: str = "bicubic",
                      bicubic_a: float = DEFAULT_BICUBIC_A) -> np.ndarray:
    """Remove the aberration from an RGB(A) image: red and blue are resampled onto green."""
    return _remap_channels(image, aberration, False, interpolation, bicubic_a)
