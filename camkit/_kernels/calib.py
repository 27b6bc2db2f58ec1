"""Kernels for calibration: the blocks of the bundle-adjustment normal equations."""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True, nogil=True, error_model="numpy")
def normal_blocks(Jm: np.ndarray, dp: np.ndarray, RX: np.ndarray, r: np.ndarray, w: np.ndarray, view: np.ndarray,
                  n_views: int):  # pragma: no cover - numba
    """Weighted normal-equation blocks of min sum w |r|^2 over intrinsics m and per-view poses.

    Per point: ``Jm`` (2, F) d pixel / d intrinsics; the pose Jacobian is
    ``Jp = [dp @ -[RX]x, dp]`` (2, 6) for R <- exp([w]x) R, t <- t + dt, built here from
    ``dp`` (2, 3) d pixel / d camera point and ``RX`` (3,) the rotated board point.
    Returns U (F, F), W (V, F, 6), V (V, 6, 6), gm (F,), gp (V, 6)."""
    N, _, F = Jm.shape
    U = np.zeros((F, F))
    W = np.zeros((n_views, F, 6))
    V = np.zeros((n_views, 6, 6))
    gm = np.zeros(F)
    gp = np.zeros((n_views, 6))
    jp = np.empty(6)
    for n in range(N):
        v = view[n]
        wn = w[n]
        x0, x1, x2 = RX[n, 0], RX[n, 1], RX[n, 2]
        for a in range(2):
            d0, d1, d2 = dp[n, a, 0], dp[n, a, 1], dp[n, a, 2]
            # dp @ -[X]x, with [X]x = [[0, -x2, x1], [x2, 0, -x0], [-x1, x0, 0]]
            jp[0] = -(d1 * x2 - d2 * x1)
            jp[1] = -(-d0 * x2 + d2 * x0)
            jp[2] = -(d0 * x1 - d1 * x0)
            jp[3] = d0
            jp[4] = d1
            jp[5] = d2
            ra = r[n, a] * wn
            for i in range(F):
                ji = Jm[n, a, i] * wn
                gm[i] += Jm[n, a, i] * ra
                for j in range(i, F):
                    U[i, j] += ji * Jm[n, a, j]
                for k in range(6):
                    W[v, i, k] += ji * jp[k]
            for k in range(6):
                gp[v, k] += jp[k] * ra
                jk = jp[k] * wn
                for l in range(k, 6):
                    V[v, k, l] += jk * jp[l]
    for i in range(F):
        for j in range(i):
            U[i, j] = U[j, i]
    for v in range(n_views):
        for k in range(6):
            for l in range(k):
                V[v, k, l] = V[v, l, k]
    return U, W, V, gm, gp
