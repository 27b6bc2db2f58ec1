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


def _make_fit_homographies(PARALLEL: int):
    """:func:`fit_homographies`'s kernel, run on the OpenMP pool where ``PARALLEL`` is 1."""

    @njit(cache=True, nogil=True, parallel=PARALLEL == 1, error_model="numpy")
    def fit_homographies(src: np.ndarray, dst: np.ndarray, out: np.ndarray) -> None:  # pragma: no cover - numba
        """``out[k]`` (3, 3): the homography taking ``src[k]`` (P, 2) to ``dst[k]`` (P, 2), P >= 4,
        by the normalised DLT (Hartley and Zisserman, alg. 4.2; the normal matrix from
        :func:`camkit._kernels.calib.dlt_normal`) in its inhomogeneous form: h33 = 1 in the
        normalised frames (the source centroid is their origin and maps to a finite point), the
        other eight from the 8 x 8 normal equations by Gaussian elimination with partial
        pivoting; NaN where the points coincide or the system is singular (collinear points)."""
        if PARALLEL:  # (the closure's int keys the cache: the twins apart)
            pass
        K, P = src.shape[0], src.shape[1]
        for k in prange(K):
            M, Ts, Td, ok = dlt_normal(src[k], dst[k])
            if not ok:
                out[k, :, :] = np.nan
                continue
            for c in range(8):  # elimination with partial pivoting on [M[:8, :8] | -M[:8, 8]]
                piv = c
                for r in range(c + 1, 8):
                    if abs(M[r, c]) > abs(M[piv, c]):
                        piv = r
                if not abs(M[piv, c]) > 1e-10 * P:
                    ok = False
                    break
                if piv != c:
                    for j in range(9):
                        M[c, j], M[piv, j] = M[piv, j], M[c, j]
                for r in range(c + 1, 8):
                    f = M[r, c] / M[c, c]
                    if f != 0.0:
                        for j in range(c, 9):
                            M[r, j] -= f * M[c, j]
            if not ok:
                out[k, :, :] = np.nan
                continue
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
                out[k, 0, c] = Hn[0, c] / t + dx * Hn[2, c]
                out[k, 1, c] = Hn[1, c] / t + dy * Hn[2, c]
                out[k, 2, c] = Hn[2, c]

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
