"""Brown-Conrady distortion (OpenCV's radial, tangential, rational and thin-prism terms).

Distortion coefficients travel as one array ``c`` of 12 values:
``k1 k2 k3 k4 k5 k6 p1 p2 s1 s2 s3 s4`` (indices 0..11). Intrinsics as ``fx fy cx cy skew``.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from camkit._kernels.rotation import PARALLEL_MIN_ROWS


@njit(cache=True, nogil=True, error_model="numpy")
def distort(x: float, y: float, c: np.ndarray):  # pragma: no cover - numba
    """Ideal normalised (x, y) -> distorted (xd, yd), the 2x2 Jacobian d(xd, yd)/d(x, y), and
    the radial numerator and denominator (for parameter derivatives and validity)."""
    r2 = x * x + y * y
    num = 1.0 + r2 * (c[0] + r2 * (c[1] + r2 * c[2]))
    den = 1.0 + r2 * (c[3] + r2 * (c[4] + r2 * c[5]))
    dnum = c[0] + r2 * (2.0 * c[1] + 3.0 * r2 * c[2])
    dden = c[3] + r2 * (2.0 * c[4] + 3.0 * r2 * c[5])
    rad = num / den
    drad = (dnum * den - num * dden) / (den * den)  # d rad / d r2
    p1 = c[6]
    p2 = c[7]
    xy = x * y
    sx = c[8] + 2.0 * c[9] * r2  # d(s1 r2 + s2 r2^2)/d r2
    sy = c[10] + 2.0 * c[11] * r2
    xd = x * rad + 2.0 * p1 * xy + p2 * (r2 + 2.0 * x * x) + r2 * (c[8] + c[9] * r2)
    yd = y * rad + p1 * (r2 + 2.0 * y * y) + 2.0 * p2 * xy + r2 * (c[10] + c[11] * r2)
    j00 = rad + 2.0 * x * x * drad + 2.0 * p1 * y + 6.0 * p2 * x + 2.0 * x * sx
    j01 = 2.0 * xy * drad + 2.0 * p1 * x + 2.0 * p2 * y + 2.0 * y * sx
    j10 = 2.0 * xy * drad + 2.0 * p1 * x + 2.0 * p2 * y + 2.0 * x * sy
    j11 = rad + 2.0 * y * y * drad + 6.0 * p1 * y + 2.0 * p2 * x + 2.0 * y * sy
    return xd, yd, j00, j01, j10, j11, num, den


@njit(cache=True, nogil=True, error_model="numpy")
def distort_only(x: float, y: float, c: np.ndarray):  # pragma: no cover - numba
    """Ideal normalised (x, y) -> distorted (xd, yd), without derivatives (the fast path)."""
    r2 = x * x + y * y
    rad = (1.0 + r2 * (c[0] + r2 * (c[1] + r2 * c[2]))) / (1.0 + r2 * (c[3] + r2 * (c[4] + r2 * c[5])))
    xy = 2.0 * x * y
    xd = x * rad + c[6] * xy + c[7] * (r2 + 2.0 * x * x) + r2 * (c[8] + c[9] * r2)
    yd = y * rad + c[6] * (r2 + 2.0 * y * y) + c[7] * xy + r2 * (c[10] + c[11] * r2)
    return xd, yd


@njit(cache=True, nogil=True, error_model="numpy")
def valid_radius(c: np.ndarray, r_search: float, n_dirs: int, n_steps: int) -> float:  # pragma: no cover
    """Largest r such that, on every sampled direction, the distortion map is one-to-one on
    the disk of ideal radius r: the rational denominator stays positive, the Jacobian
    determinant stays positive and the distorted point moves away from the centre as r grows.
    Returns ``r_search`` when no failure is found up to it."""
    best = r_search
    dr = r_search / n_steps
    for d in range(n_dirs):
        phi = 2.0 * math.pi * d / n_dirs
        cp = math.cos(phi)
        sp = math.sin(phi)
        for i in range(1, n_steps + 1):
            r = i * dr
            if r >= best:
                break
            if not _one_to_one(r, cp, sp, c):
                # Bisect the failing step: the boundary to 1/2^20 of a step.
                lo = (i - 1) * dr
                hi = r
                for _ in range(20):
                    mid = 0.5 * (lo + hi)
                    if _one_to_one(mid, cp, sp, c):
                        lo = mid
                    else:
                        hi = mid
                best = min(best, lo)
                break
    return best


@njit(cache=True, nogil=True, error_model="numpy")
def _one_to_one(r: float, cp: float, sp: float, c: np.ndarray) -> bool:  # pragma: no cover
    """At radius r along (cp, sp): positive denominator, positive Jacobian determinant, and the
    distorted point moving outward."""
    xd, yd, j00, j01, j10, j11, _num, den = distort(r * cp, r * sp, c)
    det = j00 * j11 - j01 * j10
    grow = xd * (j00 * cp + j01 * sp) + yd * (j10 * cp + j11 * sp)
    return den > 0.0 and det > 0.0 and grow > 0.0


@njit(cache=True, nogil=True, error_model="numpy")
def project_rows(pts: np.ndarray, intr: np.ndarray, c: np.ndarray, r2_valid: float,
            out: np.ndarray, lo: int, hi: int) -> None:  # pragma: no cover
    """Pixels of camera points; NaN when z <= 0 or the ideal radius is outside the valid disk."""
    fx, fy, cx, cy, skew = intr[0], intr[1], intr[2], intr[3], intr[4]
    for i in range(lo, hi):
        z = pts[i, 2]
        if z > 0.0:
            x = pts[i, 0] / z
            y = pts[i, 1] / z
            if x * x + y * y <= r2_valid:
                xd, yd = distort_only(x, y, c)
                out[i, 0] = fx * xd + skew * yd + cx
                out[i, 1] = fy * yd + cy
                continue
        out[i, 0] = np.nan
        out[i, 1] = np.nan


@njit(cache=True, nogil=True, parallel=True, error_model="numpy")
def project_parallel(pts: np.ndarray, intr: np.ndarray, c: np.ndarray, r2_valid: float,
            out: np.ndarray) -> None:  # pragma: no cover
    n = pts.shape[0]
    for chunk in prange((n + 1023) // 1024):
        project_rows(pts, intr, c, r2_valid, out, chunk * 1024, min(n, (chunk + 1) * 1024))


def project(pts: np.ndarray, intr: np.ndarray, c: np.ndarray, r2_valid: float,
            out: np.ndarray) -> None:
    """Serial below PARALLEL_MIN_ROWS rows (a parallel launch costs more than their work)."""
    if pts.shape[0] < PARALLEL_MIN_ROWS:
        project_rows(pts, intr, c, r2_valid, out, 0, pts.shape[0])
    else:
        project_parallel(pts, intr, c, r2_valid, out)


@njit(cache=True, nogil=True, error_model="numpy")
def project_jacobian_rows(pts: np.ndarray, intr: np.ndarray, c: np.ndarray, r2_valid: float,
                     uv: np.ndarray, dp: np.ndarray, dk: np.ndarray, lo: int, hi: int) -> None:  # pragma: no cover
    """Pixels, d(u, v)/d(X, Y, Z) and d(u, v)/d(params) in the order
    fx fy cx cy skew k1 k2 k3 p1 p2 k4 k5 k6 s1 s2 s3 s4 (dk is zero-initialised)."""
    fx, fy, skew = intr[0], intr[1], intr[4]
    for i in range(lo, hi):
        z = pts[i, 2]
        x = pts[i, 0] / z if z > 0.0 else 0.0
        y = pts[i, 1] / z if z > 0.0 else 0.0
        r2 = x * x + y * y
        if not (z > 0.0) or r2 > r2_valid:
            uv[i, 0] = np.nan
            uv[i, 1] = np.nan
            for a in range(2):
                for b in range(3):
                    dp[i, a, b] = np.nan
                for b in range(dk.shape[2]):
                    dk[i, a, b] = np.nan
            continue
        xd, yd, j00, j01, j10, j11, num, den = distort(x, y, c)
        uv[i, 0] = fx * xd + skew * yd + intr[2]
        uv[i, 1] = fy * yd + intr[3]
        # d(u, v)/d(x, y), then chain through x = X/Z, y = Y/Z.
        a00 = fx * j00 + skew * j10
        a01 = fx * j01 + skew * j11
        a10 = fy * j10
        a11 = fy * j11
        iz = 1.0 / z
        dp[i, 0, 0] = a00 * iz
        dp[i, 0, 1] = a01 * iz
        dp[i, 0, 2] = -(a00 * x + a01 * y) * iz
        dp[i, 1, 0] = a10 * iz
        dp[i, 1, 1] = a11 * iz
        dp[i, 1, 2] = -(a10 * x + a11 * y) * iz
        # intrinsics
        dk[i, 0, 0] = xd
        dk[i, 0, 2] = 1.0
        dk[i, 0, 4] = yd
        dk[i, 1, 1] = yd
        dk[i, 1, 3] = 1.0
        # distortion: d(xd, yd)/d coefficient, then u = fx xd + skew yd, v = fy yd
        inv_den = 1.0 / den
        rr = r2
        col = 5
        for p in range(3):  # k1 k2 k3 -> columns 5 6 7
            gx = x * rr * inv_den
            gy = y * rr * inv_den
            dk[i, 0, col + p] = fx * gx + skew * gy
            dk[i, 1, col + p] = fy * gy
            rr *= r2
        # p1, p2 -> columns 8, 9
        gx = 2.0 * x * y
        gy = r2 + 2.0 * y * y
        dk[i, 0, 8] = fx * gx + skew * gy
        dk[i, 1, 8] = fy * gy
        gx = r2 + 2.0 * x * x
        gy = 2.0 * x * y
        dk[i, 0, 9] = fx * gx + skew * gy
        dk[i, 1, 9] = fy * gy
        # k4 k5 k6 -> columns 10 11 12: d rad / d k = -num r2^n / den^2
        rr = r2
        for p in range(3):
            g = -num * rr * inv_den * inv_den
            dk[i, 0, 10 + p] = fx * x * g + skew * y * g
            dk[i, 1, 10 + p] = fy * y * g
            rr *= r2
        # s1 s2 -> xd only (columns 13, 14); s3 s4 -> yd only (columns 15, 16)
        dk[i, 0, 13] = fx * r2
        dk[i, 0, 14] = fx * r2 * r2
        dk[i, 0, 15] = skew * r2
        dk[i, 1, 15] = fy * r2
        dk[i, 0, 16] = skew * r2 * r2
        dk[i, 1, 16] = fy * r2 * r2


@njit(cache=True, nogil=True, parallel=True, error_model="numpy")
def project_jacobian_parallel(pts: np.ndarray, intr: np.ndarray, c: np.ndarray, r2_valid: float,
                     uv: np.ndarray, dp: np.ndarray, dk: np.ndarray) -> None:  # pragma: no cover
    n = pts.shape[0]
    for chunk in prange((n + 1023) // 1024):
        project_jacobian_rows(pts, intr, c, r2_valid, uv, dp, dk, chunk * 1024, min(n, (chunk + 1) * 1024))


def project_jacobian(pts: np.ndarray, intr: np.ndarray, c: np.ndarray, r2_valid: float,
                     uv: np.ndarray, dp: np.ndarray, dk: np.ndarray) -> None:
    """Serial below PARALLEL_MIN_ROWS rows (a parallel launch costs more than their work)."""
    if pts.shape[0] < PARALLEL_MIN_ROWS:
        project_jacobian_rows(pts, intr, c, r2_valid, uv, dp, dk, 0, pts.shape[0])
    else:
        project_jacobian_parallel(pts, intr, c, r2_valid, uv, dp, dk)


@njit(cache=True, nogil=True, error_model="numpy")
def undistort_one(xd: float, yd: float, c: np.ndarray, r2_valid: float, tol: float):  # pragma: no cover
    """Solve distort(x, y) = (xd, yd) for the ideal point inside the valid disk.

    Damped Newton from (xd, yd): each step is halved until the residual falls and the
    iterate stays inside the valid disk, where the map is one-to-one, so the solution found
    is the only one there. Returns (x, y, ok); ok is False when no solution within ``tol``
    (normalised units) exists inside the disk."""
    x = xd
    y = yd
    if x * x + y * y > r2_valid:
        s = math.sqrt(r2_valid / (x * x + y * y)) * 0.999
        x *= s
        y *= s
    fxd, fyd, j00, j01, j10, j11, _n, _d = distort(x, y, c)
    ex = fxd - xd
    ey = fyd - yd
    err = ex * ex + ey * ey
    for _ in range(100):
        if err <= tol * tol:
            return x, y, True
        det = j00 * j11 - j01 * j10
        if det == 0.0 or not math.isfinite(det):
            return x, y, False
        sx = (j11 * ex - j01 * ey) / det
        sy = (-j10 * ex + j00 * ey) / det
        step = 1.0
        improved = False
        for _h in range(40):
            nx = x - step * sx
            ny = y - step * sy
            if nx * nx + ny * ny <= r2_valid:
                a, b, k00, k01, k10, k11, _n, _d = distort(nx, ny, c)
                nex = a - xd
                ney = b - yd
                nerr = nex * nex + ney * ney
                if nerr < err:
                    x, y, ex, ey, err = nx, ny, nex, ney, nerr
                    j00, j01, j10, j11 = k00, k01, k10, k11
                    improved = True
                    break
            step *= 0.5
        if not improved:
            return x, y, err <= tol * tol
    return x, y, err <= tol * tol


@njit(cache=True, nogil=True, parallel=True, error_model="numpy")
def unproject(px: np.ndarray, intr: np.ndarray, c: np.ndarray, r2_valid: float, tol: float,
              out: np.ndarray) -> None:  # pragma: no cover
    """Unit rays through pixels; NaN where no ideal point in the valid disk images there."""
    fx, fy, cx, cy, skew = intr[0], intr[1], intr[2], intr[3], intr[4]
    for i in prange(px.shape[0]):
        yd = (px[i, 1] - cy) / fy
        xd = (px[i, 0] - cx - skew * yd) / fx
        x, y, ok = undistort_one(xd, yd, c, r2_valid, tol)
        if ok:
            inv = 1.0 / math.sqrt(x * x + y * y + 1.0)
            out[i, 0] = x * inv
            out[i, 1] = y * inv
            out[i, 2] = inv
        else:
            out[i, 0] = np.nan
            out[i, 1] = np.nan
            out[i, 2] = np.nan
