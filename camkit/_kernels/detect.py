"""Kernels for checkerboard corner detection: Gaussian blur, saddle response, local maxima."""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from camkit._kernels.remap import keys4

#: The parallel kernels below that a detection hands a few points, patches or quads at a time
#: run serially where their work (serial, estimated from their sizes) is under this many ns:
#: a parallel loop wakes the OpenMP pool's workers, which sleep between loops
#: (``OMP_WAIT_POLICY=PASSIVE``, camkit/__init__.py), and a wake-up costs more than the work of
#: most such calls. The wake-up's cost and the per-unit costs in the estimates were measured
#: on the 2-core machine (benchmarks/notes.md, forty-sixth session).
PARALLEL_MIN_NS = 200_000


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
def gaussian_blur(img: np.ndarray, sigma: float, out: np.ndarray, x0: int = 0,
                  y0: int = 0) -> None:  # pragma: no cover - numba
    """Separable Gaussian (radius 3 sigma, edges replicated), rows then columns, band by band
    of rows (each band's row pass, with its margins, stays in cache for its column pass).
    Each pass adds tap after tap along whole rows (the inner loop runs along x, contiguous,
    so it is vectorised), each pixel's sum in tap order, as a pixel-by-pixel loop adds it.
    ``out`` may be a box of the result only: the box of its shape whose top-left pixel is
    (``x0``, ``y0``) of ``img`` (the same values as there in the whole image's result)."""
    H, W = img.shape
    h, w = out.shape
    k = gaussian_taps(sigma)
    R = k.shape[0] // 2
    nb = (h + _BAND - 1) // _BAND
    for b in prange(nb):
        ya = b * _BAND
        yb = min(ya + _BAND, h)
        lo = max(y0 + ya - R, 0)
        hi = min(y0 + yb + R, H)
        tmp = np.empty((hi - lo, w))
        row = np.empty(w + 2 * R)
        for y in range(lo, hi):
            for x in range(w + 2 * R):
                row[x] = img[y, min(max(x0 + x - R, 0), W - 1)]
            acc = tmp[y - lo]
            for x in range(w):
                acc[x] = 0.0
            for i in range(2 * R + 1):
                ki = k[i]
                for x in range(w):
                    acc[x] += ki * row[x + i]
        for y in range(ya, yb):
            acc = out[y]
            for x in range(w):
                acc[x] = 0.0
            for i in range(2 * R + 1):
                ki = k[i]
                src = tmp[min(max(y0 + y + i - R, 0), H - 1) - lo]
                for x in range(w):
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


def _make_blur_patches(PARALLEL: int):
    """:func:`blur_patches`'s kernel, run on the OpenMP pool where ``PARALLEL`` is 1."""

    @njit(cache=True, nogil=True, parallel=PARALLEL == 1, error_model="numpy")
    def blur_patches(img: np.ndarray, origin: np.ndarray, tile: np.ndarray, side: int, sigma: float,
                     out: np.ndarray) -> None:  # pragma: no cover - numba
        """The Gaussian blur of :func:`gaussian_blur` (edges replicated), computed only on square
        patches: patch i covers image pixels ``origin[i] + (0..side-1)`` (x, y) and is written to
        ``out`` at ``tile[i] + (0..side-1)``. Each patch reads its own margin of 3 sigma, so the
        values are those of the whole image blurred."""
        if PARALLEL:  # (the closure's int keys the cache: the twins apart)
            pass
        H, W = img.shape
        k = gaussian_taps(sigma)
        R = k.shape[0] // 2
        for p in prange(origin.shape[0]):
            x0, y0 = origin[p, 0], origin[p, 1]
            tx, ty = tile[p, 0], tile[p, 1]
            # Tap after tap along whole rows (each sum in the taps' order, as gaussian_blur's).
            row = np.empty(side + 2 * R)
            tmp = np.zeros((side + 2 * R, side))
            for j in range(side + 2 * R):
                yy = min(max(y0 + j - R, 0), H - 1)
                for x in range(side + 2 * R):
                    row[x] = img[yy, min(max(x0 + x - R, 0), W - 1)]
                for i in range(2 * R + 1):
                    for x in range(side):
                        tmp[j, x] += k[i] * row[x + i]
            acc = np.empty(side)
            for y in range(side):
                acc[:] = 0.0
                for i in range(2 * R + 1):
                    for x in range(side):
                        acc[x] += k[i] * tmp[y + i, x]
                for x in range(side):
                    out[ty + y, tx + x] = acc[x]

    return blur_patches


