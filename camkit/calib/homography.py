"""Plane-to-image homographies by the normalised direct linear transform."""

from __future__ import annotations

from typing import Any

import numpy as np

from camkit._kernels import calib as calib_kernels
from camkit._validate import as_points
from camkit.calib.refine import Linearization, LMOptions, solve
from camkit.errors import EstimationError, ShapeError

__all__ = ["find_homography"]


def find_homography(plane_points: Any, pixels: Any, *, refine: bool = True) -> np.ndarray:
    """The homography ``H`` with ``lambda [u, v, 1] = H [x, y, 1]`` from plane points to pixels.

    Normalised DLT (R. Hartley, "In defense of the eight-point algorithm", IEEE TPAMI 19(6),
    1997; Hartley & Zisserman, *Multiple View Geometry*, alg. 4.2), then, with ``refine``,
    Levenberg-Marquardt (:func:`camkit.calib.refine.solve`) on the reprojection error in the
    image (the maximum-likelihood estimate for Gaussian pixel noise).

    Parameters
    ----------
    plane_points : array_like, (N, 2), N >= 4, not collinear
    pixels : array_like, (N, 2)

    Returns
    -------
    ndarray, (3, 3), scaled so that ``H[2, 2] = 1`` (or unit norm if that entry is ~0)
    """
    X = as_points(plane_points, 2, "plane_points")
    u = as_points(pixels, 2, "pixels")
    if X.ndim != 2 or X.shape != u.shape:
        raise ShapeError(f"plane_points, pixels: expected equal shapes (N, 2), got {X.shape} and {u.shape}")
    n = X.shape[0]
    if n < 4:
        raise EstimationError(f"points: a homography needs at least 4 correspondences, got {n}")
    M, Tx, Tu, ok = calib_kernels.dlt_normal(X, u)
    if not ok:
        raise EstimationError("points: all points coincide; a homography needs at least 4 spread points")
    # The null vector of A from the 9x9 normal matrix (eigh of 9x9, much cheaper than the SVD
    # of the 2N x 9 matrix A). Its eigenvalues are the squared singular values, known
    # only to ~1e-16 of the largest, so a near-degenerate set is decided on A's SVD.
    lam, vec = np.linalg.eigh(M)
    if lam[1] < 1e-10 * lam[8]:
        Hn = _dlt_svd(X, u, Tx, Tu)
    else:
        Hn = vec[:, 0].reshape(3, 3)
    H = np.linalg.solve(Tu, Hn @ Tx)
    H = H / H[2, 2] if abs(H[2, 2]) > 1e-12 * np.abs(H).max() else H / np.linalg.norm(H)
    if refine:
        H = _refine(H, X, u)
    return H


def dlt_homographies(plane_points: list[np.ndarray], pixels: list[np.ndarray]) -> list[np.ndarray | None]:
    """:func:`find_homography` without refinement for many views at once (one pass of the
    normal matrices, one stacked eigendecomposition): each view's ``H``, or None where
    ``find_homography`` would raise (fewer than 4 points, coincident or degenerate points).
    The inputs are already validated float arrays, (N_v, 2) each (a caller's own)."""
    n = len(plane_points)
    if n == 0:
        return []
    counts = np.array([len(x) for x in plane_points])
    start = np.concatenate([[0], np.cumsum(counts)]).astype(np.int64)
    X = np.ascontiguousarray(np.concatenate(plane_points), dtype=np.float64).reshape(-1, 2)
    u = np.ascontiguousarray(np.concatenate(pixels), dtype=np.float64).reshape(-1, 2)
    M, Tx, Tu, ok = calib_kernels.dlt_normal_many(X, u, start)
    lam, vec = np.linalg.eigh(M)
    Hn = vec[:, :, 0].reshape(n, 3, 3)
    H = np.linalg.solve(Tu, Hn @ Tx)
    out: list[np.ndarray | None] = []
    for v in range(n):
        if not ok[v]:
            out.append(None)
        elif lam[v, 1] < 1e-10 * lam[v, 8]:  # near-degenerate: decided on A's SVD, as find_homography does
            try:
                out.append(find_homography(X[start[v]:start[v + 1]], u[start[v]:start[v + 1]], refine=False))
            except EstimationError:
                out.append(None)
        else:
            h = H[v]
            out.append(h / h[2, 2] if abs(h[2, 2]) > 1e-12 * np.abs(h).max() else h / np.linalg.norm(h))
    return out


