"""Interpolation weights and border handling shared by remap, warps and resize.

Methods (internal codes): 0 nearest, 1 bilinear, 2 bicubic (Keys, parameter a; its weights are
closed-form polynomials in camkit._kernels.remap.keys4), 3 Lanczos-3.
Borders: 0 constant, 1 replicate, 2 reflect (half-sample symmetric: ...c b a | a b c...).
Pixel centres are at integer coordinates.
"""

from __future__ import annotations

import math

from numba import njit


@njit(cache=True, nogil=True, error_model="numpy")
def lanczos3(t: float) -> float:  # pragma: no cover
    """sinc(t) sinc(t / 3) on |t| < 3 (C. E. Duchon, J. Appl. Meteor. 18, 1979)."""
    t = abs(t)
    if t < 1e-12:
        return 1.0
    if t >= 3.0:
        return 0.0
    pt = math.pi * t
    return 3.0 * math.sin(pt) * math.sin(pt / 3.0) / (pt * pt)


@njit(cache=True, nogil=True, error_model="numpy")
def border_index(i: int, n: int, border: int) -> int:  # pragma: no cover
    """Index into [0, n) for a tap at i; -1 means 'use the fill value' (constant border)."""
    if 0 <= i < n:
        return i
    if border == 0:
        return -1
    if border == 1:
        return 0 if i < 0 else n - 1
    # half-sample symmetric reflection, period 2n
    period = 2 * n
    i = i % period
    if i < 0:
        i += period
    return i if i < n else period - 1 - i


@njit(cache=True, nogil=True, error_model="numpy")
def store(v: float, is_int: bool, lo: float, hi: float) -> float:  # pragma: no cover
    """Round to nearest (halves away from zero) and saturate for integer outputs."""
    if is_int:
        v = math.floor(v + 0.5) if v >= 0 else -math.floor(-v + 0.5)
        if v < lo:
            return lo
        if v > hi:
            return hi
    return v


@njit(cache=True, nogil=True, error_model="numpy")
def sat(v, hi):  # pragma: no cover
    """Clamp v (already offset by +0.5) to [0, hi]; the store into an unsigned array then
    truncates, which is floor(v) for v >= 0: round-half-up and saturation in one step."""
    return min(max(v, v * 0), hi)  # min/max, not branches: they vectorise
