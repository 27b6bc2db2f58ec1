"""Triangulation of point pairs seen by two calibrated cameras, with the 3-D point's
covariance from the pixel noise and from the calibration's own uncertainty."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from camkit._repr import summary_repr
from camkit._validate import as_finite_float, as_points, as_positive_int
from camkit.calib.rig import CameraRig, RigResult
from camkit.errors import ParameterError, ShapeError
from camkit.geometry.pose import Pose
from camkit.geometry.rotation import matrix_from_rvec
from camkit.lens.base import CameraModel
from camkit.stereo.rectify import StereoRectification

__all__ = ["Triangulation", "epipolar_error", "triangulate"]


@dataclass(frozen=True, slots=True, eq=False)
class Triangulation:
    """Points triangulated from two cameras.

    Attributes
    ----------
    points : ndarray, (N, 3)
        In the left (first) camera's frame, in the calibration's unit (metres); NaN rows where
        the rays do not meet in front of both cameras.
    covariance : ndarray, (N, 3, 3)
        Of each point: ``sigma_px^2 (J^T J)^-1`` from the pixel noise, plus, with a
        :class:`~camkit.calib.RigResult`, the calibration's covariance carried through the
        point's dependence on the two cameras' parameters.
    reprojection_px : ndarray, (N, 2)
        Distance of each point's image from the given pixel, left and right.
    """

    points: np.ndarray
    covariance: np.ndarray
    reprojection_px: np.ndarray

    def __repr__(self) -> str:
        return summary_repr(self)

    def sigma(self) -> np.ndarray:
        """One-sigma along each point's worst direction, (N,) (square root of the covariance's
        largest eigenvalue)."""
        return np.sqrt(np.maximum(np.linalg.eigvalsh(self.covariance)[:, -1], 0.0))


def _pair(pair: Any, cameras: tuple[Any, Any]) -> tuple[CameraModel, CameraModel, Pose, RigResult | None]:
    if isinstance(pair, RigResult):
        a, b = pair.index(cameras[0]), pair.index(cameras[1])
        if a == b:
            raise ParameterError(f"cameras: expected two different cameras, got {cameras!r}")
        return pair.cameras[a].model, pair.cameras[b].model, pair.relative_pose(a, b), pair
    if isinstance(pair, CameraRig):
        a, b = pair.index(cameras[0]), pair.index(cameras[1])
        if a == b:
            raise ParameterError(f"cameras: expected two different cameras, got {cameras!r}")
        return pair.models[a], pair.models[b], pair.relative_pose(a, b), None
    if isinstance(pair, StereoRectification):
        raise ParameterError("pair: expected a RigResult, CameraRig or (left, right, left_from_right); a "
                             "StereoRectification "
                             "holds no calibration covariance: pass (rect.left_model, rect.right_model, "
                             "left_from_right)")
    if isinstance(pair, tuple) and len(pair) == 3:
        left, right, pose = pair
        for name, m in (("pair[0] (left)", left), ("pair[1] (right)", right)):
            if not isinstance(m, CameraModel):
                raise ParameterError(f"{name}: expected a camkit camera model, got {type(m).__name__}")
        if not isinstance(pose, Pose):
            raise ParameterError(f"pair[2] (left_from_right): expected a Pose, got {type(pose).__name__}")
        return left, right, pose, None
    raise ParameterError("pair: expected a RigResult or a tuple (left model, right model, left_from_right), got "
                         f"{type(pair).__name__}")


def _project_both(left: CameraModel, right: CameraModel, Rrl: np.ndarray, trl: np.ndarray, X: np.ndarray):
    ul, dl, kl = left.project_with_jacobian(X)
    Xr = X @ Rrl.T + trl
    ur, dr, kr = right.project_with_jacobian(Xr)
    return ul, ur, dl, dr @ Rrl, kl, kr


def triangulate(px_left: Any, px_right: Any, pair: Any, *, cameras: tuple[Any, Any] = (0, 1),
                sigma_px: float = 0.0, max_iterations: int = 10) -> Triangulation:
    """The 3-D points whose images are ``px_left`` in one camera and ``px_right`` in the other.

    Each pair of rays starts at their midpoint (the closest point between them), then the
    reprojection error in both images is minimised (Gauss-Newton, 3 unknowns a point, all
    points at once): with lens distortion the midpoint of the rays is not the most likely
    point.

    Parameters
    ----------
    px_left, px_right : array_like, (N, 2)
        Corresponding pixels in the two source images.
    pair : RigResult, CameraRig, or (left model, right model, left_from_right Pose)
        With a RigResult or CameraRig, cameras ``cameras`` (names or indices) are used; with a
        RigResult the covariance includes the calibration's.
    sigma_px : float
        Standard deviation of the pixel positions (each axis, each image).
    max_iterations : int

    Returns
    -------
    Triangulation
    """
    left, right, pose, rig = _pair(pair, cameras)
    pl = as_points(px_left, 2, "px_left", nan_rows=True)
    pr = as_points(px_right, 2, "px_right", nan_rows=True)
    if pl.ndim != 2 or pl.shape != pr.shape:
        raise ShapeError(f"px_left, px_right: expected two (N, 2) arrays of the same shape, got {pl.shape} and "
                         f"{pr.shape}")
    s = as_finite_float(sigma_px, "sigma_px")
    if s < 0:
        raise ParameterError(f"sigma_px: expected a number >= 0, got {s}")
    iters = as_positive_int(max_iterations, "max_iterations")
    Rlr, tlr = pose.R, pose.t
    Rrl, trl = Rlr.T, -Rlr.T @ tlr
    # Midpoint of the two rays (in the left frame): s d1 and t + u d2 at closest approach.
    d1 = left.unproject(pl)
    d2 = right.unproject(pr) @ Rlr.T
    a, c, e = (d1 * d1).sum(-1), (d1 * d2).sum(-1), (d2 * d2).sum(-1)
    p1, p2 = d1 @ tlr, d2 @ tlr
    det = c * c - a * e
    with np.errstate(invalid="ignore", divide="ignore"):
        sl = (c * p2 - e * p1) / det
        ur = (a * p2 - c * p1) / det
    X = 0.5 * (sl[:, None] * d1 + tlr + ur[:, None] * d2)
    good = np.isfinite(X).all(axis=1) & (sl > 0) & (ur > 0) & (np.abs(det) > 1e-12)
    X[~good] = np.nan
    obs = np.concatenate([pl, pr], axis=1)
    for _ in range(iters):
        if not good.any():
            break
        ul, ur_, Jl, Jr, _, _ = _project_both(left, right, Rrl, trl, X[good])
        r = np.concatenate([ul, ur_], axis=1) - obs[good]
        J = np.concatenate([Jl, Jr], axis=1)
        JtJ = np.einsum("nki,nkj->nij", J, J)
        step = np.linalg.solve(JtJ + 1e-12 * np.eye(3), -np.einsum("nki,nk->ni", J, r)[..., None])[..., 0]
        X[good] += step
        if np.abs(step).max(initial=0.0) < 1e-12 * max(1.0, float(np.nanmax(np.abs(X)))):
            break
    cov = np.full((len(pl), 3, 3), np.nan)
    rep = np.full((len(pl), 2), np.nan)
    if good.any():
        Xg = X[good]
        ul, ur_, Jl, Jr, kl, kr = _project_both(left, right, Rrl, trl, Xg)
        J = np.concatenate([Jl, Jr], axis=1)
        inv = np.linalg.inv(np.einsum("nki,nkj->nij", J, J))
        C = s * s * inv
        if rig is not None:
            D = _calibration_jacobian(rig, pair.index(cameras[0]), pair.index(cameras[1]), Xg, kl, kr)
            idx, dr_dtheta = D
            dX = -np.einsum("nij,nkj,nkp->nip", inv, J, dr_dtheta)
            C = C + np.einsum("nip,pq,njq->nij", dX, rig.covariance[np.ix_(idx, idx)], dX)
        cov[good] = C
        rep[good] = np.stack([np.hypot(*(ul - pl[good]).T), np.hypot(*(ur_ - pr[good]).T)], axis=-1)
    front = np.isfinite(X).all(axis=1)
    if front.any():
        zr = X[front] @ Rrl.T + trl
        bad = np.flatnonzero(front)[(X[front, 2] <= 0) | (zr[:, 2] <= 0)]
        X[bad] = np.nan
        cov[bad] = np.nan
    return Triangulation(points=X, covariance=cov, reprojection_px=rep)


def _calibration_jacobian(rig: RigResult, a: int, b: int, X: np.ndarray, kl: np.ndarray,
                          kr: np.ndarray) -> tuple[list[int], np.ndarray]:
    """d residuals / d the rig's parameters of cameras ``a`` and ``b`` at the points ``X``
    (left frame), (N, 4, P), and their indices into ``rig.param_names``: the intrinsics
    analytically (the lens models' Jacobians), the cameras' poses by central differences."""
    ia, pa = rig.block(a)
    ib, pb = rig.block(b)
    ma, mb = rig.cameras[a].model, rig.cameras[b].model
    idx = ia + ib + pa + pb
    out = np.zeros((len(X), 4, len(idx)))
    names_a = [rig.param_names[k].rpartition(".")[2] for k in ia]
    names_b = [rig.param_names[k].rpartition(".")[2] for k in ib]
    out[:, :2, :len(ia)] = kl[:, :, [ma.param_names.index(n) for n in names_a]]
    out[:, 2:, len(ia):len(ia) + len(ib)] = kr[:, :, [mb.param_names.index(n) for n in names_b]]
    Ta, Tb = rig.cam_from_rig[a], rig.cam_from_rig[b]
    col = len(ia) + len(ib)
    for which, block in ((0, pa), (1, pb)):
        for j in range(len(block)):
            d = np.zeros(6)
            h = 1e-7
            d[j] = h
            diffs = []
            for sign in (1.0, -1.0):
                T = Ta if which == 0 else Tb
                Tp = Pose._unchecked(matrix_from_rvec(sign * d[:3]) @ T.R, T.t + sign * d[3:])
                ta, tb = (Tp, Tb) if which == 0 else (Ta, Tp)
                # X is fixed in the left camera's frame: move it through the rig to the right one.
                diffs.append(mb.project((tb @ ta.inverse()).apply(X)))
            out[:, 2:, col] = (diffs[0] - diffs[1]) / (2 * h)
            col += 1
    return idx, out


def epipolar_error(px_left: Any, px_right: Any, rectification: StereoRectification) -> np.ndarray:
    """How far each pair of pixels is from being images of one point: the difference of their
    rows in the rectified images (columns for a vertical pair), in rectified pixels, (N,)."""
    if not isinstance(rectification, StereoRectification):
        raise ParameterError(f"rectification: expected a StereoRectification (camkit.stereo.rectify), got "
                             f"{type(rectification).__name__}")
    ql = rectification.rectify_points(px_left, "left")
    qr = rectification.rectify_points(px_right, "right")
    if ql.shape != qr.shape:
        raise ShapeError(f"px_left, px_right: expected the same shape, got {ql.shape} and {qr.shape}")
    k = 0 if rectification.vertical else 1
    return ql[..., k] - qr[..., k]
