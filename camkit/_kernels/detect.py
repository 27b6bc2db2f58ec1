"""Kernels for checkerboard corner detection: Gaussian blur, saddle response, local maxima."""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange


@njit(cache=True, nogil=True, error_model="numpy")
def gaussian_taps(sigma: float) -> np.ndarray:  # pragma: no cover - numba
    """The normalised Gaussian's taps out to 3 sigma (one at least) either side."""
    R = max(math.ceil(3.0 * sigma), 1)
    k = np.empty(2 * R + 1)
    for i in range(2 * R + 1):
        k[i] = math.exp(-0.5 * ((i - R) / sigma) ** 2)
    return k / k.sum()


#: Rows per band of :func:`gaussian_blur` (its row pass for a band and the band's margins is
#: kept in cache for the column pass).
_BAND = 64


@njit(cache=True, nogil=True, parallel=True, error_model="numpy")
def gaussian_blur(img: np.ndarray, sigma: float, out: np.ndarray) -> None:  # pragma: no cover - numba
    """Separable Gaussian (radius 3 sigma, edges replicated), rows then columns, band by band
    of rows (each band's row pass, with its margins, stays in cache for its column pass).
    Each pass adds tap after tap along whole rows (the inner loop runs along x, contiguous,
    so it is vectorised), each pixel's sum in tap order, as a pixel-by-pixel loop adds it."""
    H, W = img.shape
    k = gaussian_taps(sigma)
    R = k.shape[0] // 2
    nb = (H + _BAND - 1) // _BAND
    for b in prange(nb):
        y0 = b * _BAND
        y1 = min(y0 + _BAND, H)
        lo = max(y0 - R, 0)
        hi = min(y1 + R, H)
        tmp = np.empty((hi - lo, W))
        row = np.empty(W + 2 * R)
        for y in range(lo, hi):
            for x in range(W + 2 * R):
                row[x] = img[y, min(max(x - R, 0), W - 1)]
            acc = tmp[y - lo]
            for x in range(W):
                acc[x] = 0.0
            for i in range(2 * R + 1):
                ki = k[i]
                for x in range(W):
                    acc[x] += ki * row[x + i]
        for y in range(y0, y1):
            acc = out[y]
            for x in range(W):
                acc[x] = 0.0
            for i in range(2 * R + 1):
                ki = k[i]
                src = tmp[min(max(y + i - R, 0), H - 1) - lo]
                for x in range(W):
                    acc[x] += ki * src[x]


@njit(cache=True, nogil=True, parallel=True, error_model="numpy")
def saddle_response(s: np.ndarray, out: np.ndarray) -> None:  # pragma: no cover
    """-(Ixx Iyy - Ixy^2) of a smoothed image: large and positive at saddle points (X-corners)."""
    H, W = s.shape
    for y in prange(H):
        for x in range(W):
            if y == 0 or x == 0 or y == H - 1 or x == W - 1:
                out[y, x] = 0.0
                continue
            ixx = s[y, x + 1] - 2.0 * s[y, x] + s[y, x - 1]
            iyy = s[y + 1, x] - 2.0 * s[y, x] + s[y - 1, x]
            ixy = 0.25 * (s[y + 1, x + 1] - s[y + 1, x - 1] - s[y - 1, x + 1] + s[y - 1, x - 1])
            out[y, x] = -(ixx * iyy - ixy * ixy)


@njit(cache=True, nogil=True, error_model="numpy")
def local_maxima(r: np.ndarray, radius: int, threshold: float, out: np.ndarray) -> int:  # pragma: no cover
    """Pixels that are the maximum of their (2 radius + 1)^2 window and above threshold; writes
    (x, y) rows into out and returns how many (at most out.shape[0])."""
    H, W = r.shape
    n = 0
    for y in range(radius, H - radius):
        for x in range(radius, W - radius):
            v = r[y, x]
            if v <= threshold:
                continue
            is_max = True
            for dy in range(-radius, radius + 1):
                for dx in range(-radius, radius + 1):
                    if r[y + dy, x + dx] > v:
                        is_max = False
                        break
                if not is_max:
                    break
            if is_max:
                if n >= out.shape[0]:
                    return n
                out[n, 0] = x
                out[n, 1] = y
                n += 1
    return n


@njit(cache=True, nogil=True, parallel=True, error_model="numpy")
def blur_patches(img: np.ndarray, origin: np.ndarray, tile: np.ndarray, side: int, sigma: float,
                 out: np.ndarray) -> None:  # pragma: no cover - numba
    """The Gaussian blur of :func:`gaussian_blur` (edges replicated), computed only on square
    patches: patch i covers image pixels ``origin[i] + (0..side-1)`` (x, y) and is written to
    ``out`` at ``tile[i] + (0..side-1)``. Each patch reads its own margin of 3 sigma, so the
    values are those of the whole image blurred."""
    H, W = img.shape
    k = gaussian_taps(sigma)
    R = k.shape[0] // 2
    for p in prange(origin.shape[0]):
        x0, y0 = origin[p, 0], origin[p, 1]
        tx, ty = tile[p, 0], tile[p, 1]
        tmp = np.empty((side + 2 * R, side))
        for j in range(side + 2 * R):
            yy = min(max(y0 + j - R, 0), H - 1)
            for x in range(side):
                acc = 0.0
                for i in range(2 * R + 1):
                    xx = min(max(x0 + x + i - R, 0), W - 1)
                    acc += k[i] * img[yy, xx]
                tmp[j, x] = acc
        for y in range(side):
            for x in range(side):
                acc = 0.0
                for i in range(2 * R + 1):
                    acc += k[i] * tmp[y + i, x]
                out[ty + y, tx + x] = acc


@njit(cache=True, nogil=True, parallel=True, error_model="numpy")
def grey_mean(img: np.ndarray, scale: float, lo: float, inv: float, out: np.ndarray) -> None:  # pragma: no cover
    """``out`` = (the mean of the first three channels of ``img`` (H, W, C) (the one channel
    where C < 3) times ``scale``, minus ``lo``) times ``inv``: grey, stretched, in one pass."""
    H, W, C = img.shape
    n = 3 if C >= 3 else 1
    f = scale / n
    for y in prange(H):
        for x in range(W):
            acc = 0.0
            for c in range(n):
                acc += img[y, x, c]
            out[y, x] = (acc * f - lo) * inv


@njit(cache=True, nogil=True, parallel=True, error_model="numpy")
def half_mean(img: np.ndarray, out: np.ndarray) -> None:  # pragma: no cover - numba
    """``out[y, x]`` = the mean of ``img``'s 2x2 block at (2x, 2y), summed in the order
    (0, 0), (1, 0) rows, then (0, 1), (1, 1), times 0.25 (as NumPy's slice sum)."""
    h, w = out.shape
    for y in prange(h):
        for x in range(w):
            out[y, x] = 0.25 * (((img[2 * y, 2 * x] + img[2 * y + 1, 2 * x]) + img[2 * y, 2 * x + 1])
                                + img[2 * y + 1, 2 * x + 1])


@njit(cache=True, nogil=True, error_model="numpy")
def channel_sum_histogram(img: np.ndarray, step: int, hist: np.ndarray) -> None:  # pragma: no cover - numba
    """``hist[v]`` += the number of pixels of ``img`` (H, W, C) uint8, every ``step``-th row
    and column, whose first three channels (the one channel where C < 3) sum to ``v``."""
    H, W, C = img.shape
    n = 3 if C >= 3 else 1
    for y in range(0, H, step):
        for x in range(0, W, step):
            acc = 0
            for c in range(n):
                acc += np.int64(img[y, x, c])
            hist[acc] += 1