_blur_patches_serial, _blur_patches_parallel = _make_blur_patches(0), _make_blur_patches(1)


def blur_patches(img: np.ndarray, origin: np.ndarray, tile: np.ndarray, side: int, sigma: float,
                 out: np.ndarray) -> None:
    """The blur of each patch (kernel ``_make_blur_patches``), serial where small
    (:data:`PARALLEL_MIN_NS`; the work counted in taps times pixels of both passes)."""
    R = gaussian_taps(sigma).shape[0] // 2
    work = 0.3 * origin.shape[0] * (2 * R + 1) * ((side + 2 * R) * side + side * side)
    (_blur_patches_parallel if work >= PARALLEL_MIN_NS else _blur_patches_serial)(img, origin, tile, side, sigma, out)
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


@njit(cache=True, nogil=True, parallel=True, error_model="numpy")
def quarter_mean(img: np.ndarray, a: float, b: float, out: np.ndarray) -> None:  # pragma: no cover - numba
    """``out``: :func:`half_mean` twice, the first level stretched by ``a * v + b`` (as
    ``_half`` of a ``RawGrey``), without the half level: the same sums in the same order, so
    the same values bit for bit (a 12 MP image's half level is 24 MB of float64 written and
    read again)."""
    h, w = out.shape
    for y in prange(h):
        for x in range(w):
            y0, x0 = 4 * y, 4 * x
            v00 = 0.25 * (((img[y0, x0] + img[y0 + 1, x0]) + img[y0, x0 + 1]) + img[y0 + 1, x0 + 1]) * a + b
            v10 = 0.25 * (((img[y0 + 2, x0] + img[y0 + 3, x0]) + img[y0 + 2, x0 + 1]) + img[y0 + 3, x0 + 1]) * a + b
            v01 = 0.25 * (((img[y0, x0 + 2] + img[y0 + 1, x0 + 2]) + img[y0, x0 + 3]) + img[y0 + 1, x0 + 3]) * a + b
            v11 = (0.25 * (((img[y0 + 2, x0 + 2] + img[y0 + 3, x0 + 2]) + img[y0 + 2, x0 + 3]) + img[y0 + 3, x0 + 3])
                   * a + b)
            out[y, x] = 0.25 * (((v00 + v10) + v01) + v11)


@njit(cache=True, nogil=True, error_model="numpy")
def channel_sum_histogram(img: np.ndarray, step: int, hist: np.ndarray) -> None:  # pragma: no cover - numba
    """``hist[v]`` += the number of pixels of ``img`` (H, W, C) uint8, every ``step``-th row
    and column, whose first three channels (the one channel where C < 3) sum to ``v``."""
    H, C = img.shape[0], img.shape[2]
    n = 3 if C >= 3 else 1
    # Four histograms, pixels taken in turn: a run of equal values (a flat area) then adds to
    # four counters, not one count that waits on its own last store.
    nb = hist.shape[0]
    h0, h1, h2, h3 = np.zeros(nb, np.int64), np.zeros(nb, np.int64), np.zeros(nb, np.int64), np.zeros(nb, np.int64)
    for y in range(0, H, step):
        row = img[y, ::step]
        m = row.shape[0]
        x = 0
        if n == 1:
            while x + 4 <= m:
                h0[row[x, 0]] += 1
                h1[row[x + 1, 0]] += 1
                h2[row[x + 2, 0]] += 1
                h3[row[x + 3, 0]] += 1
                x += 4
        while x < m:
            acc = 0
            for c in range(n):
                acc += np.int64(row[x, c])
            h0[acc] += 1
            x += 1
    for v in range(nb):
        hist[v] += h0[v] + h1[v] + h2[v] + h3[v]


