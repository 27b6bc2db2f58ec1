"""Remap and warps: out[r, c] = image sampled at (x, y) = coords(r, c), for every channel.

One kernel body, specialised by a factory per interpolation method (so the tap count is a
compile-time constant: loops unroll, weights stay in registers) and per source of
coordinates: a map array, or an affine or perspective matrix evaluated on the fly. Pixels whose taps all fall
inside the image take a fast path with the channel count specialised for 3; the rest go
through border handling. Accumulation is in the type of ``zero`` (float32 for 8/16-bit and
float32 images, float64 for float64 images).
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange, types
from numba.extending import overload

from camkit._kernels.interp import border_index, lanczos3, sat, store
from camkit._kernels.simd_gather import (
    blend_rgb,
    blend_rgb_at,
    blend_scalar_c3,
    lerp_u8c3,
    lerp_u8c3_wide,
    offset_i32,
    span,
    unzip_xy,
)

# Each tapsN(x, a) returns the first tap's index and the N weights (summing to 1) for a
# coordinate x; np.floor keeps x's float type, so float32 maps are computed in float32.


@njit(cache=True, nogil=True, error_model="numpy")
def taps1(x, a):  # pragma: no cover - numba
    return int(np.floor(x + type(x)(0.5))), (type(x)(1.0),)


@njit(cache=True, nogil=True, error_model="numpy")
def taps2(x, a):  # pragma: no cover
    f = np.floor(x)
    t = x - f
    return int(f), (type(x)(1.0) - t, t)


@njit(cache=True, nogil=True, error_model="numpy")
def keys4(t, a):  # pragma: no cover
    """Keys' kernel at t+1, t, 1-t, 2-t for t in [0, 1), in the type of t, expanded into
    branch-free polynomials: a t (1-t)^2, (a+2) t^3 - (a+3) t^2 + 1, the same at 1-t,
    a t^2 (1-t) (R. Keys, IEEE Trans. ASSP 29(6), 1981)."""
    F = type(t)
    a = F(a)
    one = F(1.0)
    u = one - t
    b = a + F(2.0)
    c = a + F(3.0)
    return a * t * u * u, (b * t - c) * t * t + one, (b * u - c) * u * u + one, a * t * t * u


@njit(cache=True, nogil=True, error_model="numpy")
def taps4(x, a):  # pragma: no cover
    f = np.floor(x)
    return int(f) - 1, keys4(np.float64(x - f), a)


@njit(cache=True, nogil=True, error_model="numpy")
def taps6(x, a):  # pragma: no cover
    f = np.floor(x)
    t = np.float64(x - f)
    w0 = lanczos3(t + 2.0)
    w1 = lanczos3(t + 1.0)
    w2 = lanczos3(t)
    w3 = lanczos3(1.0 - t)
    w4 = lanczos3(2.0 - t)
    w5 = lanczos3(3.0 - t)
    s = 1.0 / (w0 + w1 + w2 + w3 + w4 + w5)
    return int(f) - 2, (w0 * s, w1 * s, w2 * s, w3 * s, w4 * s, w5 * s)


@njit(cache=True, nogil=True, error_model="numpy")
def from_map(mp, r, c):  # pragma: no cover
    # Coordinates stay in the map's dtype: the fractional part of a float32 is exact, so
    # nothing is lost that the map itself had.
    return mp[r, c, 0], mp[r, c, 1]


@njit(cache=True, nogil=True, error_model="numpy")
def from_affine(A, r, c):  # pragma: no cover
    """A: 2x3, src_from_dst."""
    return A[0, 0] * c + A[0, 1] * r + A[0, 2], A[1, 0] * c + A[1, 1] * r + A[1, 2]


@njit(cache=True, nogil=True, error_model="numpy")
def from_perspective(P, r, c):  # pragma: no cover
    """P: 3x3 homography, src_from_dst; w <= 0 (behind the horizon) gives NaN."""
    w = P[2, 0] * c + P[2, 1] * r + P[2, 2]
    if not (w > 0.0):
        return np.nan, np.nan
    iw = 1.0 / w
    return (P[0, 0] * c + P[0, 1] * r + P[0, 2]) * iw, (P[1, 0] * c + P[1, 1] * r + P[1, 2]) * iw


def taps(x, a, n):  # pragma: no cover - numba only
    """taps1, taps2, taps4 or taps6 by ``n``, a compile-time constant (chosen while typing)."""
    raise NotImplementedError("numba only")


@overload(taps, prefer_literal=True, jit_options={"cache": True})
def _taps(x, a, n):
    if isinstance(n, types.IntegerLiteral):
        impl = {1: taps1, 2: taps2, 4: taps4, 6: taps6}[n.literal_value]
        return lambda x, a, n: impl(x, a)
    return None


def coords(mp, r, c, kind):  # pragma: no cover - numba only
    """The source position of output pixel (r, c): from_map, from_affine or from_perspective by
    ``kind`` (0, 1, 2), a compile-time constant (chosen while typing)."""
    raise NotImplementedError("numba only")


@overload(coords, prefer_literal=True, jit_options={"cache": True})
def _coords(mp, r, c, kind):
    if isinstance(kind, types.IntegerLiteral):
        impl = (from_map, from_affine, from_perspective)[kind.literal_value]
        return lambda mp, r, c, kind: impl(mp, r, c)
    return None


def _make(N: int, KIND: int, RGB: int = 0):
    """The kernel for N taps (1, 2, 4, 6) and a source of coordinates (KIND: 0 map, 1 affine,
    2 perspective); RGB = 1: for 3-channel images only. The closure captures plain ints only:
    numba prunes the branches on them before typing, and its on-disk cache recognises the
    kernels in a new process (closures over functions get a fresh cache key in every process,
    so they recompile).
    For 3 channels, the pixels with every tap inside take ``blend_rgb`` (explicit SIMD for
    uint8; see camkit._kernels.simd_gather) where its vector loads stay inside the image; the rest are
    listed and go through the border rules after the row, out of the hot loop. The channel
    count known at compile time (RGB = 1) leaves the general channel loop out of the kernel.
    Bicubic on 3 channels (RGB = 1, N = 4) runs each row in two phases: phase 1, branch-free
    so that it vectorises, turns the row's positions into offsets and float32 weights (in the
    positions' type: float32 for float32 maps); phase 2 blends the pixels with every tap
    inside (``blend_rgb_at``) and lists the others for the border rules. Measurements:
    benchmarks/notes.md."""
    SPAN = span(N, 3)  # bytes blend_rgb reads from each row's first tap
    TWO = RGB == 1 and N == 4

    @njit(cache=True, nogil=True, parallel=True, error_model="numpy")
    def remap_kernel(img, mp, a, border, fill, is_int, lo, hi, zero, out):  # pragma: no cover
        H, W = img.shape[0], img.shape[1]
        if RGB:
            C = 3
        else:
            C = img.shape[2]
        Ho, Wo = out.shape[0], out.shape[1]
        half = zero + 0.5
        hi_t = zero + hi
        flat = img.reshape(-1)  # img and out are C-contiguous
        oflat = out.reshape(-1)
        n_flat = flat.shape[0]
        W3 = W * 3
        last = n_flat - (N - 1) * W3 - SPAN  # the last first-tap offset with room for the vector loads
        for r in prange(Ho):
            todo = np.empty(Wo, np.int64)  # the pixels for the border rules, after the row
            n_todo = 0
            if TWO:
                off = np.empty(Wo, np.int64)
                ok = np.empty(Wo, np.bool_)
                wxs = np.empty((Wo, N), np.float32)
                wys = np.empty((Wo, N), np.float32)
                if KIND == 0:  # the row's x and y apart, so that the loop below reads them unit-stride
                    xs = np.empty(Wo, mp.dtype)
                    ys = np.empty(Wo, mp.dtype)
                    unzip_xy(mp.reshape(-1), 2 * r * Wo, Wo, xs, ys)
                for c in range(Wo):
                    if KIND == 0:
                        x, y = xs[c], ys[c]
                    else:
                        x, y = coords(mp, r, c, KIND)
                    F = type(x)
                    fx = np.floor(x)
                    fy = np.floor(y)
                    # every tap inside (False for NaN); the others get harmless stand-ins
                    inside = (fx >= F(1)) & (fy >= F(1)) & (fx < F(W - 2)) & (fy < F(H - 2))
                    gx = fx if inside else F(1)
                    gy = fy if inside else F(1)
                    o = (np.int64(gy) - 1) * W3 + (np.int64(gx) - 1) * 3
                    ok[c] = inside & (o <= last)
                    off[c] = o
                    w0, w1, w2, w3 = keys4(x - gx, a)
                    wxs[c, 0], wxs[c, 1], wxs[c, 2], wxs[c, 3] = w0, w1, w2, w3
                    w0, w1, w2, w3 = keys4(y - gy, a)
                    wys[c, 0], wys[c, 1], wys[c, 2], wys[c, 3] = w0, w1, w2, w3
                for c in range(Wo):
                    if ok[c]:
                        blend_rgb_at(flat, off[c], W3, wxs, wys, c, N, zero, is_int, hi_t, oflat, (r * Wo + c) * 3)
                    else:
                        todo[n_todo] = c
                        n_todo += 1
            for c in range(0 if TWO else Wo):
                x, y = coords(mp, r, c, KIND)
                # near the image (False for NaN), so the tap indices below are plain integers
                if not ((x > -N) & (x < W + N) & (y > -N) & (y < H + N)):
                    todo[n_todo] = c
                    n_todo += 1
                    continue
                x0, wx = taps(x, a, N)
                y0, wy = taps(y, a, N)
                base = y0 * W3 + x0 * 3
                if C == 3 and x0 >= 0 and y0 >= 0 and x0 + N <= W and y0 + N <= H:
                    if base <= last:  # room for the vector loads of blend_rgb
                        blend_rgb(flat, base, W3, wx, wy, zero, is_int, hi_t, oflat, (r * Wo + c) * 3)
                    else:
                        blend_scalar_c3(flat, base, W3, wx, wy, zero, is_int, hi_t, oflat, (r * Wo + c) * 3)
                elif C != 3 and x0 >= 0 and y0 >= 0 and x0 + N <= W and y0 + N <= H:
                    for ch in range(C):
                        acc = zero
                        for j in range(N):
                            for k in range(N):
                                acc += type(zero)(wy[j] * wx[k]) * img[y0 + j, x0 + k, ch]
                        if is_int:
                            out[r, c, ch] = sat(acc + half, hi_t)
                        else:
                            out[r, c, ch] = acc
                else:
                    todo[n_todo] = c
                    n_todo += 1
            for i in range(n_todo):  # taps outside the image, NaN or far away
                c = todo[i]
                x, y = coords(mp, r, c, KIND)
                far = not (abs(x) < 1e9 and abs(y) < 1e9)  # NaN, inf or absurdly far: fill
                if not far:
                    x0, wx = taps(x, a, N)
                    y0, wy = taps(y, a, N)
                    # every tap outside a constant border: fill
                    far = border == 0 and (x0 + N <= 0 or y0 + N <= 0 or x0 >= W or y0 >= H)
                if far:
                    for ch in range(C):
                        out[r, c, ch] = store(fill[ch], is_int, lo, hi)
                    continue
                for ch in range(C):
                    acc = 0.0
                    for j in range(N):
                        yy = border_index(y0 + j, H, border)
                        for k in range(N):
                            xx = border_index(x0 + k, W, border)
                            w = wy[j] * wx[k]
                            if yy < 0 or xx < 0:
                                acc += w * fill[ch]
                            else:
                                acc += w * img[yy, xx, ch]
                    out[r, c, ch] = store(acc, is_int, lo, hi)

    return remap_kernel


@njit(cache=True, nogil=True, error_model="numpy")
def border_bilinear(img, x, y, border, fill, ch):  # pragma: no cover
    """One channel at (x, y), bilinear, with taps that may leave the image (the slow path)."""
    H, W = img.shape[0], img.shape[1]
    fx = np.floor(x)
    fy = np.floor(y)
    tx = x - fx
    ty = y - fy
    x0 = int(fx)
    y0 = int(fy)
    acc = 0.0
    for j in range(2):
        yy = border_index(y0 + j, H, border)
        wj = ty if j else 1.0 - ty
        for k in range(2):
            xx = border_index(x0 + k, W, border)
            w = wj * (tx if k else 1.0 - tx)
            acc += w * (fill[ch] if (yy < 0 or xx < 0) else img[yy, xx, ch])
    return acc


@njit(cache=True, nogil=True, error_model="numpy")
def border_pixel_u8c3(img, x, y, border, fill, px):  # pragma: no cover
    """One uint8 RGB output pixel ``px`` at (x, y), bilinear, through the border rules."""
    H, W = img.shape[0], img.shape[1]
    # NaN, far away, or (constant border) every tap outside: the fill value.
    far = not (abs(x) < 1e9 and abs(y) < 1e9) or (
        border == 0 and (x <= -1.0 or y <= -1.0 or x >= W or y >= H))
    for ch in range(3):
        if far:
            v = fill[ch]
        else:
            v = border_bilinear(img, np.float64(x), np.float64(y), border, fill, ch)
        px[ch] = store(v, True, 0.0, 255.0)


def _make_bilinear_u8c3(KIND: int, TR: int = 32, TC: int = 128):
    """uint8 RGB, bilinear: the common case, in two phases per row. Phase 1 turns
    coordinates into int32 flat offsets and the fractional positions (vectorised; a map's row
    is first split into its x and y planes by ``unzip_xy``: read in place, at a stride of two
    floats, LLVM left the loop scalar); phase 2 gathers and blends each pixel with
    ``lerp_u8c3`` (explicit SIMD, float32, two lerps; before it ``blend_u8c3``'s weighted sum,
    and before that 11-bit fixed-point scalar code); offsets are multiplied in 32 bits
    (``offset_i32``; numba's int32 products are int64). For a map, the pixels whose taps leave
    the image (or whose vector loads would) take the border rules after phase 2, out of its
    loop, which then keeps its constants in registers; for the warps, phase 2 writes the fill
    value and the pixels that need the border rules are redone by a second kernel, ``fix``
    (that slow path anywhere in the warps' first kernel, even in a loop of its own, slowed
    it). Measurements: benchmarks/notes.md."""

    @njit(cache=True, nogil=True, parallel=True, error_model="numpy")
    def main(img, mp, border, fill, fill_far, todo_all, row_ok, out):  # pragma: no cover
        H, W = img.shape[0], img.shape[1]
        flat = img.reshape(-1)
        W3 = W * 3
        Ho, Wo = out.shape[0], out.shape[1]
        oflat = out.reshape(-1)  # out is C-contiguous
        last = flat.shape[0] - W3 - 8  # the last first-tap offset with room for lerp_u8c3's loads
        last32 = np.int32(last)
        W3_32 = np.int32(W3)
        # The matrix's entries as scalars (loads from mp inside the loop would be repeated:
        # the compiler cannot tell that the stores below leave mp alone).
        m00 = m01 = m02 = m10 = m11 = m12 = m20 = m21 = m22 = 0.0
        if KIND != 0:
            m00, m01, m02 = mp[0, 0], mp[0, 1], mp[0, 2]
            m10, m11, m12 = mp[1, 0], mp[1, 1], mp[1, 2]
        if KIND == 2:
            m20, m21, m22 = mp[2, 0], mp[2, 1], mp[2, 2]
        F32 = np.float32
        ALL_OK = np.uint64(0x0101010101010101)  # 8 True bools read as one word
        f0, f1, f2 = np.uint8(fill_far[0]), np.uint8(fill_far[1]), np.uint8(fill_far[2])
        no_far = fill_far[3] == 0
        # Warps: tiles of TR rows x TC columns, so that a rotated warp's taps (one output row
        # crosses ~80 input rows at 1 degree over 4000 px) stay in cache while a tile is made;
        # 32x128 measured best (benchmarks/notes.md). The map (near the identity) runs whole
        # rows (tiling it measured no gain).
        tc = TC if KIND != 0 else Wo
        for b in prange((Ho + TR - 1) // TR):
            r0 = b * TR
            r1 = min(r0 + TR, Ho)
            off = np.empty(tc, np.uint32)
            if KIND == 0:
                xs = np.empty(tc, mp.dtype)
                ys = np.empty(tc, mp.dtype)
            wx = np.empty(tc, np.float32)
            wy = np.empty(tc, np.float32)
            ok = np.empty(tc, np.bool_)
            nd = np.empty((TR, Wo), np.bool_)
            for cs in range(0, Wo, tc):
                n = min(tc, Wo - cs)
                for r in range(r0, r1):
                    nds = nd[r - r0, cs:cs + n]
                    # The row's constant terms in float64, the per-pixel arithmetic of the warps
                    # in float32 (8 lanes, not 4, and float32 -> int32 conversions, which AVX2 has
                    # packed). Positions are then within ~5e-4 px of the float64 ones at 4000 px.
                    bx = F32(m01 * r + m02)
                    by = F32(m11 * r + m12)
                    bw = F32(m21 * r + m22)
                    # Phase 1, branch-free (selects, so it vectorises): a pixel whose taps leave
                    # the image (or NaN) gets offset 0 and weights 0 and is not ok; phase 2 takes
                    # it through the border rules (map) or gives it the fill value, which fix
                    # replaces where the border rules apply (nd; warps).
                    if KIND == 0:
                        unzip_xy(mp.reshape(-1), 2 * (r * Wo + cs), n, xs, ys)
                    for i in range(n):
                        c = cs + i
                        if KIND == 0:
                            x, y = xs[i], ys[i]
                        elif KIND == 1:
                            x = F32(m00) * F32(c) + bx
                            y = F32(m10) * F32(c) + by
                        else:
                            # as from_perspective, with a select for w <= 0 (NaN), not a branch
                            w = F32(m20) * F32(c) + bw
                            iw = F32(1.0) / w
                            iw = iw if w > F32(0.0) else F32(np.nan)
                            x = (F32(m00) * F32(c) + bx) * iw
                            y = (F32(m10) * F32(c) + by) * iw
                        F = type(x)
                        fx = np.floor(x)
                        fy = np.floor(y)
                        inside = (fx >= F(0)) & (fy >= F(0)) & (fx < F(W - 1)) & (fy < F(H - 1))  # NaN: no
                        gx = fx if inside else F(0)
                        gy = fy if inside else F(0)
                        # Maps: phase 2 takes every pixel outside through the border rules itself.
                        # Warps: phase 2 writes the fill value where it is right (NaN or, for a
                        # constant border, every tap outside), fix does the rest. Offsets in
                        # int32 (the caller keeps images below 2^31 bytes), stored unsigned;
                        # lerp_u8c3 reads 8 bytes from each row's first tap: inside the image.
                        o32 = offset_i32(np.int32(gy), np.int32(gx), W3_32)
                        inside = inside & (o32 <= last32)
                        off[i] = np.uint32(o32)
                        if KIND != 0:
                            far = not ((x > F(-1.0)) & (y > F(-1.0)) & (x < F(W)) & (y < F(H)))
                            nds[i] = (not inside) & (no_far | (not far))
                        ok[i] = inside
                        wx[i] = np.float32(x - gx)
                        wy[i] = np.float32(y - gy)
                    orow = out[r, cs:cs + n]
                    row0 = (r * Wo + cs) * 3
                    for i in range(n):
                        if ok[i] and i < n - 1:  # pixel i + 1 comes next: 4 bytes stored in one
                            lerp_u8c3_wide(flat, off[i], W3, wx[i], wy[i], oflat, row0 + 3 * i)
                        elif ok[i]:
                            lerp_u8c3(flat, off[i], W3, wx[i], wy[i], oflat, row0 + 3 * i)
                        elif KIND != 0:  # the fill value (fix overwrites it where the border rules apply)
                            orow[i, 0] = f0
                            orow[i, 1] = f1
                            orow[i, 2] = f2
                    if KIND == 0:  # the map's other pixels through the border rules, 8 ok flags at a time
                        nw = n // 8
                        words = ok[:8 * nw].view(np.uint64)
                        for w in range(nw + 1):  # w = nw: the last n % 8
                            if w < nw and words[w] == ALL_OK:
                                continue
                            for i in range(8 * w, min(8 * w + 8, n)):
                                if not ok[i]:
                                    border_pixel_u8c3(img, xs[i], ys[i], border, fill, orow[i])
            for r in range(r0, r1):
                if KIND == 0:
                    row_ok[r] = True
                else:
                    row_ok[r] = not nd[r - r0].any()
                    if not row_ok[r]:
                        todo_all[r] = nd[r - r0]

    @njit(cache=True, nogil=True, parallel=True, error_model="numpy")
    def fix(img, mp, border, fill, todo_all, row_ok, out):  # pragma: no cover
        """The pixels ``main`` marked in ``todo_all`` (taps partly outside the image, or any
        outside for the replicate and reflect borders), through the border rules."""
        for r in prange(out.shape[0]):
            if row_ok[r]:
                continue
            orow = out[r]
            mark = todo_all[r]
            Wo = out.shape[1]
            nw = Wo // 8
            words = mark[:8 * nw].view(np.uint64)  # 8 pixels at a time: most words are 0
            for w in range(nw + 1):  # w = nw: the last Wo % 8 pixels
                if w < nw and words[w] == 0:
                    continue
                for c in range(8 * w, min(8 * w + 8, Wo)):
                    if mark[c]:
                        x, y = coords(mp, r, c, KIND)
                        border_pixel_u8c3(img, x, y, border, fill, orow[c])

    def kernel(img, mp, a, border, fill, is_int, lo, hi, zero, out):
        """The signature of the other kernels. ``todo`` (1 byte per output pixel) is written
        only for rows with pixels that need the border rules."""
        todo = np.empty(out.shape[:2], np.bool_)
        row_ok = np.empty(out.shape[0], np.bool_)
        # the fill value as stored, and whether pixels with every tap outside may take it
        fill_far = np.array([store(f, True, 0.0, 255.0) for f in fill] + [border == 0], np.float64)
        main(img, mp, border, fill, fill_far, todo, row_ok, out)
        if KIND != 0:
            fix(img, mp, border, fill, todo, row_ok, out)

    kernel.main, kernel.fix = main, fix

    return kernel


_N_TAPS = (1, 2, 4, 6)

#: Kernels by interpolation code (0 nearest, 1 bilinear, 2 bicubic, 3 Lanczos-3), reading
#: coordinates from a map (H_out, W_out, 2), an affine 2x3 or a perspective 3x3 matrix.
REMAP = tuple(_make(n, 0) for n in _N_TAPS)
WARP_AFFINE = tuple(_make(n, 1) for n in _N_TAPS)
WARP_PERSPECTIVE = tuple(_make(n, 2) for n in _N_TAPS)

#: The same for 3-channel images (used for uint8 RGB, bicubic and Lanczos-3), by source.
RGB = {family: tuple(_make(n, kind, 1) for n in _N_TAPS)
       for kind, family in enumerate(("map", "affine", "perspective"))}

#: The uint8 RGB bilinear specialisations, by source of coordinates.
BILINEAR_U8C3 = {"map": _make_bilinear_u8c3(0), "affine": _make_bilinear_u8c3(1),
                 "perspective": _make_bilinear_u8c3(2)}


@njit(cache=True, nogil=True, parallel=True)
def touch_pages(flat):  # pragma: no cover - numba
    """Write 0 to one byte of every 4 KiB page of ``flat`` (a fresh allocation's page faults,
    on every core), in blocks of 1 MiB."""
    n = flat.shape[0]
    for b in prange((n + (1 << 20) - 1) >> 20):
        for i in range(b << 20, min(n, (b + 1) << 20), 4096):
            flat[i] = 0
