"""Explicit SIMD for the pixel gathers of remap and the warps on uint8 RGB images, and for the
split of a map's rows into x and y (``unzip_xy``).

Why LLVM IR here: numba's auto-vectoriser cannot vectorise a gather of a few neighbouring
pixels at a scattered address, so for each tap it emits one scalar byte load and one
int-to-float conversion per channel (48 of each per bicubic RGB pixel, seen in the
assembly). ``blend_u8c3`` writes the vector code itself, per output pixel:

- each of the N rows of taps is one unaligned load of ``span(N, C)`` bytes (the N pixels'
  3N bytes, rounded up to a power of two: the caller keeps the read inside the
  image), one byte shuffle into N groups of 4 lanes (R, G, B, 0), one widening to int32 and
  one conversion to float32;
- the rows are summed with their vertical weights, the sum is multiplied by the horizontal
  weights (each repeated over its 4 lanes) and the N groups are added into 4 lanes;
- +0.5, clamp to [0, 255] and truncation: round half up and saturate, as the scalar kernels
  store uint8; 3 bytes are stored.

Bilinear uint8 RGB has its own, shorter code, ``lerp_u8c3``: two lerps (rows, then the two
taps) on the 8 bytes of each row, with no weight products, no per-pixel weight vectors and no
clamp (a convex combination of bytes stays in range), storing the pixel as one 4-byte word
where the next pixel of the row overwrites the fourth byte (``lerp_u8c3_wide``).

``unzip_xy`` splits a row of an (H, W, 2) float32 map into its x and y planes with vector
shuffles: the kernels' loops over a row then read unit-stride and vectorise (read in place,
at a stride of two floats, LLVM left them scalar).

``blend_rgb`` (weights as tuples) and ``blend_rgb_at`` (weights as rows of two float32
arrays, which phase 1 of the bicubic kernel fills vectorised) are the entry points for kernels
compiled for every dtype: the SIMD code for uint8, the scalar sum for the others (identical
results up to float32 rounding). Measurements: benchmarks/notes.md.
"""

from __future__ import annotations

import numpy as np
from llvmlite import ir
from numba import njit, types
from numba.extending import intrinsic, overload

from camkit._kernels.interp import sat
from camkit._kernels.simd_ir import (
    _F32,
    _I8,
    _I32,
    _I64,
    _V,
    _is_f32_vector,
    _is_u8_vector,
    _is_weight_rows,
    _is_weights,
    _mask,
    _splat,
    _to_f32,
)


def span(n_taps: int, channels: int) -> int:
    """Bytes read per row of taps: the n_taps pixels' n_taps * channels bytes rounded up to a
    power of two (RGB: 8 for bilinear, 16 for bicubic, 32 for Lanczos-3)."""
    p = 1
    while p < n_taps * channels:
        p *= 2
    return p


