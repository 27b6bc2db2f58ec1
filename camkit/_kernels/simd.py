"""Explicit SIMD for the pixel gathers of remap and the warps, on uint8 RGB images, for the
split of a map's rows into x and y (``unzip_xy``) and for the even/odd split of the RGB
halving (``split_even_odd_c3``: every other pixel of 16 as five two-vector shuffles; a loop
of 3-float copies with a stride of 6 does not vectorise).

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

Measured (4000x3000 RGB through a full-resolution undistortion map, both cores, the calls
of ``python -m benchmarks -k remap``): bicubic 313-334 -> ~150 ms (cv2.remap INTER_CUBIC
156-179 ms); bilinear 90-99 -> 75-81 ms (cv2.remap INTER_LINEAR 68-78 ms).

Bilinear uint8 RGB has its own, shorter code, ``lerp_u8c3``: two lerps (rows, then the two
taps) on the 8 bytes of each row, with no weight products, no per-pixel weight vectors and no
clamp (a convex combination of bytes stays in range), storing the pixel as one 4-byte word
where the next pixel of the row overwrites the fourth byte (``lerp_u8c3_wide``). Measured on
the 12 MP undistortion, one process: 63 -> 51 ms against ``blend_u8c3`` (N = 2).

``unzip_xy`` splits a row of an (H, W, 2) float32 map into its x and y planes with vector
shuffles: the kernels' loops over a row then read unit-stride and vectorise (read in place,
at a stride of two floats, LLVM left them scalar).

``vsum_eo_u8c3`` and ``filter_eo_u8`` are the uint8 RGB halving's two passes: G vertical
sums of 8 pixels at a time stored split into even and odd pixels, and the output-rate
horizontal filter with its weights broadcast once per row and a saturating narrowing to bytes.

``blend_rgb`` (weights as tuples) and ``blend_rgb_at`` (weights as rows of two float32
arrays, which phase 1 of the bicubic kernel fills vectorised) are the entry points for kernels
compiled for every dtype: the SIMD code for uint8, the scalar sum for the others (identical
results up to float32 rounding).
"""

from __future__ import annotations

import numpy as np
from llvmlite import binding as _llvm
from llvmlite import ir
from numba import njit, types
from numba.core import cgutils, config
from numba.extending import intrinsic, overload

from camkit._kernels.interp import sat

_I8, _I16, _I32, _I64, _F32 = ir.IntType(8), ir.IntType(16), ir.IntType(32), ir.IntType(64), ir.FloatType()
_V = ir.VectorType


def span(n_taps: int, channels: int) -> int:
    """Bytes read per row of taps: the n_taps pixels' n_taps * channels bytes rounded up to a
    power of two (RGB: 8 for bilinear, 16 for bicubic, 32 for Lanczos-3)."""
    p = 1
    while p < n_taps * channels:
        p *= 2
    return p


def _mask(idx) -> ir.Constant:
    idx = list(idx)
    return ir.Constant(_V(_I32, len(idx)), [ir.Constant(_I32, k) for k in idx])


def _splat(builder: ir.IRBuilder, x: ir.Value, n: int) -> ir.Value:
    v = builder.insert_element(ir.Constant(_V(_F32, n), ir.Undefined), x, ir.Constant(_I32, 0))
    return builder.shuffle_vector(v, v, _mask([0] * n))


def _to_f32(builder: ir.IRBuilder, x: ir.Value) -> ir.Value:
    return x if x.type == _F32 else builder.fptrunc(x, _F32)


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


def _is_u8_vector(a) -> bool:
    return isinstance(a, types.Array) and a.dtype == types.uint8 and a.ndim == 1 and a.layout == "C"


def _is_weights(t) -> bool:
    return isinstance(t, types.UniTuple) and t.count in (2, 4, 6) and isinstance(t.dtype, types.Float)


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


def _is_weight_rows(a) -> bool:
    return isinstance(a, types.Array) and a.dtype == types.float32 and a.ndim == 2 and a.layout == "C"


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


def _is_f32_vector(a) -> bool:
    return isinstance(a, types.Array) and a.dtype == types.float32 and a.ndim == 1 and a.layout == "C"


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


