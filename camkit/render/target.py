"""Render what a camera sees of a planar target, with exact ground truth.

A checkerboard is shaded analytically; any other :class:`~camkit.target.Target` through its
printed sheet (:meth:`~camkit.target.Target.sheet`), rasterised finely and averaged over each
pixel's footprint."""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from camkit._kernels import render as render_kernels
from camkit._repr import summary_repr
from camkit._validate import as_finite_float, as_image, as_positive_int
from camkit.errors import ParameterError, ShapeError
from camkit.geometry.pose import Pose
from camkit.lens.base import CameraModel
from camkit.target import Checkerboard, Sheet, Target

__all__ = ["RenderTruth", "render_checkerboard", "render_target", "render_texture"]


@dataclass(frozen=True, slots=True, eq=False)
class RenderTruth:
    """The exact answer for one rendered view.

    Attributes
    ----------
    corners_px : ndarray, (N, 2)
        Every target point projected through the camera model (NaN where not projectable), in
        the order of ``board.object_points()`` (for a checkerboard, its inner corners).
    visible : ndarray, (N,) bool
        Projectable and inside the image (pixel centres' extent ``[0, W-1] x [0, H-1]``).
    cam_from_target : Pose
    camera : CameraModel
    board : Target
        The target rendered (a Checkerboard or any other registered target).
    depth : ndarray, (H, W)
        Camera-frame z of the board point each pixel sees (NaN off the board's plane); what
        defocus is computed from.
    """

    corners_px: np.ndarray
    visible: np.ndarray
    cam_from_target: Pose
    camera: CameraModel
    board: Target
    depth: np.ndarray

    def __repr__(self) -> str:
        return summary_repr(self)


def _check_level(x: float, name: str) -> float:
    v = as_finite_float(x, name)
    if not 0.0 <= v <= 1.0:
        raise ParameterError(f"{name}: expected a reflectance in [0, 1], got {v}")
    return v


def _background(background: Any, H: int, W: int, C: int) -> np.ndarray:
    """A (H, W, C) float64 background from a reflectance or an image of the camera's size."""
    if isinstance(background, np.ndarray) and background.ndim >= 2:
        img = as_image(background, "background")
        if img.shape[:2] != (H, W):
            raise ShapeError(f"background: expected an image of the camera's size ({H}, {W}), got {img.shape}")
        bg = img.astype(np.float64)
        if img.dtype.kind == "u":
            bg /= np.iinfo(img.dtype).max
        bg = bg if bg.ndim == 3 else bg[:, :, None]
        if bg.shape[2] != C:
            if bg.shape[2] != 1:
                raise ShapeError(f"background: expected 1 or {C} channels, got {bg.shape[2]}")
            bg = np.repeat(bg, C, axis=2)
        return np.ascontiguousarray(bg)
    return np.full((H, W, C), _check_level(background, "background"))


def camera_rays(camera: CameraModel) -> np.ndarray:
    """Unit rays through every pixel centre, (H, W, 3): they depend on the camera only, so
    renders of several poses (motion blur) compute them once."""
    W, H = camera.width, camera.height
    grid = np.empty((H, W, 2))
    grid[..., 0] = np.arange(W)[None, :]
    grid[..., 1] = np.arange(H)[:, None]
    return np.ascontiguousarray(camera.unproject(grid))