def _dlt_svd(X: np.ndarray, u: np.ndarray, Tx: np.ndarray, Tu: np.ndarray) -> np.ndarray:
    """The normalised DLT's solution from the SVD of A, with the degeneracy test."""
    n = len(X)
    Xn = X @ Tx[:2, :2].T + Tx[:2, 2]
    un = u @ Tu[:2, :2].T + Tu[:2, 2]
    A = np.zeros((2 * n, 9))
    A[0::2, 0:2] = Xn
    A[0::2, 2] = 1
    A[0::2, 6:8] = -un[:, :1] * Xn
    A[0::2, 8] = -un[:, 0]
    A[1::2, 3:5] = Xn
    A[1::2, 5] = 1
    A[1::2, 6:8] = -un[:, 1:2] * Xn
    A[1::2, 8] = -un[:, 1]
    _, s, vt = np.linalg.svd(A, full_matrices=False)
    if s[-2] < 1e-9 * s[0]:
        raise EstimationError("points: degenerate configuration (collinear points?); a homography needs "
                              "at least 4 points, no 3 of them on a line")
    return vt[-1].reshape(3, 3)


def _project(h: np.ndarray, X: np.ndarray) -> np.ndarray:
    H = np.append(h, 1.0).reshape(3, 3)
    w = H[2, 0] * X[:, 0] + H[2, 1] * X[:, 1] + H[2, 2]
    return np.stack([(H[0, 0] * X[:, 0] + H[0, 1] * X[:, 1] + H[0, 2]) / w,
                     (H[1, 0] * X[:, 0] + H[1, 1] * X[:, 1] + H[1, 2]) / w], axis=-1)


class _HomographyProblem:
    """Reprojection residuals ``H(x) - u`` over the eight entries of H (``H[2, 2] = 1``): a
    global block alone, for :func:`camkit.calib.refine.solve`."""

    global_names = ("h00", "h01", "h02", "h10", "h11", "h12", "h20", "h21")
    local_name = ""
    local_size = 0
    n_groups = 1

    def __init__(self, X: np.ndarray, u: np.ndarray) -> None:
        self.X, self.u = X, u
        self.group = np.zeros(len(X), dtype=np.int64)
        self.no_local = np.zeros((len(X), 2, 0))

    def linearize(self, h: np.ndarray) -> Linearization:
        X = self.X
        Hm = np.append(h, 1.0).reshape(3, 3)
        w = Hm[2, 0] * X[:, 0] + Hm[2, 1] * X[:, 1] + 1.0
        p = _project(h, X)
        J = np.zeros((len(X), 2, 8))
        J[:, 0, 0:2] = X / w[:, None]
        J[:, 0, 2] = 1 / w
        J[:, 0, 6:8] = -p[:, :1] * X / w[:, None]
        J[:, 1, 3:5] = X / w[:, None]
        J[:, 1, 5] = 1 / w
        J[:, 1, 6:8] = -p[:, 1:2] * X / w[:, None]
        return Linearization(p - self.u, J, self.no_local, self.group)

    def retract(self, h: np.ndarray, d_global: np.ndarray, d_local: np.ndarray) -> np.ndarray:
        return h + d_global


def _refine(H: np.ndarray, X: np.ndarray, u: np.ndarray) -> np.ndarray:
    if abs(H[2, 2]) < 1e-12:
        return H
    h = (H / H[2, 2]).ravel()[:8]
    report = solve(_HomographyProblem(X, u), h, LMOptions(max_iterations=50, tolerance=1e-12, covariance=False))
    return np.append(report.state, 1.0).reshape(3, 3)
