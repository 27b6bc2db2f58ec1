"""Rigid transforms and pinhole projection of point rows."""

from __future__ import annotations

import numpy as np
from numba import njit, prange

from camkit._kernels.rotation import PARALLEL_MIN_ROWS


@njit(cache=True, nogil=True, error_model="numpy")
def rigid_apply_rows(R: np.ndarray, t: np.ndarray, pts: np.ndarray, out: np.ndarray, lo: int,
                     hi: int) -> None:  # pragma: no cover
    """out[i] = R @ pts[i] + t for rows of (N, 3)."""
    for i in range(lo, hi):
        x = pts[i, 0]
        y = pts[i, 1]
        z = pts[i, 2]
        out[i, 0] = R[0, 0] * x + R[0, 1] * y + R[0, 2] * z + t[0]
        out[i, 1] = R[1, 0] * x + R[1, 1] * y + R[1, 2] * z + t[1]
        out[i, 2] = R[2, 0] * x + R[2, 1] * y + R[2, 2] * z + t[2]


@njit(cache=True, nogil=True, parallel=True, error_model="numpy")
def rigid_apply_parallel(R: np.ndarray, t: np.ndarray, pts: np.ndarray, out: np.ndarray) -> None:  # pragma: no cover
    n = pts.shape[0]
    for chunk in prange((n + 1023) // 1024):
        rigid_apply_rows(R, t, pts, out, chunk * 1024, min(n, (chunk + 1) * 1024))


def rigid_apply(R: np.ndarray, t: np.ndarray, pts: np.ndarray, out: np.ndarray) -> None:
    """Serial below PARALLEL_MIN_ROWS rows (a parallel launch costs more than their work)."""
    if pts.shape[0] < PARALLEL_MIN_ROWS:
        rigid_apply_rows(R, t, pts, out, 0, pts.shape[0])
    else:
        rigid_apply_parallel(R, t, pts, out)


@njit(cache=True, nogil=True, parallel=True, error_model="numpy")
def pinhole_project(pts: np.ndarray, fx: float, fy: float, cx: float, cy: float, skew: float,
                    out: np.ndarray) -> None:  # pragma: no cover
    """u = fx X/Z + skew Y/Z + cx, v = fy Y/Z + cy; NaN for Z <= 0."""
    for i in prange(pts.shape[0]):
        z = pts[i, 2]
        if z > 0.0:
            x = pts[i, 0] / z
            y = pts[i, 1] / z
            out[i, 0] = fx * x + skew * y + cx
            out[i, 1] = fy * y + cy
        else:
            out[i, 0] = np.nan
            out[i, 1] = np.nan


@njit(cache=True, nogil=True, parallel=True, error_model="numpy")
def pinhole_unproject(px: np.ndarray, fx: float, fy: float, cx: float, cy: float, skew: float,
                      out: np.ndarray) -> None:  # pragma: no cover
    """Unit rays through pixels: y = (v - cy)/fy, x = (u - cx - skew y)/fx, ray = (x, y, 1)/n."""
    for i in prange(px.shape[0]):
        y = (px[i, 1] - cy) / fy
        x = (px[i, 0] - cx - skew * y) / fx
        inv = 1.0 / np.sqrt(x * x + y * y + 1.0)
        out[i, 0] = x * inv
        out[i, 1] = y * inv
        out[i, 2] = inv
