"""Closed-form starts for calibration: intrinsics and poses from views of a planar target,
chosen by the lens model (:meth:`CameraModel.start_projection`), and linear distortion terms
(:attr:`CameraModel.linear_start_terms`)."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from camkit._validate import as_positive_int
from camkit.calib.homography import dlt_homographies, find_homography
from camkit.calib.result import stacked_points
from camkit.calib.views import as_views
from camkit.calib.zhang import intrinsics_from_homographies, poses_from_homographies
from camkit.errors import EstimationError, ParameterError
from camkit.geometry.pose import Pose
from camkit.lens.base import CameraModel

__all__ = ["STARTS", "centred_start", "closed_form_start", "equidistant_start", "linear_distortion_start",
           "perspective_start"]


def perspective_start(objs: list[np.ndarray], imgs: list[np.ndarray], width: int, height: int,
                      zero_skew: bool) -> tuple[np.ndarray, list[Pose]]:
    """Zhang's closed form (Z. Zhang, "A flexible new technique for camera calibration", IEEE
    TPAMI 22(11), 2000, sec. 3.1): a homography per view (normalised DLT; the final refinement
    makes their own refinement needless), K from their constraints, then each view's pose."""
    seen = [np.isfinite(p).all(axis=1) for p in imgs]
    Hs = dlt_homographies([o[ok, :2] for o, ok in zip(objs, seen, strict=True)],
                          [p[ok] for p, ok in zip(imgs, seen, strict=True)])
    # Where the batch finds none, find_homography raises and says why, in words.
    Hs = [H if H is not None else find_homography(objs[k][seen[k], :2], imgs[k][seen[k]], refine=False)
          for k, H in enumerate(Hs)]
    K = intrinsics_from_homographies(Hs, zero_skew=zero_skew)
    return K, poses_from_homographies(K, Hs)


def centred_start(objs: list[np.ndarray], imgs: list[np.ndarray], width: int, height: int,
                  zero_skew: bool = True) -> tuple[np.ndarray, list[Pose]]:
    """K and poses with the principal point at the image's centre, ``((W - 1) / 2, (H - 1) / 2)``,
    and square pixels: the focal length alone from the homographies' two constraints per view
    (Zhang 2000, sec. 3.1, with ``B`` = diag(1, 1, f^2) after moving the principal point to the
    origin: ``h1^T B h2 = 0`` and ``h1^T B h1 = h2^T B h2`` are each linear in 1 / f^2), by least
    squares; OpenCV's ``initCameraMatrix2D`` starts the same way. Where strong distortion bends
    the homographies, Zhang's full closed form can put the principal point far off, and this
    start is the fallback :func:`~camkit.calib.calibrate` tries. ``zero_skew`` is accepted for
    the signature of :data:`STARTS` (the skew here is always 0). The views are checked as
    :func:`~camkit.calib.calibrate` checks them (:func:`~camkit.calib.views.as_views`)."""
    objs, imgs = as_views(objs, imgs)
    width, height = as_positive_int(width, "width"), as_positive_int(height, "height")
    if not objs:
        raise EstimationError("object_points, image_points: the centred start needs at least one view of the "
                              "board, got none")
    seen = [np.isfinite(p).all(axis=1) for p in imgs]
    Hs = dlt_homographies([o[ok, :2] for o, ok in zip(objs, seen, strict=True)],
                          [p[ok] for p, ok in zip(imgs, seen, strict=True)])
    Hs = [H if H is not None else find_homography(objs[k][seen[k], :2], imgs[k][seen[k]], refine=False)
          for k, H in enumerate(Hs)]
    c = np.array([(width - 1) / 2, (height - 1) / 2])
    T = np.array([[1.0, 0.0, -c[0]], [0.0, 1.0, -c[1]], [0.0, 0.0, 1.0]])
    A = T @ np.asarray(Hs, dtype=np.float64)
    A /= np.linalg.norm(A, axis=(1, 2))[:, None, None]
    h1, h2 = A[:, :, 0], A[:, :, 1]
    a = np.concatenate([h1[:, 0] * h2[:, 0] + h1[:, 1] * h2[:, 1],
                        h1[:, 0] ** 2 + h1[:, 1] ** 2 - h2[:, 0] ** 2 - h2[:, 1] ** 2])
    b = -np.concatenate([h1[:, 2] * h2[:, 2], h1[:, 2] ** 2 - h2[:, 2] ** 2])
    # A board square to the optical axis gives h1, h2 without a z part: both constraints vanish
    # (the homographies are scaled to unit norm, so a^T a is on the scale of 1 where views tilt).
    if not float(a @ a) > 1e-12:
        raise EstimationError("views: every board faces the camera squarely, which leaves the focal length "
                              "undetermined; tilt the board differently between photos (10-50 degrees)")
    u = float(a @ b) / float(a @ a)  # 1 / f^2
    if not u > 0:
        raise EstimationError("start: no focal length with the principal point at the image's centre explains the "
                              "views; tilt the board differently between photos")
    f = 1.0 / np.sqrt(u)
    K = np.array([[f, 0.0, c[0]], [0.0, f, c[1]], [0.0, 0.0, 1.0]])
    return K, poses_from_homographies(K, Hs)


