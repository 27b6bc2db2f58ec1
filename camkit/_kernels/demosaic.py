"""Demosaicing kernels on float planes. ``code`` is the pattern's 2x2 colour indices
(0 red, 1 green, 2 blue) in the order (0,0), (0,1), (1,0), (1,1). Borders mirror without
repeating the edge pixel (d c b | a b c d), which keeps the Bayer phase."""

from __future__ import annotations

import numpy as np
from numba import njit, prange


@njit(cache=True, nogil=True, error_model="numpy")
def m(i: int, n: int) -> int:  # pragma: no cover - numba
    """Mirror index into [0, n) (reflect-101), for offsets up to n - 1 beyond each edge."""
    if i < 0:
        i = -i
    if i >= n:
        i = 2 * n - 2 - i
    return i


@njit(cache=True, nogil=True, error_model="numpy")
def put(v: float, is_int: bool, hi: float) -> float:  # pragma: no cover
    """Round half up and saturate to [0, hi] for integer outputs; floats pass unchanged (the
    store into an unsigned array truncates, which is floor for v >= 0)."""
    if is_int:
        v += 0.5
        if v < 0.0:
            return 0.0
        if v > hi:
            return hi
    return v


@njit(cache=True, nogil=True, parallel=True, error_model="numpy")
def bilinear(cfa: np.ndarray, code: np.ndarray, is_int: bool, hi: float,
             out: np.ndarray) -> None:  # pragma: no cover
    """Each missing colour is the mean of its nearest samples (2 or 4 of them)."""
    H, W = cfa.shape
    for y in prange(H):
        for x in range(W):
            c = code[(y & 1) * 2 + (x & 1)]
            v = cfa[y, x]
            up = np.float32(cfa[m(y - 1, H), x])
            dn = np.float32(cfa[m(y + 1, H), x])
            lf = np.float32(cfa[y, m(x - 1, W)])
            rt = np.float32(cfa[y, m(x + 1, W)])
            cross = np.float32(0.25) * (up + dn + lf + rt)
            diag = np.float32(0.25) * (np.float32(cfa[m(y - 1, H), m(x - 1, W)])
                                       + cfa[m(y - 1, H), m(x + 1, W)] + cfa[m(y + 1, H), m(x - 1, W)]
                                       + cfa[m(y + 1, H), m(x + 1, W)])
            if c == 1:
                # green site: the colour of the row's other sites is left/right, the other up/down
                row_colour = code[(y & 1) * 2 + ((x + 1) & 1)]
                out[y, x, 1] = v
                out[y, x, row_colour] = put(0.5 * (lf + rt), is_int, hi)
                out[y, x, 2 - row_colour] = put(0.5 * (up + dn), is_int, hi)
            else:
                out[y, x, c] = v
                out[y, x, 1] = put(cross, is_int, hi)
                out[y, x, 2 - c] = put(diag, is_int, hi)


@njit(cache=True, nogil=True, parallel=True, error_model="numpy")
def malvar(cfa: np.ndarray, code: np.ndarray, is_int: bool, hi: float,
           out: np.ndarray) -> None:  # pragma: no cover
    """Malvar-He-Cutler gradient-corrected bilinear filters (5x5, ICASSP 2004)."""
    H, W = cfa.shape
    for y in prange(H):
        ym2 = m(y - 2, H)
        ym1 = m(y - 1, H)
        yp1 = m(y + 1, H)
        yp2 = m(y + 2, H)
        for x in range(W):
            xm2 = m(x - 2, W)
            xm1 = m(x - 1, W)
            xp1 = m(x + 1, W)
            xp2 = m(x + 2, W)
            c = code[(y & 1) * 2 + (x & 1)]
            v = cfa[y, x]
            axial2 = np.float32(cfa[ym2, x]) + cfa[yp2, x] + cfa[y, xm2] + cfa[y, xp2]
            cross1 = np.float32(cfa[ym1, x]) + cfa[yp1, x] + cfa[y, xm1] + cfa[y, xp1]
            diag1 = np.float32(cfa[ym1, xm1]) + cfa[ym1, xp1] + cfa[yp1, xm1] + cfa[yp1, xp1]
            if c == 1:
                h1 = np.float32(cfa[y, xm1]) + cfa[y, xp1]
                v1 = np.float32(cfa[ym1, x]) + cfa[yp1, x]
                h2 = np.float32(cfa[y, xm2]) + cfa[y, xp2]
                v2 = np.float32(cfa[ym2, x]) + cfa[yp2, x]
                # colour whose samples are left/right of this green site, and the other one
                along_row = (5.0 * v + 4.0 * h1 - h2 - diag1 + 0.5 * v2) / 8.0
                along_col = (5.0 * v + 4.0 * v1 - v2 - diag1 + 0.5 * h2) / 8.0
                row_colour = code[(y & 1) * 2 + ((x + 1) & 1)]
                out[y, x, 1] = v
                out[y, x, row_colour] = put(along_row, is_int, hi)
                out[y, x, 2 - row_colour] = put(along_col, is_int, hi)
            else:
                out[y, x, c] = v
                out[y, x, 1] = put((4.0 * v + 2.0 * cross1 - axial2) / 8.0, is_int, hi)
                out[y, x, 2 - c] = put((6.0 * v + 2.0 * diag1 - 1.5 * axial2) / 8.0, is_int, hi)


