"""Zhang's closed-form calibration from plane homographies."""

from __future__ import annotations

import numpy as np

from camkit.errors import EstimationError
from camkit.geometry.pose import Pose

__all__ = ["intrinsics_from_homographies", "poses_from_homographies"]


def _v(H: np.ndarray, i: int, j: int) -> np.ndarray:
    hi, hj = H[:, i], H[:, j]
    return np.array([hi[0] * hj[0], hi[0] * hj[1] + hi[1] * hj[0], hi[1] * hj[1],
                     hi[2] * hj[0] + hi[0] * hj[2], hi[2] * hj[1] + hi[1] * hj[2], hi[2] * hj[2]])


#: Said where the linear solution is not a camera (B = K^-T K^-1 not positive definite, or a
#: negative focal length squared): the views are too few or too alike, or one is wrong.
_NO_CAMERA = ("views: no camera explains these views of the board: they are too few or too alike (the board "
              "seen square-on, or always tilted the same way), or one detection is wrong. Photograph the board "
              "tilted 10-50 degrees about different axes, near the image's corners and edges too, in 10 or more "
              "photos")


def intrinsics_from_homographies(homographies: list[np.ndarray], *, zero_skew: bool = True) -> np.ndarray:
    """The intrinsic matrix K from the homographies of >= 3 views of a plane (>= 2 with
    ``zero_skew``).

    Each homography ``H = [h1 h2 h3] ~ K [r1 r2 t]`` gives two linear constraints on
    ``B = K^-T K^-1`` (``h1^T B h2 = 0``, ``h1^T B h1 = h2^T B h2``); B is the null vector of
    the stacked system and K follows in closed form (Z. Zhang, "A flexible new technique for
    camera calibration", IEEE TPAMI 22(11), 2000, sec. 3.1 and appendix B).
    """
    Hs = [np.asarray(H, dtype=np.float64) for H in homographies]
    need = 2 if zero_skew else 3
    if len(Hs) < need:
        raise EstimationError(f"views: Zhang's method needs at least {need} views of the board"
                              f"{' (skew held at 0)' if zero_skew else ''}, got {len(Hs)}; take more photos")
    rows = []
    for H in Hs:
        H = H / np.linalg.norm(H)
        rows.append(_v(H, 0, 1))
        rows.append(_v(H, 0, 0) - _v(H, 1, 1))
    if zero_skew:
        rows.append(np.array([0.0, 1.0, 0.0, 0.0, 0.0, 0.0]) * np.abs(np.array(rows)).max())
    V = np.array(rows)
    _, s, vt = np.linalg.svd(V)
    b = vt[-1]
    if s[-2] < 1e-10 * s[0]:
        raise EstimationError("views: the board orientations do not constrain the intrinsics (all views "
                              "parallel, or pure translations); tilt the board differently between photos")
    B11, B12, B22, B13, B23, B33 = b
    if B11 < 0:
        B11, B12, B22, B13, B23, B33 = -b
    den = B11 * B22 - B12 * B12
    if B11 <= 0 or den <= 0:
        raise EstimationError(_NO_CAMERA)
    v0 = (B12 * B13 - B11 * B23) / den
    lam = B33 - (B13 * B13 + v0 * (B12 * B13 - B11 * B23)) / B11
    if lam / B11 <= 0:
        raise EstimationError(_NO_CAMERA)
    alpha = np.sqrt(lam / B11)
    beta = np.sqrt(lam * B11 / den)
    gamma = -B12 * alpha * alpha * beta / lam
    u0 = gamma * v0 / beta - B13 * alpha * alpha / lam
    return np.array([[alpha, gamma, u0], [0.0, beta, v0], [0.0, 0.0, 1.0]])


def poses_from_homographies(K: np.ndarray, homographies: list[np.ndarray]) -> list[Pose]:
    """``cam_from_target`` of each view: ``r1 = l K^-1 h1, r2 = l K^-1 h2, r3 = r1 x r2,
    t = l K^-1 h3`` with ``l = 1 / |K^-1 h1|``, the board in front of the camera, and R the
    nearest rotation (Zhang 2000, sec. 3.1 and appendix C)."""
    if len(homographies) == 0:
        return []
    A = np.linalg.inv(K) @ np.asarray(homographies, dtype=np.float64)  # all views at once
    lam = 1.0 / np.linalg.norm(A[:, :, 0], axis=1)
    lam = np.where(A[:, 2, 2] * lam < 0, -lam, lam)  # the board in front of the camera (t_z > 0)
    r1, r2, t = lam[:, None] * A[:, :, 0], lam[:, None] * A[:, :, 1], lam[:, None] * A[:, :, 2]
    R = np.stack([r1, r2, np.cross(r1, r2)], axis=2)
    u, _, vt = np.linalg.svd(R)
    D = np.ones((len(R), 3))
    D[:, 2] = np.linalg.det(u @ vt)
    R = (u * D[:, None, :]) @ vt
    # R is a rotation by construction (SVD above)
    poses = [Pose._unchecked(Ri, ti) for Ri, ti in zip(R, t, strict=True)]
    return poses
