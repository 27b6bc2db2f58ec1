"""Separable resampling passes with precomputed weight tables.

A table gives, for each output index j, the first input index ``starts[j]`` and ``K``
weights (zero-padded); taps never leave the input (the tables are built that way).
Accumulation is in the type of ``zero``: float32 for 8/16-bit and float32 images, float64
for float64 images. Inner loops index from 0 upwards on slices (a signed index that may be
negative costs numba a wrap-around test per load, which also stops vectorisation).
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange, types
from numba.extending import overload

from camkit._kernels.simd_resize import filter_even_odd, split_even_odd_c3, vertical_even_odd_c3


@njit(cache=True, nogil=True, error_model="numpy", fastmath={"contract"})
def _vertical_row(src, s, wrow, zero, acc) -> None:  # pragma: no cover - numba
    """acc[:] = sum_k wrow[k] src[s + k], along contiguous rows (vectorised)."""
    T = type(zero)
    L = acc.shape[0]
    for i in range(L):
        acc[i] = zero
    for k in range(wrow.shape[0]):
        w = T(wrow[k])
        if w != 0:
            row = src[s + k]
            for i in range(L):
                acc[i] += w * row[i]


@njit(cache=True, nogil=True, error_model="numpy", fastmath={"contract"})
def _store(v, is_int, hi):  # pragma: no cover - numba
    """Round half up and saturate for integer outputs (the store truncates); floats pass.
    min/max in v's own type: comparisons against a float64 bound, with branches, cost 3x."""
    if is_int:
        T = type(v)
        return min(max(v + T(0.5), T(0.0)), T(hi))
    return v


@njit(cache=True, nogil=True, error_model="numpy", fastmath={"contract"})
def _horizontal_row(row, starts, weights, C, zero, is_int, hi, orow, c0, c1) -> None:  # pragma: no cover - numba
    """orow[c * C + ch] = sum_k w[c, k] row[(starts[c] + k) * C + ch] for c in [c0, c1), one
    row, flat."""
    T = type(zero)
    K = weights.shape[1]
    for c in range(c0, c1):
        seg = row[starts[c] * C:]
        wr = weights[c]
        if C == 3:
            a0 = zero
            a1 = zero
            a2 = zero
            for k in range(K):
                w = T(wr[k])
                a0 += w * seg[3 * k]
                a1 += w * seg[3 * k + 1]
                a2 += w * seg[3 * k + 2]
            orow[3 * c] = _store(a0, is_int, hi)
            orow[3 * c + 1] = _store(a1, is_int, hi)
            orow[3 * c + 2] = _store(a2, is_int, hi)
        else:
            for ch in range(C):
                a = zero
                for k in range(K):
                    a += T(wr[k]) * seg[C * k + ch]
                orow[C * c + ch] = _store(a, is_int, hi)


@njit(cache=True, nogil=True, error_model="numpy", fastmath={"contract"})
def _horizontal_row_eo(eo, odd_at, starts, weights, zero, is_int, hi, orow, c0, c1, scale) -> None:  # pragma: no cover
    """``_horizontal_row`` for 3 channels from a row split into its even pixels (pixel 2q at
    eo[3q]) and its odd ones (pixel 2q + 1 at eo[odd_at + 3q]), each sum times ``scale`` (a
    power of two: 1/256 for rows stored times 256; exact, so the same bytes)."""
    T = type(zero)
    K = weights.shape[1]
    for c in range(c0, c1):
        wr = weights[c]
        a0 = zero
        a1 = zero
        a2 = zero
        for k in range(K):
            p = starts[c] + k
            d = 3 * (p >> 1) + (odd_at if p & 1 else 0)
            w = T(wr[k])
            a0 += w * eo[d]
            a1 += w * eo[d + 1]
            a2 += w * eo[d + 2]
        orow[3 * c] = _store(a0 * scale, is_int, hi)
        orow[3 * c + 1] = _store(a1 * scale, is_int, hi)
        orow[3 * c + 2] = _store(a2 * scale, is_int, hi)


def _is_uint8(a) -> bool:  # pragma: no cover - numba only
    """Whether ``a`` is a uint8 array, as a compile-time constant. numba only."""
    raise NotImplementedError("_is_uint8 is compiled by numba only")


@overload(_is_uint8, jit_options={"cache": True})
def _is_uint8_impl(a):
    u8 = isinstance(a, types.Array) and a.dtype == types.uint8
    return (lambda a: True) if u8 else (lambda a: False)