@njit(cache=True, nogil=True, parallel=True, error_model="numpy")
def bilinear_int(cfa: np.ndarray, code: np.ndarray, out: np.ndarray) -> None:  # pragma: no cover - numba
    """:func:`bilinear` for integer mosaics, in integer arithmetic (the same rounding: half up).

    A row alternates colour sites and green sites, so its interior is walked two columns
    at a time, (colour, green) or (green, colour), with the channel layout fixed per loop:
    every store is then at a constant offset from 6 * pair, which LLVM turns into SIMD
    interleaved stores (an earlier version computed per-column candidate buffers and then
    selected by parity per pixel, 4x slower). The columns at each edge take the mirrored
    per-pixel path. ``out`` must be C-contiguous."""
    H, W = cfa.shape
    k0 = 1  # pairs (2k, 2k + 1) with 2k - 1 >= 0 and 2k + 2 <= W - 1
    k1 = (W - 3) // 2 + 1
    for y in prange(H):
        ym = m(y - 1, H)
        yp = m(y + 1, H)
        r0 = cfa[ym]
        r1 = cfa[y]
        r2 = cfa[yp]
        o = out[y].reshape(-1)
        p = y & 1
        ph = 0 if code[p * 2] != 1 else 1  # column parity of this row's red or blue sites
        if code[p * 2 + ph] == 0:
            if ph == 0:
                _bilinear_colour_first(r0, r1, r2, o, k0, k1, 0)
            else:
                _bilinear_green_first(r0, r1, r2, o, k0, k1, 0)
        elif ph == 0:
            _bilinear_colour_first(r0, r1, r2, o, k0, k1, 2)
        else:
            _bilinear_green_first(r0, r1, r2, o, k0, k1, 2)
        for x in range(min(2, W)):
            _bilinear_px(cfa, code, y, x, ym, yp, H, W, out)
        for x in range(max(2, 2 * k1), W):
            _bilinear_px(cfa, code, y, x, ym, yp, H, W, out)


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _bilinear_colour_first(r0, r1, r2, o, k0, k1, c) -> None:  # pragma: no cover - numba
    """Pairs (colour site at x = 2k, green site at x + 1) of a row whose colour sites have
    colour ``c`` (0 red, 2 blue); r0, r1, r2 the rows above, at and below; o the output row
    flattened. Inlined at the call sites, where ``c`` is a literal."""
    d = 2 - c
    for k in range(k0, k1):
        x = 2 * k
        a = np.int32(r0[x]) + np.int32(r2[x])
        b = np.int32(r1[x - 1]) + np.int32(r1[x + 1])
        o[3 * x + c] = r1[x]
        o[3 * x + 1] = (a + b + 2) >> 2
        o[3 * x + d] = (np.int32(r0[x - 1]) + np.int32(r0[x + 1]) + np.int32(r2[x - 1]) + np.int32(r2[x + 1])
                        + 2) >> 2
        x1 = x + 1
        o[3 * x1 + c] = (np.int32(r1[x]) + np.int32(r1[x + 2]) + 1) >> 1
        o[3 * x1 + 1] = r1[x1]
        o[3 * x1 + d] = (np.int32(r0[x1]) + np.int32(r2[x1]) + 1) >> 1


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _bilinear_green_first(r0, r1, r2, o, k0, k1, c) -> None:  # pragma: no cover - numba
    """Pairs (green site at x = 2k, colour site at x + 1); see :func:`_bilinear_colour_first`."""
    d = 2 - c
    for k in range(k0, k1):
        x = 2 * k
        o[3 * x + c] = (np.int32(r1[x - 1]) + np.int32(r1[x + 1]) + 1) >> 1
        o[3 * x + 1] = r1[x]
        o[3 * x + d] = (np.int32(r0[x]) + np.int32(r2[x]) + 1) >> 1
        x1 = x + 1
        a = np.int32(r0[x1]) + np.int32(r2[x1])
        b = np.int32(r1[x]) + np.int32(r1[x + 2])
        o[3 * x1 + c] = r1[x1]
        o[3 * x1 + 1] = (a + b + 2) >> 2
        o[3 * x1 + d] = (np.int32(r0[x]) + np.int32(r0[x + 2]) + np.int32(r2[x]) + np.int32(r2[x + 2]) + 2) >> 2