def _blend_codegen(N: int, C: int, rows: bool = False):
    """The LLVM IR of one output pixel from N x N taps of a C-channel uint8 image; the weights
    are two tuples of N floats, or (rows=True) row i of two float32 arrays (n, N)."""
    B = span(N, C)
    L = 4 * N  # N pixels, 4 lanes each
    flags = ("contract",)

    def codegen(context, builder, signature, args):
        sa = signature.args
        d = 1 if rows else 0  # the arguments after wy move by one: i comes in
        src = context.make_array(sa[0])(context, builder, args[0]).data
        dst = context.make_array(sa[5 + d])(context, builder, args[5 + d]).data
        off, stride, doff = (context.cast(builder, args[i], sa[i], types.int64) for i in (1, 2, 6 + d))
        if rows:  # one vector load of the N horizontal weights, a scalar load per vertical one
            i = context.cast(builder, args[5], sa[5], types.int64)
            at = builder.mul(i, ir.Constant(_I64, N))
            wxp, wyp = (builder.gep(context.make_array(sa[k])(context, builder, args[k]).data, [at]) for k in (3, 4))
            wxv = builder.load(builder.bitcast(wxp, _V(_F32, N).as_pointer()), align=4)
            wv = builder.shuffle_vector(wxv, wxv, _mask([k for k in range(N) for _ in range(4)]))
            wy = [builder.load(builder.gep(wyp, [ir.Constant(_I64, j)]), align=4) for j in range(N)]
        else:
            wx = [_to_f32(builder, builder.extract_value(args[3], k)) for k in range(N)]
            wy = [_to_f32(builder, builder.extract_value(args[4], k)) for k in range(N)]
            wv = ir.Constant(_V(_F32, L), ir.Undefined)  # each weight over its pixel's 4 lanes
            for k in range(N):
                for ch in range(4):
                    wv = builder.insert_element(wv, wx[k], ir.Constant(_I32, 4 * k + ch))
        # byte k*C + ch of the row -> lane 4k + ch; lane 4k + 3 = 0 for RGB (index B: the zeros)
        shuffle = _mask([k * C + ch if ch < C else B for k in range(N) for ch in range(4)])
        zeros = ir.Constant(_V(_I8, B), None)
        acc = None
        for j in range(N):
            p = builder.gep(src, [builder.add(off, builder.mul(stride, ir.Constant(_I64, j)))])
            row = builder.load(builder.bitcast(p, _V(_I8, B).as_pointer()), align=1)
            lanes = builder.shuffle_vector(row, zeros, shuffle)
            f = builder.sitofp(builder.zext(lanes, _V(_I32, L)), _V(_F32, L))
            t = builder.fmul(f, _splat(builder, wy[j], L), flags=flags)
            acc = t if acc is None else builder.fadd(acc, t, flags=flags)
        acc = builder.fmul(acc, wv, flags=flags)
        parts = [builder.shuffle_vector(acc, acc, _mask(range(4 * k, 4 * k + 4))) for k in range(N)]
        while len(parts) > 1:  # pairwise sums of the N groups
            nxt = [builder.fadd(parts[i], parts[i + 1], flags=flags) for i in range(0, len(parts) - 1, 2)]
            parts = nxt + parts[len(parts) - len(parts) % 2:]
        v = builder.fadd(parts[0], ir.Constant(_V(_F32, 4), [0.5] * 4))
        lo = ir.Constant(_V(_F32, 4), [0.0] * 4)
        hi = ir.Constant(_V(_F32, 4), [255.0] * 4)
        v = builder.select(builder.fcmp_ordered("<", v, lo), lo, v)
        v = builder.select(builder.fcmp_ordered(">", v, hi), hi, v)
        px = builder.trunc(builder.fptosi(v, _V(_I32, 4)), _V(_I8, 4))
        q = builder.gep(dst, [doff])
        for ch in range(C):
            byte = builder.extract_element(px, ir.Constant(_I32, ch))
            builder.store(byte, builder.gep(q, [ir.Constant(_I64, ch)]))
        return context.get_dummy_value()

    return codegen


def _make_intrinsic(C: int):
    """blend(src, off, stride, wx, wy, dst, doff): dst[doff + ch] = the rounded, saturated sum
    over j, k of wy[j] wx[k] src[off + j * stride + k * C + ch] for ch < C, on flat uint8 arrays;
    wx, wy: tuples of N floats (N = 2, 4 or 6; float64 ones are rounded to float32). Reads
    span(N, C) bytes from each row's first tap: the caller keeps that inside ``src``."""

    @intrinsic
    def blend(typingctx, src, off, stride, wx, wy, dst, doff):
        if not (_is_u8_vector(src) and _is_u8_vector(dst) and _is_weights(wx) and _is_weights(wy)
                and wx.count == wy.count and all(isinstance(t, types.Integer) for t in (off, stride, doff))):
            return None
        sig = types.void(src, off, stride, wx, wy, dst, doff)
        return sig, _blend_codegen(wx.count, C)

    return blend


#: uint8 RGB
blend_u8c3 = _make_intrinsic(3)


