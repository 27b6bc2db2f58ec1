"""Rectification of a stereo pair: both cameras turned to one orientation with the baseline
along the image rows, so that a point's two images lie on the same row.

The rotations are Bouguet's (J.-Y. Bouguet, Camera Calibration Toolbox for Matlab,
``rectify_stereo_pair``; the construction OpenCV's ``stereoRectify`` uses): the relative
rotation is split in half between the two cameras, then both are turned together about the
axis that brings the baseline onto the x axis (the y axis for cameras one above the other).
The rectified cameras are pinholes with one focal length and one principal point
(disparity zero at infinity), chosen from where both images' borders land, as
:func:`camkit.resample.optimal_pinhole` chooses an undistorting camera.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from camkit._repr import summary_repr
from camkit._validate import as_finite_float, as_points, as_positive_int
from camkit.errors import CamkitError, ParameterError
from camkit.geometry.pose import Pose
from camkit.geometry.rotation import matrix_from_rvec, rvec_from_matrix
from camkit.lens.base import CameraModel
from camkit.lens.pinhole import Pinhole
from camkit.resample.maps import border_rectangles, fit_pinhole, reproject_map

__all__ = ["StereoRectification", "rectify", "rectify_maps"]


@dataclass(frozen=True, slots=True, eq=False)
class StereoRectification:
    """A rectified stereo pair.

    Attributes
    ----------
    left_model, right_model : CameraModel
        The cameras as calibrated (the sources of the rectified images).
    left, right : Pinhole
        The rectified cameras: the same ``fx = fy``, ``cx`` and ``cy``.
    rect_from_left, rect_from_right : ndarray, (3, 3)
        Rotations from each camera's frame into its rectified frame (OpenCV's ``R1``, ``R2``).
    baseline : ndarray, (3,)
        Where the right rectified camera's frame is in the left's: ``X_right = X_left + t``
        with ``t = baseline`` along one axis (``(Tx, 0, 0)``, ``Tx < 0`` for a right camera to
        the right; OpenCV's ``P2[:, 3] / f``).
    Q : ndarray, (4, 4)
        Disparity to depth: ``[X, Y, Z, W] = Q @ [x, y, d, 1]`` with ``d = x_left - x_right``
        (rectified pixels; ``y`` and the disparity along y for a vertical pair), the point
        ``(X, Y, Z) / W`` in the left rectified frame, as OpenCV's ``Q``.
    valid_left, valid_right : (x, y, width, height)
        The rectangle of each rectified image whose every pixel sees its source image.
    vertical : bool
        The cameras are one above the other (rectified columns, not rows, correspond).
    """

    left_model: CameraModel
    right_model: CameraModel
    left: Pinhole
    right: Pinhole
    rect_from_left: np.ndarray
    rect_from_right: np.ndarray
    baseline: np.ndarray
    Q: np.ndarray
    valid_left: tuple[int, int, int, int]
    valid_right: tuple[int, int, int, int]
    vertical: bool

    def __repr__(self) -> str:
        return summary_repr(self)

    @property
    def P_left(self) -> np.ndarray:
        """OpenCV's ``P1``: the left rectified camera's 3x4 projection matrix."""
        return np.c_[self.left.K, np.zeros(3)]

    @property
    def P_right(self) -> np.ndarray:
        """OpenCV's ``P2``: ``K [I | baseline]`` of the right rectified camera."""
        return np.c_[self.right.K, self.right.K @ self.baseline]

    def rectify_points(self, pixels: Any, side: str) -> np.ndarray:
        """Pixels of the ``side`` ("left" or "right") source image, (..., 2), where they land in
        its rectified image (NaN where the lens has no ray for them)."""
        if side not in ("left", "right"):
            raise ParameterError(f"side: expected 'left' or 'right', got {side!r}")
        src, dst, R = ((self.left_model, self.left, self.rect_from_left) if side == "left"
                       else (self.right_model, self.right, self.rect_from_right))
        px = as_points(pixels, 2, "pixels", nan_rows=True)
        return dst.project(src.unproject(px) @ R.T)


def _relative(left_from_right: Any) -> Pose:
    if isinstance(left_from_right, Pose):
        return left_from_right
    try:
        return Pose.from_matrix(left_from_right)
    except (CamkitError, TypeError, ValueError):
        raise ParameterError("left_from_right: expected a Pose (or a 4x4 matrix) mapping points in the right "
                             f"camera's frame into the left's, got {type(left_from_right).__name__}") from None


def rectify(left: CameraModel, right: CameraModel, left_from_right: Any, *, mode: str | float = "valid",
            size: tuple[int, int] | None = None) -> StereoRectification:
    """Rectify a calibrated stereo pair.

    Parameters
    ----------
    left, right : CameraModel
        The two cameras (any lens models whose image borders are in front of the camera).
    left_from_right : Pose
        Maps points in the right camera's frame into the left's (``RigResult.relative_pose
        ("left", "right")``). OpenCV's ``stereoCalibrate`` gives ``R, T`` the other way
        (``right_from_left``): pass ``Pose(R, T).inverse()``.
    mode : "valid", "full" or a float in [0, 1]
        ``"valid"`` (0): every rectified pixel sees both source images (no black borders;
        some source pixels are cut); ``"full"`` (1): every source pixel of both images is kept
        (black borders); a float between interpolates the field of view and the centre, as
        OpenCV's ``alpha``.
    size : (width, height), optional
        Of the rectified images; the left camera's by default.

    Returns
    -------
    StereoRectification

    Raises
    ------
    ParameterError
        A camera whose border has no ray in front of the rectified camera (a fisheye beyond
        90 degrees: rectify a part of it with a narrower camera first), an unknown mode.
    """
    for name, m in (("left", left), ("right", right)):
        if not isinstance(m, CameraModel):
            raise ParameterError(f"{name}: expected a camkit camera model, got {type(m).__name__}")
    pose = _relative(left_from_right)
    if isinstance(mode, str):
        if mode not in ("valid", "full"):
            raise ParameterError(f"mode: expected 'valid', 'full' or a number in [0, 1], got {mode!r}")
        alpha = 0.0 if mode == "valid" else 1.0
    else:
        alpha = as_finite_float(mode, "mode")
        if not 0.0 <= alpha <= 1.0:
            raise ParameterError(f"mode: expected 'valid', 'full' or a number in [0, 1], got {alpha}")
    if size is None:
        w, h = left.width, left.height
    else:
        if not isinstance(size, list | tuple) or len(size) != 2:
            raise ParameterError(f"size: expected (width, height), got {size!r}")
        w, h = as_positive_int(size[0], "size width"), as_positive_int(size[1], "size height")
    # right_from_left: X_r = R X_l + T.
    inv = pose.inverse()
    R, T = inv.R, inv.t
    if not np.linalg.norm(T) > 0:
        raise ParameterError("left_from_right: the two cameras are at the same place (zero baseline)")
    # Half the relative rotation to each camera, then the common turn of the baseline onto an axis.
    r_half = matrix_from_rvec(-0.5 * rvec_from_matrix(R))
    t = r_half @ T
    axis = 0 if abs(t[0]) > abs(t[1]) else 1
    target = np.zeros(3)
    target[axis] = 1.0 if t[axis] > 0 else -1.0
    ww = np.cross(t, target)
    nw = float(np.linalg.norm(ww))
    if nw > 0:
        ww *= np.arccos(min(abs(t[axis]) / float(np.linalg.norm(t)), 1.0)) / nw
    wR = matrix_from_rvec(ww)
    R1 = wR @ r_half.T
    R2 = wR @ r_half
    base = R2 @ T
    in_l, out_l = border_rectangles(left, R1, "left")
    in_r, out_r = border_rectangles(right, R2, "right")
    inner = np.r_[np.maximum(in_l[:2], in_r[:2]), np.minimum(in_l[2:], in_r[2:])]
    outer = np.r_[np.minimum(out_l[:2], out_r[:2]), np.maximum(out_l[2:], out_r[2:])]
    if inner[2] <= inner[0] or inner[3] <= inner[1]:
        raise ParameterError("left, right: the two rectified images have no area in common (do the cameras look "
                             "the same way? check left_from_right's direction)")
    cam = fit_pinhole(inner, outer, alpha, w, h, 1.0, "left, right")
    f, cx, cy = cam.fx, cam.cx, cam.cy
    b = float(base[axis])
    Q = np.zeros((4, 4))
    Q[0, 0] = Q[1, 1] = 1.0
    Q[0, 3], Q[1, 3], Q[2, 3] = -cx, -cy, f
    Q[3, 2] = -1.0 / b
    valid = []
    for rect in (in_l, in_r):
        x0 = max(int(np.ceil(f * rect[0] + cx)), 0)
        y0 = max(int(np.ceil(f * rect[1] + cy)), 0)
        x1 = min(int(np.floor(f * rect[2] + cx)), w - 1)
        y1 = min(int(np.floor(f * rect[3] + cy)), h - 1)
        valid.append((x0, y0, max(x1 - x0 + 1, 0), max(y1 - y0 + 1, 0)))
    return StereoRectification(left_model=left, right_model=right, left=cam, right=cam, rect_from_left=R1,
                               rect_from_right=R2, baseline=base, Q=Q, valid_left=valid[0], valid_right=valid[1],
                               vertical=axis == 1)


def rectify_maps(rectification: StereoRectification, *, dtype: Any = np.float32) -> tuple[np.ndarray, np.ndarray]:
    """The maps that resample the left and right source images into their rectified images,
    for :func:`camkit.resample.remap` (``map[r, c] = (x, y)`` in the source; NaN where no
    source ray exists). Built by :func:`camkit.resample.reproject_map` (its pinhole fast
    path when the source lens has one)."""
    if not isinstance(rectification, StereoRectification):
        raise ParameterError(f"rectification: expected a StereoRectification (camkit.stereo.rectify), got "
                             f"{type(rectification).__name__}")
    r = rectification
    return (reproject_map(r.left_model, r.left, r.rect_from_left.T, dtype=dtype),
            reproject_map(r.right_model, r.right, r.rect_from_right.T, dtype=dtype))