@njit(cache=True, nogil=True, error_model="numpy")
def difference_histogram(img: np.ndarray, step: int, hist: np.ndarray) -> None:  # pragma: no cover - numba
    """``hist[d]`` += the number of horizontal neighbours of ``img`` (H, W) uint8, every
    ``step``-th row from the first, that differ by ``d`` either way. Four histograms, pairs
    taken in turn (as :func:`channel_sum_histogram`)."""
    H, W = img.shape
    nb = hist.shape[0]
    h0, h1, h2, h3 = np.zeros(nb, np.int64), np.zeros(nb, np.int64), np.zeros(nb, np.int64), np.zeros(nb, np.int64)
    for y in range(0, H, step):
        row = img[y]
        x = 0
        while x + 5 <= W:
            a0 = np.int64(row[x])
            a1 = np.int64(row[x + 1])
            a2 = np.int64(row[x + 2])
            a3 = np.int64(row[x + 3])
            a4 = np.int64(row[x + 4])
            h0[abs(a1 - a0)] += 1
            h1[abs(a2 - a1)] += 1
            h2[abs(a3 - a2)] += 1
            h3[abs(a4 - a3)] += 1
            x += 4
        while x + 1 < W:
            h0[abs(np.int64(row[x + 1]) - np.int64(row[x]))] += 1
            x += 1
    for v in range(nb):
        hist[v] += h0[v] + h1[v] + h2[v] + h3[v]


@njit(cache=True, nogil=True, error_model="numpy")
def box_means(img: np.ndarray, cx: np.ndarray, cy: np.ndarray, half: np.ndarray, ceiling: float,
              mean: np.ndarray, spread: np.ndarray, clipped: np.ndarray) -> None:  # pragma: no cover - numba
    """The mean of ``img``'s pixels in the box of ``2 half[i] + 1`` pixels a side centred on
    pixel (``cx[i]``, ``cy[i]``) (inside the image: the caller checks), their variance
    (unbiased) and the fraction of them at ``ceiling`` or above, for each i of the flat arrays."""
    for i in range(cx.shape[0]):
        h = half[i]
        s = 0.0
        ss = 0.0
        c = 0
        for y in range(cy[i] - h, cy[i] + h + 1):
            for x in range(cx[i] - h, cx[i] + h + 1):
                v = img[y, x]
                s += v
                ss += v * v
                if v >= ceiling:
                    c += 1
        n = (2 * h + 1) * (2 * h + 1)
        m = s / n
        mean[i] = m
        spread[i] = max(ss - n * m * m, 0.0) / (n - 1)
        clipped[i] = c / n


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _bilinear_grad(img: np.ndarray, x: float, y: float) -> tuple[float, float, float]:  # pragma: no cover - numba
    """The bilinear interpolant of ``img`` at (x, y) and its central differences, (value, d/dx,
    d/dy): the bilinear interpolant of the image's central-difference images. The caller keeps
    (x, y) within [1, W - 3] x [1, H - 3]."""
    x0 = math.floor(x)
    y0 = math.floor(y)
    fx = x - x0
    fy = y - y0
    # The bilinear weights of the 2x2 cell, applied to the value and to the central differences,
    # the cell's twelve pixels read once each (read in place for each of the four taps, twenty
    # reads, it was the slower: benchmarks/notes.md, fifty-sixth session); the same sums in the
    # same order.
    ix = int(x0)
    iy = int(y0)
    r0 = img[iy - 1]
    r1 = img[iy]
    r2 = img[iy + 1]
    r3 = img[iy + 2]
    p01, p02 = r0[ix], r0[ix + 1]
    p10, p11, p12, p13 = r1[ix - 1], r1[ix], r1[ix + 1], r1[ix + 2]
    p20, p21, p22, p23 = r2[ix - 1], r2[ix], r2[ix + 1], r2[ix + 2]
    p31, p32 = r3[ix], r3[ix + 1]
    val = 0.0
    gx = 0.0
    gy = 0.0
    w = (1.0 - fy) * (1.0 - fx)
    val += w * p11
    gx += w * 0.5 * (p12 - p10)
    gy += w * 0.5 * (p21 - p01)
    w = (1.0 - fy) * fx
    val += w * p12
    gx += w * 0.5 * (p13 - p11)
    gy += w * 0.5 * (p22 - p02)
    w = fy * (1.0 - fx)
    val += w * p21
    gx += w * 0.5 * (p22 - p20)
    gy += w * 0.5 * (p31 - p11)
    w = fy * fx
    val += w * p22
    gx += w * 0.5 * (p23 - p21)
    gy += w * 0.5 * (p32 - p12)
    return val, gx, gy


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _mirrored_pair(img: np.ndarray, px: float, py: float, a: np.ndarray, b: np.ndarray, shade: np.ndarray, k: int,
                   i: int) -> tuple[float, float, float]:  # pragma: no cover - numba
    """Pair ``i`` of point ``k`` of :func:`symmetry_refine` at (px, py): its residual (the
    shade at ``a`` less the shade at ``b``, less the light's gradient ``shade[k]`` across
    them) and the residual's derivatives in x and y."""
    va, gxa, gya = _bilinear_grad(img, px + a[k, i, 0], py + a[k, i, 1])
    vb, gxb, gyb = _bilinear_grad(img, px + b[k, i, 0], py + b[k, i, 1])
    light = shade[k, 0] * (a[k, i, 0] - b[k, i, 0]) + shade[k, 1] * (a[k, i, 1] - b[k, i, 1])
    return va - vb - light, gxa - gxb, gya - gyb


