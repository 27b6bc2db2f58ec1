"""Homogeneous coordinates and the 3x4 projection matrix ``P = K [R | t]``."""

from __future__ import annotations

from typing import Any

import numpy as np

from camkit._validate import as_matrix, as_points, as_real_array
from camkit.errors import ParameterError, ShapeError
from camkit.geometry.pose import Pose

__all__ = [
    "decompose_projection_matrix",
    "from_homogeneous",
    "projection_matrix",
    "to_homogeneous",
]


def _vectors(points: Any, name: str) -> np.ndarray:
    arr = as_real_array(points, name)
    if arr.ndim == 0 or arr.shape[-1] < 1:
        raise ShapeError(f"{name}: expected shape (..., n) with n >= 1, got {arr.shape}")
    return as_points(arr, arr.shape[-1], name)


def to_homogeneous(points: Any) -> np.ndarray:
    """Append a 1: (..., n) -> (..., n + 1).

    >>> to_homogeneous([[2.0, 3.0]])
    array([[2., 3., 1.]])
    """
    p = _vectors(points, "points")
    return np.concatenate([p, np.ones((*p.shape[:-1], 1))], axis=-1)


def from_homogeneous(points: Any) -> np.ndarray:
    """Divide by the last coordinate: (..., n + 1) -> (..., n); NaN rows where it is 0.

    >>> from_homogeneous([[4.0, 6.0, 2.0], [1.0, 1.0, 0.0]])
    array([[ 2.,  3.],
           [nan, nan]])
    """
    p = _vectors(points, "points")
    if p.shape[-1] < 2:
        raise ShapeError(f"points: expected shape (..., n + 1) with n >= 1, got {p.shape}")
    w = p[..., -1:]
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(w != 0, p[..., :-1] / w, np.nan)


def _rq(M: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """RQ decomposition ``M = R Q`` (R upper triangular, Q orthogonal) from NumPy's QR: with
    the reversal permutation P, ``(P M)^T = Q' R'`` gives ``M = (P R'^T P)(P Q'^T)``."""
    P = np.eye(3)[::-1]
    q, r = np.linalg.qr((P @ M).T)
    return P @ r.T @ P, P @ q.T


def _as_K(K: Any) -> np.ndarray:
    k = as_matrix(K, (3, 3), "K")
    if k[1, 0] != 0 or k[2, 0] != 0 or k[2, 1] != 0 or k[2, 2] != 1:
        raise ParameterError(f"K: expected upper triangular with K[2, 2] = 1, got {k.tolist()}")
    if k[0, 0] <= 0 or k[1, 1] <= 0:
        raise ParameterError(f"K: expected positive focal lengths, got fx={k[0, 0]}, fy={k[1, 1]}")
    return k


def projection_matrix(K: Any, cam_from_world: Pose) -> np.ndarray:
    """The 3x4 camera matrix ``P = K [R | t]``: ``lambda [u, v, 1] = P [X, Y, Z, 1]``.

    Parameters
    ----------
    K : array_like, (3, 3)
        Intrinsics, upper triangular, ``K[2, 2] = 1``, positive focal lengths.
    cam_from_world : Pose

    Returns
    -------
    ndarray, (3, 4)
    """
    k = _as_K(K)
    if not isinstance(cam_from_world, Pose):
        raise ParameterError(
            f"cam_from_world: expected a camkit.geometry.Pose, got {type(cam_from_world).__name__}"
        )
    return k @ np.hstack([cam_from_world.R, cam_from_world.t[:, None]])


def decompose_projection_matrix(P: Any) -> tuple[np.ndarray, Pose]:
    """Split ``P = s K [R | t]`` into ``K`` and ``cam_from_world`` by RQ decomposition.

    The RQ decomposition of the left 3x3 block gives an upper-triangular ``K`` and an
    orthogonal ``R``; signs are fixed so that ``K`` has a positive diagonal and ``det R = +1``
    (P is defined up to a scale that may be negative), and ``K`` is scaled so ``K[2, 2] = 1``
    (Hartley & Zisserman, *Multiple View Geometry*, 2nd ed., sec. 6.2.4).

    Parameters
    ----------
    P : array_like, (3, 4)
        Finite, with a non-singular left 3x3 block (a finite camera).

    Returns
    -------
    K : ndarray, (3, 3)
    cam_from_world : Pose

    Examples
    --------
    >>> import numpy as np
    >>> from camkit.geometry import Pose, projection_matrix
    >>> K = np.array([[800.0, 0, 320], [0, 810, 240], [0, 0, 1]])
    >>> pose = Pose.from_rvec([0.1, 0.2, 0.3], [1.0, 2.0, 3.0])
    >>> K2, pose2 = decompose_projection_matrix(-2.5 * projection_matrix(K, pose))
    >>> bool(np.allclose(K2, K) and pose2.allclose(pose))
    True
    """
    p = as_matrix(P, (3, 4), "P")
    M = p[:, :3]
    scale = np.abs(M).max()
    if scale == 0 or abs(np.linalg.det(M / scale)) < 1e-12:
        raise ParameterError(
            "P: expected a finite camera (non-singular left 3x3 block), got a singular one"
        )
    if np.linalg.det(M) < 0:
        p = -p
        M = p[:, :3]
    K, R = _rq(M)
    D = np.diag(np.sign(np.diag(K)))  # D D = I; K D has a positive diagonal
    K, R = K @ D, D @ R
    t = np.linalg.solve(K, p[:, 3])
    K = K / K[2, 2]
    return K, Pose(R, t)
