"""Kernels for square marker detection: adaptive threshold, 4-connected labelling, and each
region's area, bounding box and quad corners, in passes over the image."""

from __future__ import annotations

import numpy as np
from numba import njit, prange


@njit(cache=True, nogil=True, error_model="numpy")
def integral(g: np.ndarray, ii: np.ndarray) -> None:  # pragma: no cover - numba
    """``ii`` (H + 1, W + 1): the integral image of ``g`` (zeros on the first row and column)."""
    H, W = g.shape
    ii[0, :] = 0.0
    for y in range(H):
        ii[y + 1, 0] = 0.0
        acc = 0.0
        for x in range(W):
            acc += g[y, x]
            ii[y + 1, x + 1] = ii[y, x + 1] + acc


@njit(cache=True, nogil=True, parallel=True, error_model="numpy")
def dark_mask(g: np.ndarray, ii: np.ndarray, r: int, c: float, out: np.ndarray) -> None:  # pragma: no cover
    """``out[y, x] = g[y, x] < mean of g over the (2r+1)^2 window (clipped at the borders) - c``,
    from the integral image ``ii`` (:func:`integral`)."""
    H, W = g.shape
    for y in prange(H):
        y0 = max(y - r, 0)
        y1 = min(y + r + 1, H)
        for x in range(W):
            x0 = max(x - r, 0)
            x1 = min(x + r + 1, W)
            tot = ii[y1, x1] - ii[y0, x1] - ii[y1, x0] + ii[y0, x0]
            out[y, x] = g[y, x] < tot / ((y1 - y0) * (x1 - x0)) - c


@njit(cache=True, nogil=True, parallel=True, error_model="numpy")
def cross_filter(src: np.ndarray, dilate: bool, out: np.ndarray) -> None:  # pragma: no cover - numba
    """Erosion (``dilate`` False: a pixel stays set where it and its four neighbours are set)
    or dilation (set where it or one of its four neighbours is) of ``src`` by the 3 x 3 cross;
    off the image counts as unset."""
    H, W = src.shape
    for y in prange(H):
        for x in range(W):
            a = src[y, x]
            b = src[y - 1, x] if y > 0 else False
            c = src[y + 1, x] if y < H - 1 else False
            d = src[y, x - 1] if x > 0 else False
            e = src[y, x + 1] if x < W - 1 else False
            out[y, x] = (a or b or c or d or e) if dilate else (a and b and c and d and e)


@njit(cache=True, nogil=True, error_model="numpy")
def _find(parent: np.ndarray, a: int) -> int:  # pragma: no cover - numba
    while parent[a] != a:
        parent[a] = parent[parent[a]]
        a = parent[a]
    return a


