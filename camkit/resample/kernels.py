"""Interpolation kernels: nearest, bilinear, bicubic (Keys) and Lanczos-3.

Every resampling function in camkit names its kernel with one of :data:`INTERPOLATIONS`.
Pixel centres are at integer coordinates (docs/conventions.md), so sampling at ``x = 2.0``
returns pixel 2 exactly with every kernel, and ``x = 2.5`` lies halfway between pixels 2 and 3.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from camkit._validate import as_finite_float, as_real_array, check_choice

__all__ = ["DEFAULT_BICUBIC_A", "INTERPOLATIONS", "kernel", "kernel_support"]

INTERPOLATIONS = ("nearest", "bilinear", "bicubic", "lanczos3")

#: Keys' parameter for the bicubic kernel. -0.5 makes the kernel third-order accurate (Keys
#: 1981) and matches Pillow and scikit-image; OpenCV's INTER_CUBIC uses -0.75 (sharper, with
#: more overshoot). Every bicubic function takes ``bicubic_a`` to select it.
DEFAULT_BICUBIC_A = -0.5

_CODES = {name: i for i, name in enumerate(INTERPOLATIONS)}
_SUPPORT = {"nearest": 0.5, "bilinear": 1.0, "bicubic": 2.0, "lanczos3": 3.0}


def interpolation_code(name: Any, argname: str = "interpolation") -> int:
    """The kernel's internal code (for camkit._kernels), after checking the name."""
    return _CODES[check_choice(name, INTERPOLATIONS, argname)]


def kernel_support(name: str) -> float:
    """Half-width of the kernel in pixels (nearest 0.5, bilinear 1, bicubic 2, Lanczos-3 3)."""
    return _SUPPORT[check_choice(name, INTERPOLATIONS, "name")]


def kernel(name: str, t: Any, *, bicubic_a: float = DEFAULT_BICUBIC_A) -> np.ndarray:
    """Evaluate a kernel at offsets ``t`` (pixels).

    - nearest: 1 on [-0.5, 0.5), else 0;
    - bilinear (triangle): ``max(0, 1 - |t|)``;
    - bicubic (R. Keys, "Cubic convolution interpolation for digital image processing",
      IEEE TASSP 29(6), 1981, doi:10.1109/TASSP.1981.1163711):
      ``(a+2)|t|^3 - (a+3)|t|^2 + 1`` on ``|t| <= 1``, ``a|t|^3 - 5a|t|^2 + 8a|t| - 4a`` on
      ``1 < |t| < 2``; ``a = -0.5`` by default (OpenCV uses -0.75);
    - lanczos3: ``sinc(t) sinc(t/3)`` on ``|t| < 3`` (C. E. Duchon, J. Appl. Meteor. 18, 1979).

    Resampling normalises the taps' weights to sum to 1 (Lanczos' raw weights do not).

    Examples
    --------
    >>> kernel("bicubic", [0.0, 0.5, 1.0, 1.5]).round(4)
    array([ 1.    ,  0.5625,  0.    , -0.0625])
    """
    name = check_choice(name, INTERPOLATIONS, "name")
    a = as_finite_float(bicubic_a, "bicubic_a")
    x = np.abs(as_real_array(t, "t"))
    if name == "nearest":
        tt = as_real_array(t, "t")
        return ((tt >= -0.5) & (tt < 0.5)).astype(np.float64)
    if name == "bilinear":
        return np.maximum(0.0, 1.0 - x)
    if name == "bicubic":
        inner = ((a + 2) * x - (a + 3)) * x * x + 1
        outer = ((a * x - 5 * a) * x + 8 * a) * x - 4 * a
        return np.where(x <= 1, inner, np.where(x < 2, outer, 0.0))
    with np.errstate(invalid="ignore", divide="ignore"):
        v = np.sinc(x) * np.sinc(x / 3.0)
    return np.where(x < 3, v, 0.0)
