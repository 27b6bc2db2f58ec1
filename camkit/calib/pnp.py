"""Pose of a known camera from 2-D/3-D correspondences (perspective-n-point)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from camkit._repr import summary_repr
from camkit._validate import as_points
from camkit.calib.homography import find_homography
from camkit.calib.refine import Linearization, LMOptions, solve
from camkit.calib.views import pose_jacobian
from camkit.errors import EstimationError, ParameterError, ShapeError
from camkit.geometry.pose import Pose
from camkit.geometry.rotation import matrix_from_rvec
from camkit.lens.base import CameraModel

__all__ = ["PnPResult", "solve_pnp"]


@dataclass(frozen=True, slots=True, eq=False)
class PnPResult:
    """The pose found, its reprojection error, and how the refinement ended."""

    cam_from_object: Pose
    rms_px: float
    converged: bool
    iterations: int
    message: str

    def __repr__(self) -> str:
        return summary_repr(self)


def _nearest_rotation(M: np.ndarray) -> np.ndarray:
    u, _, vt = np.linalg.svd(M)
    return u @ np.diag([1.0, 1.0, np.linalg.det(u @ vt)]) @ vt


def solve_pnp(object_points: Any, pixels: Any, model: CameraModel, *, max_iterations: int = 100) -> PnPResult:
    """``cam_from_object`` from object points and their pixels, the camera known.

    The pixels are unprojected to rays (so any lens model works), a linear start is made on
    the normalised coordinates (a plane homography for >= 4 coplanar points, Zhang's
    decomposition; the DLT of ``[R | t]`` for >= 6 points in general position), and the pose is
    refined by Levenberg-Marquardt (:func:`camkit.calib.refine.solve`) on the reprojection error
    in pixels.

    Parameters
    ----------
    object_points : array_like, (N, 3)
    pixels : array_like, (N, 2)
    model : CameraModel

    Raises
    ------
    EstimationError
        Too few points, collinear points, or pixels outside the lens's valid region.
    """
    X = as_points(object_points, 3, "object_points")
    u = as_points(pixels, 2, "pixels")
    if X.ndim != 2 or X.shape[0] != u.shape[0] or u.ndim != 2:
        raise ShapeError(f"object_points, pixels: expected (N, 3) and (N, 2), got {X.shape} and {u.shape}")
    if not isinstance(model, CameraModel):
        raise ParameterError(f"model: expected a camkit camera model, got {type(model).__name__}")
    n = len(X)
    if n < 4:
        raise EstimationError(f"points: the pose needs at least 4 points (coplanar) or 6 (general), got {n}")
    rays = model.unproject(u)
    if not (np.isfinite(rays).all() and (rays[:, 2] > 1e-6).all()):
        raise EstimationError("pixels: some pixels have no ray in front of the camera under this model")
    xn = rays[:, :2] / rays[:, 2:]
    centre = X.mean(axis=0)
    _, s, vt = np.linalg.svd(X - centre)
    if s[1] < 1e-9 * max(s[0], 1e-300):
        raise EstimationError("object_points: the points are collinear; the rotation about their line is undetermined")
    if s[2] <= 1e-6 * s[0]:
        # Coplanar: plane frame (e1, e2, normal) at the centroid; homography plane -> normalised image.
        E = vt  # rows: e1, e2, normal
        q = (X - centre) @ E[:2].T
        H = find_homography(q, xn)
        lam = 1.0 / np.linalg.norm(H[:, 0])
        if H[2, 2] * lam < 0:
            lam = -lam
        r1, r2, t = lam * H[:, 0], lam * H[:, 1], lam * H[:, 2]
        R_plane = _nearest_rotation(np.stack([r1, r2, np.cross(r1, r2)], axis=1))
        R = R_plane @ E  # camera <- plane frame <- object
        t = t - R @ centre
    else:
        if n < 6:
            raise EstimationError(f"points: {n} points not on one plane; the general case needs at least 6")
        A = np.zeros((2 * n, 12))
        Xh = np.hstack([X - centre, np.ones((n, 1))])
        A[0::2, 0:4] = Xh
        A[0::2, 8:12] = -xn[:, :1] * Xh
        A[1::2, 4:8] = Xh
        A[1::2, 8:12] = -xn[:, 1:2] * Xh
        P = np.linalg.svd(A, full_matrices=False)[2][-1].reshape(3, 4)
        scale = np.cbrt(np.linalg.det(P[:, :3]))
        P = P / scale
        R = _nearest_rotation(P[:, :3])
        t = P[:, 3] - R @ centre
    pose = Pose(R, t)
    return _refine(pose, X, u, model, max_iterations)


class _PoseProblem:
    """Reprojection residuals of one pose, a global block alone (``R <- exp([w]x) R``,
    ``t <- t + dt``), for :func:`camkit.calib.refine.solve`."""

    global_names = ("wx", "wy", "wz", "tx", "ty", "tz")
    local_name = ""
    local_size = 0
    n_groups = 1

    def __init__(self, X: np.ndarray, u: np.ndarray, model: CameraModel) -> None:
        self.X, self.u, self.model = X, u, model
        self.group = np.zeros(len(X), dtype=np.int64)
        self.no_local = np.zeros((len(X), 2, 0))

    def linearize(self, pose: Pose) -> Linearization:
        RX = self.X @ pose.R.T
        uv, dp, _ = self.model.project_with_jacobian(RX + pose.t)
        return Linearization(uv - self.u, pose_jacobian(dp, RX), self.no_local, self.group)

    def retract(self, pose: Pose, d_global: np.ndarray, d_local: np.ndarray) -> Pose:
        return Pose(matrix_from_rvec(d_global[:3]) @ pose.R, pose.t + d_global[3:])


def _refine(pose: Pose, X: np.ndarray, u: np.ndarray, model: CameraModel, max_iterations: int) -> PnPResult:
    problem = _PoseProblem(X, u, model)
    if not np.isfinite(problem.linearize(pose).residuals).all():
        raise EstimationError("start: the linear pose puts points behind the camera or outside the lens's valid "
                              "region; check the correspondences")
    report = solve(problem, pose, LMOptions(max_iterations=max_iterations, tolerance=1e-14, damping=1e-3,
                                            covariance=False))
    r = report.residuals
    return PnPResult(report.state, float(np.sqrt((r * r).sum() / len(X))), report.converged, report.iterations,
                     report.message)