def equidistant_start(objs: list[np.ndarray], imgs: list[np.ndarray], width: int,
                       height: int) -> tuple[np.ndarray, list[Pose]]:
    """K and poses for a fisheye lens from the equidistant model ``r = f theta`` about the
    image centre: for a trial f each pixel becomes a ray, rays within 80 degrees of the axis a
    point on the normalised plane, and a homography per view is fitted to them; the f whose
    homographies explain the rays best (smallest median angle) wins, on a grid of 41 field
    angles for the farthest corner, 15-175 degrees, then refined on a finer grid."""
    c = np.array([(width - 1) / 2.0, (height - 1) / 2.0])
    r_max = max(float(np.nanmax(np.hypot(*(p - c).T))) for p in imgs)

    def fit(f: float) -> tuple[float, list[np.ndarray]]:
        errs, keep, planes, xns = [], [], [], []
        for o, p in zip(objs, imgs, strict=True):
            d = p - c
            r = np.hypot(d[:, 0], d[:, 1])
            theta = r / f
            ok = np.isfinite(r) & (theta < np.radians(80.0))
            if ok.sum() < 4:
                return np.inf, []
            scale = np.tan(theta[ok]) / np.maximum(r[ok], 1e-12)
            keep.append((d, r, theta, ok))
            planes.append(o[ok, :2])
            xns.append(d[ok] * scale[:, None])
        Hs = dlt_homographies(planes, xns)
        if any(H is None for H in Hs):
            return np.inf, []
        for (d, r, theta, ok), o2, H in zip(keep, planes, Hs, strict=True):
            q = np.c_[o2, np.ones(ok.sum())] @ H.T
            ray_h = q / np.linalg.norm(q, axis=1, keepdims=True) * np.sign(q[:, 2:3])
            ray_o = np.c_[np.sin(theta[ok])[:, None] * d[ok] / np.maximum(r[ok], 1e-12)[:, None],
                          np.cos(theta[ok])]
            errs.append(np.arccos(np.clip((ray_h * ray_o).sum(axis=1), -1.0, 1.0)))
        return float(np.median(np.concatenate(errs))), Hs

    grid = r_max / np.radians(np.linspace(15.0, 175.0, 41))
    scores = [fit(f)[0] for f in grid]
    k = int(np.argmin(scores))
    if not np.isfinite(scores[k]):
        raise EstimationError("start: no focal length explains the corners as views of a plane through a fisheye "
                              "lens; check the object points' units and the image points' order")
    lo, hi = grid[min(k + 1, len(grid) - 1)], grid[max(k - 1, 0)]
    fine = np.linspace(lo, hi, 11)
    f = float(fine[int(np.argmin([fit(v)[0] for v in fine]))])
    _, Hs = fit(f)
    K = np.array([[f, 0.0, c[0]], [0.0, f, c[1]], [0.0, 0.0, 1.0]])
    return K, poses_from_homographies(K, [K @ H for H in Hs])


def _equidistant(objs: list[np.ndarray], imgs: list[np.ndarray], width: int, height: int,
                 zero_skew: bool) -> tuple[np.ndarray, list[Pose]]:
    return equidistant_start(objs, imgs, width, height)


#: The starts by :meth:`CameraModel.start_projection`.
STARTS: dict[str, Callable[..., tuple[np.ndarray, list[Pose]]]] = {
    "perspective": perspective_start,
    "equidistant": _equidistant,
}


def closed_form_start(cls: type[CameraModel], objs: list[np.ndarray], imgs: list[np.ndarray], width: int,
                      height: int, zero_skew: bool) -> tuple[np.ndarray, list[Pose]]:
    """K and the poses for the views, by the start the model asks for."""
    kind = cls.start_projection()
    if kind not in STARTS:
        raise ParameterError(f"{cls.__name__}.start_projection(): expected one of {sorted(STARTS)}, got {kind!r}")
    return STARTS[kind](objs, imgs, width, height, zero_skew)


def linear_distortion_start(cam: CameraModel, objs: list[np.ndarray], imgs: list[np.ndarray], poses: list[Pose],
                            free_names: set[str]) -> CameraModel:
    """The model's ``linear_start_terms`` (radial terms multiplying the ideal offset by r^2,
    r^4, ...) by linear least squares from the pinhole start (Zhang 2000, eq. 13), where all of
    them are free; else the model unchanged. A start outside the model's valid parameters
    keeps the model unchanged too, and so does one under which a view's points fold back
    (outside the model's valid region: the solver cannot start there): the terms are then
    fitted again without the highest (k1 alone), and where that folds back too, the model is
    kept as it came (real plantcv_wide set, a 5.5 MP wide-angle lens whose board fills the frame:
    Zhang's start gave k1 0.97, k2 -11.6, folding back inside the board's farthest corner,
    and calibration stopped at the start)."""
    terms = cam.linear_start_terms
    if not terms or not set(terms) <= free_names:
        return cam
    X = stacked_points(objs, poses)  # all views at once
    p = np.concatenate(imgs)
    ok = np.isfinite(p).all(axis=1)
    X, p = X[ok], p[ok]
    x, y = X[:, 0] / X[:, 2], X[:, 1] / X[:, 2]
    r2 = x * x + y * y
    du, dv = cam.fx * x, cam.fy * y  # ideal pixel minus the principal point
    rhs = np.concatenate([p[:, 0] - cam.cx - du, p[:, 1] - cam.cy - dv])
    for n in range(len(terms), 0, -1):
        powers = [r2 ** (k + 1) for k in range(n)]
        rows = [np.stack([du * q for q in powers], -1), np.stack([dv * q for q in powers], -1)]
        k = np.linalg.lstsq(np.concatenate(rows), rhs, rcond=None)[0]
        try:
            out = cam.replace(**{t: float(v) for t, v in zip(terms[:n], k, strict=True)})
        except ParameterError:
            continue
        if np.isfinite(out.project(X)).all():
            return out
    return cam
