"""Affine and perspective warps, computing source coordinates on the fly (no map in memory)."""

from __future__ import annotations

from typing import Any

import numpy as np

from camkit._alloc import new_image
from camkit._validate import as_matrix, as_positive_int
from camkit.errors import ParameterError
from camkit.resample.kernels import DEFAULT_BICUBIC_A
from camkit.resample.remap import accumulator_zero, pick_kernel, sampling_setup

__all__ = ["warp_affine", "warp_perspective"]


def _warp(family: str, matrix: np.ndarray, image, width, height, interpolation, border, fill_value,
          bicubic_a) -> np.ndarray:
    img, img3, method, border_code, a, fill, (is_int, lo, hi) = sampling_setup(
        image, interpolation, border, fill_value, bicubic_a)
    w = as_positive_int(width, "width")
    h = as_positive_int(height, "height")
    out = new_image((h, w, img3.shape[2]), img.dtype)
    pick_kernel(family, method, img3)(img3, np.ascontiguousarray(matrix), a, border_code, fill, is_int,
                                      lo, hi, accumulator_zero(img.dtype), out)
    return out if img.ndim == 3 else out[:, :, 0]


def warp_affine(image: np.ndarray, A: Any, *, width: int, height: int, interpolation: str = "bilinear",
                border: str = "constant", fill_value: Any = 0,
                bicubic_a: float = DEFAULT_BICUBIC_A) -> np.ndarray:
    """Warp an image by an affine map ``A`` (2x3, destination <- source, as OpenCV's
    ``warpAffine`` takes it): output pixel ``p`` samples the input at ``A^-1 p``.

    Parameters
    ----------
    image : ndarray, (H, W) or (H, W, C)
    A : array_like, (2, 3)
        ``[x_dst, y_dst] = A[:, :2] @ [x_src, y_src] + A[:, 2]``, pixel centres at integers.
    width, height : int
        Output size.
    interpolation, border, fill_value, bicubic_a
        As :func:`camkit.resample.remap`.

    Examples
    --------
    >>> import numpy as np
    >>> img = np.arange(16.0).reshape(4, 4)
    >>> warp_affine(img, [[1, 0, 1], [0, 1, 0]], width=4, height=4)  # shift right by 1
    array([[ 0.,  0.,  1.,  2.],
           [ 0.,  4.,  5.,  6.],
           [ 0.,  8.,  9., 10.],
           [ 0., 12., 13., 14.]])
    """
    m = as_matrix(A, (2, 3), "A")
    full = np.vstack([m, [0.0, 0.0, 1.0]])
    if abs(np.linalg.det(full)) < 1e-12 * max(1.0, np.abs(m[:, :2]).max() ** 2):
        raise ParameterError(f"A: expected an invertible affine map, got a singular one {m.tolist()}")
    inv = np.linalg.inv(full)[:2]
    return _warp("affine", inv, image, width, height, interpolation, border, fill_value, bicubic_a)


def warp_perspective(image: np.ndarray, H: Any, *, width: int, height: int,
                     interpolation: str = "bilinear", border: str = "constant", fill_value: Any = 0,
                     bicubic_a: float = DEFAULT_BICUBIC_A) -> np.ndarray:
    """Warp an image by a homography ``H`` (3x3, destination <- source, as OpenCV's
    ``warpPerspective`` takes it): output pixel ``p`` samples the input at ``H^-1 p``
    (homogeneous). Output pixels whose preimage lies beyond the horizon (``w <= 0``) get
    ``fill_value``.

    Parameters
    ----------
    image : ndarray, (H, W) or (H, W, C)
    H : array_like, (3, 3), invertible
    width, height : int
    interpolation, border, fill_value, bicubic_a
        As :func:`camkit.resample.remap`.
    """
    m = as_matrix(H, (3, 3), "H")
    scale = np.abs(m).max()
    if scale == 0 or abs(np.linalg.det(m / scale)) < 1e-12:
        raise ParameterError(f"H: expected an invertible homography, got a singular one {m.tolist()}")
    inv = np.linalg.inv(m)
    if inv[2, 2] < 0:  # the homography's scale is free; pick the sign that makes w > 0 in front
        inv = -inv
    return _warp("perspective", inv, image, width, height, interpolation, border, fill_value,
                 bicubic_a)
