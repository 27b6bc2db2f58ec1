"""Colour filter arrays: which colour each photosite records.

A Bayer sensor puts a red, green or blue filter over each photosite in a 2x2 tile named by
its colours in reading order: "RGGB" has red at (row 0, col 0), green at (0, 1) and (1, 0),
blue at (1, 1). A three-layer sensor (Foveon, or a three-chip camera) records all three
colours at every site and needs no demosaicing; it is here for comparison.
"""

from __future__ import annotations

import numpy as np

from camkit._validate import as_image, as_positive_int, check_choice
from camkit.errors import ShapeError

__all__ = ["PATTERNS", "cfa_masks", "mosaic", "pattern_code", "three_layer"]

PATTERNS = ("RGGB", "BGGR", "GRBG", "GBRG")
_INDEX = {"R": 0, "G": 1, "B": 2}


def pattern_code(pattern: str) -> np.ndarray:
    """The 2x2 tile's colour indices (0 red, 1 green, 2 blue) in reading order, int64 (4,)."""
    p = check_choice(pattern, PATTERNS, "pattern")
    return np.array([_INDEX[ch] for ch in p], dtype=np.int64)


def cfa_masks(height: int, width: int, pattern: str) -> np.ndarray:
    """Boolean (H, W, 3): True where the sensor records that colour. ``pattern`` is one of
    :data:`PATTERNS` or ``"three-layer"`` (every colour everywhere).

    >>> cfa_masks(2, 2, "RGGB")[..., 0]
    array([[ True, False],
           [False, False]])
    """
    h = as_positive_int(height, "height")
    w = as_positive_int(width, "width")
    if pattern == "three-layer":
        return np.ones((h, w, 3), dtype=bool)
    code = pattern_code(pattern)
    yy, xx = np.mgrid[0:h, 0:w]
    site = code[(yy & 1) * 2 + (xx & 1)]
    return site[..., None] == np.arange(3)


def mosaic(rgb: np.ndarray, pattern: str = "RGGB") -> np.ndarray:
    """The raw image a Bayer sensor records of ``rgb``: ``raw[y, x] = rgb[y, x, colour(y, x)]``.

    Parameters
    ----------
    rgb : ndarray, (H, W, 3), uint8, uint16, float32 or float64
    pattern : {"RGGB", "BGGR", "GRBG", "GBRG"}

    Returns
    -------
    ndarray, (H, W), the dtype of ``rgb``

    >>> import numpy as np
    >>> rgb = np.stack([np.full((2, 2), 10), np.full((2, 2), 20), np.full((2, 2), 30)], -1).astype(np.uint8)
    >>> mosaic(rgb, "GRBG")
    array([[20, 10],
           [30, 20]], dtype=uint8)
    """
    img = as_image(rgb, "rgb", max_channels=3)
    if img.ndim != 3 or img.shape[2] != 3:
        raise ShapeError(f"rgb: expected shape (H, W, 3), got {img.shape}")
    code = pattern_code(pattern)
    yy, xx = np.mgrid[0:img.shape[0], 0:img.shape[1]]
    return np.take_along_axis(img, code[(yy & 1) * 2 + (xx & 1)][..., None], axis=2)[..., 0].copy()


def three_layer(rgb: np.ndarray) -> np.ndarray:
    """What a three-layer sensor records of ``rgb``: every colour at every site (a copy)."""
    img = as_image(rgb, "rgb", max_channels=3)
    if img.ndim != 3 or img.shape[2] != 3:
        raise ShapeError(f"rgb: expected shape (H, W, 3), got {img.shape}")
    return img.copy()
