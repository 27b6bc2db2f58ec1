"""Rotation kernels: rotation vector, quaternion (w, x, y, z) and matrix, batched over rows."""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

# Below this angle (radians) sin(t)/t is evaluated by its Taylor series; the truncation
# error of three terms is t^6/5040 < 1e-27.
_SMALL_ANGLE = 1e-4


#: Below this many rows the serial kernels run: launching the parallel loop costs about a
#: millisecond on the 2-core machine, far more than a few rotations.
PARALLEL_MIN_ROWS = 4096


@njit(cache=True, nogil=True, error_model="numpy")
def rvec_to_matrix_rows(rvec: np.ndarray, out: np.ndarray, lo: int, hi: int) -> None:  # pragma: no cover
    """Rodrigues' formula R = cos(t) I + sin(t)/t [r]x + (1-cos t)/t^2 r r^T, rows lo..hi of (N, 3)."""
    for i in range(lo, hi):
        x = rvec[i, 0]
        y = rvec[i, 1]
        z = rvec[i, 2]
        t2 = x * x + y * y + z * z
        if t2 < _SMALL_ANGLE * _SMALL_ANGLE:
            a = 1.0 - t2 / 6.0 + t2 * t2 / 120.0
            b = 0.5 - t2 / 24.0 + t2 * t2 / 720.0
        else:
            t = math.sqrt(t2)
            a = math.sin(t) / t
            h = math.sin(0.5 * t) / t
            b = 2.0 * h * h  # (1 - cos t) / t^2 without cancellation
        c = 1.0 - b * t2
        out[i, 0, 0] = c + b * x * x
        out[i, 0, 1] = b * x * y - a * z
        out[i, 0, 2] = b * x * z + a * y
        out[i, 1, 0] = b * x * y + a * z
        out[i, 1, 1] = c + b * y * y
        out[i, 1, 2] = b * y * z - a * x
        out[i, 2, 0] = b * x * z - a * y
        out[i, 2, 1] = b * y * z + a * x
        out[i, 2, 2] = c + b * z * z


@njit(cache=True, nogil=True, parallel=True, error_model="numpy")
def rvec_to_matrix_parallel(rvec: np.ndarray, out: np.ndarray) -> None:  # pragma: no cover
    n = rvec.shape[0]
    chunks = (n + 1023) // 1024
    for c in prange(chunks):
        rvec_to_matrix_rows(rvec, out, c * 1024, min(n, (c + 1) * 1024))


def rvec_to_matrix(rvec: np.ndarray, out: np.ndarray) -> None:
    """Rows of rotation vectors (N, 3) to matrices (N, 3, 3): serial for few rows."""
    if rvec.shape[0] < PARALLEL_MIN_ROWS:
        rvec_to_matrix_rows(rvec, out, 0, rvec.shape[0])
    else:
        rvec_to_matrix_parallel(rvec, out)


@njit(cache=True, nogil=True, parallel=True, error_model="numpy")
def matrix_to_quat(R: np.ndarray, out: np.ndarray) -> None:  # pragma: no cover - numba
    """Shepperd's method: pick the largest of w, x, y, z to divide by, so no branch loses
    precision (S. W. Shepperd, J. Guidance and Control 1(3), 1978, doi:10.2514/3.55767).
    Output (w, x, y, z) with w >= 0, unit norm."""
    for i in prange(R.shape[0]):
        r00 = R[i, 0, 0]
        r11 = R[i, 1, 1]
        r22 = R[i, 2, 2]
        tr = r00 + r11 + r22
        if tr >= r00 and tr >= r11 and tr >= r22:
            s = 2.0 * math.sqrt(max(1.0 + tr, 0.0))
            w = 0.25 * s
            x = (R[i, 2, 1] - R[i, 1, 2]) / s
            y = (R[i, 0, 2] - R[i, 2, 0]) / s
            z = (R[i, 1, 0] - R[i, 0, 1]) / s
        elif r00 >= r11 and r00 >= r22:
            s = 2.0 * math.sqrt(max(1.0 + r00 - r11 - r22, 0.0))
            w = (R[i, 2, 1] - R[i, 1, 2]) / s
            x = 0.25 * s
            y = (R[i, 0, 1] + R[i, 1, 0]) / s
            z = (R[i, 0, 2] + R[i, 2, 0]) / s
        elif r11 >= r22:
            s = 2.0 * math.sqrt(max(1.0 + r11 - r00 - r22, 0.0))
            w = (R[i, 0, 2] - R[i, 2, 0]) / s
            x = (R[i, 0, 1] + R[i, 1, 0]) / s
            y = 0.25 * s
            z = (R[i, 1, 2] + R[i, 2, 1]) / s
        else:
            s = 2.0 * math.sqrt(max(1.0 + r22 - r00 - r11, 0.0))
            w = (R[i, 1, 0] - R[i, 0, 1]) / s
            x = (R[i, 0, 2] + R[i, 2, 0]) / s
            y = (R[i, 1, 2] + R[i, 2, 1]) / s
            z = 0.25 * s
        n = math.sqrt(w * w + x * x + y * y + z * z)
        if w < 0.0:
            n = -n
        out[i, 0] = w / n
        out[i, 1] = x / n
        out[i, 2] = y / n
        out[i, 3] = z / n


@njit(cache=True, nogil=True, parallel=True, error_model="numpy")
def quat_to_matrix(q: np.ndarray, out: np.ndarray) -> None:  # pragma: no cover - numba
    """Unit quaternion (w, x, y, z), Hamilton convention, to a rotation matrix."""
    for i in prange(q.shape[0]):
        n = math.sqrt(q[i, 0] ** 2 + q[i, 1] ** 2 + q[i, 2] ** 2 + q[i, 3] ** 2)
        w = q[i, 0] / n
        x = q[i, 1] / n
        y = q[i, 2] / n
        z = q[i, 3] / n
        out[i, 0, 0] = 1.0 - 2.0 * (y * y + z * z)
        out[i, 0, 1] = 2.0 * (x * y - w * z)
        out[i, 0, 2] = 2.0 * (x * z + w * y)
        out[i, 1, 0] = 2.0 * (x * y + w * z)
        out[i, 1, 1] = 1.0 - 2.0 * (x * x + z * z)
        out[i, 1, 2] = 2.0 * (y * z - w * x)
        out[i, 2, 0] = 2.0 * (x * z - w * y)
        out[i, 2, 1] = 2.0 * (y * z + w * x)
        out[i, 2, 2] = 1.0 - 2.0 * (x * x + y * y)


@njit(cache=True, nogil=True, parallel=True, error_model="numpy")
def quat_to_rvec(q: np.ndarray, out: np.ndarray) -> None:  # pragma: no cover - numba
    """Unit quaternion to rotation vector with angle in [0, pi]: t = 2 atan2(|v|, w)."""
    for i in prange(q.shape[0]):
        w = q[i, 0]
        x = q[i, 1]
        y = q[i, 2]
        z = q[i, 3]
        if w < 0.0:
            w = -w
            x = -x
            y = -y
            z = -z
        n = math.sqrt(x * x + y * y + z * z)
        if n < 1e-7:
            # atan2(n, w)/n = (1/w)(1 - n^2/(3 w^2) + ...); the dropped term is < 1e-14 relative.
            scale = 2.0 / w * (1.0 - n * n / (3.0 * w * w))
        else:
            scale = 2.0 * math.atan2(n, w) / n
        out[i, 0] = x * scale
        out[i, 1] = y * scale
        out[i, 2] = z * scale