@njit(cache=True, nogil=True, error_model="numpy")
def label4(mask: np.ndarray, labels: np.ndarray) -> int:  # pragma: no cover - numba
    """4-connected components of ``mask`` into ``labels`` (1..n, 0 off the mask), numbered in
    raster order of their first pixel; returns n. Two passes with union-find."""
    H, W = mask.shape
    parent = np.empty(H * W // 2 + 2, dtype=np.int64)
    n = 0
    for y in range(H):
        for x in range(W):
            if not mask[y, x]:
                labels[y, x] = 0
                continue
            up = labels[y - 1, x] if y > 0 else 0
            left = labels[y, x - 1] if x > 0 else 0
            if up == 0 and left == 0:
                n += 1
                if n >= parent.shape[0]:
                    grown = np.empty(2 * parent.shape[0], dtype=np.int64)
                    grown[:parent.shape[0]] = parent
                    parent = grown
                parent[n] = n
                labels[y, x] = n
            elif up != 0 and left != 0:
                a, b = _find(parent, up), _find(parent, left)
                if a != b:
                    if a < b:
                        parent[b] = a
                    else:
                        parent[a] = b
                labels[y, x] = min(a, b)
            else:
                labels[y, x] = up if up != 0 else left
    final = np.zeros(n + 1, dtype=np.int64)
    m = 0
    for k in range(1, n + 1):
        root = _find(parent, k)
        if root == k:
            m += 1
            final[k] = m
    for k in range(1, n + 1):
        final[k] = final[_find(parent, k)]
    for y in range(H):
        for x in range(W):
            if labels[y, x] != 0:
                labels[y, x] = final[labels[y, x]]
    return m


@njit(cache=True, nogil=True, error_model="numpy")
def region_quads(labels: np.ndarray, n: int, min_area: int, max_area: int, min_side: int, stats: np.ndarray,
                 quads: np.ndarray) -> None:  # pragma: no cover - numba
    """Per region k (1..n): ``stats[k - 1] = (area, x0, y0, x1, y1)`` (bounding box inclusive)
    and, for the regions of ``min_area`` to ``max_area`` pixels whose box is ``min_side`` or
    more a side, at most 8 times longer than wide and a fifth filled, ``quads[k - 1]`` (4, 2):
    the farthest pixel from the centroid (a), the farthest from a (b), and the farthest from
    the line ab on either side (e, f), as (a, e, b, f). The area of a region without a quad
    (left out, or all on one side of ab) is made negative. One pass over the image, then three
    over each kept region's box."""
    H, W = labels.shape
    sx = np.zeros(n + 1)
    sy = np.zeros(n + 1)
    for k in range(n):
        stats[k, 0] = 0
        stats[k, 1] = W
        stats[k, 2] = H
        stats[k, 3] = -1
        stats[k, 4] = -1
    for y in range(H):
        for x in range(W):
            k = labels[y, x]
            if k == 0:
                continue
            stats[k - 1, 0] += 1
            if x < stats[k - 1, 1]:
                stats[k - 1, 1] = x
            if y < stats[k - 1, 2]:
                stats[k - 1, 2] = y
            if x > stats[k - 1, 3]:
                stats[k - 1, 3] = x
            if y > stats[k - 1, 4]:
                stats[k - 1, 4] = y
            sx[k] += x
            sy[k] += y
    keep = np.zeros(n + 1, dtype=np.bool_)
    for k in range(1, n + 1):
        area = stats[k - 1, 0]
        w = stats[k - 1, 3] - stats[k - 1, 1] + 1
        h = stats[k - 1, 4] - stats[k - 1, 2] + 1
        # A quad's box: not too thin, and a fifth of it filled at least (a curve or a cable is not).
        keep[k] = (min_area <= area <= max_area and min(w, h) >= min_side and max(w, h) <= 8 * min(w, h)
                   and 5 * area >= w * h)
        if keep[k]:
            sx[k] /= area
            sy[k] /= area
    hi = np.full(n + 1, -np.inf)
    lo = np.full(n + 1, np.inf)
    for k in range(1, n + 1):  # passes 2-4 over each kept region's own box only
        if not keep[k]:
            continue
        x0, y0, x1, y1 = stats[k - 1, 1], stats[k - 1, 2], stats[k - 1, 3], stats[k - 1, 4]
        best = -1.0
        for y in range(y0, y1 + 1):  # a: farthest from the centroid
            for x in range(x0, x1 + 1):
                if labels[y, x] == k:
                    d = (x - sx[k]) ** 2 + (y - sy[k]) ** 2
                    if d > best:
                        best = d
                        quads[k - 1, 0, 0] = x
                        quads[k - 1, 0, 1] = y
        ax, ay = quads[k - 1, 0, 0], quads[k - 1, 0, 1]
        best = -1.0
        for y in range(y0, y1 + 1):  # b: farthest from a
            for x in range(x0, x1 + 1):
                if labels[y, x] == k:
                    d = (x - ax) ** 2 + (y - ay) ** 2
                    if d > best:
                        best = d
                        quads[k - 1, 2, 0] = x
                        quads[k - 1, 2, 1] = y
        dx, dy = quads[k - 1, 2, 0] - ax, quads[k - 1, 2, 1] - ay
        for y in range(y0, y1 + 1):  # e, f: farthest from the line ab on either side
            for x in range(x0, x1 + 1):
                if labels[y, x] == k:
                    side = dx * (y - ay) - dy * (x - ax)
                    if side > hi[k]:
                        hi[k] = side
                        quads[k - 1, 1, 0] = x
                        quads[k - 1, 1, 1] = y
                    if side < lo[k]:
                        lo[k] = side
                        quads[k - 1, 3, 0] = x
                        quads[k - 1, 3, 1] = y
    for k in range(1, n + 1):  # a region left out, or on one side of ab, has no quad: mark it
        if not (keep[k] and hi[k] > 0 and lo[k] < 0):
            stats[k - 1, 0] = -stats[k - 1, 0]
