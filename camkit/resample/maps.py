"""Maps between camera models: reprojection, undistortion, rectification, and the choice of
the new pinhole camera.

A map answers, for every pixel of the image to make (the destination), where to sample the
image one has (the source): ``map[r, c] = (x_src, y_src)``, ready for
:func:`camkit.resample.remap`. Destination pixels that see no source pixel's ray (outside the
source lens's valid region, behind a pinhole) hold NaN, which remap turns into the fill value.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from camkit._validate import as_finite_float, as_positive_int, as_rotation_matrix
from camkit.errors import ParameterError
from camkit.lens.base import CameraModel
from camkit.lens.pinhole import Pinhole

__all__ = ["border_rectangles", "fit_pinhole", "optimal_pinhole", "reproject_map", "undistort_map"]

_CHUNK_PIXELS = 1 << 18  # rows per chunk in the generic path: ~256 k pixels, a few MB


def _check_model(m: Any, name: str) -> CameraModel:
    if not isinstance(m, CameraModel):
        raise ParameterError(f"{name}: expected a camkit camera model, got {type(m).__name__}")
    return m


def _check_dtype(dtype: Any) -> np.dtype:
    dt = np.dtype(dtype)
    if dt not in (np.dtype(np.float32), np.dtype(np.float64)):
        raise ParameterError(f"dtype: expected float32 or float64, got {dt}")
    return dt


def reproject_map(src_model: CameraModel, dst_model: CameraModel, rotation: Any = None, *,
                  dtype: Any = np.float32) -> np.ndarray:
    """The map that resamples an image of ``src_model`` into the lattice of ``dst_model``.

    For each destination pixel ``p``: ``map[p] = src.project(rotation @ dst.unproject(p))``.

    Parameters
    ----------
    src_model, dst_model : CameraModel
        Any registry models; the map has the destination's size.
    rotation : array_like, (3, 3), optional
        ``src_from_dst``: a ray ``d`` in the destination camera's frame is ``rotation @ d`` in
        the source camera's frame (rectification). OpenCV's ``R`` argument of
        ``initUndistortRectifyMap`` is the other direction, ``dst_from_src``: pass ``R.T``.
    dtype : float32 (default) or float64

    Returns
    -------
    ndarray, (dst.height, dst.width, 2)
        ``[..., 0] = x``, ``[..., 1] = y`` in the source image; NaN where no source ray exists.
    """
    src = _check_model(src_model, "src_model")
    dst = _check_model(dst_model, "dst_model")
    dt = _check_dtype(dtype)
    R = np.eye(3) if rotation is None else as_rotation_matrix(rotation, "rotation")
    out = np.empty((dst.height, dst.width, 2), dtype=dt)
    if dst.is_pinhole:
        M = np.ascontiguousarray(R @ np.linalg.inv(dst.K))
        if src.map_from_rays(M, out):
            return out
    # Generic path: any pair of models, a band of rows at a time (bounded memory).
    rows = max(1, _CHUNK_PIXELS // dst.width)
    u = np.arange(dst.width, dtype=np.float64)
    for r0 in range(0, dst.height, rows):
        v = np.arange(r0, min(r0 + rows, dst.height), dtype=np.float64)
        grid = np.empty((len(v), dst.width, 2))
        grid[..., 0] = u[None, :]
        grid[..., 1] = v[:, None]
        rays = dst.unproject(grid.reshape(-1, 2))
        px = src.project(rays @ R.T)
        out[r0:r0 + len(v)] = px.reshape(len(v), dst.width, 2)
    return out


def undistort_map(model: CameraModel, new_model: CameraModel | None = None, *,
                  dtype: Any = np.float32) -> np.ndarray:
    """The map that removes a lens's distortion: :func:`reproject_map` from ``model`` to
    ``new_model`` (by default a :class:`Pinhole` with the same ``fx, fy, cx, cy, skew`` and size,
    as OpenCV's ``undistort`` does; :func:`optimal_pinhole` chooses a better one).

    Examples
    --------
    >>> from camkit.lens import BrownConrady
    >>> cam = BrownConrady(fx=500.0, fy=500.0, cx=319.5, cy=239.5, width=640, height=480, k1=-0.2)
    >>> m = undistort_map(cam)
    >>> m.shape, m.dtype
    ((480, 640, 2), dtype('float32'))
    >>> [round(float(v), 3) for v in m[240, 320]]  # near the centre, barely any shift
    [320.0, 240.0]
    """
    model = _check_model(model, "model")
    if new_model is None:
        new_model = Pinhole(fx=model.fx, fy=model.fy, cx=model.cx, cy=model.cy, skew=model.skew,
                            width=model.width, height=model.height)
    return reproject_map(model, new_model, dtype=dtype)


def _border_pixels(w: int, h: int) -> dict[str, np.ndarray]:
    """The outer edges of the border pixels, sampled every pixel (and at the corners)."""
    xs = np.arange(-0.5, w - 0.5 + 1e-9, 1.0)
    ys = np.arange(-0.5, h - 0.5 + 1e-9, 1.0)
    return {
        "left": np.stack([np.full_like(ys, -0.5), ys], axis=-1),
        "right": np.stack([np.full_like(ys, w - 0.5), ys], axis=-1),
        "top": np.stack([xs, np.full_like(xs, -0.5)], axis=-1),
        "bottom": np.stack([xs, np.full_like(xs, h - 0.5)], axis=-1),
    }


def optimal_pinhole(model: CameraModel, alpha: float = 0.0, *, width: int | None = None,
                    height: int | None = None) -> Pinhole:
    """A pinhole camera for undistorting ``model``'s images, from ``alpha = 0`` (every output
    pixel sees the scene: no empty borders) to ``alpha = 1`` (every source pixel is kept).

    The source image's border, sampled at every pixel of its outer edge, is unprojected to
    ideal normalised coordinates. ``alpha = 0`` fits the output into the largest rectangle
    bounded by the four edge curves (the rightmost point of the left edge, the lowest of the
    top edge, ...); ``alpha = 1`` fits the bounding box of the whole border into it; values
    between interpolate the field of view (``1 / fx``) and the centre linearly. The new camera
    keeps ``fy / fx`` and zero skew, and centres the rectangle in the output.

    Every quantity is a maximum or minimum over dense samples, so the result moves smoothly
    with the input: a 0.1 px change of the principal point moves the new one by about as much
    (OpenCV's ``getOptimalNewCameraMatrix`` samples a coarse grid and can jump by tens of
    pixels, opencv/opencv#24923).

    Parameters
    ----------
    model : CameraModel
    alpha : float in [0, 1]
    width, height : int, optional
        Output size; the model's by default.

    Returns
    -------
    Pinhole

    Raises
    ------
    ParameterError
        If the model does not map its image border to rays in front of the camera (a fisheye
        beyond 90 degrees cannot be undistorted onto one plane with ``alpha = 1``).
    """
    model = _check_model(model, "model")
    a = as_finite_float(alpha, "alpha")
    if not 0.0 <= a <= 1.0:
        raise ParameterError(f"alpha: expected a number in [0, 1], got {a}")
    w = model.width if width is None else as_positive_int(width, "width")
    h = model.height if height is None else as_positive_int(height, "height")
    inner, outer = border_rectangles(model)
    return fit_pinhole(inner, outer, a, w, h, model.fy / model.fx)


def _clip_to_rays(model: CameraModel, px: np.ndarray, rays: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Border pixels whose ray the lens model does not give (NaN: outside a fitted
    polynomial's valid region, which can turn back before the image's corners when no photo
    reached them), moved toward the image's centre to the edge of the region that has rays
    (bisection along the line to the centre, to 1/1000 of its length)."""
    bad = ~np.isfinite(rays).all(axis=-1)
    if not bad.any():
        return px, rays
    c = np.array([(model.width - 1) / 2.0, (model.height - 1) / 2.0])
    lo, hi = np.zeros(int(bad.sum())), np.ones(int(bad.sum()))
    d = px[bad] - c
    for _ in range(10):
        mid = 0.5 * (lo + hi)
        ok = np.isfinite(model.unproject(c + mid[:, None] * d)).all(axis=-1)
        lo = np.where(ok, mid, lo)
        hi = np.where(ok, hi, mid)
    px, rays = px.copy(), rays.copy()
    px[bad] = c + lo[:, None] * d
    rays[bad] = model.unproject(px[bad])
    return px, rays


def border_rectangles(model: CameraModel, rotation: Any = None, name: str = "model") -> tuple[np.ndarray, np.ndarray]:
    """Where the image's border goes on the normalised plane ``z = 1`` of a camera turned by
    ``rotation`` (``new_from_model``; none by default): the inner rectangle (bounded by the four
    edge curves: the rightmost point of the left edge, the lowest of the top edge, ...) and the
    outer one (the whole border's bounding box), each ``[x0, y0, x1, y1]``. The border is
    sampled at every pixel of its outer edge. Where the lens model gives no ray for a border
    pixel (outside a fitted polynomial's valid region), the border follows the edge of the
    region that has rays instead: those pixels see nothing in the model.

    Raises
    ------
    ParameterError
        If a border pixel's ray points behind the (turned) camera (a fisheye beyond 90
        degrees), naming ``name``.
    """
    R = np.eye(3) if rotation is None else as_rotation_matrix(rotation, "rotation")
    edges = {}
    for side, px in _border_pixels(model.width, model.height).items():
        px, rays = _clip_to_rays(model, px, model.unproject(px))
        rays = rays @ R.T
        ok = np.isfinite(rays).all(axis=-1) & (rays[:, 2] > 1e-6)
        if not ok.all():
            raise ParameterError(
                f"{name}: {int((~ok).sum())} pixels of the image's {side} edge have no ray in front of "
                "the camera (outside the lens's valid region, or beyond 90 degrees); no pinhole "
                "camera can show them"
            )
        edges[side] = rays[:, :2] / rays[:, 2:]
    inner = np.array([edges["left"][:, 0].max(), edges["top"][:, 1].max(),
                      edges["right"][:, 0].min(), edges["bottom"][:, 1].min()])
    allpts = np.concatenate(list(edges.values()))
    outer = np.array([allpts[:, 0].min(), allpts[:, 1].min(), allpts[:, 0].max(), allpts[:, 1].max()])
    return inner, outer


def fit_pinhole(inner: np.ndarray, outer: np.ndarray, alpha: float, width: int, height: int,
                ratio: float = 1.0, name: str = "model") -> Pinhole:
    """The pinhole camera of ``width x height`` pixels (``fy = ratio * fx``, zero skew) whose
    image lies inside the rectangle ``inner`` at ``alpha = 0`` and holds ``outer`` at
    ``alpha = 1`` (rectangles ``[x0, y0, x1, y1]`` on the normalised plane; see
    :func:`border_rectangles`); between, the field of view (``1 / fx``) and the centre are
    interpolated linearly, so the camera moves continuously with ``alpha`` and the input."""
    w, h = width, height
    if inner[2] <= inner[0] or inner[3] <= inner[1]:
        raise ParameterError(f"{name}: the undistorted image has no inner rectangle (the edges cross)")

    def extent(rect: np.ndarray, cover: bool) -> float:
        # The output spans w / fx by h / fy in normalised units (pixel edges at -0.5, w - 0.5).
        # 'cover': the output lies inside rect; otherwise rect lies inside the output.
        sx = (rect[2] - rect[0]) / w
        sy = (rect[3] - rect[1]) * ratio / h
        return min(sx, sy) if cover else max(sx, sy)

    # 1 / fx at alpha = 0 (inside the inner rectangle) and alpha = 1 (holding the outer one),
    # interpolated linearly, as is the centre: continuous in alpha and in the model.
    inv_f = (1 - alpha) * extent(inner, cover=True) + alpha * extent(outer, cover=False)
    centre = (1 - alpha) * (inner[:2] + inner[2:]) / 2 + alpha * (outer[:2] + outer[2:]) / 2
    fx = 1.0 / inv_f
    fy = fx * ratio
    cx = (w - 1) / 2.0 - fx * centre[0]
    cy = (h - 1) / 2.0 - fy * centre[1]
    return Pinhole(fx=fx, fy=fy, cx=cx, cy=cy, skew=0.0, width=w, height=h)
