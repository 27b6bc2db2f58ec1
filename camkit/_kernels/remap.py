"""Remap: out[r, c] = image sampled at map[r, c] (x, y), for every channel.

One kernel body, specialised per interpolation method by a factory so the tap count is a
compile-time constant (loops unroll, weights stay in registers). Pixels whose taps all fall
inside the image take a fast path with the channel count specialised for 3; the rest go
through border handling. Accumulation is in the type of ``zero`` (float32 for 8/16-bit and
float32 images, float64 for float64 images).
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange

from camkit._kernels.interp import border_index, keys, lanczos3, store

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
def taps4(x, a):  # pragma: no cover
    f = np.floor(x)
    t = np.float64(x - f)
    return int(f) - 1, (keys(t + 1.0, a), keys(t, a), keys(1.0 - t, a), keys(2.0 - t, a))


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
def sat(v, hi):  # pragma: no cover
    """Clamp v (already offset by +0.5) to [0, hi]; the store into an unsigned array then
    truncates, which is floor(v) for v >= 0: round-half-up and saturation in one step."""
    if v < 0:
        return v * 0
    if v > hi:
        return hi
    return v


def _make(N: int, taps):
    @njit(cache=True, nogil=True, parallel=True, error_model="numpy")
    def remap_kernel(img, mp, a, border, fill, is_int, lo, hi, zero, out):  # pragma: no cover
        H, W, C = img.shape
        Ho, Wo = out.shape[0], out.shape[1]
        half = zero + 0.5
        hi_t = zero + hi
        for r in prange(Ho):
            for c in range(Wo):
                # Coordinates stay in the map's dtype: the fractional part of a float32 is
                # exact, so nothing is lost that the map itself had.
                x = mp[r, c, 0]
                y = mp[r, c, 1]
                if not (abs(x) < 1e9 and abs(y) < 1e9):  # NaN, inf or absurdly far: fill
                    for ch in range(C):
                        out[r, c, ch] = store(fill[ch], is_int, lo, hi)
                    continue
                x0, wx = taps(x, a)
                y0, wy = taps(y, a)
                if x0 >= 0 and y0 >= 0 and x0 + N <= W and y0 + N <= H:
                    if C == 3:
                        a0 = zero
                        a1 = zero
                        a2 = zero
                        for j in range(N):
                            wj = wy[j]
                            for k in range(N):
                                w = type(zero)(wj * wx[k])
                                a0 += w * img[y0 + j, x0 + k, 0]
                                a1 += w * img[y0 + j, x0 + k, 1]
                                a2 += w * img[y0 + j, x0 + k, 2]
                        if is_int:
                            out[r, c, 0] = sat(a0 + half, hi_t)
                            out[r, c, 1] = sat(a1 + half, hi_t)
                            out[r, c, 2] = sat(a2 + half, hi_t)
                        else:
                            out[r, c, 0] = a0
                            out[r, c, 1] = a1
                            out[r, c, 2] = a2
                    else:
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


#: Kernels by interpolation code: 0 nearest, 1 bilinear, 2 bicubic, 3 Lanczos-3.
REMAP = (_make(1, taps1), _make(2, taps2), _make(4, taps4), _make(6, taps6))