def _make_symmetry_refine(PARALLEL: int):
    """:func:`symmetry_refine`'s kernel, run on the OpenMP pool where ``PARALLEL`` is 1."""

    @njit(cache=True, nogil=True, parallel=PARALLEL == 1, error_model="numpy")
    def symmetry_refine(img: np.ndarray, taps: np.ndarray, p0: np.ndarray, a: np.ndarray, b: np.ndarray, m: np.ndarray,
                        shade: np.ndarray, iters: int, tol: float, out: np.ndarray, cov: np.ndarray, wres: np.ndarray,
                        normal: np.ndarray, sens: np.ndarray) -> None:  # pragma: no cover - numba
        """Move each point to where the image is point-symmetric through it: Gauss-Newton on the
        translation t of ``sum_i (I(p + t + a_i) - I(p + t + b_i))^2`` over its ``m[k]`` pairs of
        offsets ``a[k, i]``, ``b[k, i]`` (px; b the mirror image of a through the point on the
        board's local map), bilinear image values with central-difference gradients. ``img`` is
        the image smoothed with the separable kernel ``taps`` (odd length; ``[1.0]``: not
        smoothed), which the covariance carries. ``shade[k]``: the gradient of the light across
        point k (shade per px; zeros: none), taken off each pair's residual (linear light is not
        point-symmetric).

        Writes ``out[k]`` (NaN where a sample leaves the image, the normal matrix is singular or
        it has not converged to ``tol`` px in ``iters`` steps), ``cov[k]`` = (xx, xy, yy) of the
        point's covariance per unit white pixel noise (the linearised estimator's, through the
        bilinear weights of both samples of every pair and the smoothing), and ``wres[k]``: the
        white pixel noise that the final residuals would imply (their sum of squares over the sum
        of the squared weights they carry, the smoothing's sum of squared weights included), and
        ``normal[k]`` = (xx, xy, yy) of the normal matrix J^T J at the solution (its gradients are
        read on the noisy image, so the noise adds to it: the caller weighs that share), and
        ``sens[k]`` = (xx, xy, yx, yy) of sum_i J_i (a_i - b_i)^T: the point moves by
        (J^T J)^-1 sens dg where the light's gradient given is off by dg."""
        if PARALLEL:  # (the closure's int keys the cache: the twins apart)
            pass
        H, W = img.shape
        R = taps.shape[0] // 2
        t2 = 0.0
        for i in range(taps.shape[0]):
            t2 += taps[i] * taps[i]
        for k in prange(p0.shape[0]):
            out[k, 0] = np.nan
            out[k, 1] = np.nan
            cov[k, 0] = np.nan
            cov[k, 1] = np.nan
            cov[k, 2] = np.nan
            wres[k] = np.nan
            normal[k, 0] = np.nan
            normal[k, 1] = np.nan
            normal[k, 2] = np.nan
            for j in range(4):
                sens[k, j] = np.nan
            n = m[k]
            if n < 3:
                continue
            px = p0[k, 0]
            py = p0[k, 1]
            good = False
            inside = True
            for _it in range(iters):
                sxx = 0.0
                sxy = 0.0
                syy = 0.0
                rx = 0.0
                ry = 0.0
                for i in range(n):
                    xa = px + a[k, i, 0]
                    ya = py + a[k, i, 1]
                    xb = px + b[k, i, 0]
                    yb = py + b[k, i, 1]
                    if (min(xa, xb) < 1.0 or max(xa, xb) > W - 3.0 or min(ya, yb) < 1.0 or max(ya, yb) > H - 3.0
                            or not (xa == xa and xb == xb and ya == ya and yb == yb)):
                        inside = False
                        break
                    r, jx, jy = _mirrored_pair(img, px, py, a, b, shade, k, i)
                    sxx += jx * jx
                    sxy += jx * jy
                    syy += jy * jy
                    rx += jx * r
                    ry += jy * r
                if not inside:
                    break
                det = sxx * syy - sxy * sxy
                if not det > 1e-12 * (sxx + syy) * (sxx + syy):
                    break
                dx = -(syy * rx - sxy * ry) / det
                dy = -(sxx * ry - sxy * rx) / det
                px += dx
                py += dy
                if dx * dx + dy * dy < tol * tol:
                    good = True
                    break
            if not good:
                continue
            # The covariance at the solution: t = -(J^T J)^-1 J^T r, r linear in the pixels through
            # the bilinear weights, so Cov = M^-1 (sum_pix g g^T) M^-1 per unit noise, g the
            # pixel's weight in J^T r. The pixels touched lie in the samples' bounding box.
            xmin = 1e300
            ymin = 1e300
            xmax = -1e300
            ymax = -1e300
            for i in range(n):
                xmin = min(xmin, px + a[k, i, 0], px + b[k, i, 0])
                xmax = max(xmax, px + a[k, i, 0], px + b[k, i, 0])
                ymin = min(ymin, py + a[k, i, 1], py + b[k, i, 1])
                ymax = max(ymax, py + a[k, i, 1], py + b[k, i, 1])
            if xmin < 1.0 or xmax > W - 3.0 or ymin < 1.0 or ymax > H - 3.0:
                continue
            bx = math.floor(xmin)
            by = math.floor(ymin)
            gw = math.floor(xmax) - bx + 2
            gh = math.floor(ymax) - by + 2
            g = np.zeros((gh, gw, 2))
            sxx = 0.0
            sxy = 0.0
            syy = 0.0
            rr = 0.0
            ww = 0.0
            bxx = 0.0
            bxy = 0.0
            byx = 0.0
            byy = 0.0
            for i in range(n):
                xa = px + a[k, i, 0]
                ya = py + a[k, i, 1]
                xb = px + b[k, i, 0]
                yb = py + b[k, i, 1]
                r, jx, jy = _mirrored_pair(img, px, py, a, b, shade, k, i)
                sxx += jx * jx
                sxy += jx * jy
                syy += jy * jy
                rr += r * r
                bxx += jx * (xa - xb)
                bxy += jx * (ya - yb)
                byx += jy * (xa - xb)
                byy += jy * (ya - yb)
                for s in range(2):
                    xs = xa if s == 0 else xb
                    ys = ya if s == 0 else yb
                    sign = 1.0 if s == 0 else -1.0
                    x0 = math.floor(xs)
                    y0 = math.floor(ys)
                    fx = xs - x0
                    fy = ys - y0
                    for j in range(2):
                        wy = fy if j == 1 else 1.0 - fy
                        for q in range(2):
                            w = sign * wy * (fx if q == 1 else 1.0 - fx)
                            ww += w * w
                            g[y0 - by + j, x0 - bx + q, 0] += w * jx
                            g[y0 - by + j, x0 - bx + q, 1] += w * jy
            det = sxx * syy - sxy * sxy
            if not det > 0.0:
                continue
            ixx = syy / det
            ixy = -sxy / det
            iyy = sxx / det
            # Through the smoothing: a raw pixel's weight is the smoothed grid's weights convolved
            # with the (symmetric) taps, over the grid grown by the kernel's radius.
            tmp = np.zeros((gh, gw + 2 * R, 2))
            for yy in range(gh):
                for xx in range(gw):
                    for i in range(2 * R + 1):
                        tmp[yy, xx + i, 0] += taps[i] * g[yy, xx, 0]
                        tmp[yy, xx + i, 1] += taps[i] * g[yy, xx, 1]
            cxx = 0.0
            cxy = 0.0
            cyy = 0.0
            for yy in range(gh + 2 * R):
                for xx in range(gw + 2 * R):
                    g0 = 0.0
                    g1 = 0.0
                    for i in range(2 * R + 1):
                        j = yy - i
                        if 0 <= j < gh:
                            g0 += taps[i] * tmp[j, xx, 0]
                            g1 += taps[i] * tmp[j, xx, 1]
                    u = ixx * g0 + ixy * g1
                    v = ixy * g0 + iyy * g1
                    cxx += u * u
                    cxy += u * v
                    cyy += v * v
            out[k, 0] = px
            out[k, 1] = py
            cov[k, 0] = cxx
            cov[k, 1] = cxy
            cov[k, 2] = cyy
            wres[k] = math.sqrt(rr / (ww * t2 * t2)) if ww > 0.0 else np.nan
            normal[k, 0] = sxx
            normal[k, 1] = sxy
            normal[k, 2] = syy
            sens[k, 0] = bxx
            sens[k, 1] = bxy
            sens[k, 2] = byx
            sens[k, 3] = byy

    return symmetry_refine


