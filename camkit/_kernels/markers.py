"""Kernels for square marker detection: adaptive threshold, 4-connected labelling, and each
region's area, bounding box and quad corners, in passes over the image; the batched
homographies of the markers' small point sets."""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from camkit._kernels.calib import dlt_normal
from camkit._kernels.detect import PARALLEL_MIN_NS
from camkit._kernels.lattice import bilinear

#: :func:`refine_quads`: a side's edge found farther than this from the line through all of them
#: (pixels, or cells where that is more) is left out of the line fitted again...
_EDGE_OFF_LINE_PX = 1.5
_EDGE_OFF_LINE_CELLS = 0.3
#: ... where at most this many of the side's eleven places are off it (more are not strays but a
#: side too thin to tell its edges apart: corpus view 383, markers seen edge on as slivers), and
#: where that distance is within half the search's reach (0.8 of a cell), so that a stray can be
#: told from blur and noise (cells of 3.75 px or more; on cells of 1.3-2.4 px the refit dropped
#: places the noise had moved and lost markers: ChArUco corpus view 1453, AprilGrid view 110).
_EDGE_OFF_LINE_MOST = 3


@njit(cache=True, nogil=True, error_model="numpy")
def _running_sums(src: np.ndarray, stretch: bool, lo: float, inv: float, grey: np.ndarray,
                  ii: np.ndarray) -> None:  # pragma: no cover - numba
    """``ii`` (H + 1, W + 1): the integral image of ``src`` (H, W) (zeros on the first row and
    column), each entry the one above plus the row's running sum; with ``stretch``, of the
    grey ``(src - lo) * inv`` (as :func:`camkit._kernels.detect.grey_mean` makes it from one
    channel), written to ``grey`` on the way. Four rows at a time: their running sums are four
    chains of additions side by side, not one that waits on each add (the same additions in
    the same order)."""
    H, W = src.shape
    ii[0, :] = 0.0
    y = 0
    while y + 4 <= H:
        r0, r1, r2, r3 = src[y], src[y + 1], src[y + 2], src[y + 3]
        p, o0, o1, o2, o3 = ii[y], ii[y + 1], ii[y + 2], ii[y + 3], ii[y + 4]
        o0[0] = o1[0] = o2[0] = o3[0] = 0.0
        a0 = a1 = a2 = a3 = 0.0
        for x in range(W):
            if stretch:
                e0 = ((0.0 + r0[x]) * 1.0 - lo) * inv
                e1 = ((0.0 + r1[x]) * 1.0 - lo) * inv
                e2 = ((0.0 + r2[x]) * 1.0 - lo) * inv
                e3 = ((0.0 + r3[x]) * 1.0 - lo) * inv
                grey[y, x] = e0
                grey[y + 1, x] = e1
                grey[y + 2, x] = e2
                grey[y + 3, x] = e3
            else:
                e0, e1, e2, e3 = float(r0[x]), float(r1[x]), float(r2[x]), float(r3[x])
            a0 += e0
            a1 += e1
            a2 += e2
            a3 += e3
            v0 = p[x + 1] + a0
            v1 = v0 + a1
            v2 = v1 + a2
            o0[x + 1] = v0
            o1[x + 1] = v1
            o2[x + 1] = v2
            o3[x + 1] = v2 + a3
        y += 4
    while y < H:
        ii[y + 1, 0] = 0.0
        acc = 0.0
        for x in range(W):
            e = float(src[y, x])
            if stretch:
                e = ((0.0 + src[y, x]) * 1.0 - lo) * inv
                grey[y, x] = e
            acc += e
            ii[y + 1, x + 1] = ii[y, x + 1] + acc
        y += 1


@njit(cache=True, nogil=True, error_model="numpy")
def integral(g: np.ndarray, ii: np.ndarray) -> None:  # pragma: no cover - numba
    """``ii`` (H + 1, W + 1): the integral image of ``g`` (:func:`_running_sums`)."""
    _running_sums(g, False, 0.0, 1.0, g, ii)


@njit(cache=True, nogil=True, error_model="numpy")
def grey_integral(raw: np.ndarray, lo: float, inv: float, out: np.ndarray,
                  ii: np.ndarray) -> None:  # pragma: no cover - numba
    """:func:`camkit._kernels.detect.grey_mean` of the one-channel ``raw`` (H, W) (scale 1)
    into ``out``, and in the same pass ``ii`` its integral image as :func:`integral` makes it:
    the same values bit for bit, the grey read once (:func:`_running_sums`)."""
    _running_sums(raw, True, lo, inv, out, ii)


@njit(cache=True, nogil=True, error_model="numpy")
def _dark_row(g: np.ndarray, ii: np.ndarray, y: int, r: int, c: float, oy: np.ndarray) -> None:  # pragma: no cover
    """Row ``y`` of :func:`dark_mask` into ``oy`` (W,). Where the window lies wholly inside the
    row, its area is the row's one number and the loop runs on slices indexed from zero (so
    that it vectorises; the same comparisons)."""
    H, W = g.shape
    y0 = max(y - r, 0)
    y1 = min(y + r + 1, H)
    hy = y1 - y0
    top, bot, gy = ii[y0], ii[y1], g[y]
    xa = min(r, W)
    xb = max(W - r - 1, xa)
    for x in range(xa):
        x0 = max(x - r, 0)
        x1 = min(x + r + 1, W)
        tot = bot[x1] - top[x1] - bot[x0] + top[x0]
        oy[x] = gy[x] < tot / (hy * (x1 - x0)) - c
    if xb > xa:
        area = float(hy * (2 * r + 1))
        b1, t1, b0, t0, gg, oo = bot[2 * r + 1:], top[2 * r + 1:], bot[0:], top[0:], gy[r:], oy[r:]
        for i in range(xb - xa):
            tot = b1[i] - t1[i] - b0[i] + t0[i]
            oo[i] = gg[i] < tot / area - c
    for x in range(xb, W):
        x0 = max(x - r, 0)
        x1 = min(x + r + 1, W)
        tot = bot[x1] - top[x1] - bot[x0] + top[x0]
        oy[x] = gy[x] < tot / (hy * (x1 - x0)) - c


@njit(cache=True, nogil=True, error_model="numpy")
def dark_mask(g: np.ndarray, ii: np.ndarray, r: int, c: float, out: np.ndarray) -> None:  # pragma: no cover
    """``out[y, x] = g[y, x] < mean of g over the (2r+1)^2 window (clipped at the borders) - c``,
    from the integral image ``ii`` (:func:`integral`), row by row (:func:`_dark_row`). Serial:
    the masks are made on threads side by side."""
    for y in range(g.shape[0]):
        _dark_row(g, ii, y, r, c, out[y])


@njit(cache=True, nogil=True, error_model="numpy")
def _count_runs(row: np.ndarray) -> int:  # pragma: no cover - numba
    """How many runs of set pixels one mask row (uint8) holds: a run starts where a set pixel
    follows a clear one."""
    c = np.int64(row[0])
    for x in range(1, row.shape[0]):
        c += row[x] > row[x - 1]
    return c