@intrinsic
def evens8_f32c3(typingctx, src, so, dst, do):
    """dst[do + 3 m + ch] = src[so + 6 m + ch] for m < 8, ch < 3: every other pixel of 16 RGB
    pixels of a float32 row, as six vector loads, five two-vector shuffles and three vector
    stores (a loop of scalar copies does not vectorise). Reads src[so : so + 48]."""
    if not (_is_f32_vector(src) and _is_f32_vector(dst) and isinstance(so, types.Integer)
            and isinstance(do, types.Integer)):
        return None

    def codegen(context, builder, signature, args):
        sa = signature.args
        s = context.make_array(sa[0])(context, builder, args[0]).data
        d = context.make_array(sa[2])(context, builder, args[2]).data
        so_, do_ = (context.cast(builder, args[k], sa[k], types.int64) for k in (1, 3))
        x = [builder.load(builder.bitcast(builder.gep(s, [builder.add(so_, ir.Constant(_I64, 8 * k))]),
                                          _V(_F32, 8).as_pointer()), align=4) for k in range(6)]

        def sh(a, b, idx):
            return builder.shuffle_vector(a, b, _mask(idx))
        # floats 0-2 6-8 12-14 18-20 24-26 30-32 36-38 42-44 of the 48, eight to a vector
        y0 = sh(x[0], x[1], [0, 1, 2, 6, 7, 8, 12, 13])
        y1 = sh(sh(x[1], x[2], [6, 10, 11, 12, 0, 0, 0, 0]), x[3], [0, 1, 2, 3, 8, 9, 10, 14])
        y2 = sh(sh(x[3], x[4], [7, 8, 12, 13, 14, 0, 0, 0]), x[5], [0, 1, 2, 3, 4, 10, 11, 12])
        for k, y in enumerate((y0, y1, y2)):
            p = builder.gep(d, [builder.add(do_, ir.Constant(_I64, 8 * k))])
            builder.store(y, builder.bitcast(p, _V(_F32, 8).as_pointer()), align=4)
        return context.get_dummy_value()

    return types.void(src, so, dst, do), codegen


def split_even_odd_c3(row, width, dst, odd_at):  # pragma: no cover - numba only
    """dst[3 q + ch] = pixel 2q of the 3-channel ``row`` (``width`` pixels), dst[odd_at + 3 q + ch]
    = pixel 2q + 1: SIMD for float32 rows, a scalar loop otherwise. numba only."""
    raise NotImplementedError("split_even_odd_c3 is compiled by numba only")