def make_vertical_horizontal(KY: int, KX: int, C: int, STEP: int):
    """The shrinking kernel (both passes per output row) for KY vertical taps, C channels and,
    with KX > 0, a shared row of KX horizontal weights for the outputs away from the borders,
    every STEP input pixels (STEP = 0: the ``step`` argument).
    The tap and channel counts are compile-time constants, so the tap loops unroll and the
    loops over a row, the innermost ones, vectorise with the taps in registers. With a known
    STEP, each iteration makes two output rows, converting each input byte once for both
    (four rows at once did not vectorise).
    RGB halving (C = 3, STEP = 2): each vertical sum is split into its even and its odd pixels
    (``split_even_odd_c3``, explicit SIMD), so the horizontal filter runs at the output rate
    along both halves, unit-stride, storing straight into the output row: half the FMAs of the
    full-rate filter and no strided pick.
    uint8 RGB halving, explicit SIMD (``vertical_even_odd_c3``, ``filter_even_odd``): four
    output rows per iteration, their 14 input rows converted once for all four, the sums
    stored already split into even and odd pixels (no row of sums written, read back and
    split); the horizontal filter loads its weights once per row, adds from +0.5 and narrows
    to bytes with saturating packs (no float clamp, no per-vector test of ``is_int``). Same
    sums in the same order, so the same bytes.
    With Keys' a = -0.5 weights (the default bicubic halving, away from the borders) and AVX2,
    those sums are exact integer sums (``vsum_eo_u8c3_keys2``: the weights factor as
    [1, 3, 3, 1] * [-3, 0, 38, 0, -3] / 256), stored times 256; the horizontal weights (and
    the border outputs' sums) are then taken over 256; the same bytes as the float sums.
    Measurements of each step: benchmarks/notes.md.
    Rows near the borders, whose input windows are not STEP apart, and other dtypes take the
    two-row and one-row loops and the split."""
    EO = int(C == 3 and STEP == 2 and KX > 0)
    GROUP = (4 if EO else 2) if STEP > 0 else 1

    @njit(cache=True, nogil=True, parallel=True, error_model="numpy", fastmath={"contract"})
    def kernel(src, sy, wy, sx, wx, zero, is_int, hi, out, pw, step, first, c0, c1):  # pragma: no cover - numba
        """src (H_in, W_in * C), out (H_out, W_out, C). Per output row: the vertical sum into
        a row buffer; then, for outputs c0..c1-1 (which share the weights ``pw`` and start at
        ``step * c + first``), the horizontal filter at the full input rate along that
        buffer (``step`` times the work of the decimated sum, but SIMD-wide), read every
        ``step`` pixels; the table ``sx, wx`` serves the other outputs."""
        T = type(zero)
        L = src.shape[1]
        Wo = out.shape[1]
        v = np.empty(max(KX, 1), type(zero))  # the shared horizontal weights, once per call
        for k in range(KX):
            v[k] = T(pw[k])
        # for sums stored times 256 (the uint8 halving's exact integer sums): the same weights
        # over 256, a power of two, so the products and the bytes out are the same
        v256 = v * T(1.0 / 256.0)
        G = GROUP if EO and _is_uint8(src) else min(GROUP, 2)  # output rows per iteration
        Ho = out.shape[0]
        n_even = (L // 3 + 1) // 2
        for jj in prange((Ho + G - 1) // G):
            j = G * jj
            nrows = min(G, Ho - j)
            w = np.empty((G, KY), type(zero))
            for t in range(nrows):
                for k in range(KY):
                    w[t, k] = T(wy[j + t, k])
            s = sy[j]
            eo = np.empty((G if EO else 0, L), type(zero))  # per row: the even pixels, then the odd
            regular = nrows == G
            for t in range(1, nrows):
                regular = regular and sy[j + t] == s + t * STEP
            # uint8 RGB halving: G rows summed at once, each input byte converted once for all,
            # and stored split into even and odd pixels (no row of sums to split afterwards)
            scale = np.float32(0.0)  # what the fused sums were stored times (0: not fused)
            if EO and c0 < c1 and regular:
                scale = vertical_even_odd_c3(src, s, w, eo, C * n_even, KY, STEP, GROUP)
            fused = scale > 0
            vt = v256 if scale == 256 else v
            acc = np.empty((G, 0 if fused else L), type(zero))  # rows of sums, where not fused
            if fused:
                pass  # the sums are in eo
            elif G == 2 and nrows == 2 and sy[j + 1] == s + STEP:
                # Two output rows from the KY + STEP input rows they span: each input value
                # is converted once for both (the conversions, not the FMAs, bound this loop)
                w0 = w[0]
                w1 = w[1]
                acc0 = acc[0]
                acc1 = acc[1]
                for i in range(L):
                    a0 = zero
                    a1 = zero
                    for k in range(KY + STEP):
                        x = T(src[s + k, i])
                        if k < KY:
                            a0 += w0[k] * x
                        if k >= STEP:
                            a1 += w1[k - STEP] * x
                    acc0[i] = a0
                    acc1[i] = a1
            else:  # one row at a time (near the borders; uint8 RGB groups of 4 that are not regular)
                for t in range(nrows):
                    st = sy[j + t]
                    wt = w[t]
                    acct = acc[t]
                    for i in range(L):
                        a = zero
                        for k in range(KY):
                            a += wt[k] * src[st + k, i]
                        acct[i] = a
            stp = STEP if STEP > 0 else step
            n = (stp * (c1 - 1 - c0) + 1) * C if KX > 0 and c0 < c1 and not EO else 0
            full = np.empty(n, type(zero))  # the full-rate row, shared by the rows made here
            if EO:
                # tap k of output c0 is pixel 2 c0 + first + k: even taps in one half, odd in
                # the other, at consecutive pixels
                sa = first
                sb = first + 1
                a0 = C * (c0 + sa // 2) + (C * n_even if sa % 2 else 0)
                b0 = C * (c0 + sb // 2) + (C * n_even if sb % 2 else 0)
            for t in range(nrows):
                acct = acc[t]
                orow = out[j + t].reshape(-1)
                if EO and c0 < c1:
                    eot = eo[t]
                    if not fused:
                        split_even_odd_c3(acct, L // 3, eot, C * n_even)
                    ea = eot[a0:]
                    eb = eot[b0:]
                    o = orow[c0 * C:]
                    nc = (c1 - c0) * C
                    for i in range(filter_even_odd(ea, eb, vt, o, nc, KX), nc):
                        a = zero
                        for m in range(KX // 2):
                            a += vt[2 * m] * ea[i + 3 * m] + vt[2 * m + 1] * eb[i + 3 * m]
                        if KX % 2:
                            a += vt[KX - 1] * ea[i + 3 * (KX // 2)]
                        o[i] = _store(a, is_int, hi)
                    inv = T(1.0 / 256.0) if scale == 256 else T(1.0)
                    _horizontal_row_eo(eot, C * n_even, sx, wx, zero, is_int, hi, orow, 0, c0, inv)
                    _horizontal_row_eo(eot, C * n_even, sx, wx, zero, is_int, hi, orow, c1, Wo, inv)
                elif KX > 0 and c0 < c1:
                    seg = acct[(stp * c0 + first) * C:]
                    for i in range(n):
                        a = zero
                        for k in range(KX):
                            a += v[k] * seg[i + k * C]
                        full[i] = a
                    o = orow[c0 * C:]
                    sC = stp * C
                    for c in range(c1 - c0):
                        for ch in range(C):
                            o[c * C + ch] = _store(full[c * sC + ch], is_int, hi)
                    _horizontal_row(acct, sx, wx, C, zero, is_int, hi, orow, 0, c0)
                    _horizontal_row(acct, sx, wx, C, zero, is_int, hi, orow, c1, Wo)
                else:
                    _horizontal_row(acct, sx, wx, C, zero, is_int, hi, orow, 0, Wo)

    return kernel


@njit(cache=True, nogil=True, parallel=True, error_model="numpy", fastmath={"contract"})
def vertical_horizontal(src: np.ndarray, sy: np.ndarray, wy: np.ndarray, sx: np.ndarray, wx: np.ndarray, zero,
                        is_int: bool, hi: float, out: np.ndarray) -> None:  # pragma: no cover - numba
    """Both passes per output row from the tables (any tap count): the vertical sum of src
    (H_in, W_in * C) into a row buffer, then the horizontal pass into out (H_out, W_out, C)."""
    L = src.shape[1]
    C = out.shape[2]
    for j in prange(out.shape[0]):
        acc = np.full(L, zero)
        _vertical_row(src, sy[j], wy[j], zero, acc)
        _horizontal_row(acc, sx, wx, C, zero, is_int, hi, out[j].reshape(-1), 0, out.shape[1])


def make_horizontal_vertical(KX: int, KY: int, C: int, P: int, Q: int):
    """The kernel for resizes that do not shrink vertically (each input row filtered
    horizontally once, into a ring of KY + 1 rows; each output row the vertical sum of KY of
    them), for KY vertical taps, C channels and, with P > 0, KX horizontal taps that repeat
    with period P outputs per Q inputs (an enlargement by P/Q, e.g. 3/2).

    The periodic outputs are computed polyphase: for each phase p, the KX-tap filter of that
    phase runs at the full input rate along the row (contiguous, SIMD-wide: Q times the
    decimated work, 8 lanes at a time), and the outputs of the phase are read every Q input
    pixels; the weight table serves the outputs near the borders. The vertical sum of the KY
    ring rows is unrolled for 1, 2, 4 and 6 taps (the kernels' supports when not shrinking),
    with the rounding store in the same loop (against the table-driven passes it replaces:
    benchmarks/notes.md)."""

    @njit(cache=True, nogil=True, parallel=True, error_model="numpy", fastmath={"contract"})
    def kernel(src, sy, wy, sx, wx, pw, pfirst, c0, M, zero, is_int, hi, out, n_strips):  # pragma: no cover - numba
        """src (H_in, W_in * C), out (H_out, W_out, C); outputs c0 + P m + p (m < M) start at
        input ``pfirst[p] + Q m`` with weights ``pw[p]``; the table ``sx, wx`` serves the
        others. Output rows are cut into ``n_strips`` strips run in parallel, each with its own
        ring (``sy`` never decreases, so a row leaves the ring only once no later output row of
        the strip needs it; a strip's first KY - 1 rows are filtered twice)."""
        T = type(zero)
        H_out = out.shape[0]
        Wo = out.shape[1]
        L = Wo * C
        R = KY + 1
        v = np.empty((max(P, 1), max(KX, 1)), type(zero))
        for p in range(P):
            for k in range(KX):
                v[p, k] = T(pw[p, k])
        n = (Q * (M - 1) + 1) * C if M > 0 else 0
        for s in prange(n_strips):
            j0 = (H_out * s) // n_strips
            j1 = (H_out * (s + 1)) // n_strips
            ring = np.empty((R, L), type(zero))
            full = np.empty((max(P, 1), n), type(zero))
            rf = np.empty(src.shape[1], type(zero))
            w = np.empty(KY, type(zero))
            nxt = sy[j0]
            for j in range(j0, j1):
                while nxt < sy[j] + KY:
                    row = src[nxt]
                    for i in range(row.shape[0]):
                        rf[i] = row[i]
                    rr = ring[nxt % R]
                    for p in range(P):
                        seg = rf[pfirst[p] * C:]
                        f = full[p]
                        for i in range(n):
                            a = zero
                            for k in range(KX):
                                a += v[p, k] * seg[i + k * C]
                            f[i] = a
                    if M > 0:
                        o = rr[c0 * C:]
                        for m in range(M):
                            for p in range(P):
                                for ch in range(C):
                                    o[(P * m + p) * C + ch] = full[p, Q * m * C + ch]
                    _horizontal_row(rf, sx, wx, C, zero, False, 0.0, rr, 0, c0)
                    _horizontal_row(rf, sx, wx, C, zero, False, 0.0, rr, c0 + P * M, Wo)
                    nxt += 1
                for k in range(KY):
                    w[k] = T(wy[j, k])
                b = sy[j]
                orow = out[j].reshape(-1)
                if KY == 1:
                    r0 = ring[b % R]
                    w0 = w[0]
                    for i in range(L):
                        orow[i] = _store(w0 * r0[i], is_int, hi)
                elif KY == 2:
                    r0 = ring[b % R]
                    r1 = ring[(b + 1) % R]
                    w0 = w[0]
                    w1 = w[1]
                    for i in range(L):
                        orow[i] = _store(w0 * r0[i] + w1 * r1[i], is_int, hi)
                elif KY == 4:
                    r0 = ring[b % R]
                    r1 = ring[(b + 1) % R]
                    r2 = ring[(b + 2) % R]
                    r3 = ring[(b + 3) % R]
                    w0 = w[0]
                    w1 = w[1]
                    w2 = w[2]
                    w3 = w[3]
                    for i in range(L):
                        orow[i] = _store(w0 * r0[i] + w1 * r1[i] + w2 * r2[i] + w3 * r3[i], is_int, hi)
                elif KY == 6:
                    r0 = ring[b % R]
                    r1 = ring[(b + 1) % R]
                    r2 = ring[(b + 2) % R]
                    r3 = ring[(b + 3) % R]
                    r4 = ring[(b + 4) % R]
                    r5 = ring[(b + 5) % R]
                    w0 = w[0]
                    w1 = w[1]
                    w2 = w[2]
                    w3 = w[3]
                    w4 = w[4]
                    w5 = w[5]
                    for i in range(L):
                        a = w0 * r0[i] + w1 * r1[i] + w2 * r2[i] + w3 * r3[i] + w4 * r4[i] + w5 * r5[i]
                        orow[i] = _store(a, is_int, hi)
                else:
                    for i in range(L):
                        a = zero
                        for k in range(KY):
                            a += w[k] * ring[(b + k) % R, i]
                        orow[i] = _store(a, is_int, hi)

    return kernel
