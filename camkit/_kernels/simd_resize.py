"""Explicit SIMD for the uint8 RGB halving of :mod:`camkit._kernels.resize`.

``split_even_odd_c3`` splits a row into its even and odd pixels (every other pixel of 16 as
five two-vector shuffles; a loop of 3-float copies with a stride of 6 does not vectorise).
``vsum_eo_u8c3`` and ``filter_eo_u8`` are the halving's two passes: G vertical sums of 8
pixels at a time stored split into even and odd pixels, and the output-rate horizontal filter
with its weights broadcast once per row and a saturating narrowing to bytes.
``vsum_eo_u8c3_keys2`` is the vertical pass for Keys' cubic in exact integer arithmetic with
AVX2's ``vpmaddwd``, on CPUs that have it (kept because the benchmark shows it paying:
benchmarks/notes.md).
"""

from __future__ import annotations

import numpy as np
from llvmlite import binding as _llvm
from llvmlite import ir
from numba import njit, types
from numba.core import cgutils, config
from numba.extending import intrinsic, overload

from camkit._kernels.simd_ir import (
    _F32,
    _I8,
    _I16,
    _I32,
    _I64,
    _V,
    _is_f32_vector,
    _is_u8_rows,
    _is_u8_vector,
    _is_weight_rows,
    _mask,
    _splat,
)


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
