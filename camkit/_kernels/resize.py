"""Separable resampling passes with precomputed weight tables.

A table gives, for each output index j, the first input index ``starts[j]`` and ``K``
weights (zero-padded); taps never leave the input (the tables are built that way).
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange


@njit(cache=True, nogil=True, parallel=True, error_model="numpy", fastmath={"contract"})
def vertical(src: np.ndarray, starts: np.ndarray, weights: np.ndarray, is_int: bool, hi: float,
             out: np.ndarray) -> None:  # pragma: no cover - numba
    """src (H_in, L), out (H_out, L): out[j] = sum_k w[j, k] src[starts[j] + k], row-wise, so
    the inner loop runs over a contiguous row (vectorised)."""
    L = src.shape[1]
    K = weights.shape[1]
    for j in prange(out.shape[0]):
        acc = np.zeros(L, dtype=np.float32)
        s = starts[j]
        for k in range(K):
            w = np.float32(weights[j, k])
            if w != 0:
                row = src[s + k]
                for i in range(L):
                    acc[i] += w * row[i]
        if is_int:
            for i in range(L):
                v = acc[i] + np.float32(0.5)
                out[j, i] = 0 if v < 0 else hi if v > hi else v
        else:
            for i in range(L):
                out[j, i] = acc[i]


@njit(cache=True, nogil=True, parallel=True, error_model="numpy", fastmath={"contract"})
def horizontal(src: np.ndarray, starts: np.ndarray, weights: np.ndarray, is_int: bool, hi: float,
               out: np.ndarray) -> None:  # pragma: no cover
    """src (H, W_in, C), out (H, W_out, C): out[:, j] = sum_k w[j, k] src[:, starts[j] + k]."""
    C = src.shape[2]
    K = weights.shape[1]
    Wo = out.shape[1]
    for r in prange(src.shape[0]):
        for j in range(Wo):
            s = starts[j]
            if C == 3:
                a0 = np.float32(0)
                a1 = np.float32(0)
                a2 = np.float32(0)
                for k in range(K):
                    w = np.float32(weights[j, k])
                    a0 += w * src[r, s + k, 0]
                    a1 += w * src[r, s + k, 1]
                    a2 += w * src[r, s + k, 2]
                if is_int:
                    a0 += np.float32(0.5)
                    a1 += np.float32(0.5)
                    a2 += np.float32(0.5)
                    out[r, j, 0] = 0 if a0 < 0 else hi if a0 > hi else a0
                    out[r, j, 1] = 0 if a1 < 0 else hi if a1 > hi else a1
                    out[r, j, 2] = 0 if a2 < 0 else hi if a2 > hi else a2
                else:
                    out[r, j, 0] = a0
                    out[r, j, 1] = a1
                    out[r, j, 2] = a2
            else:
                for ch in range(C):
                    acc = np.float32(0)
                    for k in range(K):
                        acc += np.float32(weights[j, k]) * src[r, s + k, ch]
                    if is_int:
                        acc += np.float32(0.5)
                        out[r, j, ch] = 0 if acc < 0 else hi if acc > hi else acc
                    else:
                        out[r, j, ch] = acc