_symmetry_refine_serial, _symmetry_refine_parallel = _make_symmetry_refine(0), _make_symmetry_refine(1)


def symmetry_refine(img: np.ndarray, taps: np.ndarray, p0: np.ndarray, a: np.ndarray, b: np.ndarray, m: np.ndarray,
                    shade: np.ndarray, iters: int, tol: float, out: np.ndarray, cov: np.ndarray, wres: np.ndarray,
                    normal: np.ndarray, sens: np.ndarray) -> None:
    """Each point moved to its point of symmetry (kernel ``_make_symmetry_refine``), serial
    where small (:data:`PARALLEL_MIN_NS`; the work counted in pairs times steps) or for one
    point (the loop is over the points)."""
    work = 20.0 * float(np.sum(m)) * iters
    (_symmetry_refine_parallel if work >= PARALLEL_MIN_NS and len(p0) > 1 else _symmetry_refine_serial)(
        img, taps, p0, a, b, m, shade, iters, tol, out, cov, wres, normal, sens)


def _make_saddle_fit(PARALLEL: int):
    """:func:`saddle_fit`'s kernel, run on the OpenMP pool where ``PARALLEL`` is 1."""

    @njit(cache=True, nogil=True, parallel=PARALLEL == 1, error_model="numpy")
    def saddle_fit(s: np.ndarray, pts: np.ndarray, r: int, iters: int, pinv: np.ndarray, cvar: float, q: np.ndarray,
                   sigma: np.ndarray, resid: np.ndarray) -> None:  # pragma: no cover - numba
        """The saddle fit of :func:`camkit.target.checkerboard._saddle_fit`, point by point: the
        quadratic ``pinv`` (6, (2r+1)^2: the pseudo-inverse of its design matrix, columns dx^2,
        dx dy, dy^2, dx, dy, 1 over the window's offsets in row-major order) fitted on the
        (2r+1)^2 window about each estimate, sampled bicubically (Keys, a = -0.5, edges
        replicated, as :func:`camkit._kernels.lattice.sample_points`: the window's offsets are
        whole pixels, so each row of four taps is summed once per window row); ``iters`` steps
        to the quadratic's saddle, each at most a pixel either way (none where it is flat), then
        the fit again. Writes the place ``q[k]``, its sigma ``sigma[k]`` (the residuals' variance
        times ``cvar``, the (3, 3) element of (A^T A)^-1, through the saddle's equations; NaN
        where the saddle lies half a pixel or more from the window's centre), and the residuals'
        standard deviation ``resid[k]`` (NaN where the sigma is); all NaN for an estimate that is
        not finite."""
        if PARALLEL:  # (the closure's int keys the cache: the twins apart)
            pass
        H, W = s.shape
        n = 2 * r + 1
        N = n * n
        for k in prange(pts.shape[0]):
            hrow = np.empty((n + 3, n))
            vals = np.empty(N)
            c = np.zeros(6)
            qx = pts[k, 0]
            qy = pts[k, 1]
            if not (math.isfinite(qx) and math.isfinite(qy)):  # no place to fit at
                q[k, 0] = q[k, 1] = sigma[k] = resid[k] = np.nan
                continue
            for it in range(iters + 1):
                fx = math.floor(qx)
                fy = math.floor(qy)
                wx = keys4(qx - fx, -0.5)
                wy = keys4(qy - fy, -0.5)
                ix = int(fx) - r - 1
                iy = int(fy) - r - 1
                for j in range(n + 3):
                    yy = min(max(iy + j, 0), H - 1)
                    for i in range(n):
                        acc = 0.0
                        for m in range(4):
                            xx = min(max(ix + i + m, 0), W - 1)
                            acc += wx[m] * s[yy, xx]
                        hrow[j, i] = acc
                for j in range(n):
                    for i in range(n):
                        acc = 0.0
                        for m in range(4):
                            acc += wy[m] * hrow[j + m, i]
                        vals[j * n + i] = acc
                for t in range(6):
                    acc = 0.0
                    for i in range(N):
                        acc += pinv[t, i] * vals[i]
                    c[t] = acc
                a, b, cc, d, e = c[0], c[1], c[2], c[3], c[4]
                det = 4.0 * a * cc - b * b
                sx = (-2.0 * cc * d + b * e) / det
                sy = (b * d - 2.0 * a * e) / det
                if it == iters:
                    ss = 0.0
                    for j in range(n):
                        for i in range(n):
                            dx = float(i - r)
                            dy = float(j - r)
                            f = a * dx * dx + b * dx * dy + cc * dy * dy + d * dx + e * dy + c[5]
                            rr = vals[j * n + i] - f
                            ss += rr * rr
                    var = ss / max(N - 6, 1)
                    h11, h12, h22 = 2.0 * cc / det, -b / det, 2.0 * a / det
                    sg = math.sqrt(0.5 * var * cvar * (h11 * h11 + 2.0 * h12 * h12 + h22 * h22))
                    q[k, 0] = qx
                    q[k, 1] = qy
                    sigma[k] = sg if math.hypot(sx, sy) < 0.5 else np.nan
                    resid[k] = math.sqrt(var) if math.isfinite(sigma[k]) else np.nan
                    break
                sx = 0.0 if math.isnan(sx) else min(max(sx, -1.0), 1.0)
                sy = 0.0 if math.isnan(sy) else min(max(sy, -1.0), 1.0)
                qx += sx
                qy += sy

    return saddle_fit


