"""Kernels for square marker detection: adaptive threshold, 4-connected labelling, and each
region's area, bounding box and quad corners, in passes over the image; the batched
homographies of the markers' small point sets."""

from __future__ import annotations

import math

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
def label4(mask: np.ndarray, labels: np.ndarray) -> tuple[int, np.ndarray, np.ndarray]:  # pragma: no cover
    """4-connected components of ``mask`` into ``labels`` (1..n, 0 off the mask), numbered in
    raster order of their first pixel. Two passes with union-find; the second also gathers
    each region's ``stats`` (n, 5): area, x0, y0, x1, y1 (bounding box inclusive), and
    ``sums`` (n, 2): the sums of its pixels' x and y. Returns (n, stats, sums)."""
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
    stats = np.empty((m, 5), dtype=np.int64)
    sums = np.zeros((m, 2))
    for k in range(m):
        stats[k, 0] = 0
        stats[k, 1] = W
        stats[k, 2] = H
        stats[k, 3] = -1
        stats[k, 4] = -1
    for y in range(H):
        for x in range(W):
            if labels[y, x] != 0:
                k = final[labels[y, x]]
                labels[y, x] = k
                k -= 1
                stats[k, 0] += 1
                if x < stats[k, 1]:
                    stats[k, 1] = x
                if y < stats[k, 2]:
                    stats[k, 2] = y
                if x > stats[k, 3]:
                    stats[k, 3] = x
                if y > stats[k, 4]:
                    stats[k, 4] = y
                sums[k, 0] += x
                sums[k, 1] += y
    return m, stats, sums


@njit(cache=True, nogil=True, error_model="numpy")
def region_quads(labels: np.ndarray, n: int, min_area: int, max_area: int, min_side: int, stats: np.ndarray,
                 sums: np.ndarray, quads: np.ndarray) -> None:  # pragma: no cover - numba
    """For the regions k (1..n) of :func:`label4` (its ``stats`` and ``sums``) of ``min_area``
    to ``max_area`` pixels whose box is ``min_side`` or more a side, at most 8 times longer
    than wide and a fifth filled, ``quads[k - 1]`` (4, 2): the farthest pixel from the
    centroid (a), the farthest from a (b), and the farthest from the line ab on either side
    (e, f), as (a, e, b, f). The area of a region without a quad (left out, or all on one
    side of ab) is made negative. Three passes over each kept region's box."""
    sx = np.zeros(n + 1)
    sy = np.zeros(n + 1)
    keep = np.zeros(n + 1, dtype=np.bool_)
    for k in range(1, n + 1):
        area = stats[k - 1, 0]
        w = stats[k - 1, 3] - stats[k - 1, 1] + 1
        h = stats[k - 1, 4] - stats[k - 1, 2] + 1
        # A quad's box: not too thin, and a fifth of it filled at least (a curve or a cable is not).
        keep[k] = (min_area <= area <= max_area and min(w, h) >= min_side and max(w, h) <= 8 * min(w, h)
                   and 5 * area >= w * h)
        if keep[k]:
            sx[k] = sums[k - 1, 0] / area
            sy[k] = sums[k - 1, 1] / area
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


@njit(cache=True, nogil=True, error_model="numpy")
def _norm(p: np.ndarray, k: int, T: np.ndarray) -> bool:  # pragma: no cover - numba
    """Hartley's normalisation of point set ``p[k]`` (P, 2): ``T`` = (scale, cx, cy), the
    scale taking the mean distance from the centroid to sqrt(2); False where the points
    coincide."""
    P = p.shape[1]
    cx = 0.0
    cy = 0.0
    for i in range(P):
        cx += p[k, i, 0]
        cy += p[k, i, 1]
    cx /= P
    cy /= P
    d = 0.0
    for i in range(P):
        d += math.hypot(p[k, i, 0] - cx, p[k, i, 1] - cy)
    d /= P
    if not d > 1e-12:
        return False
    T[0] = math.sqrt(2.0) / d
    T[1] = cx
    T[2] = cy
    return True