@njit(cache=True, nogil=True, error_model="numpy")
def _interleave(orow, code, y, raw, green_at_c, other_at_c, row_at_g, col_at_g, x0, x1) -> None:  # pragma: no cover
    """Write columns x0..x1-1 of row y from per-column candidates: at a red/blue site its own
    sample, ``green_at_c`` and ``other_at_c`` (the opposite colour); at a green site its own
    sample, ``row_at_g`` (the colour of this row's other sites) and ``col_at_g``. Selecting by
    column parity inside one loop keeps it a single pass over contiguous buffers."""
    p = y & 1
    ph = 0 if code[p * 2] != 1 else 1  # column parity of this row's red or blue sites
    if code[p * 2 + ph] == 0:  # a red row
        for x in range(x0, x1):
            own = (x & 1) == ph
            orow[x, 0] = raw[x] if own else row_at_g[x]
            orow[x, 1] = green_at_c[x] if own else raw[x]
            orow[x, 2] = other_at_c[x] if own else col_at_g[x]
    else:  # a blue row
        for x in range(x0, x1):
            own = (x & 1) == ph
            orow[x, 0] = other_at_c[x] if own else col_at_g[x]
            orow[x, 1] = green_at_c[x] if own else raw[x]
            orow[x, 2] = raw[x] if own else row_at_g[x]


@njit(cache=True, nogil=True, error_model="numpy")
def _bilinear_px(cfa, code, y, x, ym, yp, H, W, out) -> None:  # pragma: no cover - numba
    c = code[(y & 1) * 2 + (x & 1)]
    xm = m(x - 1, W)
    xp = m(x + 1, W)
    if c == 1:
        rc = code[(y & 1) * 2 + ((x + 1) & 1)]
        out[y, x, 1] = cfa[y, x]
        out[y, x, rc] = (np.int32(cfa[y, xm]) + np.int32(cfa[y, xp]) + 1) >> 1
        out[y, x, 2 - rc] = (np.int32(cfa[ym, x]) + np.int32(cfa[yp, x]) + 1) >> 1
    else:
        out[y, x, c] = cfa[y, x]
        out[y, x, 1] = (np.int32(cfa[ym, x]) + np.int32(cfa[yp, x]) + np.int32(cfa[y, xm]) + np.int32(cfa[y, xp])
                        + 2) >> 2
        out[y, x, 2 - c] = (np.int32(cfa[ym, xm]) + np.int32(cfa[ym, xp]) + np.int32(cfa[yp, xm])
                            + np.int32(cfa[yp, xp]) + 2) >> 2


