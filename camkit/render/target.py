"""Render what a camera sees of a planar checkerboard, with exact ground truth."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from camkit._kernels import render as _kr
from camkit._validate import as_finite_float, as_positive_int
from camkit.calib.targets import Checkerboard
from camkit.errors import ParameterError
from camkit.geometry.pose import Pose
from camkit.lens.base import CameraModel

__all__ = ["RenderTruth", "render_checkerboard"]


@dataclass(frozen=True, slots=True, eq=False)
class RenderTruth:
    """The exact answer for one rendered view.

    Attributes
    ----------
    corners_px : ndarray, (N, 2)
        Every inner corner projected through the camera model (NaN where not projectable), in
        the order of ``board.object_points()``.
    visible : ndarray, (N,) bool
        Projectable and inside the image (pixel centres' extent ``[0, W-1] x [0, H-1]``).
    cam_from_target : Pose
    camera : CameraModel
    board : Checkerboard
    depth : ndarray, (H, W)
        Camera-frame z of the board point each pixel sees (NaN off the board's plane); what
        defocus is computed from.
    """

    corners_px: np.ndarray
    visible: np.ndarray
    cam_from_target: Pose
    camera: CameraModel
    board: Checkerboard
    depth: np.ndarray


def _check_level(x: float, name: str) -> float:
    v = as_finite_float(x, name)
    if not 0.0 <= v <= 1.0:
        raise ParameterError(f"{name}: expected a reflectance in [0, 1], got {v}")
    return v


def render_checkerboard(camera: CameraModel, cam_from_target: Pose, board: Checkerboard, *,
                        supersample: int = 16, black: float = 0.05, white: float = 0.95,
                        background: float = 0.5) -> tuple[np.ndarray, RenderTruth]:
    """The image (reflectance, float64 in [0, 1]) a camera forms of a checkerboard.

    Each pixel is traced back through ``camera.unproject`` to the board plane, and its value
    is the board's mean reflectance over the pixel's footprint (the pixel square mapped onto
    the plane by the local affine approximation of the lens, estimated from the neighbours'
    intersections), sampled on a ``supersample x supersample`` grid where the footprint
    crosses an edge. The box filter is symmetric, so edges are anti-aliased and corner
    positions unbiased.

    Parameters
    ----------
    camera : CameraModel
        Any registry model; the image has its size.
    cam_from_target : Pose
        Board frame to camera frame.
    board : Checkerboard
    supersample : int
        Samples per pixel side at edges.
    black, white, background : float in [0, 1]
        Reflectances of the black squares, the white squares and margin, and off the board.

    Returns
    -------
    image : ndarray, (H, W), float64
    truth : RenderTruth
    """
    if not isinstance(camera, CameraModel):
        raise ParameterError(f"camera: expected a camkit camera model, got {type(camera).__name__}")
    if not isinstance(cam_from_target, Pose):
        raise ParameterError(f"cam_from_target: expected a Pose, got {type(cam_from_target).__name__}")
    if not isinstance(board, Checkerboard):
        raise ParameterError(f"board: expected a Checkerboard, got {type(board).__name__}")
    S = as_positive_int(supersample, "supersample")
    levels = [_check_level(v, n) for v, n in ((black, "black"), (white, "white"), (background, "background"))]
    W, H = camera.width, camera.height
    grid = np.empty((H, W, 2))
    grid[..., 0] = np.arange(W)[None, :]
    grid[..., 1] = np.arange(H)[:, None]
    rays = np.ascontiguousarray(camera.unproject(grid))
    uv = np.empty((H, W, 2))
    _kr.plane_coords(rays, cam_from_target.R, cam_from_target.t, uv)
    ext = np.array([*board.extent(), board.inner_cols, board.inner_rows], dtype=np.float64)
    image = np.empty((H, W))
    _kr.shade(uv, board.square, ext, levels[0], levels[1], levels[2], S, image)
    corners = camera.project(cam_from_target.apply(board.object_points()))
    visible = (np.isfinite(corners).all(axis=-1) & (corners[:, 0] >= 0) & (corners[:, 0] <= W - 1)
               & (corners[:, 1] >= 0) & (corners[:, 1] <= H - 1))
    depth = np.empty((H, W))
    _kr.plane_depth(rays, cam_from_target.R, cam_from_target.t, depth)
    return image, RenderTruth(corners, visible, cam_from_target, camera, board, depth)
