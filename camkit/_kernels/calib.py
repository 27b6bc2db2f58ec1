"""Kernels for estimation: the blocks of the normal equations, the DLT, stacked view rotations."""

from __future__ import annotations

import math

import numpy as np
from numba import njit


def make_normal_blocks(L: int):
    """The kernel ``normal_blocks(Jg, Jl, r, w, group, n_groups)`` for local blocks of size
    ``L`` (a compile-time constant: the local loops unroll, as the pose blocks' 6 did when the
    kernel was written for poses alone).

    Weighted normal-equation blocks of ``min sum_n w_n |r_n|^2`` over a global block g (shared
    by every observation) and local blocks l (observation n depends on block ``group[n]``
    only), in one pass. ``Jg`` (N, K, G) d residual / d global, ``Jl`` (N, K, L) d residual /
    d its local block, ``r`` (N, K), ``w`` (N,). Returns U (G, G), W (B, G, L), V (B, L, L),
    gg (G,), gl (B, L)."""

    @njit(cache=True, nogil=True, error_model="numpy")
    def normal_blocks(Jg, Jl, r, w, group, n_groups):  # pragma: no cover - numba
        N, K, G = Jg.shape
        U = np.zeros((G, G))
        W = np.zeros((n_groups, G, L))
        V = np.zeros((n_groups, L, L))
        gg = np.zeros(G)
        gl = np.zeros((n_groups, L))
        jl = np.empty(L)
        for n in range(N):
            v = group[n]
            wn = w[n]
            for a in range(K):
                for k in range(L):
                    jl[k] = Jl[n, a, k]
                ra = r[n, a] * wn
                for i in range(G):
                    if Jg[n, a, i] == 0.0:  # sparse rows (a camera's own intrinsics, a fixed camera): adds nothing
                        continue
                    ji = Jg[n, a, i] * wn
                    gg[i] += Jg[n, a, i] * ra
                    for j in range(i, G):
                        U[i, j] += ji * Jg[n, a, j]
                    for k in range(L):
                        W[v, i, k] += ji * jl[k]
                for k in range(L):
                    gl[v, k] += jl[k] * ra
                    jk = jl[k] * wn
                    for l in range(k, L):
                        V[v, k, l] += jk * jl[l]
        for i in range(G):
            for j in range(i):
                U[i, j] = U[j, i]
        for v in range(n_groups):
            for k in range(L):
                for l in range(k):
                    V[v, k, l] = V[v, l, k]
        return U, W, V, gg, gl

    return normal_blocks


@njit(cache=True, nogil=True, error_model="numpy")
def dlt_normal(X: np.ndarray, u: np.ndarray):  # pragma: no cover - numba
    """Hartley-normalised DLT for a plane-to-image homography in one pass over the points.

    Returns ``(M, Tx, Tu, ok)``: ``M = A^T A`` (9, 9) of the DLT rows built from the
    normalised points, the two normalising similarities (centroid to 0, mean distance to
    sqrt 2), and ``ok`` False when either point set collapses to one point."""
    n = X.shape[0]
    Tx = np.eye(3)
    Tu = np.eye(3)
    if not (_hartley(X, Tx) and _hartley(u, Tu)):
        return np.zeros((9, 9)), Tx, Tu, False
    M = np.zeros((9, 9))
    a = np.zeros(9)
    b = np.zeros(9)
    for i in range(n):
        x = Tx[0, 0] * X[i, 0] + Tx[0, 2]
        y = Tx[1, 1] * X[i, 1] + Tx[1, 2]
        p = Tu[0, 0] * u[i, 0] + Tu[0, 2]
        q = Tu[1, 1] * u[i, 1] + Tu[1, 2]
        # rows [x y 1 0 0 0 -px -py -p] and [0 0 0 x y 1 -qx -qy -q]
        a[0] = x
        a[1] = y
        a[2] = 1.0
        a[6] = -p * x
        a[7] = -p * y
        a[8] = -p
        b[3] = x
        b[4] = y
        b[5] = 1.0
        b[6] = -q * x
        b[7] = -q * y
        b[8] = -q
        for j in range(9):
            aj = a[j]
            bj = b[j]
            for k in range(9):
                M[j, k] += aj * a[k] + bj * b[k]
    return M, Tx, Tu, True


