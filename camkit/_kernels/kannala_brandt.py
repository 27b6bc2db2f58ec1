"""Kannala-Brandt fisheye: theta_d = theta (1 + k1 theta^2 + k2 theta^4 + k3 theta^6 + k4 theta^8).

Coefficients travel as ``c = [k1, k2, k3, k4]``; intrinsics as ``fx fy cx cy skew``.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from camkit._kernels.rotation import PARALLEL_MIN_ROWS


@njit(cache=True, nogil=True, error_model="numpy")
def theta_d(t: float, c: np.ndarray):  # pragma: no cover - numba
    """theta_d(theta) and its derivative."""
    t2 = t * t
    poly = 1.0 + t2 * (c[0] + t2 * (c[1] + t2 * (c[2] + t2 * c[3])))
    dpoly = 1.0 + t2 * (3.0 * c[0] + t2 * (5.0 * c[1] + t2 * (7.0 * c[2] + t2 * 9.0 * c[3])))
    return t * poly, dpoly


@njit(cache=True, nogil=True, error_model="numpy")
def valid_theta(c: np.ndarray, n_steps: int) -> float:  # pragma: no cover
    """Largest theta in [0, pi] up to which theta_d is strictly increasing (one-to-one)."""
    dt = math.pi / n_steps
    for i in range(1, n_steps + 1):
        _v, d = theta_d(i * dt, c)
        if d <= 0.0:
            return (i - 1) * dt
    return math.pi


@njit(cache=True, nogil=True, parallel=True, error_model="numpy")
def project(pts: np.ndarray, intr: np.ndarray, c: np.ndarray, t_valid: float,
            out: np.ndarray) -> None:  # pragma: no cover
    fx, fy, cx, cy, skew = intr[0], intr[1], intr[2], intr[3], intr[4]
    for i in prange(pts.shape[0]):
        X = pts[i, 0]
        Y = pts[i, 1]
        rho = math.sqrt(X * X + Y * Y)
        t = math.atan2(rho, pts[i, 2])
        if t > t_valid or (rho == 0.0 and pts[i, 2] <= 0.0):
            out[i, 0] = np.nan
            out[i, 1] = np.nan
            continue
        td, _d = theta_d(t, c)
        s = td / rho if rho > 0.0 else 0.0
        xd = s * X
        yd = s * Y
        out[i, 0] = fx * xd + skew * yd + cx
        out[i, 1] = fy * yd + cy


@njit(cache=True, nogil=True, error_model="numpy")
def project_jacobian_rows(pts: np.ndarray, intr: np.ndarray, c: np.ndarray, t_valid: float,
                     uv: np.ndarray, dp: np.ndarray, dk: np.ndarray, lo: int, hi: int) -> None:  # pragma: no cover
    """Parameters: fx fy cx cy skew k1 k2 k3 k4 (dk zero-initialised)."""
    fx, fy, skew = intr[0], intr[1], intr[4]
    for i in range(lo, hi):
        X = pts[i, 0]
        Y = pts[i, 1]
        Z = pts[i, 2]
        rho2 = X * X + Y * Y
        rho = math.sqrt(rho2)
        t = math.atan2(rho, Z)
        if t > t_valid or (rho == 0.0 and Z <= 0.0):
            for a in range(2):
                uv[i, a] = np.nan
                for b in range(3):
                    dp[i, a, b] = np.nan
                for b in range(dk.shape[2]):
                    dk[i, a, b] = np.nan
            continue
        g, dg = theta_d(t, c)
        R2 = rho2 + Z * Z
        if rho > 0.0:
            ux = X / rho
            uy = Y / rho
            xd = g * ux
            yd = g * uy
            # d(xd)/d(X, Y, Z) with theta = atan2(rho, Z), unit direction (ux, uy)
            a = dg * Z / R2  # d theta / d rho times dg
            b = g / rho
            dxdX = a * ux * ux + b * uy * uy
            dxdY = (a - b) * ux * uy
            dydY = a * uy * uy + b * ux * ux
            dxdZ = -dg * rho / R2 * ux
            dydZ = -dg * rho / R2 * uy
        else:
            ux = 0.0
            uy = 0.0
            xd = 0.0
            yd = 0.0
            dxdX = 1.0 / Z
            dxdY = 0.0
            dydY = 1.0 / Z
            dxdZ = 0.0
            dydZ = 0.0
        dydX = dxdY
        uv[i, 0] = fx * xd + skew * yd + intr[2]
        uv[i, 1] = fy * yd + intr[3]
        dp[i, 0, 0] = fx * dxdX + skew * dydX
        dp[i, 0, 1] = fx * dxdY + skew * dydY
        dp[i, 0, 2] = fx * dxdZ + skew * dydZ
        dp[i, 1, 0] = fy * dydX
        dp[i, 1, 1] = fy * dydY
        dp[i, 1, 2] = fy * dydZ
        dk[i, 0, 0] = xd
        dk[i, 0, 2] = 1.0
        dk[i, 0, 4] = yd
        dk[i, 1, 1] = yd
        dk[i, 1, 3] = 1.0
        tp = t * t * t
        for p in range(4):
            gx = tp * ux
            gy = tp * uy
            dk[i, 0, 5 + p] = fx * gx + skew * gy
            dk[i, 1, 5 + p] = fy * gy
            tp *= t * t


@njit(cache=True, nogil=True, parallel=True, error_model="numpy")
def project_jacobian_parallel(pts: np.ndarray, intr: np.ndarray, c: np.ndarray, t_valid: float,
                     uv: np.ndarray, dp: np.ndarray, dk: np.ndarray) -> None:  # pragma: no cover
    n = pts.shape[0]
    for chunk in prange((n + 1023) // 1024):
        project_jacobian_rows(pts, intr, c, t_valid, uv, dp, dk, chunk * 1024, min(n, (chunk + 1) * 1024))


def project_jacobian(pts: np.ndarray, intr: np.ndarray, c: np.ndarray, t_valid: float,
                     uv: np.ndarray, dp: np.ndarray, dk: np.ndarray) -> None:
    """Serial below PARALLEL_MIN_ROWS rows (a parallel launch costs more than their work)."""
    if pts.shape[0] < PARALLEL_MIN_ROWS:
        project_jacobian_rows(pts, intr, c, t_valid, uv, dp, dk, 0, pts.shape[0])
    else:
        project_jacobian_parallel(pts, intr, c, t_valid, uv, dp, dk)


@njit(cache=True, nogil=True, error_model="numpy")
def solve_theta(td: float, c: np.ndarray, t_valid: float, td_valid: float, tol: float):  # pragma: no cover
    """theta in [0, t_valid] with theta_d(theta) = td: Newton safeguarded by bisection on a
    bracket where theta_d is increasing, so it always converges. (theta, ok)."""
    if not (td <= td_valid):  # also refuses NaN
        return 0.0, False
    lo = 0.0
    hi = t_valid
    t = min(td, t_valid)
    for _ in range(200):
        v, d = theta_d(t, c)
        f = v - td
        if abs(f) <= tol:
            return t, True
        if f > 0.0:
            hi = t
        else:
            lo = t
        nt = t - f / d if d > 0.0 else 0.5 * (lo + hi)
        if not (lo < nt < hi):
            nt = 0.5 * (lo + hi)
        if nt == t:
            break
        t = nt
    v, d = theta_d(t, c)
    return t, abs(v - td) <= tol


@njit(cache=True, nogil=True, parallel=True, error_model="numpy")
def unproject(px: np.ndarray, intr: np.ndarray, c: np.ndarray, t_valid: float, td_valid: float,
              tol: float, out: np.ndarray) -> None:  # pragma: no cover
    fx, fy, cx, cy, skew = intr[0], intr[1], intr[2], intr[3], intr[4]
    for i in prange(px.shape[0]):
        yd = (px[i, 1] - cy) / fy
        xd = (px[i, 0] - cx - skew * yd) / fx
        rd = math.sqrt(xd * xd + yd * yd)
        t, ok = solve_theta(rd, c, t_valid, td_valid, tol)
        if not ok:
            out[i, 0] = np.nan
            out[i, 1] = np.nan
            out[i, 2] = np.nan
            continue
        st = math.sin(t)
        if rd > 0.0:
            out[i, 0] = st * xd / rd
            out[i, 1] = st * yd / rd
        else:
            out[i, 0] = 0.0
            out[i, 1] = 0.0
        out[i, 2] = math.cos(t)