_saddle_fit_serial, _saddle_fit_parallel = _make_saddle_fit(0), _make_saddle_fit(1)


def saddle_fit(s: np.ndarray, pts: np.ndarray, r: int, iters: int, pinv: np.ndarray, cvar: float, q: np.ndarray,
               sigma: np.ndarray, resid: np.ndarray) -> None:
    """The saddle fit of each point (kernel ``_make_saddle_fit``), serial where small
    (:data:`PARALLEL_MIN_NS`; the work counted in taps of the window's rows times steps)."""
    n = 2 * r + 1
    work = 3.0 * pts.shape[0] * (iters + 1) * ((n + 3) * n + 2 * n * n)
    (_saddle_fit_parallel if work >= PARALLEL_MIN_NS else _saddle_fit_serial)(s, pts, r, iters, pinv, cvar, q,
                                                                               sigma, resid)
@njit(cache=True, nogil=True, error_model="numpy")
def _patch_grad(s: np.ndarray, x0: int, y0: int, side: int, i: int, j: int) -> tuple[float, float]:  # pragma: no cover
    """Central differences of ``s`` at pixel (x0 + i, y0 + j) of the patch of ``side`` pixels
    whose top-left is (x0, y0); 0 across the patch's own edge."""
    gx = 0.5 * (s[y0 + j, x0 + i + 1] - s[y0 + j, x0 + i - 1]) if 0 < i < side - 1 else 0.0
    gy = 0.5 * (s[y0 + j + 1, x0 + i] - s[y0 + j - 1, x0 + i]) if 0 < j < side - 1 else 0.0
    return gx, gy


