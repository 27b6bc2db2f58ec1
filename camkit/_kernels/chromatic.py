"""Radial magnification maps for lateral chromatic aberration.

Forward: a point at normalised radius r (as green sees it) lands at r s(r) in this channel,
``s(r) = v + c r + b r^2``. The inverse solves ``r s(r) = rho`` by Newton's method kept
inside a bracket on which ``r s(r)`` increases.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange


@njit(cache=True, nogil=True, parallel=True, error_model="numpy")
def radial_map(cx: float, cy: float, norm: float, v: float, c: float, b: float, inverse: bool,
               r_hi: float, out: np.ndarray) -> None:  # pragma: no cover - numba
    """out[row, col] = the position to sample for output pixel (col, row).

    Not inverse: centre + (p - centre) s(r). Inverse: centre + (p - centre) r / rho with
    r s(r) = rho, r in [0, r_hi]; NaN if rho is beyond r_hi s(r_hi)."""
    H, W = out.shape[0], out.shape[1]
    rho_hi = r_hi * (v + c * r_hi + b * r_hi * r_hi)
    for row in prange(H):
        dy = row - cy
        for col in range(W):
            dx = col - cx
            rho = math.sqrt(dx * dx + dy * dy) / norm
            if not inverse:
                s = v + c * rho + b * rho * rho
            elif rho == 0.0:
                s = 1.0 / v
            elif rho > rho_hi:
                s = np.nan
            else:
                lo = 0.0
                hi = r_hi
                r = rho / v
                if not (lo < r < hi):
                    r = 0.5 * (lo + hi)
                for _ in range(100):
                    f = r * (v + c * r + b * r * r) - rho
                    if abs(f) <= 1e-14:
                        break
                    if f > 0.0:
                        hi = r
                    else:
                        lo = r
                    d = v + 2.0 * c * r + 3.0 * b * r * r
                    nr = r - f / d
                    if not (lo < nr < hi):
                        nr = 0.5 * (lo + hi)
                    if nr == r:
                        break
                    r = nr
                s = r / rho
            out[row, col, 0] = cx + dx * s
            out[row, col, 1] = cy + dy * s