@njit(cache=True, nogil=True, error_model="numpy")
def _write_runs(row: np.ndarray, a0: np.ndarray, a1: np.ndarray) -> int:  # pragma: no cover - numba
    """One mask row's (uint8) runs' first and last columns into ``a0``, ``a1`` from slot 0, and
    their count. The row's changes first, without branches (each pixel writes its column to
    the next slot of ``a0``, which a change moves on: so the slot after the last change is
    written too, and ``a0`` holds one more than the row's changes), then split: they
    alternate, a run's start and the column after its end."""
    W = row.shape[0]
    k = 0
    prev = 0
    for x in range(W):
        v = np.int64(row[x])
        a0[k] = x
        k += v ^ prev
        prev = v
    n = (k + 1) // 2
    for i in range(k // 2):
        a1[i] = a0[2 * i + 1] - 1
    if k % 2:
        a1[n - 1] = W - 1
    for i in range(1, n):
        a0[i] = a0[2 * i]
    return n


@njit(cache=True, nogil=True, error_model="numpy")
def cross_filter(src: np.ndarray, dilate: bool, out: np.ndarray) -> None:  # pragma: no cover - numba
    """Erosion (``dilate`` False: a pixel stays set where it and its four neighbours are set)
    or dilation (set where it or one of its four neighbours is) of ``src`` by the 3 x 3 cross;
    off the image counts as unset. Serial, as :func:`dark_mask`."""
    H, W = src.shape
    for y in range(H):
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
def mask_runs(mask: np.ndarray) -> tuple[int, np.ndarray, np.ndarray, np.ndarray]:  # pragma: no cover - numba
    """The runs of set pixels of ``mask``, row by row, left to right: (count, y, x0, x1), int32;
    counted first (:func:`_count_runs`), then written (:func:`_write_runs`)."""
    H, W = mask.shape
    m = mask.view(np.uint8)
    n = 0
    for y in range(H):
        n += _count_runs(m[y])
    ry = np.empty(n, dtype=np.int32)
    r0 = np.empty(n, dtype=np.int32)
    r1 = np.empty(n, dtype=np.int32)
    b0 = np.empty(W + 1, dtype=np.int32)  # (:func:`_write_runs` writes past the row's runs)
    b1 = np.empty(W // 2 + 1, dtype=np.int32)
    k = 0
    for y in range(H):
        ke = _write_runs(m[y], b0, b1)
        ry[k:k + ke] = y
        r0[k:k + ke] = b0[:ke]
        r1[k:k + ke] = b1[:ke]
        k += ke
    return n, ry, r0, r1


@njit(cache=True, nogil=True, error_model="numpy")
def region_quads(mask: np.ndarray, min_area: int, max_area: int,
                 min_side: int) -> tuple[np.ndarray, np.ndarray]:  # pragma: no cover - numba
    """The 4-connected regions of ``mask``, numbered in raster order of their first pixel, from
    its runs of set pixels (a run joins those of the row above that it overlaps; union-find):
    ``stats`` (n, 6): area, x0, y0, x1, y1 (bounding box inclusive), and a flag (below), and, for the regions of
    ``min_area`` to ``max_area`` pixels whose box is ``min_side`` or more a side, at most 8
    times longer than wide and a fifth filled, ``quads`` (n, 4, 2): the farthest pixel from
    the centroid (a), the farthest from a (b), and the farthest from the line ab on either
    side (e, f), as (a, e, b, f), the first in raster order where several are as far. A
    distance from a point is convex along a run and from a line linear, so only a run's ends
    are looked at. Where that quad covers under 0.6 of the region (a sliver: a marker seen
    nearly edge on, whose two farthest pixels can be the ends of one long side) or the box
    is too thin or too empty for it, the quad is the largest one on the corners of the
    region's convex hull (:func:`_hull_quad`), kept where the region fills 0.35 of it at
    least (a curve or a cable does not) and it covers 0.6 of the region; ``stats[:, 5]`` is 1
    for those. The area of a region without a quad (left out, or all on one side of ab) is
    made negative. Only the regions of the right area and box have their runs gathered (most
    regions of a threshold's mask are specks)."""
    nr, ry, r0, r1 = mask_runs(mask)
    return _run_regions(nr, ry, r0, r1, min_area, max_area, min_side)


@njit(cache=True, nogil=True, error_model="numpy")
def _run_regions(nr: int, ry: np.ndarray, r0: np.ndarray, r1: np.ndarray, min_area: int, max_area: int,
                 min_side: int) -> tuple[np.ndarray, np.ndarray]:  # pragma: no cover - numba
    """:func:`region_quads` from the mask's ``nr`` runs (:func:`mask_runs`)."""
    parent = np.arange(nr).astype(np.int32)
    # Join each run to the runs of the row above that it overlaps (4-connected: a shared column).
    # A root is its region's first run (the lower index wins), so parent[k] <= k throughout; the
    # run's own root is carried along (only its unions move it).
    prev_start, prev_end = 0, 0
    i = 0
    while i < nr:
        y = ry[i]
        j = i
        while j < nr and ry[j] == y:
            j += 1
        if prev_end > prev_start and ry[prev_start] == y - 1:
            p = prev_start
            for k in range(i, j):
                while p < prev_end and r1[p] < r0[k]:
                    p += 1
                q = p
                a = k
                while q < prev_end and r0[q] <= r1[k]:
                    b = _find(parent, q)
                    if a != b:
                        if a < b:
                            parent[b] = a
                        else:
                            parent[a] = b
                            a = b
                    q += 1
        prev_start, prev_end = i, j
        i = j
    # Each run's root: its parent's, the parent's settled first (parent[k] <= k).
    n = 0
    for k in range(nr):
        parent[k] = parent[parent[k]]
        n += parent[k] == k
    # Each run's region, numbered in raster order, and the regions' sums, added in the runs'
    # order.
    reg = np.empty(nr, dtype=np.int32)
    stats = np.empty((n, 6), dtype=np.int64)
    nrun = np.zeros(n, dtype=np.int64)
    sxy = np.zeros((n, 2))
    g = 0
    for k in range(nr):
        a = parent[k]
        y, x0, x1 = ry[k], r0[k], r1[k]
        ln = x1 - x0 + 1
        if a == k:
            h = g
            g += 1
            stats[h, 0], stats[h, 1], stats[h, 2], stats[h, 3], stats[h, 4], stats[h, 5] = ln, x0, y, x1, y, 0
        else:
            h = reg[a]
            stats[h, 0] += ln
            stats[h, 1] = min(stats[h, 1], x0)
            stats[h, 3] = max(stats[h, 3], x1)
            stats[h, 4] = y
        reg[k] = h
        nrun[h] += 1
        sxy[h, 0] += 0.5 * (x0 + x1) * ln
        sxy[h, 1] += y * ln
    # The runs of the regions of the right area and box, each region's in raster order (a
    # stable counting sort).
    start = np.zeros(n + 1, dtype=np.int64)
    for g in range(n):
        area = stats[g, 0]
        w = stats[g, 3] - stats[g, 1] + 1
        h = stats[g, 4] - stats[g, 2] + 1
        start[g + 1] = start[g]
        if min_area <= area <= max_area and min(w, h) >= min_side:
            start[g + 1] += nrun[g]
        else:
            stats[g, 0] = -area
    order = np.empty(start[n], dtype=np.int64)
    fill = start[:n].copy()
    for k in range(nr):
        g = reg[k]
        if fill[g] < start[g + 1]:
            order[fill[g]] = k
            fill[g] += 1
    quads = np.zeros((n, 4, 2))
    for g in range(n):
        area = stats[g, 0]
        if area <= 0:
            continue
        w = stats[g, 3] - stats[g, 1] + 1
        h = stats[g, 4] - stats[g, 2] + 1
        # A quad's box: not too thin, and a fifth of it filled at least (a curve or a cable is
        # not); else the hull's quad.
        if not (max(w, h) <= 8 * min(w, h) and 5 * area >= w * h):
            _hull_quad(g, area, start, order, ry, r0, r1, stats, quads)
            continue
        cx, cy = sxy[g, 0] / area, sxy[g, 1] / area
        best = -1.0
        ax, ay = 0.0, 0.0
        for t in range(start[g], start[g + 1]):  # a: farthest from the centroid
            k = order[t]
            for x in (r0[k], r1[k]):
                d = (x - cx) ** 2 + (ry[k] - cy) ** 2
                if d > best:
                    best, ax, ay = d, x, ry[k]
        best = -1.0
        bx, by = 0.0, 0.0
        for t in range(start[g], start[g + 1]):  # b: farthest from a
            k = order[t]
            for x in (r0[k], r1[k]):
                d = (x - ax) ** 2 + (ry[k] - ay) ** 2
                if d > best:
                    best, bx, by = d, x, ry[k]
        dx, dy = bx - ax, by - ay
        hi, lo = -np.inf, np.inf
        ex, ey, fx, fy = 0.0, 0.0, 0.0, 0.0
        for t in range(start[g], start[g + 1]):  # e, f: farthest from the line ab on either side
            k = order[t]
            for x in (r0[k], r1[k]):
                side = dx * (ry[k] - ay) - dy * (x - ax)
                if side > hi:
                    hi, ex, ey = side, x, ry[k]
                if side < lo:
                    lo, fx, fy = side, x, ry[k]
        quads[g, 0, 0], quads[g, 0, 1] = ax, ay
        quads[g, 1, 0], quads[g, 1, 1] = ex, ey
        quads[g, 2, 0], quads[g, 2, 1] = bx, by
        quads[g, 3, 0], quads[g, 3, 1] = fx, fy
        if not (hi > 0 and lo < 0 and abs(_shoelace(quads[g])) >= 0.6 * area):
            _hull_quad(g, area, start, order, ry, r0, r1, stats, quads)
    return stats, quads


@njit(cache=True, nogil=True, error_model="numpy")
def mask_quads(mask: np.ndarray, min_area: int, max_area: int, min_side: int) -> np.ndarray:  # pragma: no cover
    """The quads (K, 4, 2) of the regions of ``mask`` (:func:`region_quads`) that are quads, not
    triangles or blobs: their four corners span 0.6 of the region's area at least, and a quad
    not taken from the hull has a box at most 8 times longer than wide; clockwise in the image
    (positive shoelace area, y down), in the regions' order."""
    stats, quads = region_quads(mask, min_area, max_area, min_side)
    return _kept_quads(stats, quads)


@njit(cache=True, nogil=True, error_model="numpy")
def runs_quads(ry: np.ndarray, r0: np.ndarray, r1: np.ndarray, min_area: int, max_area: int,
               min_side: int) -> np.ndarray:  # pragma: no cover - numba
    """:func:`mask_quads` from a mask's runs (:func:`mask_runs`; ``ry`` as long as the runs)."""
    stats, quads = _run_regions(ry.shape[0], ry, r0, r1, min_area, max_area, min_side)
    return _kept_quads(stats, quads)


@njit(cache=True, nogil=True, error_model="numpy")
def _kept_quads(stats: np.ndarray, quads: np.ndarray) -> np.ndarray:  # pragma: no cover - numba
    """:func:`mask_quads`' quads of :func:`region_quads`' regions."""
    n = stats.shape[0]
    keep = np.zeros(n, dtype=np.bool_)
    k = 0
    for g in range(n):
        area = stats[g, 0]
        if area <= 0:
            continue
        w = stats[g, 3] - stats[g, 1] + 1
        h = stats[g, 4] - stats[g, 2] + 1
        if (stats[g, 5] == 1 or max(w, h) <= 8 * min(w, h)) and abs(_shoelace(quads[g])) >= 0.6 * area:
            keep[g] = True
            k += 1
    out = np.empty((k, 4, 2))
    k = 0
    for g in range(n):
        if keep[g]:
            flip = _shoelace(quads[g]) <= 0
            for c in range(4):
                src = 3 - c if flip else c
                out[k, c, 0] = quads[g, src, 0]
                out[k, c, 1] = quads[g, src, 1]
            k += 1
    return out


@njit(cache=True, nogil=True, error_model="numpy")
def _shoelace(q: np.ndarray) -> float:  # pragma: no cover - numba
    """The signed area of the polygon ``q`` (P, 2)."""
    s = 0.0
    P = q.shape[0]
    for i in range(P):
        j = (i + 1) % P
        s += q[i, 0] * q[j, 1] - q[j, 0] * q[i, 1]
    return 0.5 * s


@njit(cache=True, nogil=True, error_model="numpy")
def _tri2(hx: np.ndarray, hy: np.ndarray, i: int, j: int, k: int) -> float:  # pragma: no cover - numba
    """Twice the signed area of the hull's triangle (i, j, k)."""
    return (hx[j] - hx[i]) * (hy[k] - hy[i]) - (hy[j] - hy[i]) * (hx[k] - hx[i])


@njit(cache=True, nogil=True, error_model="numpy")
def _turn(hx: np.ndarray, hy: np.ndarray, h: int, x: float, y: float) -> float:  # pragma: no cover - numba
    """Twice the signed area of the chain's last two points and (x, y): > 0 where it turns left."""
    return (hx[h - 1] - hx[h - 2]) * (y - hy[h - 2]) - (hy[h - 1] - hy[h - 2]) * (x - hx[h - 2])


@njit(cache=True, nogil=True, error_model="numpy")
def _hull_quad(g: int, area: int, start: np.ndarray, order: np.ndarray, ry: np.ndarray, r0: np.ndarray,
               r1: np.ndarray, stats: np.ndarray, quads: np.ndarray) -> None:  # pragma: no cover - numba
    """Region ``g``'s quad (see :func:`region_quads`): the largest quadrilateral on the corners
    of the convex hull of its runs' ends (Andrew's monotone chain over the rows' outer ends,
    already in (y, x) order; then, for each first corner, the third swept round the hull with
    the best second and fourth corners following it, as the area is unimodal along a convex
    polygon's side between two fixed corners). Kept (``stats[g, 5]`` 1) where the region
    fills 0.35 of the quad at least and the quad covers 0.6 of the region; else the region's
    area is made negative."""
    nrow = 0
    last = -1
    for t in range(start[g], start[g + 1]):
        if ry[order[t]] != last:
            nrow += 1
            last = ry[order[t]]
    px = np.empty(2 * nrow)
    py = np.empty(2 * nrow)
    m = -1
    last = -1
    for t in range(start[g], start[g + 1]):  # each row's first and last pixel, in (y, x) order
        k = order[t]
        if ry[k] != last:
            m += 2
            last = ry[k]
            px[m - 1], py[m - 1] = r0[k], ry[k]
        px[m], py[m] = r1[k], ry[k]
    P = 2 * nrow
    hx = np.empty(2 * P)
    hy = np.empty(2 * P)
    h = 0
    for i in range(P):  # lower chain
        while h >= 2 and _turn(hx, hy, h, px[i], py[i]) <= 0:
            h -= 1
        hx[h], hy[h] = px[i], py[i]
        h += 1
    lo = h + 1
    for i in range(P - 2, -1, -1):  # upper chain
        while h >= lo and _turn(hx, hy, h, px[i], py[i]) <= 0:
            h -= 1
        hx[h], hy[h] = px[i], py[i]
        h += 1
    m = h - 1  # the first point closes the chain
    if m < 4:
        stats[g, 0] = -area
        return
    # The largest quadrilateral in a convex polygon spans 2 / pi of its area at least (Sas,
    # 1939: an n-gon's n / (2 pi) sin(2 pi / n), the least for an ellipse); a region that fills
    # under 0.35 of that fills under 0.35 of the quad, and is left without the search.
    hull2 = 0.0
    for i in range(m):
        hull2 += hx[i] * hy[i + 1] - hx[i + 1] * hy[i]
    if area < 0.35 * 0.6366 * 0.5 * abs(hull2):
        stats[g, 0] = -area
        return
    best = 0.0
    bi, bj, bk, bl = 0, 1, 2, 3
    for i in range(m):
        j = i + 1
        l = i + 3
        for k in range(i + 2, i + m - 1):
            if j >= k:
                j = k - 1
            while j + 1 < k and _tri2(hx, hy, i % m, (j + 1) % m, k % m) >= _tri2(hx, hy, i % m, j % m, k % m):
                j += 1
            if l <= k:
                l = k + 1
            while l + 1 < i + m and _tri2(hx, hy, k % m, (l + 1) % m, i % m) >= _tri2(hx, hy, k % m, l % m, i % m):
                l += 1
            a2 = _tri2(hx, hy, i % m, j % m, k % m) + _tri2(hx, hy, k % m, l % m, i % m)
            if a2 > best:
                best, bi, bj, bk, bl = a2, i % m, j % m, k % m, l % m
    if not (area >= 0.35 * 0.5 * best and 0.5 * best >= 0.6 * area):
        stats[g, 0] = -area
        return
    for c, v in enumerate((bi, bj, bk, bl)):
        quads[g, c, 0], quads[g, c, 1] = hx[v], hy[v]
    stats[g, 5] = 1


@njit(cache=True, nogil=True, error_model="numpy")
def _fit_homography(src: np.ndarray, dst: np.ndarray, out: np.ndarray) -> None:  # pragma: no cover - numba
    """``out`` (3, 3): the homography taking ``src`` (P, 2) to ``dst`` (P, 2) of
    :func:`fit_homographies`; NaN where the points coincide or the system is singular."""
    P = src.shape[0]
    M, Ts, Td, ok = dlt_normal(src, dst)
    if not ok:
        out[:, :] = np.nan
        return
    for c in range(8):  # elimination with partial pivoting on [M[:8, :8] | -M[:8, 8]]
        piv = c
        for r in range(c + 1, 8):
            if abs(M[r, c]) > abs(M[piv, c]):
                piv = r
        if not abs(M[piv, c]) > 1e-10 * P:
            out[:, :] = np.nan
            return
        if piv != c:
            for j in range(9):
                M[c, j], M[piv, j] = M[piv, j], M[c, j]
        for r in range(c + 1, 8):
            f = M[r, c] / M[c, c]
            if f != 0.0:
                for j in range(c, 9):
                    M[r, j] -= f * M[c, j]
    h = np.empty(9)
    h[8] = 1.0
    for c in range(7, -1, -1):
        acc = -M[c, 8]
        for j in range(c + 1, 8):
            acc -= M[c, j] * h[j]
        h[c] = acc / M[c, c]
    # H = Td^-1 Hn Ts; Td = [[t, 0, -t dx], [0, t, -t dy], [0, 0, 1]] inverts in closed form.
    Hn = h.reshape(3, 3) @ Ts
    t = Td[0, 0]
    dx, dy = -Td[0, 2] / t, -Td[1, 2] / t
    for c in range(3):
        out[0, c] = Hn[0, c] / t + dx * Hn[2, c]
        out[1, c] = Hn[1, c] / t + dy * Hn[2, c]
        out[2, c] = Hn[2, c]


def _make_fit_homographies(PARALLEL: int):
    """:func:`fit_homographies`'s kernel, run on the OpenMP pool where ``PARALLEL`` is 1."""

    @njit(cache=True, nogil=True, parallel=PARALLEL == 1, error_model="numpy")
    def fit_homographies(src: np.ndarray, dst: np.ndarray, out: np.ndarray) -> None:  # pragma: no cover - numba
        """``out[k]`` (3, 3): the homography taking ``src[k]`` (P, 2) to ``dst[k]`` (P, 2), P >= 4,
        by the normalised DLT (Hartley and Zisserman, alg. 4.2; the normal matrix from
        :func:`camkit._kernels.calib.dlt_normal`) in its inhomogeneous form: h33 = 1 in the
        normalised frames (the source centroid is their origin and maps to a finite point), the
        other eight from the 8 x 8 normal equations by Gaussian elimination with partial
        pivoting; NaN where the points coincide or the system is singular (collinear points)
        (:func:`_fit_homography`)."""
        if PARALLEL:  # (the closure's int keys the cache: the twins apart)
            pass
        for k in prange(src.shape[0]):
            _fit_homography(src[k], dst[k], out[k])

    return fit_homographies


_fit_homographies_serial, _fit_homographies_parallel = _make_fit_homographies(0), _make_fit_homographies(1)


def fit_homographies(src: np.ndarray, dst: np.ndarray, out: np.ndarray) -> None:
    """Each point set's homography (kernel ``_make_fit_homographies``), serial where small
    (:data:`~camkit._kernels.detect.PARALLEL_MIN_NS`; the work counted in sets and their points)."""
    work = src.shape[0] * (800.0 + 60.0 * src.shape[1])
    (_fit_homographies_parallel if work >= PARALLEL_MIN_NS else _fit_homographies_serial)(src, dst, out)
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


@njit(cache=True, nogil=True, error_model="numpy")
def _weighted_line(ex: np.ndarray, ey: np.ndarray, w: np.ndarray) -> tuple[float, float, float]:  # pragma: no cover
    """The line through the points (``ex``, ``ey``) weighted by ``w`` (total least squares): its
    weighted mean and its direction's angle; NaN where the weights sum to nothing."""
    ws = 0.0
    mx = 0.0
    my = 0.0
    for i in range(len(w)):
        ws += w[i]
        mx += w[i] * ex[i]
        my += w[i] * ey[i]
    if not ws > 0:
        return np.nan, np.nan, np.nan
    mx /= ws
    my /= ws
    cxx = 0.0
    cyy = 0.0
    cxy = 0.0
    for i in range(len(w)):
        rx, ry = ex[i] - mx, ey[i] - my
        cxx += w[i] * rx * rx
        cyy += w[i] * ry * ry
        cxy += w[i] * rx * ry
    return mx, my, 0.5 * np.arctan2(2.0 * cxy, cxx - cyy)


@njit(cache=True, nogil=True, error_model="numpy")
def _lines_meet(mid: np.ndarray, dirn: np.ndarray, quad: np.ndarray, cell: float,
                new: np.ndarray) -> bool:  # pragma: no cover - numba
    """``new`` (4, 2): where the lines through ``mid`` along ``dirn`` (4, 2 each: a quad's sides)
    meet, corner j where side j - 1 meets side j; False where two are parallel or a corner lies
    more than ``cell`` from ``quad``'s."""
    for j in range(4):
        i = (j + 3) % 4
        cross = dirn[i, 0] * dirn[j, 1] - dirn[i, 1] * dirn[j, 0]
        if abs(cross) <= 1e-6:
            return False
        s1 = ((mid[j, 0] - mid[i, 0]) * dirn[j, 1] - (mid[j, 1] - mid[i, 1]) * dirn[j, 0]) / cross
        new[j, 0] = mid[i, 0] + s1 * dirn[i, 0]
        new[j, 1] = mid[i, 1] + s1 * dirn[i, 1]
        if not (np.hypot(new[j, 0] - quad[j, 0], new[j, 1] - quad[j, 1]) <= cell):
            return False
    return True


@njit(cache=True, nogil=True, error_model="numpy")
def refine_quads(img: np.ndarray, quads: np.ndarray, n_cells: int, iters: int,
                 out: np.ndarray) -> None:  # pragma: no cover - numba
    """``out`` (K, 4, 2): each quad of ``quads`` (K, 4, 2) with its corners where the lines of
    its sides' edges meet (see :func:`camkit.target._markers.refine_quads`): each side's edge at
    eleven places 0.2-0.8 along it, the strongest dark-to-light rise outward within 0.8 of a
    cell (a cell: the mean side over ``n_cells``), to a tenth of a pixel by a parabola; a line
    through them weighted by the rise, fitted again without the places farther from it than
    :data:`_EDGE_OFF_LINE_PX` (or :data:`_EDGE_OFF_LINE_CELLS` of a cell) where at most
    :data:`_EDGE_OFF_LINE_MOST` are and cells are 3.75 px or more; corners where adjacent lines
    meet (the lines fitted again, else the first: :func:`_lines_meet`). ``iters`` rounds; a
    round whose corners are not all found within a cell of the quad's either way is not
    taken."""
    n_t, n_o = 11, 17
    vals = np.empty(n_o)
    ex = np.empty(n_t)
    ey = np.empty(n_t)
    w = np.empty(n_t)
    w2 = np.empty(n_t)
    mid = np.empty((4, 2))
    dirn = np.empty((4, 2))
    mid2 = np.empty((4, 2))
    dirn2 = np.empty((4, 2))
    new = np.empty((4, 2))
    for k in range(quads.shape[0]):
        cell = 0.0
        for j in range(4):
            j1 = (j + 1) % 4
            cell += np.hypot(quads[k, j1, 0] - quads[k, j, 0], quads[k, j1, 1] - quads[k, j, 1])
        cell /= 4.0 * n_cells
        for j in range(4):
            out[k, j, 0] = quads[k, j, 0]
            out[k, j, 1] = quads[k, j, 1]
        for _ in range(iters):
            cx = 0.25 * (out[k, 0, 0] + out[k, 1, 0] + out[k, 2, 0] + out[k, 3, 0])
            cy = 0.25 * (out[k, 0, 1] + out[k, 1, 1] + out[k, 2, 1] + out[k, 3, 1])
            good = True
            for j in range(4):
                j1 = (j + 1) % 4
                ax, ay = out[k, j, 0], out[k, j, 1]
                dx, dy = out[k, j1, 0] - ax, out[k, j1, 1] - ay
                length = max(np.hypot(dx, dy), 1e-12)
                nx, ny = dy / length, -dx / length
                if (0.5 * (ax + out[k, j1, 0]) - cx) * nx + (0.5 * (ay + out[k, j1, 1]) - cy) * ny < 0:
                    nx, ny = -nx, -ny
                n_pos = 0
                for ti in range(n_t):
                    t = 0.2 + 0.06 * ti
                    bx, by = ax + t * dx, ay + t * dy
                    for oi in range(n_o):
                        o = (-0.8 + 0.1 * oi) * cell
                        vals[oi] = bilinear(img, bx + o * nx, by + o * ny)
                    best, kmax = -np.inf, 0
                    for gi in range(n_o - 2):
                        gv = vals[gi + 2] - vals[gi]
                        if gv > best:
                            best, kmax = gv, gi
                    kk = min(max(kmax, 1), n_o - 4)
                    gm = vals[kk + 1] - vals[kk - 1]
                    g0 = vals[kk + 2] - vals[kk]
                    gp = vals[kk + 3] - vals[kk + 1]
                    den = gm - 2.0 * g0 + gp
                    frac = 0.5 * (gm - gp) / den if den < 0 else 0.0
                    if kk != kmax or abs(frac) > 1.0:
                        frac = 0.0
                    off = (0.1 * (kk + 1 + frac) - 0.8) * cell
                    ex[ti], ey[ti] = bx + off * nx, by + off * ny
                    w[ti] = max(g0, 0.0)
                    if w[ti] > 0:
                        n_pos += 1
                if n_pos < 5:
                    good = False
                    break
                mx, my, ang = _weighted_line(ex, ey, w)
                if not np.isfinite(ang):
                    good = False
                    break
                mid[j, 0], mid[j, 1] = mx, my
                dirn[j, 0], dirn[j, 1] = np.cos(ang), np.sin(ang)
                # Once again without the places off the line: near an obtuse corner of a quad seen
                # at a slant, the search across a side can reach the next side's edge (corpus
                # view 1301's marker 0: one place 8.8 px off tilted the line and put two
                # corners 3-5 px off).
                tol = max(_EDGE_OFF_LINE_PX, _EDGE_OFF_LINE_CELLS * cell)
                n2 = 0
                for ti in range(n_t):
                    off_line = abs((ex[ti] - mx) * dirn[j, 1] - (ey[ti] - my) * dirn[j, 0])
                    w2[ti] = w[ti] if off_line <= tol else 0.0
                    if w2[ti] > 0:
                        n2 += 1
                mid2[j, 0], mid2[j, 1] = mx, my
                dirn2[j, 0], dirn2[j, 1] = dirn[j, 0], dirn[j, 1]
                if n2 >= max(5, n_pos - _EDGE_OFF_LINE_MOST) and n2 < n_pos and tol <= 0.4 * cell:
                    mx, my, ang = _weighted_line(ex, ey, w2)
                    mid2[j, 0], mid2[j, 1] = mx, my
                    dirn2[j, 0], dirn2[j, 1] = np.cos(ang), np.sin(ang)
            if not good:
                break
            # The corners from the lines fitted again; where one of them lies more than a cell
            # from the quad's, from the first lines (a quad whose corners lie near a cell off
            # moves further towards its marker's than its first lines took it, and the round is
            # not taken: AprilGrid corpus view 1550's tags 5 and 7, 2-6 px off, cells of 4-5 px).
            if not _lines_meet(mid2, dirn2, quads[k], cell, new) and not _lines_meet(mid, dirn, quads[k], cell, new):
                break
            for j in range(4):
                out[k, j, 0] = new[j, 0]
                out[k, j, 1] = new[j, 1]



@njit(cache=True, nogil=True, error_model="numpy")
def _pairwise_sum(a: np.ndarray, i0: int, n: int) -> float:  # pragma: no cover - numba
    """``a[i0:i0 + n].sum()`` in NumPy's order for a short contiguous run (under 128: eight
    running sums, then the rest one by one)."""
    if n < 8:
        s = 0.0
        for i in range(n):
            s += a[i0 + i]
        return s
    r0, r1, r2, r3 = a[i0], a[i0 + 1], a[i0 + 2], a[i0 + 3]
    r4, r5, r6, r7 = a[i0 + 4], a[i0 + 5], a[i0 + 6], a[i0 + 7]
    i = 8
    while i < n - n % 8:
        r0 += a[i0 + i]
        r1 += a[i0 + i + 1]
        r2 += a[i0 + i + 2]
        r3 += a[i0 + i + 3]
        r4 += a[i0 + i + 4]
        r5 += a[i0 + i + 5]
        r6 += a[i0 + i + 6]
        r7 += a[i0 + i + 7]
        i += 8
    s = ((r0 + r1) + (r2 + r3)) + ((r4 + r5) + (r6 + r7))
    while i < n:
        s += a[i0 + i]
        i += 1
    return s


@njit(cache=True, nogil=True, error_model="numpy")
def box_shades(img: np.ndarray, a: float, b: float, px: np.ndarray, half: np.ndarray, gx: np.ndarray,
               gy: np.ndarray, mean: np.ndarray, var: np.ndarray, inside: np.ndarray) -> None:  # pragma: no cover
    """Each box's shade and spread: for each place ``px[k, p]`` (K, P, 2), the image (``img``
    stretched by ``a * v + b``; bilinear, edges replicated) at the place plus ``half[k]``
    times each offset (``gx``, ``gy``, G), ``mean[k, p]`` and ``var[k, p]`` (unbiased) of those
    G samples, as NumPy's ``mean`` and ``var(ddof=1)`` sum them (:func:`_pairwise_sum`); and
    ``inside[k]`` cleared where a box of every place reaches off the image (a ``half`` either
    way of the place)."""
    H, W = img.shape
    K, P = px.shape[0], px.shape[1]
    G = gx.shape[0]
    v = np.empty(G)
    dev = np.empty(G)
    for k in range(K):
        h = half[k]
        for p in range(P):
            x0, y0 = px[k, p, 0], px[k, p, 1]
            if not (x0 - h >= 0 and y0 - h >= 0 and x0 + h <= W - 1 and y0 + h <= H - 1):
                inside[k] = False
            for j in range(G):
                v[j] = bilinear(img, x0 + h * gx[j], y0 + h * gy[j]) * a + b
            m = _pairwise_sum(v, 0, G) / G
            for j in range(G):
                d = v[j] - m
                dev[j] = d * d
            mean[k, p] = m
            var[k, p] = _pairwise_sum(dev, 0, G) / (G - 1)


@njit(cache=True, nogil=True, error_model="numpy")
def _inverse4(N: np.ndarray, inv: np.ndarray) -> float:  # pragma: no cover - numba
    """``inv`` = the inverse of the 4 x 4 ``N`` (Gauss-Jordan, partial pivoting); returns the
    determinant of ``N`` scaled to a unit diagonal (0 where a pivot vanishes: ``inv`` then
    undefined). (:func:`camkit._kernels.lattice._solve_lu` solves for one right-hand side and
    gives no determinant: here the whole inverse, the covariance, and the rank test are
    wanted.)"""
    a = np.empty((4, 8))
    s = np.empty(4)
    for i in range(4):
        s[i] = 1.0 / math.sqrt(N[i, i]) if N[i, i] > 0.0 else 0.0
    for i in range(4):
        for j in range(4):
            a[i, j] = N[i, j] * s[i] * s[j]
            a[i, 4 + j] = 1.0 if i == j else 0.0
    det = 1.0
    for c in range(4):
        piv = c
        for r in range(c + 1, 4):
            if abs(a[r, c]) > abs(a[piv, c]):
                piv = r
        if not abs(a[piv, c]) > 0.0:
            return 0.0
        if piv != c:
            det = -det
            for j in range(8):
                t = a[c, j]
                a[c, j] = a[piv, j]
                a[piv, j] = t
        det *= a[c, c]
        f = 1.0 / a[c, c]
        for j in range(8):
            a[c, j] *= f
        for r in range(4):
            if r != c:
                g = a[r, c]
                if g != 0.0:
                    for j in range(8):
                        a[r, j] -= g * a[c, j]
    # (The scaled matrix's inverse, scaled back: N^-1 = S (S N S)^-1 S.)
    for i in range(4):
        for j in range(4):
            inv[i, j] = a[i, 4 + j] * s[i] * s[j]
    return det


@njit(cache=True, nogil=True, error_model="numpy")
def light_fit(s0: np.ndarray, s1: np.ndarray, v0: np.ndarray, v1: np.ndarray, d: np.ndarray, noise: float,
              n_box: int, misfit_share: float, theta: np.ndarray, cov: np.ndarray, seen: np.ndarray,
              fits: np.ndarray, full_rank: np.ndarray) -> None:  # pragma: no cover - numba
    """The light across each ChArUco corner from its mirrored boxes (step 8 of
    :func:`camkit.target.charuco._light`): the boxes' shades ``s0``, ``s1`` and spreads ``v0``,
    ``v1`` (K, P) at the offsets ``+d``, ``-d`` (K, P, 2 px) from the corner; half the pair's
    difference ``D = M (m . d) + a . d`` (``M`` the pair's mean shade) fitted for ``theta`` =
    (m, a) by weighted least squares, each pair's variance its boxes' spreads (the image's
    ``noise`` squared at least) over ``4 n_box``. Writes ``theta[k]``, its covariance
    ``cov[k]`` (4, 4) scaled by the residuals' chi-square per degree of freedom where over 1,
    ``seen[k]`` (the reading's chi-square against no light), ``fits[k]`` (the residuals' RMS
    within three of the pairs' noise sigmas plus ``misfit_share`` of the squares'
    half-contrast: the brighter half of the pairs' shades against the rest) and
    ``full_rank[k]`` (the normal matrix scaled to a unit diagonal has a determinant over
    1e-9: places in two directions and two shades)."""
    K, P = s0.shape
    nn = noise * noise
    dof = P - 4
    N = np.empty((4, 4))
    inv = np.empty((4, 4))
    A = np.empty((P, 4))
    D = np.empty(P)
    w = np.empty(P)
    M = np.empty(P)
    b = np.empty(4)
    for k in range(K):
        vsum = 0.0
        for p in range(P):
            D[p] = 0.5 * (s0[k, p] - s1[k, p])
            M[p] = 0.5 * (s0[k, p] + s1[k, p])
            x0 = v0[k, p] if v0[k, p] > nn else nn
            x1 = v1[k, p] if v1[k, p] > nn else nn
            var = (x0 + x1) / (4.0 * n_box)
            vsum += var
            w[p] = 1.0 / var
            A[p, 0] = M[p] * d[k, p, 0]
            A[p, 1] = M[p] * d[k, p, 1]
            A[p, 2] = d[k, p, 0]
            A[p, 3] = d[k, p, 1]
        for i in range(4):
            for j in range(4):
                acc = 0.0
                for p in range(P):
                    acc += A[p, i] * w[p] * A[p, j]
                N[i, j] = acc
            acc = 0.0
            for p in range(P):
                acc += A[p, i] * w[p] * D[p]
            b[i] = acc
        det = _inverse4(N, inv)
        full_rank[k] = det > 1e-9
        if not full_rank[k]:
            continue
        for i in range(4):
            acc = 0.0
            for j in range(4):
                acc += inv[i, j] * b[j]
            theta[k, i] = acc
        chi = 0.0
        rr = 0.0
        for p in range(P):
            r = D[p]
            for i in range(4):
                r -= A[p, i] * theta[k, i]
            chi += r * r * w[p]
            rr += r * r
        chi /= dof
        grow = chi if chi > 1.0 else 1.0
        q = 0.0
        for i in range(4):
            for j in range(4):
                cov[k, i, j] = inv[i, j] * grow
                q += theta[k, i] * N[i, j] * theta[k, j]
        seen[k] = q / grow
        Ms = np.sort(M)
        h = P // 2
        lo = 0.0
        hi = 0.0
        for p in range(h):
            lo += Ms[p]
        for p in range(h, P):
            hi += Ms[p]
        contrast = 0.5 * (hi / (P - h) - lo / h)
        fits[k] = math.sqrt(rr / dof) <= 3.0 * math.sqrt(vsum / P) + misfit_share * contrast


@njit(cache=True, nogil=True, error_model="numpy")
def _median(v: np.ndarray, work: np.ndarray) -> float:  # pragma: no cover - numba
    """NumPy's median of ``v`` (NaN where any is NaN, as NumPy's; two middle values' mean),
    sorted in ``work`` (as long as ``v``)."""
    q = v.shape[0]
    work[:] = v
    work.sort()  # NaN last
    if q == 0 or np.isnan(work[q - 1]):
        return np.nan
    if q % 2:
        return work[q // 2]
    return (work[q // 2 - 1] + work[q // 2]) / 2.0


def _make_read_cells(PARALLEL: int):
    """:func:`read_cells`'s kernel, run on the OpenMP pool where ``PARALLEL`` is 1."""

    @njit(cache=True, nogil=True, parallel=PARALLEL == 1, error_model="numpy")
    def read_cells(img: np.ndarray, a: float, b: float, Hs: np.ndarray, pts: np.ndarray, n_cells: int, m: int,
                   cell: np.ndarray, white: np.ndarray) -> None:  # pragma: no cover - numba
        """The cells of each quad's marker and the white margin round it, in one pass: point ``j``
        of ``pts`` (P, 2; the first ``n_cells * m``, each cell's ``m`` points in turn, then the
        margin's) taken through homography ``Hs[k]`` and sampled bilinearly (edges replicated)
        on ``img`` stretched by ``a * v + b``; ``cell[k, c]`` the mean of cell ``c``'s samples,
        ``white[k]`` the median of the margin's. A homography's row that is not finite samples
        at NaN's place (NaN out): the caller refuses those quads."""
        if PARALLEL:  # (the closure's int keys the cache: the twins apart)
            pass
        K = Hs.shape[0]
        P = pts.shape[0]
        for k in prange(K):
            v = np.empty(P)
            for j in range(P):
                x, y = pts[j, 0], pts[j, 1]
                X = Hs[k, 0, 0] * x + Hs[k, 0, 1] * y + Hs[k, 0, 2]
                Y = Hs[k, 1, 0] * x + Hs[k, 1, 1] * y + Hs[k, 1, 2]
                Z = Hs[k, 2, 0] * x + Hs[k, 2, 1] * y + Hs[k, 2, 2]
                px, py = X / Z, Y / Z
                if np.isfinite(px) and np.isfinite(py):
                    v[j] = bilinear(img, px, py) * a + b
                else:
                    v[j] = np.nan
            for c in range(n_cells):
                cell[k, c] = _pairwise_sum(v, c * m, m) / m
            white[k] = _median(v[n_cells * m:], np.empty(P - n_cells * m))

    return read_cells


_read_cells_serial, _read_cells_parallel = _make_read_cells(0), _make_read_cells(1)


def read_cells(img: np.ndarray, a: float, b: float, Hs: np.ndarray, pts: np.ndarray, n_cells: int, m: int,
               cell: np.ndarray, white: np.ndarray) -> None:
    """Each quad's cells and margin (kernel ``_make_read_cells``), serial where small
    (:data:`~camkit._kernels.detect.PARALLEL_MIN_NS`; the work counted in samples)."""
    work = 9.0 * Hs.shape[0] * pts.shape[0]
    (_read_cells_parallel if work >= PARALLEL_MIN_NS else _read_cells_serial)(img, a, b, Hs, pts, n_cells, m, cell,
                                                                             white)


@njit(cache=True, nogil=True, error_model="numpy")
def cell_verdicts(cell: np.ndarray, white: np.ndarray, ok: np.ndarray, n: int, border: int, rim_contrast: float,
                  rim_to_refine: float, good: np.ndarray, rimmed: np.ndarray,
                  bits: np.ndarray) -> None:  # pragma: no cover - numba
    """What each quad's cells say (see :func:`camkit.target._markers.read_markers_rims`):
    ``cell`` (K, n * n) the marker's cells row by row (a black border ``border`` cells wide
    round the code), ``white`` (K,) its margin, ``ok`` (K,) whether it was read at all. The
    border's median is black, the threshold halfway to the margin; ``good``: the margin 0.15
    lighter than black at least and 0.85 of the border's cells below the threshold, ``bits``
    (K, (n - 2 border)^2) then the code's cells above it (row by row); ``rimmed``: the margin
    ``rim_contrast`` lighter, ``rim_to_refine`` of the border below and a code's cell above
    (a black square's cells are all dark)."""
    K = cell.shape[0]
    nb = n - 2 * border
    n_rim = n * n - nb * nb
    rim = np.empty(n_rim)
    work = np.empty(n_rim)
    for k in range(K):
        j = 0
        for y in range(n):
            for x in range(n):
                if y < border or y >= n - border or x < border or x >= n - border:
                    rim[j] = cell[k, y * n + x]
                    j += 1
        black = _median(rim, work)
        t = 0.5 * (white[k] + black)
        dark = 0
        for j in range(n_rim):
            dark += rim[j] < t
        frac = dark / n_rim
        lift = white[k] - black
        contrast = ok[k] and np.isfinite(white[k]) and lift > 0.15
        lit = False
        i = 0
        for y in range(border, n - border):
            for x in range(border, n - border):
                b = cell[k, y * n + x] > t
                bits[k, i] = b
                lit |= b
                i += 1
        good[k] = contrast and frac >= 0.85
        rimmed[k] = contrast and lift > rim_contrast and frac >= rim_to_refine and lit


@njit(cache=True, nogil=True, error_model="numpy")
def rim_verdicts(vals: np.ndarray, white: np.ndarray, ok: np.ndarray, contrast: float, dark_share: float,
                 out: np.ndarray) -> None:  # pragma: no cover - numba
    """Whether each quad's border reads as a marker's (see :func:`camkit.target._markers._rims`):
    ``vals`` (K, R) one sample a border cell, ``white`` (K,) the margin's; the border's median
    ``contrast`` darker than the margin at least, and ``dark_share`` of its samples below the
    threshold halfway between."""
    K, R = vals.shape
    work = np.empty(R)
    for k in range(K):
        black = _median(vals[k], work)
        t = 0.5 * (white[k] + black)
        dark = 0
        for j in range(R):
            dark += vals[k, j] < t
        out[k] = ok[k] and white[k] - black > contrast and dark / R >= dark_share


@njit(cache=True, nogil=True, error_model="numpy")
def _popcount(v: np.uint64) -> int:  # pragma: no cover - numba
    """The set bits of ``v`` (the SWAR count: pairs, nibbles, then bytes summed by a multiply)."""
    v = v - ((v >> np.uint64(1)) & np.uint64(0x5555555555555555))
    v = (v & np.uint64(0x3333333333333333)) + ((v >> np.uint64(2)) & np.uint64(0x3333333333333333))
    v = (v + (v >> np.uint64(4))) & np.uint64(0x0F0F0F0F0F0F0F0F)
    return int((v * np.uint64(0x0101010101010101)) >> np.uint64(56))


@njit(cache=True, nogil=True, error_model="numpy")
def nearest_codes(bits: np.ndarray, turned: np.ndarray, ids: np.ndarray, turns: np.ndarray,
                  errors: np.ndarray) -> None:  # pragma: no cover - numba
    """For each observed code ``bits[k]`` (n*n uint8, row by row, at most 64), the code nearest
    in Hamming distance among ``turned`` (4, N: each code turned ``t`` quarter turns by
    ``np.rot90``, bit ``i`` its ``i``-th cell): ``ids``, ``turns``, ``errors``, the first in
    (turn, code) order where several are as near."""
    K, nn = bits.shape
    N = turned.shape[1]
    for k in range(K):
        obs = np.uint64(0)
        for i in range(nn):
            if bits[k, i]:
                obs |= np.uint64(1) << np.uint64(i)
        best, bt, bi = nn + 1, 0, 0
        for t in range(4):
            for c in range(N):
                d = _popcount(obs ^ turned[t, c])
                if d < best:
                    best, bt, bi = d, t, c
        ids[k], turns[k], errors[k] = bi, bt, best


@njit(cache=True, nogil=True, error_model="numpy")
def marker_clearance(sign: np.ndarray, lo: float, hi: float, u: np.ndarray, v: np.ndarray,
                     out: np.ndarray) -> None:  # pragma: no cover - numba
    """``out[k]``: how far (px) a ChArUco corner lies from the two markers beside it, the
    nearest point of either marker's four sides, through its steps ``u[k]``, ``v[k]`` (a
    square's along the board's x and y, px) with the corner at 0; inf where that is NaN (a
    step unknown). The markers span ``lo`` to ``hi`` of their squares; one lies on the
    corner's (+x, -y ``sign[k]``) side, the other on its (-x, +y ``sign[k]``) side. (The
    arithmetic of ``camkit.target.charuco._clearance``'s arrays, point by point.)"""
    cx = np.empty(4)
    cy = np.empty(4)
    for k in range(sign.shape[0]):
        best = np.inf
        nan = False
        for m in range(2):
            sa = 1.0 if m == 0 else -1.0
            sb = (-1.0 if m == 0 else 1.0) * sign[k]
            for j in range(4):
                mx = hi if j == 1 or j == 2 else lo
                my = hi if j >= 2 else lo
                a = sa * mx
                b = sb * my
                cx[j] = a * u[k, 0] + b * v[k, 0]
                cy[j] = a * u[k, 1] + b * v[k, 1]
            for j in range(4):
                dx = cx[(j + 1) % 4] - cx[j]
                dy = cy[(j + 1) % 4] - cy[j]
                t = -(cx[j] * dx + cy[j] * dy) / max(dx * dx + dy * dy, 1e-12)
                t = min(max(t, 0.0), 1.0)
                h = math.hypot(cx[j] + t * dx, cy[j] + t * dy)
                if h != h:
                    nan = True
                elif h < best:
                    best = h
        out[k] = np.inf if nan else best


@njit(cache=True, nogil=True, error_model="numpy")
def light_reading(img: np.ndarray, a: float, b: float, c: np.ndarray, e1: np.ndarray, e2: np.ndarray,
                  reach: np.ndarray, margin: float, min_clear: float, box: float, gx: np.ndarray, gy: np.ndarray,
                  noise: float, misfit_share: float, min_chi2: float, d: np.ndarray, theta: np.ndarray,
                  cov: np.ndarray, fits: np.ndarray, read: np.ndarray) -> None:  # pragma: no cover - numba
    """The light across each ChArUco corner ``c[k]`` (K, 2), read from its mirrored boxes (the
    front of :func:`camkit.target.charuco._light`, in its arithmetic): its steps ``e1[k]``,
    ``e2[k]`` (px along the board's x and y), its fit's ``reach[k]`` (px) and the white
    margin's share of a square ``margin`` place ten boxes (half-size ``box`` of the places'
    clearance; samples ``gx``, ``gy``) at ``+d[k]`` and ``-d[k]`` (K, 10, 2, written) where
    that clearance is ``min_clear`` px at least; their shades and spreads
    (:func:`box_shades`, image ``img`` stretched by ``a * v + b``) give ``theta[k]``,
    ``cov[k]`` and ``fits[k]`` (:func:`light_fit`, the image's ``noise``, ``misfit_share``).
    ``read[k]``: the corner's boxes are clear, inside the image, in two directions and two
    shades, and the light read has a chi-square over ``min_chi2``; the rest of its outputs
    are undefined where not."""
    K = c.shape[0]
    G = gx.shape[0]
    along = (0.0, 0.0, 0.5, 0.0, 1.0)
    across = (0.0, 0.5, 0.0, 1.0, 0.0)
    px = np.empty((1, 10, 2))
    s0 = np.empty((1, 10))
    s1 = np.empty((1, 10))
    v0 = np.empty((1, 10))
    v1 = np.empty((1, 10))
    hb = np.empty(1)
    inside = np.empty(1, dtype=np.bool_)
    seen = np.empty(1)
    fit1 = np.empty(1, dtype=np.bool_)
    rank = np.empty(1, dtype=np.bool_)
    th = np.empty((1, 4))
    cv = np.empty((1, 4, 4))
    for k in range(K):
        read[k] = False
        l1 = math.hypot(e1[k, 0], e1[k, 1])
        l2 = math.hypot(e2[k, 0], e2[k, 1])
        sine = abs(e1[k, 0] * e2[k, 1] - e1[k, 1] * e2[k, 0]) / max(l1 * l2, 1e-12)
        r = reach[k]
        clear = min(0.5 * r, 0.5 * margin * min(l1, l2) * sine)
        if not clear >= min_clear:
            continue
        a1 = clear / (l1 * sine)
        a2 = clear / (l2 * sine)
        for p in range(5):
            bx = min(a1 + along[p] * (r / l1), 0.5)
            by = min(a2 + across[p] * (r / l2), 0.5)
            for q in range(2):
                oy = by if q == 0 else -by
                i = p + 5 * q
                d[k, i, 0] = bx * e1[k, 0] + oy * e2[k, 0]
                d[k, i, 1] = bx * e1[k, 1] + oy * e2[k, 1]
        hb[0] = box * clear
        inside[0] = True
        for i in range(10):
            px[0, i, 0] = c[k, 0] + d[k, i, 0]
            px[0, i, 1] = c[k, 1] + d[k, i, 1]
        box_shades(img, a, b, px, hb, gx, gy, s0, v0, inside)
        for i in range(10):
            px[0, i, 0] = c[k, 0] + -d[k, i, 0]
            px[0, i, 1] = c[k, 1] + -d[k, i, 1]
        box_shades(img, a, b, px, hb, gx, gy, s1, v1, inside)
        light_fit(s0, s1, v0, v1, d[k:k + 1], noise, G, misfit_share, th, cv, seen, fit1, rank)
        if not (inside[0] and rank[0] and seen[0] > min_chi2):
            continue
        read[k] = True
        fits[k] = fit1[0]
        for i in range(4):
            theta[k, i] = th[0, i]
            for j in range(4):
                cov[k, i, j] = cv[0, i, j]


@njit(cache=True, nogil=True, error_model="numpy")
def light_verdicts(idx: np.ndarray, c: np.ndarray, shift: np.ndarray, scov: np.ndarray, fits: np.ndarray,
                   win: np.ndarray, max_shift: float, min_chi2: float, max_sigma: float, out: np.ndarray,
                   sig: np.ndarray) -> None:  # pragma: no cover - numba
    """The end of :func:`camkit.target.charuco._light`, in its arithmetic: each corner
    ``idx[k]`` placed at ``c[k]`` and moved ``shift[k]`` by its refit under the light read
    (NaN where the refit found no saddle), the move's covariance ``scov[k]`` (2, 2). A move
    counts where its chi-square is over ``min_chi2`` (or unknown); it is taken where the
    light's pairs fit it (``fits[k]``) and it is at most ``max_shift`` of the fit's window
    ``win[k]``: ``out[idx[k]]`` moved, ``sig[idx[k]]`` grown by the move's variance. Any
    other move that counts is added to the corner's sigma, and the corner dropped (NaN)
    where that passes ``max_sigma``."""
    for k in range(idx.shape[0]):
        i = idx[k]
        s00, s01, s11 = scov[k, 0, 0], scov[k, 0, 1], scov[k, 1, 1]
        svar = 0.5 * (s00 + s11)
        sx, sy = shift[k, 0], shift[k, 1]
        size = math.hypot(sx, sy)
        small = math.isfinite(size) and size <= max_shift * win[k] and math.isfinite(svar)
        sdet = s00 * s11 - s01 * s01
        chi2 = (s11 * (sx * sx) - 2.0 * s01 * sx * sy + s00 * (sy * sy)) / sdet
        if chi2 <= min_chi2:  # (NaN: the move unknown, it counts)
            continue
        if fits[k] and small:
            out[i, 0] = c[k, 0] + sx
            out[i, 1] = c[k, 1] + sy
            sig[i] = math.sqrt(sig[i] * sig[i] + svar)
            continue
        grown = math.sqrt(sig[i] * sig[i] + size * size)
        if grown <= max_sigma:
            sig[i] = grown
        else:
            out[i, 0] = np.nan
            out[i, 1] = np.nan
            sig[i] = np.nan


@njit(cache=True, nogil=True, error_model="numpy")
def light_jacobian(quad: np.ndarray, lin: np.ndarray, theta: np.ndarray, q: np.ndarray, pts: np.ndarray,
                   J: np.ndarray) -> None:  # pragma: no cover - numba
    """How far each of the light's four numbers moves each saddle (``J`` (K, 2, 4), px per
    unit; the end of :func:`camkit.target.charuco._light_refit`, in its arithmetic): the
    inverse Hessian of the fit's quadratic terms ``quad[k]`` (a, b, c of a x^2 + b x y + c y^2)
    times each number's change of its linear terms ``lin[k]`` (4, 2), scaled by how much
    further the refit moved (``pts[k]`` to ``q[k]``) than the light ``theta[k]`` predicts to
    first order: 1 to 2 times (1 where either is unknown)."""
    for k in range(quad.shape[0]):
        a2, b2, c2 = quad[k, 0], quad[k, 1], quad[k, 2]
        det = 4.0 * a2 * c2 - b2 * b2
        h00 = 2.0 * c2 / det
        h01 = -b2 / det
        h11 = 2.0 * a2 / det
        for t in range(4):
            J[k, 0, t] = h00 * lin[k, t, 0] + h01 * lin[k, t, 1]
            J[k, 1, t] = h01 * lin[k, t, 0] + h11 * lin[k, t, 1]
        # (The first-order move summed as NumPy's einsum sums four terms: pairs 0, 2 and 1, 3.)
        fx = (J[k, 0, 0] * theta[k, 0] + J[k, 0, 2] * theta[k, 2]) + (J[k, 0, 1] * theta[k, 1]
                                                                      + J[k, 0, 3] * theta[k, 3])
        fy = (J[k, 1, 0] * theta[k, 0] + J[k, 1, 2] * theta[k, 2]) + (J[k, 1, 1] * theta[k, 1]
                                                                      + J[k, 1, 3] * theta[k, 3])
        ratio = math.hypot(q[k, 0] - pts[k, 0], q[k, 1] - pts[k, 1]) / math.hypot(fx, fy)
        gain = 1.0 if ratio != ratio else min(max(ratio, 1.0), 2.0)
        for i in range(2):
            for t in range(4):
                J[k, i, t] *= gain


@njit(cache=True, nogil=True, error_model="numpy")
def _x_verdict(v: np.ndarray, work: np.ndarray) -> tuple[bool, float]:  # pragma: no cover - numba
    """Whether the shades ``v`` (32, round a closed curve about a corner) are an X-junction's
    (:func:`x_junctions`), and the middle of the darkest and brightest; the sums as NumPy's
    ``mean`` makes them (:func:`_pairwise_sum`; ``work``: 32 scratch values)."""
    n = v.shape[0]
    m = _pairwise_sum(v, 0, n) / n
    lo = v[0]
    hi = v[0]
    nan = False
    changes = 0
    prev = v[n - 1] > m
    for j in range(n):
        x = v[j]
        if x != x:
            nan = True
        lo = min(lo, x)
        hi = max(hi, x)
        s = x > m
        changes += s != prev
        prev = s
        work[j] = abs(x - v[(j + n // 2) % n])
    if nan:
        return False, np.nan
    contrast = hi - lo
    sym = _pairwise_sum(work, 0, n) / n / max(contrast, 1e-12)
    return changes == 4 and contrast > 0.15 and sym < 0.25, 0.5 * (lo + hi)


@njit(cache=True, nogil=True, error_model="numpy")
def x_verdicts(v: np.ndarray, is_x: np.ndarray, mid: np.ndarray) -> None:  # pragma: no cover - numba
    """:func:`_x_verdict` of each row of shades ``v`` (K, 32)."""
    work = np.empty(v.shape[1])
    for k in range(v.shape[0]):
        is_x[k], mid[k] = _x_verdict(v[k], work)


@njit(cache=True, nogil=True, error_model="numpy")
def x_junctions(img: np.ndarray, a: float, b: float, pts: np.ndarray, rho: np.ndarray, cos: np.ndarray,
                sin: np.ndarray, is_x: np.ndarray, mid: np.ndarray) -> None:  # pragma: no cover - numba
    """Whether each point ``pts[k]`` is an X-junction, on the circle of radius ``rho[k]`` about
    it (32 places at angles of cosines ``cos``, sines ``sin``; the image ``img`` stretched by
    ``a * v + b``, bilinear, edges replicated): the shade crosses its mean four times, its
    darkest and brightest differ by 0.15 at least, and it is point-symmetric (the mean
    difference of opposite shades under a quarter of that contrast); ``mid[k]`` the middle of
    the darkest and brightest shades (NaN where a shade is)."""
    n = cos.shape[0]
    v = np.empty(n)
    work = np.empty(n)
    for k in range(pts.shape[0]):
        for j in range(n):
            v[j] = bilinear(img, pts[k, 0] + rho[k] * cos[j], pts[k, 1] + rho[k] * sin[j]) * a + b
        is_x[k], mid[k] = _x_verdict(v, work)


@njit(cache=True, nogil=True, error_model="numpy")
def _mapped(H: np.ndarray, x: float, y: float) -> tuple[float, float]:  # pragma: no cover - numba
    """(x, y) through the homography ``H`` (3, 3), each row's sum as NumPy's einsum makes it
    (``h0 x + h2``, then ``+ h1 y``: :func:`camkit.target._homography.apply_homographies`)."""
    u = (H[0, 0] * x + H[0, 2] * 1.0) + H[0, 1] * y
    v = (H[1, 0] * x + H[1, 2] * 1.0) + H[1, 1] * y
    w = (H[2, 0] * x + H[2, 2] * 1.0) + H[2, 1] * y
    return u / w, v / w


@njit(cache=True, nogil=True, error_model="numpy")
def pair_votes(obj: np.ndarray, img: np.ndarray, grid: np.ndarray, pitch: np.ndarray, floor: float,
               agree: np.ndarray, disagree: np.ndarray) -> None:  # pragma: no cover - numba
    """For each of n markers (``obj`` (n, 4, 2): its corners on the board; ``img`` (n, 4, 2): in
    the image; ``grid`` (n, 2): its place in the layout; ``pitch`` (n,): its layout's pitch in
    pixels), how many of the pairs within two places of it fit one homography and how many do
    not (``camkit.target._markers._pair_votes``): the homography of both markers' eight corners
    (:func:`_fit_homography`) misses none by ``floor`` px or 0.15 of the smaller pitch (the
    worst miss the largest distance, a homography that sends a point to infinity or none at
    all missing by inf; the points mapped by :func:`_mapped`)."""
    n = obj.shape[0]
    src = np.empty((8, 2))
    dst = np.empty((8, 2))
    H = np.empty((3, 3))
    for i in range(n):
        agree[i] = 0
        disagree[i] = 0
    for a in range(n):
        for j in range(a + 1, n):
            if max(abs(grid[a, 0] - grid[j, 0]), abs(grid[a, 1] - grid[j, 1])) > 2:
                continue
            for c in range(4):
                for e in range(2):
                    src[c, e] = obj[a, c, e]
                    src[4 + c, e] = obj[j, c, e]
                    dst[c, e] = img[a, c, e]
                    dst[4 + c, e] = img[j, c, e]
            _fit_homography(src, dst, H)
            worst = 0.0
            for p in range(8):
                px, py = _mapped(H, src[p, 0], src[p, 1])
                miss = math.hypot(px - dst[p, 0], py - dst[p, 1])
                if not math.isfinite(miss):  # (NaN: no homography, or a point sent to infinity)
                    worst = np.inf
                    break
                worst = max(worst, miss)
            if worst < max(floor, 0.15 * min(pitch[a], pitch[j])):
                agree[a] += 1
                agree[j] += 1
            else:
                disagree[a] += 1
                disagree[j] += 1


@njit(cache=True, nogil=True, error_model="numpy")
def charuco_predictions(sq: np.ndarray, homs: np.ndarray, side: np.ndarray, obj: np.ndarray, img: np.ndarray,
                        sx: int, sy: int, s: float, offsets: np.ndarray, five: np.ndarray, size: np.ndarray,
                        count: np.ndarray) -> None:  # pragma: no cover - numba
    """Step 4's predictions of a ChArUco board's corners (``camkit.target.charuco._detect``, in
    its arithmetic) from its C confirmed markers: their squares ``sq`` (C, 2), homographies
    ``homs`` (C, 3, 3) board to image, pitches ``side`` (C,) px, corners ``obj`` (C, 4, 2) on
    the board and ``img`` (C, 4, 2) in the image; the board ``sx`` x ``sy`` squares of side
    ``s``. Each inner corner touched by a marker's square: its place and the places half a
    square either way along x and y (``offsets`` (5, 2)), ``five`` (N, 5, 2), through each
    touching marker's homography, averaged (summed in the markers' order); where two or more
    confirmed markers touch it, through the homography of all their corners, and where two,
    its place the midpoint of their corners nearest it (the steps moved with it); ``size``
    (N,): the largest touching pitch, 0 where none touches; ``count`` (N,): how many markers
    touch it (``five`` NaN where none)."""
    C = sq.shape[0]
    nx = sx - 1
    N = five.shape[0]
    count[:] = 0.0
    five[:, :, :] = 0.0
    size[:] = 0.0
    for c in range(C):
        for t in range(4):  # the square's corners (0, 0), (1, 0), (0, 1), (1, 1)
            X = sq[c, 0] + (t & 1)
            Y = sq[c, 1] + (t >> 1)
            if X < 1 or Y < 1 or X > sx - 1 or Y > sy - 1:
                continue
            cid = (Y - 1) * nx + (X - 1)
            for o in range(5):
                px, py = _mapped(homs[c], X * s + offsets[o, 0], Y * s + offsets[o, 1])
                five[cid, o, 0] += px
                five[cid, o, 1] += py
            count[cid] += 1.0
            size[cid] = max(size[cid], side[c])
    src = np.empty((4 * C, 2))
    dst = np.empty((4 * C, 2))
    H = np.empty((3, 3))
    q = np.empty((5, 2))
    touch = np.empty(C, dtype=np.int64)
    for cid in range(N):
        if count[cid] == 0.0:
            five[cid, :, :] = np.nan
            continue
        for o in range(5):
            five[cid, o, 0] /= count[cid]
            five[cid, o, 1] /= count[cid]
        cx = cid % nx + 1
        cy = cid // nx + 1
        k = 0
        for c in range(C):
            if cx - 1 <= sq[c, 0] <= cx and cy - 1 <= sq[c, 1] <= cy:
                touch[k] = c
                k += 1
        if k < 2:
            continue
        for i in range(k):
            for j in range(4):
                src[4 * i + j, 0] = obj[touch[i], j, 0]
                src[4 * i + j, 1] = obj[touch[i], j, 1]
                dst[4 * i + j, 0] = img[touch[i], j, 0]
                dst[4 * i + j, 1] = img[touch[i], j, 1]
        _fit_homography(src[:4 * k], dst[:4 * k], H)
        good = True
        for o in range(5):
            q[o, 0], q[o, 1] = _mapped(H, cx * s + offsets[o, 0], cy * s + offsets[o, 1])
            good = good and math.isfinite(q[o, 0]) and math.isfinite(q[o, 1])
        if not good:
            continue
        five[cid, :, :] = q
        if k != 2:
            continue
        # The two markers' corners nearest the chessboard corner: their midpoint.
        mx = 0.0
        my = 0.0
        for i in range(2):
            best = 0
            bd = np.inf
            for j in range(4):
                d = math.hypot(obj[touch[i], j, 0] - cx * s, obj[touch[i], j, 1] - cy * s)
                if d < bd:
                    bd = d
                    best = j
            mx += img[touch[i], best, 0]
            my += img[touch[i], best, 1]
        mx /= 2
        my /= 2
        if math.isfinite(mx) and math.isfinite(my):
            dx = mx - five[cid, 0, 0]
            dy = my - five[cid, 0, 1]
            for o in range(5):
                five[cid, o, 0] += dx
                five[cid, o, 1] += dy


@njit(cache=True, nogil=True, error_model="numpy")
def circle_colours(img: np.ndarray, a: float, b: float, q: np.ndarray, u: np.ndarray, v: np.ndarray,
                   sign: np.ndarray, mid: np.ndarray, rho: np.ndarray, on_board: np.ndarray,
                   out: np.ndarray) -> None:  # pragma: no cover - numba
    """``camkit.target.charuco._colours_on_circle``, in its arithmetic: whether each corner
    ``q[k]`` is darker than ``mid[k]`` along the bisectors of its black squares' sectors
    (``u + sign v`` and its opposite) and lighter along its white squares' (``u - sign v``, its
    opposite), at ``rho[k]`` px from it (the unit steps' sums scaled to that length; on the
    board where ``on_board[k]``: the steps' sums times ``rho[k] / sqrt 2``, ``rho`` in
    squares); the image ``img`` stretched by ``a * v + b``, bilinear."""
    dx = np.empty(4)
    dy = np.empty(4)
    for k in range(q.shape[0]):
        s = sign[k]
        if on_board[k]:
            px, py = u[k, 0] + s * v[k, 0], u[k, 1] + s * v[k, 1]
            mx, my = u[k, 0] - s * v[k, 0], u[k, 1] - s * v[k, 1]
            f = rho[k] / math.sqrt(2.0)
            dx[0], dy[0] = px * f, py * f
            dx[1], dy[1] = -px * f, -py * f
            dx[2], dy[2] = mx * f, my * f
            dx[3], dy[3] = -mx * f, -my * f
        else:
            lu = max(math.hypot(u[k, 0], u[k, 1]), 1e-12)
            lv = max(math.hypot(v[k, 0], v[k, 1]), 1e-12)
            ux, uy = u[k, 0] / lu, u[k, 1] / lu
            vx, vy = v[k, 0] / lv, v[k, 1] / lv
            px, py = ux + s * vx, uy + s * vy
            mx, my = ux - s * vx, uy - s * vy
            dx[0], dy[0] = px, py
            dx[1], dy[1] = -px, -py
            dx[2], dy[2] = mx, my
            dx[3], dy[3] = -mx, -my
            for i in range(4):
                f = rho[k] / max(math.hypot(dx[i], dy[i]), 1e-12)
                dx[i] *= f
                dy[i] *= f
        ok = True
        for i in range(4):
            val = bilinear(img, q[k, 0] + dx[i], q[k, 1] + dy[i]) * a + b
            ok = ok and (val < mid[k] if i < 2 else val > mid[k])
        out[k] = ok