@njit(cache=True, nogil=True, error_model="numpy")
def light_divide(s: np.ndarray, origin: np.ndarray, at: np.ndarray, theta: np.ndarray, sm2: float, side: int,
                 out: np.ndarray) -> None:  # pragma: no cover - numba
    """The ChArUco detector's light divided out of smoothed patches (its step 8): patch k of
    ``s`` (``side`` pixels, top-left at ``origin[k]`` (x, y)) about the point ``at[k]`` (its
    place within the patch), under light ``theta[k]`` = (m_x, m_y, a_x, a_y) per px from it,
    is written to ``out`` as ``(v - a . d - sm2 m . grad v) / (1 + m . d)``, ``d`` the pixel's
    offset from the point, ``grad`` central differences (0 across the patch's edge)."""
    for k in range(origin.shape[0]):
        x0, y0 = origin[k, 0], origin[k, 1]
        mx, my, ax, ay = theta[k, 0], theta[k, 1], theta[k, 2], theta[k, 3]
        for j in range(side):
            dy = j - at[k, 1]
            for i in range(side):
                dx = i - at[k, 0]
                gx, gy = _patch_grad(s, x0, y0, side, i, j)
                out[y0 + j, x0 + i] = ((s[y0 + j, x0 + i] - ax * dx - ay * dy - sm2 * (mx * gx + my * gy))
                                       / (1.0 + mx * dx + my * dy))