@njit(cache=True, nogil=True, error_model="numpy")
def _split_scalar_c3(row, start, width, dst, odd_at):  # pragma: no cover - numba
    for p in range(start, width):
        d = 3 * (p // 2) + (odd_at if p % 2 else 0)
        for ch in range(3):
            dst[d + ch] = row[3 * p + ch]


@overload(split_even_odd_c3, jit_options={"cache": True})
def _split_even_odd_c3(row, width, dst, odd_at):
    if _is_f32_vector(row) and _is_f32_vector(dst):
        def simd(row, width, dst, odd_at):  # pragma: no cover - numba
            # blocks of 16 pixels; the odd half of block b reads row[48 b + 3 : 48 b + 51]
            nb = (3 * width - 51) // 48 + 1 if width >= 17 else 0
            for b in range(nb):
                evens8_f32c3(row, 48 * b, dst, 24 * b)
                evens8_f32c3(row, 48 * b + 3, dst, odd_at + 24 * b)
            _split_scalar_c3(row, 16 * nb, width, dst, odd_at)
        return simd

    def scalar(row, width, dst, odd_at):  # pragma: no cover - numba
        _split_scalar_c3(row, 0, width, dst, odd_at)
    return scalar


def _is_u8_rows(a) -> bool:
    return isinstance(a, types.Array) and a.dtype == types.uint8 and a.ndim == 2 and a.layout == "C"


#: Of 8 RGB pixels (24 floats): the floats of pixels 0, 2, 4, 6, and of pixels 1, 3, 5, 7.
_EVEN_C3 = [3 * p + ch for p in (0, 2, 4, 6) for ch in range(3)]
_ODD_C3 = [3 * p + ch for p in (1, 3, 5, 7) for ch in range(3)]


def _store_even_odd(builder: ir.IRBuilder, rows: list, base: ir.Value, erow: ir.Value, even: ir.Value,
                    odd_at: ir.Value, ev_idx: list, od_idx: list) -> None:
    """For each row t of sums, given as float vectors to take end to end (``rows[t]``), store
    its elements ev_idx at base[t erow + even] and od_idx at base[t erow + odd_at + even]: a
    block of the split sums' even and odd pixels."""
    odd = builder.add(even, odd_at)
    for t, vecs in enumerate(rows):
        px = vecs[0]
        for v in vecs[1:]:
            n, m = px.type.count, v.type.count
            wide = builder.shuffle_vector(v, v, _mask(list(range(m)) + [0] * (n - m))) if m < n else v
            px = builder.shuffle_vector(px, wide, _mask(list(range(n)) + list(range(n, n + m))))
        row = builder.mul(erow, ir.Constant(_I64, t))
        for off, idx in ((even, ev_idx), (odd, od_idx)):
            part = builder.shuffle_vector(px, px, _mask(idx))
            q = builder.gep(base, [builder.add(row, off)])
            builder.store(part, builder.bitcast(q, _V(_F32, len(idx)).as_pointer()), align=4)


@intrinsic(prefer_literal=True)
def vsum_eo_u8c3(typingctx, src, s, w, eo, odd_at, nb, KY, STEP, G):
    """For t < G and the first 8 nb pixels of the uint8 RGB rows ``src`` (H, 3 W): the vertical
    sum v_t = sum_k w[t, k] src[s + t STEP + k] of KY rows, in float32, stored split into its
    even and odd pixels: pixel 2q at eo[t, 3q], pixel 2q + 1 at eo[t, odd_at + 3q].

    One loop over blocks of 8 pixels (24 bytes): each of the KY + (G - 1) STEP input rows is
    loaded and converted once, as three vectors of 8, and added into the G sums that use it
    (the FMAs in the order k = 0, 1, ..., as the scalar code sums); each sum's three vectors
    are then shuffled into 4 even and 4 odd pixels and stored. Rows are read from
    src[s : s + KY + (G - 1) STEP]; the caller keeps them inside src."""
    if not (_is_u8_rows(src) and _is_weight_rows(w) and _is_weight_rows(eo)
            and all(isinstance(t, types.Integer) for t in (s, odd_at, nb))
            and all(isinstance(t, types.IntegerLiteral) for t in (KY, STEP, G))):
        return None
    ky, st, g = KY.literal_value, STEP.literal_value, G.literal_value
    flags = ("contract",)

    def codegen(context, builder, signature, args):
        sa = signature.args
        sarr = context.make_array(sa[0])(context, builder, args[0])
        earr = context.make_array(sa[3])(context, builder, args[3])
        pw = context.make_array(sa[2])(context, builder, args[2]).data
        stride = cgutils.unpack_tuple(builder, sarr.shape, 2)[1]  # C-contiguous uint8: bytes per row
        erow = cgutils.unpack_tuple(builder, earr.shape, 2)[1]
        s_, odd, nb_ = (context.cast(builder, args[k], sa[k], types.int64) for k in (1, 4, 5))
        wv = [[_splat(builder, builder.load(builder.gep(pw, [ir.Constant(_I64, t * ky + k)])), 8) for k in range(ky)]
              for t in range(g)]
        base = builder.mul(s_, stride)
        with cgutils.for_range(builder, nb_) as loop:
            b = loop.index
            off = builder.add(base, builder.mul(b, ir.Constant(_I64, 24)))
            acc = [[None] * 3 for _ in range(g)]
            for k in range(ky + (g - 1) * st):
                rp = builder.add(off, builder.mul(stride, ir.Constant(_I64, k)))
                xs = []
                for j in range(3):
                    p = builder.gep(sarr.data, [builder.add(rp, ir.Constant(_I64, 8 * j))])
                    by = builder.load(builder.bitcast(p, _V(_I8, 8).as_pointer()), align=1)
                    xs.append(builder.uitofp(builder.zext(by, _V(_I32, 8)), _V(_F32, 8)))
                for t in range(g):
                    kk = k - t * st
                    if 0 <= kk < ky:
                        for j in range(3):
                            m = builder.fmul(xs[j], wv[t][kk], flags=flags)
                            acc[t][j] = m if acc[t][j] is None else builder.fadd(acc[t][j], m, flags=flags)
            _store_even_odd(builder, acc, earr.data, erow, builder.mul(b, ir.Constant(_I64, 12)), odd,
                            _EVEN_C3, _ODD_C3)
        return context.get_dummy_value()

    return types.void(src, s, w, eo, odd_at, nb, KY, STEP, G), codegen


#: The vertical weights of the uint8 RGB halving with Keys' cubic (a = -0.5) stretched by 2,
#: away from the borders, times 256: [-3, -9, 29, 111, 111, 29, -9, -3] (exact dyadic values).
#: As a polynomial it has a triple root at -1: [1, 3, 3, 1] convolved with [-3, 0, 38, 0, -3].
HALF_KEYS_256 = (-3.0, -9.0, 29.0, 111.0, 111.0, 29.0, -9.0, -3.0)


def _target_has_avx2() -> bool:
    """Whether numba compiles for a CPU with AVX2: the host's, unless NUMBA_CPU_NAME or
    NUMBA_CPU_FEATURES name another (as for caches shared between machines)."""
    try:
        if config.CPU_FEATURES is not None:
            return "+avx2" in config.CPU_FEATURES.replace(" ", "").split(",")
        if config.CPU_NAME not in (None, "host"):
            return False  # a named CPU without a feature list: do not guess
        return bool(_llvm.get_host_cpu_features().get("avx2", False))
    except Exception:  # pragma: no cover - a host llvmlite cannot describe
        return False


#: ``vsum_eo_u8c3_keys2`` calls AVX2's ``vpmaddwd`` (LLVM does not form it from the generic
#: integer code here); other targets take the float sums.
HAS_AVX2 = _target_has_avx2()


@intrinsic(prefer_literal=True)
def vsum_eo_u8c3_keys2(typingctx, src, s, eo, odd_at, nb, G):
    """``vsum_eo_u8c3`` for the weights ``HALF_KEYS_256 / 256`` in every row, STEP 2, in exact
    integer arithmetic, for the first 16 nb pixels; the sums are stored times 256.

    The weights factor as [1, 3, 3, 1] * [-3, 0, 38, 0, -3] (a triple zero at the Nyquist
    frequency: Keys' a = -0.5 kernel reproduces quadratics, Keys 1981), so with
    S_m = r_m + 3 r_(m+1) + 3 r_(m+2) + r_(m+3) (16-bit, <= 2040), the sum of output row t is
    38 S_(2t+2) - 3 (S_(2t) + S_(2t+4)): a few 16-bit adds per input row, shared by the G
    rows, and one ``vpmaddwd`` per 8 values of each row, against 8 float FMAs and a
    conversion of every input byte. Blocks of 16 pixels (48 bytes, three 16-lane vectors per
    row); the 16-bit lanes come out of the interleaving in the order of AVX2's unpack
    (within 128-bit halves), which the final even/odd shuffle undoes."""
    if not (_is_u8_rows(src) and _is_weight_rows(eo) and HAS_AVX2
            and all(isinstance(t, types.Integer) for t in (s, odd_at, nb))
            and isinstance(G, types.IntegerLiteral)):
        return None
    g = G.literal_value

    def codegen(context, builder, signature, args):
        sa = signature.args
        sarr = context.make_array(sa[0])(context, builder, args[0])
        earr = context.make_array(sa[2])(context, builder, args[2])
        stride = cgutils.unpack_tuple(builder, sarr.shape, 2)[1]
        erow = cgutils.unpack_tuple(builder, earr.shape, 2)[1]
        s_, odd, nb_ = (context.cast(builder, args[k], sa[k], types.int64) for k in (1, 3, 4))
        v16 = _V(_I16, 16)
        three = ir.Constant(v16, [3] * 16)
        wpair = ir.Constant(v16, [-3, 38] * 8)
        pmadd = cgutils.get_or_insert_function(builder.module, ir.FunctionType(_V(_I32, 8), [v16, v16]),
                                               "llvm.x86.avx2.pmadd.wd")
        base = builder.mul(s_, stride)
        nrows = 2 * (g + 1) + 4
        # lanes of A (pairs with B) in the order vpunpck{l,h}wd interleave them
        halves = [[4 * h + i for i in range(4)] + [8 + 4 * h + i for i in range(4)] for h in range(2)]
        where = {16 * j + x: 16 * j + 8 * h + n for j in range(3) for h in range(2) for n, x in enumerate(halves[h])}
        ev_idx = [where[3 * p + ch] for p in range(0, 16, 2) for ch in range(3)]
        od_idx = [where[3 * p + ch] for p in range(1, 16, 2) for ch in range(3)]
        with cgutils.for_range(builder, nb_) as loop:
            b = loop.index
            off = builder.add(base, builder.mul(b, ir.Constant(_I64, 48)))
            res = [[] for _ in range(g)]
            for j in range(3):
                R = []
                for k in range(nrows):
                    p = builder.gep(sarr.data, [builder.add(off, builder.add(builder.mul(stride, ir.Constant(_I64, k)),
                                                                            ir.Constant(_I64, 16 * j)))])
                    R.append(builder.zext(builder.load(builder.bitcast(p, _V(_I8, 16).as_pointer()), align=1), v16))
                S = [builder.add(builder.add(R[2 * u], R[2 * u + 3]),
                                 builder.mul(builder.add(R[2 * u + 1], R[2 * u + 2]), three)) for u in range(g + 2)]
                for t in range(g):
                    A = builder.add(S[t], S[t + 2])
                    for h in range(2):
                        pr = builder.shuffle_vector(A, S[t + 1], _mask([k for i in halves[h] for k in (i, 16 + i)]))
                        res[t].append(builder.sitofp(builder.call(pmadd, [pr, wpair]), _V(_F32, 8)))
            _store_even_odd(builder, res, earr.data, erow, builder.mul(b, ir.Constant(_I64, 24)), odd,
                            ev_idx, od_idx)
        return context.get_dummy_value()

    return types.void(src, s, eo, odd_at, nb, G), codegen


@njit(cache=True, nogil=True, error_model="numpy")
def _vsum_tail_c3(src, s, w, eo, odd_at, STEP, first):  # pragma: no cover - numba
    """The scalar rest of ``vertical_even_odd_c3``: pixels first.. of the G = w.shape[0] sums of
    KY = w.shape[1] rows, in the order of the SIMD sums."""
    for p in range(first, src.shape[1] // 3):
        d = 3 * (p >> 1) + (odd_at if p & 1 else 0)
        for t in range(w.shape[0]):
            for ch in range(3):
                a = np.float32(0.0)
                for k in range(w.shape[1]):
                    a += w[t, k] * np.float32(src[s + t * STEP + k, 3 * p + ch])
                eo[t, d + ch] = a


def vertical_even_odd_c3(src, s, w, eo, odd_at, KY, STEP, G):  # pragma: no cover - numba only
    """For uint8 RGB rows ``src`` (H, 3 W): the G vertical sums of all W pixels, stored split
    into even and odd pixels, returning the factor they were stored times: 256.0 where every
    row's weights are ``HALF_KEYS_256 / 256`` (``vsum_eo_u8c3_keys2``, exact integer sums;
    AVX2 hosts), 1.0 otherwise (``vsum_eo_u8c3``). The last W % 16 or W % 8 pixels are summed in
    scalar code, in the same order (exactly, for the first). For other dtypes nothing is done
    and it returns 0.0 (the caller sums and splits itself). numba only."""
    raise NotImplementedError("vertical_even_odd_c3 is compiled by numba only")


@overload(vertical_even_odd_c3, prefer_literal=True, jit_options={"cache": True})
def _vertical_even_odd_c3(src, s, w, eo, odd_at, KY, STEP, G):
    if not all(isinstance(t, types.IntegerLiteral) for t in (KY, STEP, G)):
        return None
    if _is_u8_rows(src) and _is_weight_rows(w) and _is_weight_rows(eo):
        halving = HAS_AVX2 and KY.literal_value == 8 and STEP.literal_value == 2
        h256 = np.array(HALF_KEYS_256, np.float32)
        hg = np.tile(h256, (G.literal_value, 1))  # the tail's weights, times 256

        def floats(src, s, w, eo, odd_at, KY, STEP, G):  # pragma: no cover - numba
            nb = src.shape[1] // 3 // 8
            vsum_eo_u8c3(src, s, w, eo, odd_at, nb, KY, STEP, G)
            _vsum_tail_c3(src, s, w, eo, odd_at, STEP, 8 * nb)
            return np.float32(1.0)

        def keys_or_floats(src, s, w, eo, odd_at, KY, STEP, G):  # pragma: no cover - numba
            keys = True
            for t in range(G):
                for k in range(KY):
                    keys = keys and w[t, k] * np.float32(256.0) == h256[k]
            if keys:
                nb = src.shape[1] // 3 // 16
                vsum_eo_u8c3_keys2(src, s, eo, odd_at, nb, G)
                _vsum_tail_c3(src, s, hg, eo, odd_at, STEP, 16 * nb)  # times 256, exact
                return np.float32(256.0)
            nb = src.shape[1] // 3 // 8
            vsum_eo_u8c3(src, s, w, eo, odd_at, nb, KY, STEP, G)
            _vsum_tail_c3(src, s, w, eo, odd_at, STEP, 8 * nb)
            return np.float32(1.0)

        return keys_or_floats if halving else floats

    def other(src, s, w, eo, odd_at, KY, STEP, G):  # pragma: no cover - numba
        return np.float32(0.0)
    return other


@intrinsic(prefer_literal=True)
def filter_eo_u8(typingctx, ea, eb, v, out, n, K):
    """out[i] = the uint8 of sum_m (v[2m] ea[i + 3m] + v[2m + 1] eb[i + 3m]), plus
    v[K - 1] ea[i + 3 (K // 2)] for odd K, rounded half up and saturated, for i < 8 (n // 8):
    the halving's horizontal filter at the output rate along the even (ea) and odd (eb)
    pixels. The K weights are loaded and broadcast once, before the loop; per 8 outputs, K
    FMAs from +0.5, truncation and a saturating narrowing to bytes (no float min/max)."""
    if not (_is_f32_vector(ea) and _is_f32_vector(eb) and _is_f32_vector(v) and _is_u8_vector(out)
            and isinstance(n, types.Integer) and isinstance(K, types.IntegerLiteral)):
        return None
    kk = K.literal_value
    flags = ("contract",)

    def codegen(context, builder, signature, args):
        sa = signature.args
        pa, pb, pv, po = (context.make_array(sa[k])(context, builder, args[k]).data for k in range(4))
        nb = builder.sdiv(context.cast(builder, args[4], sa[4], types.int64), ir.Constant(_I64, 8))
        w = [_splat(builder, builder.load(builder.gep(pv, [ir.Constant(_I64, k)])), 8) for k in range(kk)]
        lo = ir.Constant(_V(_I32, 8), [0] * 8)
        hi = ir.Constant(_V(_I32, 8), [255] * 8)
        with cgutils.for_range(builder, nb) as loop:
            i = builder.mul(loop.index, ir.Constant(_I64, 8))
            acc = ir.Constant(_V(_F32, 8), [0.5] * 8)
            for k in range(kk):
                p = builder.gep(pa if k % 2 == 0 else pb, [builder.add(i, ir.Constant(_I64, 3 * (k // 2)))])
                x = builder.load(builder.bitcast(p, _V(_F32, 8).as_pointer()), align=4)
                acc = builder.fadd(acc, builder.fmul(x, w[k], flags=flags), flags=flags)
            q = builder.fptosi(acc, _V(_I32, 8))
            q = builder.select(builder.icmp_signed("<", q, lo), lo, q)
            q = builder.select(builder.icmp_signed(">", q, hi), hi, q)
            dst = builder.bitcast(builder.gep(po, [i]), _V(_I8, 8).as_pointer())
            builder.store(builder.trunc(q, _V(_I8, 8)), dst, align=1)
        return context.get_dummy_value()

    return types.void(ea, eb, v, out, n, K), codegen


def filter_even_odd(ea, eb, v, out, n, K):  # pragma: no cover - numba only
    """``filter_eo_u8`` for uint8 outputs, returning how many outputs it made (8 (n // 8));
    0 for other dtypes (the caller filters them all). numba only."""
    raise NotImplementedError("filter_even_odd is compiled by numba only")


@overload(filter_even_odd, prefer_literal=True, jit_options={"cache": True})
def _filter_even_odd(ea, eb, v, out, n, K):
    if not isinstance(K, types.IntegerLiteral):
        return None
    if _is_f32_vector(ea) and _is_f32_vector(eb) and _is_f32_vector(v) and _is_u8_vector(out):
        def simd(ea, eb, v, out, n, K):  # pragma: no cover - numba
            filter_eo_u8(ea, eb, v, out, n, K)
            return n // 8 * 8
        return simd

    def other(ea, eb, v, out, n, K):  # pragma: no cover - numba
        return 0
    return other


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