@intrinsic(prefer_literal=True)
def blend_u8c3_at(typingctx, src, off, stride, wxs, wys, i, dst, doff, n):
    """blend_u8c3 with the weights of row i of two C-contiguous float32 arrays (m, n), n (2, 4
    or 6) a compile-time constant that the caller makes the arrays' second dimension: the
    horizontal weights come in one vector load instead of n scalar ones and 4n inserts."""
    if not (_is_u8_vector(src) and _is_u8_vector(dst) and _is_weight_rows(wxs) and _is_weight_rows(wys)
            and isinstance(n, types.IntegerLiteral) and n.literal_value in (2, 4, 6)
            and all(isinstance(t, types.Integer) for t in (off, stride, i, doff))):
        return None
    sig = types.void(src, off, stride, wxs, wys, i, dst, doff, n)
    return sig, _blend_codegen(n.literal_value, 3, rows=True)


@njit(cache=True, nogil=True, error_model="numpy", fastmath={"contract"})
def blend_scalar_c3(flat, base, stride, wx, wy, zero, is_int, hi_t, oflat, doff):  # pragma: no cover - numba
    """The same sum for 3 channels in scalar code, in the type of ``zero``, for every dtype."""
    T = type(zero)
    a0 = zero
    a1 = zero
    a2 = zero
    u1 = np.uint64(1)
    u2 = np.uint64(2)
    for j in range(len(wy)):
        rb = np.uint64(base + j * stride)  # unsigned offsets: no wrap-around test per load
        for k in range(len(wx)):
            w = T(wy[j] * wx[k])
            pb = rb + np.uint64(3 * k)
            a0 += w * flat[pb]
            a1 += w * flat[pb + u1]
            a2 += w * flat[pb + u2]
    if is_int:
        half = T(0.5)
        oflat[doff] = sat(a0 + half, hi_t)
        oflat[doff + 1] = sat(a1 + half, hi_t)
        oflat[doff + 2] = sat(a2 + half, hi_t)
    else:
        oflat[doff] = a0
        oflat[doff + 1] = a1
        oflat[doff + 2] = a2


def _lerp_codegen(wide: bool):
    """The LLVM IR of one bilinear uint8 RGB output pixel as two lerps (see lerp_u8c3)."""
    flags = ("contract",)

    def codegen(context, builder, signature, args):
        sa = signature.args
        src = context.make_array(sa[0])(context, builder, args[0]).data
        dst = context.make_array(sa[5])(context, builder, args[5]).data
        off, stride, doff = (context.cast(builder, args[i], sa[i], types.int64) for i in (1, 2, 6))
        tx, ty = _to_f32(builder, args[3]), _to_f32(builder, args[4])
        rows = []
        for j in range(2):  # 8 bytes, widened and converted: lanes 0-2 the first tap, 3-5 the second
            p = builder.gep(src, [builder.add(off, builder.mul(stride, ir.Constant(_I64, j)))])
            b = builder.load(builder.bitcast(p, _V(_I8, 8).as_pointer()), align=1)
            rows.append(builder.uitofp(builder.zext(b, _V(_I32, 8)), _V(_F32, 8)))
        d = builder.fsub(rows[1], rows[0], flags=flags)
        v = builder.fadd(rows[0], builder.fmul(d, _splat(builder, ty, 8), flags=flags), flags=flags)
        second = builder.shuffle_vector(v, v, _mask([3, 4, 5, 6, 7, 0, 1, 2]))
        d = builder.fsub(second, v, flags=flags)
        v = builder.fadd(v, builder.fmul(d, _splat(builder, tx, 8), flags=flags), flags=flags)
        v = builder.fadd(builder.shuffle_vector(v, v, _mask(range(4))), ir.Constant(_V(_F32, 4), [0.5] * 4))
        px = builder.trunc(builder.fptosi(v, _V(_I32, 4)), _V(_I8, 4))
        q = builder.gep(dst, [doff])
        if wide:
            builder.store(builder.bitcast(px, _I32), builder.bitcast(q, _I32.as_pointer()), align=1)
        else:
            for ch in range(3):
                byte = builder.extract_element(px, ir.Constant(_I32, ch))
                builder.store(byte, builder.gep(q, [ir.Constant(_I64, ch)]))
        return context.get_dummy_value()

    return codegen