@njit(cache=True, nogil=True, parallel=True, error_model="numpy")
def fit_homographies(src: np.ndarray, dst: np.ndarray, out: np.ndarray) -> None:  # pragma: no cover - numba
    """``out[k]`` (3, 3): the homography taking ``src[k]`` (P, 2) to ``dst[k]`` (P, 2), P >= 4,
    by the normalised DLT (Hartley and Zisserman, alg. 4.2) in its inhomogeneous form (h33 = 1
    in the normalised frames, where the source centroid is the origin and maps to a finite
    point): least squares of the 2P linear equations through their 8 x 8 normal equations,
    Gaussian elimination with partial pivoting; NaN where the points coincide or the system
    is singular (collinear points)."""
    K, P = src.shape[0], src.shape[1]
    for k in prange(K):
        Ts = np.empty(3)
        Td = np.empty(3)
        if not (_norm(src, k, Ts) and _norm(dst, k, Td)):
            out[k, :, :] = np.nan
            continue
        M = np.zeros((8, 9))  # [A^T A | A^T b]
        row = np.empty(9)
        for i in range(P):
            x = (src[k, i, 0] - Ts[1]) * Ts[0]
            y = (src[k, i, 1] - Ts[2]) * Ts[0]
            u = (dst[k, i, 0] - Td[1]) * Td[0]
            v = (dst[k, i, 1] - Td[2]) * Td[0]
            for e in range(2):
                row[:] = 0.0
                if e == 0:  # h11 x + h12 y + h13 - u (h31 x + h32 y) = u
                    row[0], row[1], row[2] = x, y, 1.0
                    row[6], row[7], row[8] = -u * x, -u * y, u
                else:  # h21 x + h22 y + h23 - v (h31 x + h32 y) = v
                    row[3], row[4], row[5] = x, y, 1.0
                    row[6], row[7], row[8] = -v * x, -v * y, v
                for a in range(8):
                    ra = row[a]
                    if ra != 0.0:
                        for b in range(9):
                            M[a, b] += ra * row[b]
        ok = True
        for c in range(8):  # elimination with partial pivoting
            piv = c
            for r in range(c + 1, 8):
                if abs(M[r, c]) > abs(M[piv, c]):
                    piv = r
            if not abs(M[piv, c]) > 1e-10 * P:
                ok = False
                break
            if piv != c:
                for b in range(9):
                    M[c, b], M[piv, b] = M[piv, b], M[c, b]
            for r in range(c + 1, 8):
                f = M[r, c] / M[c, c]
                if f != 0.0:
                    for b in range(c, 9):
                        M[r, b] -= f * M[c, b]
        if not ok:
            out[k, :, :] = np.nan
            continue
        h = np.empty(9)
        h[8] = 1.0
        for c in range(7, -1, -1):
            acc = M[c, 8]
            for b in range(c + 1, 8):
                acc -= M[c, b] * h[b]
            h[c] = acc / M[c, c]
        # H = Td^-1 Hn Ts, Ts = [[s, 0, -s cx], [0, s, -s cy], [0, 0, 1]], Td^-1 likewise inverted.
        s, cx, cy = Ts[0], Ts[1], Ts[2]
        t, dx, dy = Td[0], Td[1], Td[2]
        for r in range(3):
            a0, a1, a2 = h[3 * r], h[3 * r + 1], h[3 * r + 2]
            h[3 * r] = a0 * s
            h[3 * r + 1] = a1 * s
            h[3 * r + 2] = a2 - a0 * s * cx - a1 * s * cy
        for c in range(3):
            g0, g1, g2 = h[c], h[3 + c], h[6 + c]
            out[k, 0, c] = g0 / t + dx * g2
            out[k, 1, c] = g1 / t + dy * g2
            out[k, 2, c] = g2


@njit(cache=True, nogil=True, error_model="numpy")
def unique_quads(quads: np.ndarray, centre: np.ndarray, span: np.ndarray, order: np.ndarray,
                 keep: np.ndarray) -> None:  # pragma: no cover - numba
    """Clear ``keep`` for each quad (K, 4, 2) whose corners all lie within 5 % of an earlier
    kept quad's span (plus a pixel) of that quad's: the same marker found again. ``order``:
    the quads by their centre's x, so that only those within a tenth of a span in x are
    compared."""
    n = order.shape[0]
    for i in range(n):
        a = order[i]
        if not keep[a]:
            continue
        for j in range(i + 1, n):
            b = order[j]
            if centre[b, 0] - centre[a, 0] > 0.1 * span[a]:
                break
            if not keep[b]:
                continue
            worst = 0.0
            for c in range(4):
                for e in range(2):
                    worst = max(worst, abs(quads[b, c, e] - quads[a, c, e]))
            if worst < 0.05 * span[a] + 1.0:
                keep[b] = False