def _plane_uv(camera: CameraModel, cam_from_target: Pose,
              rays: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    W, H = camera.width, camera.height
    rays = camera_rays(camera) if rays is None else rays
    uv = np.empty((H, W, 2))
    render_kernels.plane_coords(rays, cam_from_target.R, cam_from_target.t, uv)
    depth = np.empty((H, W))
    render_kernels.plane_depth(rays, cam_from_target.R, cam_from_target.t, depth)
    return uv, depth


def render_texture(camera: CameraModel, cam_from_target: Pose, texture: np.ndarray, size: Any, *,
                   supersample: int = 4, background: Any = 0.5) -> tuple[np.ndarray, np.ndarray]:
    """The image of a texture printed on the plane rectangle ``[0, width] x [0, height]``
    (metres, ``size = (width, height)``) of the target frame, seen through ``camera``.

    Each pixel averages the texture (bilinear) over its footprint on the plane, sampled on a
    ``supersample x supersample`` grid, so a minified texture does not alias. Returns the
    image (float64 in [0, 1] for integer textures, the texture's scale for float ones; the
    texture's channel count) and the depth map (camera z per pixel, NaN off the plane).
    """
    if not isinstance(camera, CameraModel):
        raise ParameterError(f"camera: expected a camkit camera model, got {type(camera).__name__}")
    if not isinstance(cam_from_target, Pose):
        raise ParameterError(f"cam_from_target: expected a Pose, got {type(cam_from_target).__name__}")
    tex = as_image(texture, "texture")
    tex3 = tex.astype(np.float64) / (np.iinfo(tex.dtype).max if tex.dtype.kind == "u" else 1.0)
    tex3 = np.ascontiguousarray(tex3 if tex3.ndim == 3 else tex3[:, :, None])
    sz = np.asarray(size, dtype=np.float64) if not isinstance(size, np.ndarray) else size.astype(np.float64)
    if sz.shape != (2,) or not np.isfinite(sz).all() or (sz <= 0).any():
        raise ParameterError(f"size: expected (width, height) in metres, both > 0, got {size!r}")
    S = as_positive_int(supersample, "supersample")
    H, W, C = camera.height, camera.width, tex3.shape[2]
    bg = _background(background, H, W, C)
    uv, depth = _plane_uv(camera, cam_from_target)
    out = np.empty((H, W, C))
    render_kernels.shade_texture(uv, tex3, float(sz[0]), float(sz[1]), bg, S, out)
    return (out if tex.ndim == 3 else out[:, :, 0]), depth


def render_checkerboard(camera: CameraModel, cam_from_target: Pose, board: Checkerboard, *,
                        supersample: int = 16, black: float = 0.05, white: float = 0.95,
                        background: Any = 0.5) -> tuple[np.ndarray, RenderTruth]:
    """The image (reflectance, float64 in [0, 1]) a camera forms of a checkerboard.

    Each pixel is traced back through ``camera.unproject`` to the board plane, and its value
    is the board's mean reflectance over the pixel's footprint (the pixel square mapped onto
    the plane by the local affine approximation of the lens, estimated from the neighbours'
    intersections), sampled at ``supersample^2`` points of a rank-1 lattice
    (:func:`edge_lattice`: every sample on its own row and column of the footprint) where the
    footprint
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
    black, white : float in [0, 1]
        Reflectances of the black squares, and of the white squares and margin.
    background : float in [0, 1], or an (H, W) image of the camera's size
        What is seen off the board: a grey level or a texture (integer images are scaled to
        [0, 1]).

    Returns
    -------
    image : ndarray, (H, W), float64
    truth : RenderTruth
    """
    return _render_board(camera, cam_from_target, board, supersample, black, white, background, None)


def render_target(camera: CameraModel, cam_from_target: Pose, target: Target, *, supersample: int = 16,
                  black: float = 0.05, white: float = 0.95, background: Any = 0.5) -> tuple[np.ndarray, RenderTruth]:
    """The image (reflectance, float64 in [0, 1]) a camera forms of any target, and the truth.

    A :class:`~camkit.target.Checkerboard` goes through :func:`render_checkerboard`; any other
    target's sheet is rasterised with every edge on a texel boundary (:func:`_sheet_density`)
    and averaged over each pixel's footprint (``supersample^2`` samples). Parameters as
    :func:`render_checkerboard`; ``truth.corners_px`` holds every point of
    ``target.object_points()``.
    """
    return _render_board(camera, cam_from_target, target, supersample, black, white, background, None)


@functools.lru_cache(maxsize=16)
def edge_lattice(supersample: int) -> tuple[int, int]:
    """``(N, g)``: N = supersample^2 points ``((k + 1/2) / N, ((k g mod N) + 1/2) / N)``, a
    rank-1 lattice whose generator g (coprime to N) maximises the smallest distance between
    points on the unit torus (the spectral test; for 16 -> (256, 185), close to a hexagonal
    packing). Every point has its own row and column, and no edge direction lines up with
    many points at once (an upright grid lines up with rows and columns, a grid turned by
    atan(1/S) with its own rows)."""
    n = supersample * supersample
    if n < 3:
        return n, 1
    k = np.arange(1, n)
    best, best_g = -1.0, 1
    for g in range(1, n):
        if math.gcd(g, n) != 1:
            continue
        x = k / n
        y = (k * g % n) / n
        d = float(np.min(np.hypot(np.minimum(x, 1 - x), np.minimum(y, 1 - y))))
        if d > best + 1e-12:
            best, best_g = d, g
    return n, best_g


def _render_board(camera: CameraModel, cam_from_target: Pose, board: Checkerboard, supersample: int,
                  black: float, white: float, background: Any,
                  rays: np.ndarray | None) -> tuple[np.ndarray, RenderTruth]:
    """render_checkerboard's body; ``rays`` (from :func:`camera_rays`) may be shared by
    several poses of one camera."""
    if not isinstance(camera, CameraModel):
        raise ParameterError(f"camera: expected a camkit camera model, got {type(camera).__name__}")
    if not isinstance(cam_from_target, Pose):
        raise ParameterError(f"cam_from_target: expected a Pose, got {type(cam_from_target).__name__}")
    if not isinstance(board, Target):
        raise ParameterError(f"board: expected a camkit target (e.g. a Checkerboard), got {type(board).__name__}")
    S = as_positive_int(supersample, "supersample")
    levels = [_check_level(v, n) for v, n in ((black, "black"), (white, "white"))]
    W, H = camera.width, camera.height
    bg = _background(background, H, W, 1)[:, :, 0].copy()
    uv, depth = _plane_uv(camera, cam_from_target, rays)
    image = np.empty((H, W))
    if isinstance(board, Checkerboard):
        ext = np.array([*board.extent(), board.inner_cols, board.inner_rows], dtype=np.float64)
        render_kernels.shade(uv, board.square, ext, levels[0], levels[1], bg, *edge_lattice(S), image)
    else:
        _shade_sheet(board, uv, levels[0], levels[1], bg, S, image)
    corners = camera.project(cam_from_target.apply(board.object_points()))
    visible = (np.isfinite(corners).all(axis=-1) & (corners[:, 0] >= 0) & (corners[:, 0] <= W - 1)
               & (corners[:, 1] >= 0) & (corners[:, 1] <= H - 1))
    return image, RenderTruth(corners, visible, cam_from_target, camera, board, depth)


def _sheet_density(sheet: Sheet) -> float:
    """Texels per metre for rasterising ``sheet``: every mark's edge on a texel boundary (a
    whole number of texels per ``q``, the largest length dividing every edge's offset from
    the sheet's corner, to 0.1 um), as fine as 4096 texels a side allow. An edge between texels
    would otherwise be carried only by its texels' coverage (:meth:`Sheet.coverage`), which
    bilinear sampling reproduces less exactly; where no such density fits in 4096 texels, 64
    texels across the smallest mark."""
    u0, v0, u1, v1 = sheet.extent
    b = sheet.black
    limit = 4096.0 / max(u1 - u0, v1 - v0)
    offsets = np.concatenate([(b[:, [0, 2]] - u0).ravel(), (b[:, [1, 3]] - v0).ravel(), [u1 - u0, v1 - v0]])
    units = np.rint(offsets * 1e7).astype(np.int64)  # 0.1 um
    q = float(np.gcd.reduce(units[units > 0])) * 1e-7 if (units > 0).any() else 0.0
    if q > 0 and np.allclose(units * 1e-7, offsets, rtol=0, atol=1e-9) and q * limit >= 1.0:
        return math.floor(q * limit) / q
    mark = float(np.min(np.minimum(b[:, 2] - b[:, 0], b[:, 3] - b[:, 1]))) if len(b) else u1 - u0
    return min(64.0 / mark, limit)


def _shade_sheet(target: Target, uv: np.ndarray, black: float, white: float, bg: np.ndarray, S: int,
                 out: np.ndarray) -> None:
    """Shade ``out`` (H, W) from the target's sheet, rasterised at :func:`_sheet_density`, seen
    at the plane coordinates ``uv``."""
    sheet = target.sheet()
    u0, v0, _, _ = sheet.extent
    density = _sheet_density(sheet)
    tex = (white - (white - black) * sheet.coverage(density))[:, :, None]
    # The raster's size is rounded to whole pixels: the texture spans exactly that many.
    size_u, size_v = tex.shape[1] / density, tex.shape[0] / density
    shifted = np.ascontiguousarray(uv - [u0, v0])
    res = np.empty(out.shape + (1,))
    render_kernels.shade_texture(shifted, np.ascontiguousarray(tex), size_u, size_v,
                                 np.ascontiguousarray(bg[:, :, None]), S, res)
    out[:] = res[:, :, 0]