def _make_lerp(wide: bool):
    @intrinsic
    def lerp(typingctx, src, off, stride, tx, ty, dst, doff):
        if not (_is_u8_vector(src) and _is_u8_vector(dst) and isinstance(tx, types.Float)
                and isinstance(ty, types.Float) and all(isinstance(t, types.Integer) for t in (off, stride, doff))):
            return None
        return types.void(src, off, stride, tx, ty, dst, doff), _lerp_codegen(wide)

    return lerp


#: lerp_u8c3(src, off, stride, tx, ty, dst, doff): dst[doff:doff + 3] = the bilinear blend of
#: the 2 x 2 RGB pixels of the flat uint8 image ``src`` from offset ``off`` (rows ``stride``
#: bytes apart) at fractions tx, ty in [0, 1), rounded half up: v = r0 + ty (r1 - r0) over the
#: two rows' 8 bytes (lanes 0-2 the first tap's channels, 3-5 the second's), then
#: v[0:3] + tx (v[3:6] - v[0:3]). A convex combination of bytes stays in [0, 255] (to float32
#: rounding), so no clamp. Reads 8 bytes from each row: the caller keeps that inside ``src``.
lerp_u8c3 = _make_lerp(False)
#: The same, storing 4 bytes (the fourth is garbage): for a pixel whose right neighbour in the
#: same output row is written after it by the same thread.
lerp_u8c3_wide = _make_lerp(True)


@intrinsic
def offset_i32(typingctx, iy, ix, stride):
    """iy * stride + 3 * ix in 32-bit arithmetic, for int32 arguments: numba widens int32
    products to int64, which AVX2 has no packed multiply for (a vectorised loop then emulates
    it in ~15 instructions per 8 lanes; here one ``vpmulld``). The caller keeps the result
    below 2^31 (images below 2 GiB)."""
    if not all(isinstance(t, types.Integer) and t.bitwidth == 32 and t.signed for t in (iy, ix, stride)):
        return None

    def codegen(context, builder, signature, args):
        a, b, s = args
        p = builder.mul(a, s, flags=("nsw",))
        return builder.add(p, builder.mul(b, ir.Constant(_I32, 3), flags=("nsw",)), flags=("nsw",))

    return types.int32(iy, ix, stride), codegen


@intrinsic
def unzip8_f32(typingctx, src, so, dx, dy, do):
    """dx[do + m] = src[so + 2 m], dy[do + m] = src[so + 2 m + 1] for m < 8: two vector loads,
    two shuffles and two vector stores. Reads src[so : so + 16]."""
    if not (_is_f32_vector(src) and _is_f32_vector(dx) and _is_f32_vector(dy)
            and isinstance(so, types.Integer) and isinstance(do, types.Integer)):
        return None

    def codegen(context, builder, signature, args):
        sa = signature.args
        s = context.make_array(sa[0])(context, builder, args[0]).data
        so_, do_ = (context.cast(builder, args[k], sa[k], types.int64) for k in (1, 4))
        a, b = (builder.load(builder.bitcast(builder.gep(s, [builder.add(so_, ir.Constant(_I64, 8 * k))]),
                                             _V(_F32, 8).as_pointer()), align=4) for k in range(2))
        for k, first in ((2, 0), (3, 1)):
            d = context.make_array(sa[k])(context, builder, args[k]).data
            v = builder.shuffle_vector(a, b, _mask(range(first, 16, 2)))
            builder.store(v, builder.bitcast(builder.gep(d, [do_]), _V(_F32, 8).as_pointer()), align=4)
        return context.get_dummy_value()

    return types.void(src, so, dx, dy, do), codegen