@njit(cache=True, nogil=True, error_model="numpy")
def dlt_normal_many(X: np.ndarray, u: np.ndarray, start: np.ndarray):  # pragma: no cover - numba
    """:func:`dlt_normal` for many point sets at once: set v is rows ``start[v]:start[v+1]``
    of the stacked ``X`` and ``u``. Returns ``(M (V, 9, 9), Tx (V, 3, 3), Tu (V, 3, 3), ok
    (V,))``; a set of fewer than 4 points is not ok."""
    V = start.shape[0] - 1
    M = np.zeros((V, 9, 9))
    Tx = np.zeros((V, 3, 3))
    Tu = np.zeros((V, 3, 3))
    ok = np.zeros(V, dtype=np.bool_)
    for v in range(V):
        a, b = start[v], start[v + 1]
        if b - a < 4:
            for i in range(3):
                Tx[v, i, i] = 1.0
                Tu[v, i, i] = 1.0
            continue
        M[v], Tx[v], Tu[v], ok[v] = dlt_normal(X[a:b], u[a:b])
    return M, Tx, Tu, ok


@njit(cache=True, nogil=True, error_model="numpy")
def _hartley(P: np.ndarray, T: np.ndarray) -> bool:  # pragma: no cover - numba
    """Fill T with the similarity moving P's centroid to 0 and its mean distance to sqrt 2
    (R. Hartley, IEEE TPAMI 19(6), 1997); False when the points coincide."""
    n = P.shape[0]
    cx = 0.0
    cy = 0.0
    for i in range(n):
        cx += P[i, 0]
        cy += P[i, 1]
    cx /= n
    cy /= n
    d = 0.0
    for i in range(n):
        d += math.sqrt((P[i, 0] - cx) ** 2 + (P[i, 1] - cy) ** 2)
    d /= n
    if d < 1e-12:
        return False
    s = math.sqrt(2.0) / d
    T[0, 0] = s
    T[1, 1] = s
    T[0, 2] = -s * cx
    T[1, 2] = -s * cy
    return True


@njit(cache=True, nogil=True, error_model="numpy")
def rotate_views(Rs: np.ndarray, ts: np.ndarray, obj: np.ndarray, view: np.ndarray):  # pragma: no cover - numba
    """``RX = R_v X`` and ``Xc = R_v X + t_v`` for stacked board points ``obj`` (N, 3) of views
    ``view`` (N,), poses ``Rs`` (V, 3, 3), ``ts`` (V, 3)."""
    N = obj.shape[0]
    RX = np.empty((N, 3))
    Xc = np.empty((N, 3))
    for n in range(N):
        v = view[n]
        x, y, z = obj[n, 0], obj[n, 1], obj[n, 2]
        for i in range(3):
            a = Rs[v, i, 0] * x + Rs[v, i, 1] * y + Rs[v, i, 2] * z
            RX[n, i] = a
            Xc[n, i] = a + ts[v, i]
    return RX, Xc


@njit(cache=True, nogil=True, error_model="numpy")
def pose_jacobian(dp: np.ndarray, RX: np.ndarray, out: np.ndarray) -> None:  # pragma: no cover - numba
    """``out`` (N, 2, 6) = ``[dp @ -[RX]x, dp]``: d pixel / d (w, dt) for ``R <- exp([w]x) R,
    t <- t + dt``, from ``dp`` (N, 2, 3) d pixel / d camera point and ``RX`` (N, 3) the rotated
    point (``dp @ -[X]x`` is ``X x dp`` row by row)."""
    for n in range(dp.shape[0]):
        x0, x1, x2 = RX[n, 0], RX[n, 1], RX[n, 2]
        for a in range(2):
            d0, d1, d2 = dp[n, a, 0], dp[n, a, 1], dp[n, a, 2]
            out[n, a, 0] = x1 * d2 - x2 * d1
            out[n, a, 1] = x2 * d0 - x0 * d2
            out[n, a, 2] = x0 * d1 - x1 * d0
            out[n, a, 3] = d0
            out[n, a, 4] = d1
            out[n, a, 5] = d2
