"""Maps from a pinhole destination lattice to any source model, fused per source model.

For destination pixel (u, v) the source-camera ray is ``M @ (u, v, 1)`` with
``M = R_src_from_dst @ inv(K_dst)``; the source model projects it. Each row is computed
branch-free into contiguous buffers (so LLVM vectorises it), then interleaved into the
(H, W, 2) map. ``fastmath={"contract"}`` allows fused multiply-adds only: IEEE semantics,
NaN and inf included, are kept.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from camkit._kernels.kannala_brandt import theta_d


@njit(cache=True, nogil=True, parallel=True, error_model="numpy", fastmath={"contract"})
def pinhole_to_pinhole(M: np.ndarray, intr: np.ndarray, out: np.ndarray) -> None:  # pragma: no cover
    fx, fy, cx, cy, skew = intr[0], intr[1], intr[2], intr[3], intr[4]
    H, W = out.shape[0], out.shape[1]
    for r in prange(H):
        bu = np.empty(W, dtype=out.dtype)
        bv = np.empty(W, dtype=out.dtype)
        X0 = M[0, 1] * r + M[0, 2]
        Y0 = M[1, 1] * r + M[1, 2]
        Z0 = M[2, 1] * r + M[2, 2]
        for c in range(W):
            Z = M[2, 0] * c + Z0
            iz = 1.0 / Z
            x = (M[0, 0] * c + X0) * iz
            y = (M[1, 0] * c + Y0) * iz
            ok = Z > 0.0
            bu[c] = fx * x + skew * y + cx if ok else np.nan
            bv[c] = fy * y + cy if ok else np.nan
        for c in range(W):
            out[r, c, 0] = bu[c]
            out[r, c, 1] = bv[c]


@njit(cache=True, nogil=True, parallel=True, error_model="numpy", fastmath={"contract"})
def pinhole_to_brown_conrady(M: np.ndarray, intr: np.ndarray, k: np.ndarray, r2_valid: float,
                             out: np.ndarray) -> None:  # pragma: no cover
    """The distortion is camkit._kernels.brown_conrady.distort_only, written out twice: once
    for rows of constant depth (no rotation about y, the usual undistortion, no division per
    pixel) and once in general. A helper function here stops LLVM from vectorising."""
    fx, fy, cx, cy, skew = intr[0], intr[1], intr[2], intr[3], intr[4]
    H, W = out.shape[0], out.shape[1]
    rational = k[3] != 0.0 or k[4] != 0.0 or k[5] != 0.0
    flat = M[2, 0] == 0.0
    for r in prange(H):
        bu = np.empty(W, dtype=out.dtype)
        bv = np.empty(W, dtype=out.dtype)
        X0 = M[0, 1] * r + M[0, 2]
        Y0 = M[1, 1] * r + M[1, 2]
        Z0 = M[2, 1] * r + M[2, 2]
        if flat and not rational:
            iz = 1.0 / Z0
            ax = M[0, 0] * iz
            x0 = X0 * iz
            ay = M[1, 0] * iz
            y0 = Y0 * iz
            front = Z0 > 0.0
            for c in range(W):
                x = ax * c + x0
                y = ay * c + y0
                r2 = x * x + y * y
                rad = 1.0 + r2 * (k[0] + r2 * (k[1] + r2 * k[2]))
                xy = 2.0 * x * y
                xd = x * rad + k[6] * xy + k[7] * (r2 + 2.0 * x * x) + r2 * (k[8] + k[9] * r2)
                yd = y * rad + k[6] * (r2 + 2.0 * y * y) + k[7] * xy + r2 * (k[10] + k[11] * r2)
                ok = front & (r2 <= r2_valid)
                bu[c] = fx * xd + skew * yd + cx if ok else np.nan
                bv[c] = fy * yd + cy if ok else np.nan
        else:
            for c in range(W):
                Z = M[2, 0] * c + Z0
                iz = 1.0 / Z
                x = (M[0, 0] * c + X0) * iz
                y = (M[1, 0] * c + Y0) * iz
                r2 = x * x + y * y
                rad = (1.0 + r2 * (k[0] + r2 * (k[1] + r2 * k[2]))) / (
                    1.0 + r2 * (k[3] + r2 * (k[4] + r2 * k[5])))
                xy = 2.0 * x * y
                xd = x * rad + k[6] * xy + k[7] * (r2 + 2.0 * x * x) + r2 * (k[8] + k[9] * r2)
                yd = y * rad + k[6] * (r2 + 2.0 * y * y) + k[7] * xy + r2 * (k[10] + k[11] * r2)
                ok = (Z > 0.0) & (r2 <= r2_valid)
                bu[c] = fx * xd + skew * yd + cx if ok else np.nan
                bv[c] = fy * yd + cy if ok else np.nan
        for c in range(W):
            out[r, c, 0] = bu[c]
            out[r, c, 1] = bv[c]


@njit(cache=True, nogil=True, parallel=True, error_model="numpy", fastmath={"contract"})
def pinhole_to_kannala_brandt(M: np.ndarray, intr: np.ndarray, k: np.ndarray, t_valid: float,
                              out: np.ndarray) -> None:  # pragma: no cover
    fx, fy, cx, cy, skew = intr[0], intr[1], intr[2], intr[3], intr[4]
    H, W = out.shape[0], out.shape[1]
    for r in prange(H):
        bu = np.empty(W, dtype=out.dtype)
        bv = np.empty(W, dtype=out.dtype)
        X0 = M[0, 1] * r + M[0, 2]
        Y0 = M[1, 1] * r + M[1, 2]
        Z0 = M[2, 1] * r + M[2, 2]
        for c in range(W):
            X = M[0, 0] * c + X0
            Y = M[1, 0] * c + Y0
            Z = M[2, 0] * c + Z0
            rho = math.sqrt(X * X + Y * Y)
            t = math.atan2(rho, Z)
            td, _d = theta_d(t, k)
            s = td / rho if rho > 0.0 else 0.0
            ok = (t <= t_valid) & ((rho > 0.0) | (Z > 0.0))
            bu[c] = fx * s * X + skew * s * Y + cx if ok else np.nan
            bv[c] = fy * s * Y + cy if ok else np.nan
        for c in range(W):
            out[r, c, 0] = bu[c]
            out[r, c, 1] = bv[c]