@njit(cache=True, nogil=True, parallel=True, error_model="numpy")
def malvar_int(cfa: np.ndarray, code: np.ndarray, hi: int, out: np.ndarray) -> None:  # pragma: no cover
    """:func:`malvar` for integer mosaics in integer arithmetic: the filters' weights times 16
    are integers, so ``(sum + 8) >> 4`` is the same round-half-up result as the float path.
    Per row, the four filters (green-site along the row and along the column, colour-site
    green and opposite colour) are evaluated for every interior column into contiguous
    buffers (vectorised loops), then interleaved by column parity; the two columns at each
    edge take the mirrored path."""
    H, W = cfa.shape
    for y in prange(H):
        ym2 = m(y - 2, H)
        ym1 = m(y - 1, H)
        yp1 = m(y + 1, H)
        yp2 = m(y + 2, H)
        for x in (0, 1, W - 2, W - 1):
            if 0 <= x < W:
                _malvar_px(cfa, code, hi, y, x, ym2, ym1, yp1, yp2, W, out)
        a2 = cfa[ym2]
        a1 = cfa[ym1]
        r = cfa[y]
        b1 = cfa[yp1]
        b2 = cfa[yp2]
        f_row = np.empty(W, np.int32)
        f_col = np.empty(W, np.int32)
        f_g = np.empty(W, np.int32)
        f_o = np.empty(W, np.int32)
        for x in range(2, W - 2):
            v = np.int32(r[x])
            h1 = np.int32(r[x - 1]) + np.int32(r[x + 1])
            v1 = np.int32(a1[x]) + np.int32(b1[x])
            h2 = np.int32(r[x - 2]) + np.int32(r[x + 2])
            v2 = np.int32(a2[x]) + np.int32(b2[x])
            d1 = np.int32(a1[x - 1]) + np.int32(a1[x + 1]) + np.int32(b1[x - 1]) + np.int32(b1[x + 1])
            f_row[x] = min(max((10 * v + 8 * h1 - 2 * h2 - 2 * d1 + v2 + 8) >> 4, 0), hi)
            f_col[x] = min(max((10 * v + 8 * v1 - 2 * v2 - 2 * d1 + h2 + 8) >> 4, 0), hi)
            f_g[x] = min(max((8 * v + 4 * (h1 + v1) - 2 * (h2 + v2) + 8) >> 4, 0), hi)
            f_o[x] = min(max((12 * v + 4 * d1 - 3 * (h2 + v2) + 8) >> 4, 0), hi)
        _interleave(out[y], code, y, r, f_g, f_o, f_row, f_col, 2, W - 2)


@njit(cache=True, nogil=True, error_model="numpy")
def _malvar_px(cfa, code, hi, y, x, ym2, ym1, yp1, yp2, W, out) -> None:  # pragma: no cover - numba
    xm2 = m(x - 2, W)
    xm1 = m(x - 1, W)
    xp1 = m(x + 1, W)
    xp2 = m(x + 2, W)
    c = code[(y & 1) * 2 + (x & 1)]
    v = np.int32(cfa[y, x])
    d1 = np.int32(cfa[ym1, xm1]) + np.int32(cfa[ym1, xp1]) + np.int32(cfa[yp1, xm1]) + np.int32(cfa[yp1, xp1])
    if c == 1:
        h1 = np.int32(cfa[y, xm1]) + np.int32(cfa[y, xp1])
        v1 = np.int32(cfa[ym1, x]) + np.int32(cfa[yp1, x])
        h2 = np.int32(cfa[y, xm2]) + np.int32(cfa[y, xp2])
        v2 = np.int32(cfa[ym2, x]) + np.int32(cfa[yp2, x])
        rc = code[(y & 1) * 2 + ((x + 1) & 1)]
        out[y, x, 1] = cfa[y, x]
        out[y, x, rc] = min(max((10 * v + 8 * h1 - 2 * h2 - 2 * d1 + v2 + 8) >> 4, 0), hi)
        out[y, x, 2 - rc] = min(max((10 * v + 8 * v1 - 2 * v2 - 2 * d1 + h2 + 8) >> 4, 0), hi)
    else:
        ax2 = np.int32(cfa[ym2, x]) + np.int32(cfa[yp2, x]) + np.int32(cfa[y, xm2]) + np.int32(cfa[y, xp2])
        cr1 = np.int32(cfa[ym1, x]) + np.int32(cfa[yp1, x]) + np.int32(cfa[y, xm1]) + np.int32(cfa[y, xp1])
        out[y, x, c] = cfa[y, x]
        out[y, x, 1] = min(max((8 * v + 4 * cr1 - 2 * ax2 + 8) >> 4, 0), hi)
        out[y, x, 2 - c] = min(max((12 * v + 4 * d1 - 3 * ax2 + 8) >> 4, 0), hi)