@njit(cache=True, nogil=True, error_model="numpy")
def light_response(s: np.ndarray, origin: np.ndarray, at: np.ndarray, sm2: float, side: int, r: int,
                   pinv: np.ndarray, quad: np.ndarray, lin: np.ndarray) -> None:  # pragma: no cover - numba
    """For :func:`light_divide`'s patches: the quadratic fitted (``pinv``, as
    :func:`saddle_fit`'s, window ``r``) on the window about the pixel nearest each point, its
    terms dx^2, dx dy, dy^2 (``quad`` (K, 3)), and the change of its linear terms (dx, dy) per
    unit of each of the light's four numbers (``lin`` (K, 4, 2): m_x, m_y, a_x, a_y; the
    patch's change for m_x is ``v dx + sm2 dv/dx``, for a_x ``dx``)."""
    n = 2 * r + 1
    for k in range(origin.shape[0]):
        x0, y0 = origin[k, 0], origin[k, 1]
        ci = math.floor(at[k, 0] + 0.5)
        cj = math.floor(at[k, 1] + 0.5)
        for t in range(3):
            quad[k, t] = 0.0
        for a in range(4):
            lin[k, a, 0] = 0.0
            lin[k, a, 1] = 0.0
        for wj in range(n):
            j = cj + wj - r
            dy = j - at[k, 1]
            for wi in range(n):
                i = ci + wi - r
                dx = i - at[k, 0]
                q = wj * n + wi
                v = s[y0 + j, x0 + i]
                gx, gy = _patch_grad(s, x0, y0, side, i, j)
                for t in range(3):
                    quad[k, t] += v * pinv[t, q]
                c0 = v * dx + sm2 * gx
                c1 = v * dy + sm2 * gy
                p3, p4 = pinv[3, q], pinv[4, q]
                lin[k, 0, 0] += c0 * p3
                lin[k, 0, 1] += c0 * p4
                lin[k, 1, 0] += c1 * p3
                lin[k, 1, 1] += c1 * p4
                lin[k, 2, 0] += dx * p3
                lin[k, 2, 1] += dx * p4
                lin[k, 3, 0] += dy * p3
                lin[k, 3, 1] += dy * p4
