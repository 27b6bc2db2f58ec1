"""Plain NumPy float64 reference implementations that camkit's resampling kernels must match.

Written for clarity, not speed: every tap is gathered explicitly with the border rule.
"""

from __future__ import annotations

import numpy as np

from camkit.resample.kernels import kernel

TAPS = {"nearest": 1, "bilinear": 2, "bicubic": 4, "lanczos3": 6}


def border_index(i: np.ndarray, n: int, border: str) -> np.ndarray:
    """Index into [0, n), or -1 for 'take the fill value'."""
    if border == "constant":
        return np.where((i >= 0) & (i < n), i, -1)
    if border == "replicate":
        return np.clip(i, 0, n - 1)
    period = 2 * n  # reflect: ... c b a | a b c ... (half-sample symmetric)
    j = np.mod(i, period)
    return np.where(j < n, j, period - 1 - j)


def tap_weights(x: np.ndarray, method: str, a: float) -> tuple[np.ndarray, np.ndarray]:
    """First tap index and weights (..., N) for coordinates x."""
    n = TAPS[method]
    if method == "nearest":
        return np.floor(x + 0.5).astype(np.int64), np.ones((*x.shape, 1))
    f = np.floor(x)
    first = f.astype(np.int64) - (n // 2 - 1)
    offsets = np.arange(n) - (n // 2 - 1)
    t = (x - f)[..., None] - offsets
    w = kernel(method, t, bicubic_a=a)
    return first, w / w.sum(axis=-1, keepdims=True)


def remap_reference(image: np.ndarray, map_xy: np.ndarray, method: str = "bilinear",
                    border: str = "constant", fill_value: float = 0.0, a: float = -0.5) -> np.ndarray:
    img = image.astype(np.float64)
    if img.ndim == 2:
        img = img[:, :, None]
    H, W, C = img.shape
    x = map_xy[..., 0].astype(np.float64)
    y = map_xy[..., 1].astype(np.float64)
    bad = ~(np.isfinite(x) & np.isfinite(y))
    x = np.where(bad, 0.0, x)
    y = np.where(bad, 0.0, y)
    x0, wx = tap_weights(x, method, a)
    y0, wy = tap_weights(y, method, a)
    n = wx.shape[-1]
    out = np.zeros((*x.shape, C))
    for j in range(n):
        iy = border_index(y0 + j, H, border)
        for k in range(n):
            ix = border_index(x0 + k, W, border)
            w = (wy[..., j] * wx[..., k])[..., None]
            outside = (iy < 0) | (ix < 0)
            vals = img[np.clip(iy, 0, H - 1), np.clip(ix, 0, W - 1)]
            out += w * np.where(outside[..., None], fill_value, vals)
    out[bad] = fill_value
    return out if image.ndim == 3 else out[..., 0]


def to_dtype(ref: np.ndarray, dtype: np.dtype) -> np.ndarray:
    if np.dtype(dtype).kind == "u":
        info = np.iinfo(dtype)
        return np.clip(np.floor(ref + 0.5), info.min, info.max)
    return ref