def unzip_xy(flat, start, n, xs, ys):  # pragma: no cover - numba only
    """xs[k] = flat[start + 2 k], ys[k] = flat[start + 2 k + 1] for k < n: a row of an (H, W, 2)
    map split into its x and y planes. SIMD for float32, a scalar loop otherwise. numba only."""
    raise NotImplementedError("unzip_xy is compiled by numba only")


@njit(cache=True, nogil=True, error_model="numpy")
def _unzip_scalar(flat, start, k0, n, xs, ys):  # pragma: no cover - numba
    for k in range(k0, n):
        xs[k] = flat[start + 2 * k]
        ys[k] = flat[start + 2 * k + 1]


@overload(unzip_xy, jit_options={"cache": True})
def _unzip_xy(flat, start, n, xs, ys):
    if _is_f32_vector(flat) and _is_f32_vector(xs) and _is_f32_vector(ys):
        def simd(flat, start, n, xs, ys):  # pragma: no cover - numba
            nb = n // 8
            for b in range(nb):
                unzip8_f32(flat, start + 16 * b, xs, ys, 8 * b)
            _unzip_scalar(flat, start, 8 * nb, n, xs, ys)
        return simd

    def scalar(flat, start, n, xs, ys):  # pragma: no cover - numba
        _unzip_scalar(flat, start, 0, n, xs, ys)
    return scalar


def blend_rgb_at(flat, base, stride, wxs, wys, i, n, zero, is_int, hi_t, oflat, doff):  # pragma: no cover
    """``blend_rgb`` with the weights in row i of two float32 arrays (m, n), n a compile-time
    constant: ``blend_u8c3_at`` for uint8, the scalar code for the other dtypes. numba only."""
    raise NotImplementedError("blend_rgb_at is compiled by numba only")


@overload(blend_rgb_at, prefer_literal=True, jit_options={"cache": True})
def _blend_rgb_at(flat, base, stride, wxs, wys, i, n, zero, is_int, hi_t, oflat, doff):
    if not isinstance(n, types.IntegerLiteral):
        return None
    if _is_u8_vector(flat) and _is_u8_vector(oflat) and _is_weight_rows(wxs) and _is_weight_rows(wys):
        def simd(flat, base, stride, wxs, wys, i, n, zero, is_int, hi_t, oflat, doff):  # pragma: no cover - numba
            blend_u8c3_at(flat, base, stride, wxs, wys, i, oflat, doff, n)
        return simd

    def scalar(flat, base, stride, wxs, wys, i, n, zero, is_int, hi_t, oflat, doff):  # pragma: no cover - numba
        blend_scalar_c3(flat, base, stride, wxs[i], wys[i], zero, is_int, hi_t, oflat, doff)
    return scalar


def blend_rgb(flat, base, stride, wx, wy, zero, is_int, hi_t, oflat, doff):  # pragma: no cover
    """oflat[doff:doff + 3] = the N x N taps of a 3-channel image from flat offset ``base``
    blended with the weights wy (rows) and wx (columns), rounded and saturated for integer
    images: the SIMD code for uint8, which reads span(N, 3) bytes from each row's first tap
    (the caller checks the room), the scalar code for the other dtypes. numba only."""
    raise NotImplementedError("blend_rgb is compiled by numba only")


@overload(blend_rgb, jit_options={"cache": True})
def _blend_rgb(flat, base, stride, wx, wy, zero, is_int, hi_t, oflat, doff):
    if _is_u8_vector(flat) and _is_u8_vector(oflat) and _is_weights(wx):
        def simd(flat, base, stride, wx, wy, zero, is_int, hi_t, oflat, doff):  # pragma: no cover - numba
            blend_u8c3(flat, base, stride, wx, wy, oflat, doff)
        return simd

    def scalar(flat, base, stride, wx, wy, zero, is_int, hi_t, oflat, doff):  # pragma: no cover - numba
        blend_scalar_c3(flat, base, stride, wx, wy, zero, is_int, hi_t, oflat, doff)
    return scalar
