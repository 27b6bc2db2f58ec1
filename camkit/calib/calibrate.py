"""Camera calibration from point correspondences: closed-form start, then nonlinear
least squares over the intrinsics, the distortion and every view's pose."""

from __future__ import annotations

import os
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from camkit._kernels import calib as _kc
from camkit._validate import as_points, as_positive_float, as_positive_int, check_choice
from camkit.calib.homography import find_homography
from camkit.calib.zhang import intrinsics_from_homographies, poses_from_homographies
from camkit.errors import EstimationError, ParameterError, ShapeError
from camkit.geometry.pose import Pose
from camkit.geometry.rotation import matrix_from_rvec
from camkit.io.images import read_image
from camkit.lens.base import CameraModel, get_model
from camkit.target import Checkerboard, detect_corners

__all__ = ["DEFAULT_FIX", "CalibrationResult", "calibrate", "calibrate_images", "default_fix", "held_parameters"]

#: Held at their start values by default for Brown-Conrady (``BrownConrady.default_fixed``):
#: skew, and the terms beyond k1, k2, p1, p2, k3 (OpenCV's default 5-coefficient model).
DEFAULT_FIX = ("skew", "k4", "k5", "k6", "s1", "s2", "s3", "s4")


def default_fix(model: str) -> tuple[str, ...]:
    """The parameters ``calibrate`` holds unless freed: the model's ``default_fixed``
    (:data:`DEFAULT_FIX` for Brown-Conrady, skew alone for the others; Kannala-Brandt fits
    k1..k4, as OpenCV's fisheye module does)."""
    return tuple(get_model(model).default_fixed)


def held_parameters(model: str, fix: Any = (), free: Any = ()) -> tuple[str, ...]:
    """The parameters calibration holds: the model's defaults, plus ``fix``, less ``free``.

    ``fix`` and ``free`` take parameter names or group names of the model (``"k3"``,
    ``"tangential"``); a name the model does not have is an error, whatever the model (a
    pinhole has no ``k6``). Returns the held names in the model's parameter order.

    Examples
    --------
    >>> held_parameters("brown-conrady", fix=("k3",), free=("k4",))
    ('skew', 'k3', 'k5', 'k6', 's1', 's2', 's3', 's4')
    """
    cls = get_model(model)
    sets = []
    for arg, label in ((fix, "fix"), (free, "free")):
        if arg is None:
            arg = ()
        if isinstance(arg, str) or not all(isinstance(f, str) for f in arg):
            raise ParameterError(f"{label}: expected a tuple of parameter or group names, got {arg!r}")
        unknown = [f for f in arg if f not in cls.param_names and f not in cls.param_groups]
        if unknown:
            raise ParameterError(f"{label}: {unknown} are not parameters of the {cls.name} model; expected names "
                                 f"from {cls.param_names} or groups {tuple(cls.param_groups)}")
        sets.append({cls.param_names[i] for i in cls.param_indices(tuple(arg))} if arg else set())
    both = sets[0] & sets[1]
    if both:
        raise ParameterError(f"fix, free: {sorted(both)} named in both")
    held = (set(cls.default_fixed) | sets[0]) - sets[1]
    return tuple(n for n in cls.param_names if n in held)


@dataclass(frozen=True, slots=True, eq=False)
class CalibrationResult:
    """What a calibration found, and how well it is known.

    Attributes
    ----------
    model : CameraModel
    poses : list of Pose
        ``cam_from_target`` per view.
    rms_px : float
        The reprojection RMS as OpenCV's ``calibrateCamera`` returns it:
        ``sqrt(mean over corners of (dx^2 + dy^2))``, pixels; the same definition as
        ``view_rms_px``.
    std_px : (float, float)
        Standard deviation of the residuals along x and y (as Bouguet's toolbox reports it).
    view_rms_px : ndarray, (n_views,)
        ``sqrt(mean(dx^2 + dy^2))`` over each view's corners in use.
    residuals : list of ndarray
        Per view, (N_i, 2) pixels ``projected - observed``; NaN for rejected corners.
    free_params : tuple of str
        The model parameters estimated (the others were held).
    covariance : ndarray
        Covariance of ``free_params`` (pixels^2 noise scaled by the residual variance).
    stddev : dict
        Standard deviation per free parameter.
    rejected : list of (view, index, reason)
        Corners left out as outliers; ``view`` indexes the input views.
    view_indices : tuple of int
        For each entry of ``poses``, ``view_rms_px`` and ``residuals``, the index of its view
        in the input (views with fewer than 4 corners, or where no board was found, are left
        out and listed in ``rejected_views``).
    rejected_views : list of (view, reason)
    detections : list of Detection or None
        With :func:`calibrate_images`, the detection of every input image.
    object_points, image_points : list of ndarray
        The input, per input view.
    converged : bool
    iterations : int
    cost : float
        Final sum of squared residuals (pixels^2).
    message : str
    """

    model: CameraModel
    poses: list[Pose]
    rms_px: float
    std_px: tuple[float, float]
    view_rms_px: np.ndarray
    residuals: list[np.ndarray]
    free_params: tuple[str, ...]
    covariance: np.ndarray
    stddev: dict[str, float]
    rejected: list[tuple[int, int, str]] = field(default_factory=list)
    view_indices: tuple[int, ...] = ()
    rejected_views: list[tuple[int, str]] = field(default_factory=list)
    detections: list[Any] | None = None
    object_points: list[np.ndarray] = field(default_factory=list)
    image_points: list[np.ndarray] = field(default_factory=list)
    converged: bool = False
    iterations: int = 0
    cost: float = float("nan")
    message: str = ""

    def view_ypr_deg(self) -> np.ndarray:
        """Yaw, pitch, roll (degrees) of the camera relative to the board, per view (n, 3)."""
        return np.degrees(np.array([p.inverse().ypr() for p in self.poses]))


def _as_views(object_points: Any, image_points: Any) -> tuple[list[np.ndarray], list[np.ndarray]]:
    if not isinstance(object_points, list | tuple) or not isinstance(image_points, list | tuple):
        raise ShapeError("object_points, image_points: expected lists with one array per view")
    if len(object_points) != len(image_points):
        raise ShapeError(f"object_points, image_points: expected one array per view each, got "
                         f"{len(object_points)} and {len(image_points)}")
    objs, imgs = [], []
    for i, (o, p) in enumerate(zip(object_points, image_points, strict=True)):
        o = as_points(o, 3, f"object_points[{i}]")
        p = as_points(p, 2, f"image_points[{i}]", nan_rows=True)
        if o.ndim != 2 or p.ndim != 2 or len(o) != len(p):
            raise ShapeError(f"view {i}: expected (N, 3) object points and (N, 2) image points, got "
                             f"{o.shape} and {p.shape}")
        if np.abs(o[:, 2]).max() > 1e-9 * max(1.0, np.abs(o).max()):
            raise ParameterError(f"object_points[{i}]: expected a planar target with Z = 0")
        objs.append(o)
        imgs.append(p)
    return objs, imgs


def calibrate(object_points: Any, image_points: Any, *, width: int, height: int, model: str = "brown-conrady",
              fix: tuple[str, ...] | None = None, free: tuple[str, ...] | None = None,
              robust_loss: str | None = None, robust_scale_px: float = 1.0,
              reject_sigma: float | None = 5.0, max_iterations: int = 200) -> CalibrationResult:
    """Calibrate a camera from views of a planar target.

    Layers: a homography per view (normalised DLT), Zhang's closed form for K and the poses,
    a linear start for k1, k2 (Zhang 2000, sec. 3.3); for Kannala-Brandt instead the
    equidistant projection ``r = f theta`` (J. Kannala and S. Brandt, IEEE TPAMI 28(8), 2006,
    sec. 3.2: its initialisation), f chosen as the one under which every view's corners lie
    on a plane. Then Levenberg-Marquardt over the free
    model parameters and every pose (rotations updated multiplicatively), with the lens
    models' analytic Jacobians. The model's default held parameters (:func:`default_fix`), plus
    those named in ``fix``, less those named in ``free`` (names or groups such as
    ``"tangential"``; see :func:`held_parameters`), keep their start value (0 for distortion).
    ``robust_loss`` ("huber" or
    "cauchy", scale ``robust_scale_px``) reweights residuals; corners whose residual exceeds
    ``reject_sigma`` robust standard deviations are rejected with the reason recorded, and the
    fit repeated once.

    Parameters
    ----------
    object_points : list of (N_i, 3) arrays, Z = 0
    image_points : list of (N_i, 2) arrays; NaN rows for corners not seen
    width, height : int
    model : registry name

    Returns
    -------
    CalibrationResult

    Raises
    ------
    EstimationError
        Too few views or points, or views that cannot determine the camera; the message names
        the cause and what to do.
    """
    objs, imgs = _as_views(object_points, image_points)
    w = as_positive_int(width, "width")
    h = as_positive_int(height, "height")
    cls = get_model(model)
    held = held_parameters(model, fix, free)
    if robust_loss is not None:
        check_choice(robust_loss, ("huber", "cauchy"), "robust_loss")
    scale = as_positive_float(robust_scale_px, "robust_scale_px")
    fixed = set(cls.param_indices(held)) if held else set()
    free = [i for i in range(len(cls.param_names)) if i not in fixed]
    # Closed-form start (pinhole part), from views with >= 4 seen points.
    keep, rejected_views = [], []
    for i, (o, p) in enumerate(zip(objs, imgs, strict=True)):
        seen = np.isfinite(p).all(axis=1)
        n = int(seen.sum())
        reason = (f"only {n} corners (4 needed)" if n < 4
                  else f"the {n} corners seen lie on one line" if _collinear(o[seen, :2]) else None)
        if reason:
            rejected_views.append((i, reason))
        keep.append(reason is None)
    if sum(keep) < (2 if "skew" not in {cls.param_names[i] for i in free} else 3):
        raise EstimationError(f"views: only {sum(keep)} views have 4 or more corners; calibration needs at least "
                              "3 (2 with skew held at 0) views of the board in different orientations")
    kept_objs = [o for o, k in zip(objs, keep, strict=True) if k]
    kept_imgs = [p for p, k in zip(imgs, keep, strict=True) if k]
    if cls.name == "kannala-brandt":
        K, start_poses = _equidistant_start(kept_objs, kept_imgs, w, h)
    else:
        Hs = []
        for o, p in zip(kept_objs, kept_imgs, strict=True):
            ok = np.isfinite(p).all(axis=1)
            Hs.append(find_homography(o[ok, :2], p[ok], refine=False))  # the LM below refines
        K = intrinsics_from_homographies(Hs, zero_skew=0 not in [i for i in free if cls.param_names[i] == "skew"])
        start_poses = poses_from_homographies(K, Hs)
    normals = np.array([p.R[:, 2] for p in start_poses])
    spread = np.degrees(np.arccos(np.clip(np.abs(normals @ normals.T), -1, 1))).max()
    if spread < 5.0:
        # Zhang 2000 sec. 3.3: with every board normal parallel the focal length is not
        # determined; with lens distortion the linear system is not exactly singular, so this
        # is checked on the geometry, not on the numbers.
        raise EstimationError(f"views: every board is within {spread:.1f} degrees of the same orientation; the "
                              "focal length cannot be determined. Tilt the board differently between photos "
                              "(10-50 degrees, about different axes)")
    poses_k = iter(start_poses)
    poses = [next(poses_k) if k else None for k in keep]
    start = {"fx": K[0, 0], "fy": K[1, 1], "cx": K[0, 2], "cy": K[1, 2], "skew": K[0, 1]}
    if "skew" in {cls.param_names[i] for i in fixed}:
        start["skew"] = 0.0
    cam = cls(**start, width=w, height=h)
    views = [i for i, k in enumerate(keep) if k]
    cam = _linear_radial_start(cam, [objs[i] for i in views], [imgs[i] for i in views], [poses[i] for i in views],
                               free)
    mask = [np.isfinite(imgs[i]).all(axis=1) for i in views]
    rejected: list[tuple[int, int, str]] = []
    # With outlier rejection: a first fit to 1e-6 relative cost decrease is enough to tell the
    # outliers; the final fit, without them, goes to 1e-10.
    tolerances = (1e-6, 1e-10) if reject_sigma is not None else (1e-10,)
    total_iterations = 0
    for rnd, tol in enumerate(tolerances):
        final = rnd == len(tolerances) - 1
        cam, vposes, info = _levenberg_marquardt(cam, [objs[i] for i in views], [imgs[i] for i in views],
                                                 [poses[i] for i in views], mask, free, robust_loss, scale,
                                                 max_iterations, tol, covariance=final)
        total_iterations += info["iterations"]
        for k, i in enumerate(views):
            poses[i] = vposes[k]
        if final:
            break
        # The solver's residuals at its solution, stacked view by view over the corners in use.
        res = np.hypot(info["residuals"][:, 0], info["residuals"][:, 1])
        sigma = 1.4826 * np.median(res) / 0.8326  # MAD of the 2-D residual norm -> per-axis sigma
        limit = reject_sigma * max(sigma, 1e-6) * np.sqrt(2)
        start = 0
        for k, i in enumerate(views):
            used = np.flatnonzero(mask[k])
            r = res[start:start + len(used)]
            start += len(used)
            for j, rj in zip(used[r > limit], r[r > limit], strict=True):
                rejected.append((i, int(j), f"residual {rj:.2f} px > {reject_sigma:g} robust sigma ({limit:.2f} px)"))
            mask[k][used[r > limit]] = False
    info["iterations"] = total_iterations
    return _result(cam, objs, imgs, poses, views, mask, free, info, rejected, rejected_views)


def _collinear(xy: np.ndarray) -> bool:
    s = np.linalg.svd(xy - xy.mean(axis=0), compute_uv=False)
    return bool(s[1] <= 1e-6 * s[0])


def _stacked_points(objs: list[np.ndarray], poses: list[Pose]) -> np.ndarray:
    """Every view's board points in its camera frame, stacked view by view (one kernel call)."""
    view = np.repeat(np.arange(len(objs), dtype=np.int64), [len(o) for o in objs])
    Rs = np.array([pose.R for pose in poses])
    ts = np.array([pose.t for pose in poses])
    return _kc.rotate_views(Rs, ts, np.ascontiguousarray(np.concatenate(objs), dtype=np.float64), view)[1]


def _linear_radial_start(cam: CameraModel, objs, imgs, poses, free) -> CameraModel:
    """k1, k2 from the pinhole start by linear least squares (Zhang 2000, eq. 13)."""
    names = {cam.param_names[i] for i in free}
    if not {"k1", "k2"} <= names or cam.name != "brown-conrady":
        return cam
    X = _stacked_points(objs, poses)  # all views at once
    p = np.concatenate(imgs)
    ok = np.isfinite(p).all(axis=1)
    X, p = X[ok], p[ok]
    x, y = X[:, 0] / X[:, 2], X[:, 1] / X[:, 2]
    r2 = x * x + y * y
    du, dv = cam.fx * x, cam.fy * y  # ideal pixel minus the principal point
    rows = [np.stack([du * r2, du * r2 * r2], -1), np.stack([dv * r2, dv * r2 * r2], -1)]
    rhs = [p[:, 0] - cam.cx - du, p[:, 1] - cam.cy - dv]
    k = np.linalg.lstsq(np.concatenate(rows), np.concatenate(rhs), rcond=None)[0]
    try:
        return cam.replace(k1=float(k[0]), k2=float(k[1]))
    except ParameterError:
        return cam


def _weights(r: np.ndarray, loss: str | None, scale: float) -> np.ndarray:
    if loss is None:
        return np.ones(len(r))
    n = np.hypot(r[:, 0], r[:, 1]) / scale
    if loss == "huber":
        return np.where(n <= 1, 1.0, 1.0 / np.maximum(n, 1e-300))
    return 1.0 / (1.0 + n * n)


def _seed_valid_radius(model: CameraModel, points_cam: np.ndarray) -> None:
    """Inside the solver a Brown-Conrady model needs to be one-to-one only as far out as the
    points it projects: scan the disk up to 2 % beyond the farthest point's ideal radius
    (32 directions, 64 steps, each failing step bisected: the solver evaluates its trial
    models a dozen times per fit, so the scan is kept cheap; the default scan, 64 x 512 over
    three times the image corner's radius, is for the model returned) and record that as the
    model's valid radius. Only for the solver's own trial models; the model returned is built
    fresh."""
    from camkit._kernels import brown_conrady as _kb

    z = points_cam[:, 2]
    with np.errstate(divide="ignore", invalid="ignore"):
        r = np.hypot(points_cam[:, 0], points_cam[:, 1]) / z
    r = r[(z > 0) & np.isfinite(r)]
    coeffs = model._coeffs()
    if r.size == 0 or not coeffs.any():
        return
    model._cache["r_valid"] = float(_kb.valid_radius(coeffs, 1.02 * float(r.max()), 32, 64))


def _normal_blocks(Jm, dp, RX, r, w, view, n_views):
    """Blocks of the weighted normal equations: U (intrinsics), W (intrinsics x pose, per view),
    V (6x6 per view), and the gradients (one pass of a numba kernel; a view left without
    points by outlier rejection gets zero blocks)."""
    from camkit._kernels.calib import normal_blocks

    return normal_blocks(np.ascontiguousarray(Jm), np.ascontiguousarray(dp), np.ascontiguousarray(RX),
                         np.ascontiguousarray(r), np.ascontiguousarray(w, dtype=np.float64),
                         np.ascontiguousarray(view, dtype=np.int64), n_views)


def _levenberg_marquardt(cam, objs, imgs, poses, mask, free, loss, scale, max_iterations, tol=1e-10,
                         covariance=True):
    """Minimise the (weighted) squared reprojection error over free model parameters and poses.

    Pose updates: R <- exp([w]x) R, t <- t + dt (a local parametrisation of the rotation). All
    views are evaluated at once (stacked points, rotations as arrays, one projection), and each
    step solves the normal equations by the Schur complement of the block-diagonal pose part,
    as bundle adjustment does (B. Triggs et al., "Bundle adjustment - a modern synthesis",
    1999, sec. 6.1); the undamped complement's inverse is the intrinsics' covariance."""
    n_free = len(free)
    n_views = len(objs)
    n_params = n_free + 6 * n_views
    cls = type(cam)
    obj = np.concatenate([o[m] for o, m in zip(objs, mask, strict=True)])
    img = np.concatenate([p[m] for p, m in zip(imgs, mask, strict=True)])
    view = np.repeat(np.arange(len(mask), dtype=np.int64), [int(m.sum()) for m in mask])
    obj = np.ascontiguousarray(obj, dtype=np.float64)
    n_pts = len(obj)
    if n_params > 2 * n_pts:
        raise EstimationError(f"points: {n_pts} corners cannot determine {n_params} unknowns; use more views "
                              "or more corners per view")
    Rs = np.array([p.R for p in poses])
    ts = np.array([p.t for p in poses])
    p_model = cam.params()

    def evaluate(p_model, Rs, ts):
        c = cls.from_params(p_model, width=cam.width, height=cam.height)
        RX, Xc = _kc.rotate_views(Rs, ts, obj, view)
        if cls.name == "brown-conrady":
            _seed_valid_radius(c, Xc)
        uv, dp, dk = c.project_with_jacobian(Xc)
        return c, uv - img, dk[:, :, free], (dp, RX)

    c, r, Jm, Jp = evaluate(p_model, Rs, ts)
    wts = _weights(r, loss, scale)
    cost = float((wts[:, None] * r * r).sum())
    if not np.isfinite(cost):
        raise EstimationError("start: the closed-form start projects points outside the lens model's valid "
                              "region; check the object points' units and the image points' order")
    mu = 1e-6
    converged, message, it = False, "", 0
    for it in range(1, max_iterations + 1):  # noqa: B007 - the count is reported after the loop
        U, W, V, gm, gp = _normal_blocks(Jm, *Jp, r, wts, view, n_views)
        dU = np.where(np.diag(U) > 0, np.diag(U), 1.0)
        dV = np.where(np.diagonal(V, axis1=1, axis2=2) > 0, np.diagonal(V, axis1=1, axis2=2), 1.0)
        improved = False
        for _ in range(30):
            try:
                Vinv = np.linalg.inv(V + mu * dV[:, :, None] * np.eye(6))
                S = U + mu * np.diag(dU) - np.einsum("vik,vkl,vjl->ij", W, Vinv, W)
                dm = np.linalg.solve(S, -gm + np.einsum("vik,vkl,vl->i", W, Vinv, gp))
            except np.linalg.LinAlgError:
                mu *= 10
                continue
            d = np.einsum("vkl,vl->vk", Vinv, -gp - np.einsum("vik,i->vk", W, dm))
            p_new = p_model.copy()
            p_new[free] += dm
            # R' = exp([w]x) R, t' = t + dt: consistent with d X / d w = -[R X_o]x above.
            Rs_new = matrix_from_rvec(d[:, :3]) @ Rs
            ts_new = ts + d[:, 3:]
            try:
                c_new, r_new, Jm_new, Jp_new = evaluate(p_new, Rs_new, ts_new)
            except ParameterError:
                mu *= 10
                continue
            w_new = _weights(r_new, loss, scale)
            cost_new = float((w_new[:, None] * r_new * r_new).sum())
            if np.isfinite(cost_new) and cost_new < cost:
                rel = (cost - cost_new) / max(cost, 1e-300)
                p_model, Rs, ts, c, r, Jm, Jp, wts, cost = (p_new, Rs_new, ts_new, c_new, r_new, Jm_new, Jp_new,
                                                             w_new, cost_new)
                mu = max(mu / 10, 1e-15)
                improved = True
                step = max(np.abs(dm).max(initial=0.0), np.abs(d).max())
                if rel < tol or step < 1e-12:
                    converged, message = True, f"converged: relative cost decrease {rel:.1e} < {tol:.0e}"
                break
            mu *= 4
        if not improved:
            converged = True
            message = "converged: no step reduces the cost further"
            break
        if converged:
            break
    else:
        message = f"stopped after {max_iterations} iterations without converging"
    # Marginal covariance of the intrinsics (unit noise): the inverse of the undamped Schur
    # complement of the (unweighted) normal equations.
    cov_unit = np.full((n_free, n_free), np.nan)
    if covariance:
        U, W, V, _, _ = _normal_blocks(Jm, *Jp, r, np.ones(len(r)), view, n_views)
        try:
            S0 = U - np.einsum("vik,vkl,vjl->ij", W, np.linalg.inv(V), W)
            cov_unit = np.linalg.inv(S0)
        except np.linalg.LinAlgError:
            pass
    poses = [Pose._unchecked(R, t) for R, t in zip(Rs, ts, strict=True)]
    # A fresh model: the one used in the loop knows its valid region only as far as the data.
    c = cls.from_params(p_model, width=cam.width, height=cam.height)
    return c, poses, {"converged": converged, "iterations": it, "cost": cost, "message": message,
                      "cov_unit": cov_unit, "n_params": n_params, "residuals": r}


def _result(cam, objs, imgs, poses, views, mask, free, info, rejected, rejected_views) -> CalibrationResult:
    # Every view's residuals from one projection of all the points.
    counts = [len(objs[i]) for i in views]
    view = np.repeat(np.arange(len(views), dtype=np.int64), counts)
    Xc = _stacked_points([objs[i] for i in views], [poses[i] for i in views])
    used = np.concatenate(mask)
    res = cam.project(Xc) - np.concatenate([imgs[i] for i in views])
    res[~used] = np.nan
    residuals = [np.full_like(imgs[i], np.nan) for i in range(len(imgs))]
    for i, r in zip(views, np.split(res, np.cumsum(counts)[:-1]), strict=True):
        residuals[i] = r
    sq = np.where(used, (res**2).sum(axis=1), 0.0)
    n_used = np.bincount(view, weights=used, minlength=len(views))
    view_rms = np.full(len(imgs), np.nan)
    with np.errstate(invalid="ignore", divide="ignore"):
        view_rms[views] = np.sqrt(np.bincount(view, weights=sq, minlength=len(views)) / n_used)
    R = res[used]
    dof = max(R.size - info["n_params"], 1)
    sigma2 = float((R**2).sum() / dof)
    cov = info["cov_unit"] * sigma2
    names = tuple(cam.param_names[i] for i in free)
    return CalibrationResult(
        model=cam, poses=[poses[i] for i in views], rms_px=float(np.sqrt((R**2).sum(axis=1).mean())),
        std_px=(float(R[:, 0].std()), float(R[:, 1].std())), view_rms_px=view_rms[views],
        residuals=[residuals[i] for i in views], free_params=names, covariance=cov,
        stddev={n: float(np.sqrt(cov[j, j])) for j, n in enumerate(names)}, rejected=rejected,
        view_indices=tuple(views), rejected_views=rejected_views, object_points=objs, image_points=imgs,
        converged=info["converged"], iterations=info["iterations"], cost=info["cost"], message=info["message"])


def _equidistant_start(objs: list[np.ndarray], imgs: list[np.ndarray], width: int,
                       height: int) -> tuple[np.ndarray, list[Pose]]:
    """K and poses for a fisheye lens from the equidistant model ``r = f theta`` about the
    image centre: for a trial f each pixel becomes a ray, rays within 80 degrees of the axis a
    point on the normalised plane, and a homography per view is fitted to them; the f whose
    homographies explain the rays best (smallest median angle) wins, on a grid of 41 field
    angles for the farthest corner, 15-175 degrees, then refined on a finer grid."""
    c = np.array([(width - 1) / 2.0, (height - 1) / 2.0])
    r_max = max(float(np.nanmax(np.hypot(*(p - c).T))) for p in imgs)

    def fit(f: float) -> tuple[float, list[np.ndarray]]:
        errs, Hs = [], []
        for o, p in zip(objs, imgs, strict=True):
            d = p - c
            r = np.hypot(d[:, 0], d[:, 1])
            theta = r / f
            ok = np.isfinite(r) & (theta < np.radians(80.0))
            if ok.sum() < 4:
                return np.inf, []
            scale = np.tan(theta[ok]) / np.maximum(r[ok], 1e-12)
            xn = d[ok] * scale[:, None]
            try:
                H = find_homography(o[ok, :2], xn, refine=False)
            except EstimationError:
                return np.inf, []
            q = np.c_[o[ok, :2], np.ones(ok.sum())] @ H.T
            ray_h = q / np.linalg.norm(q, axis=1, keepdims=True) * np.sign(q[:, 2:3])
            ray_o = np.c_[np.sin(theta[ok])[:, None] * d[ok] / np.maximum(r[ok], 1e-12)[:, None],
                          np.cos(theta[ok])]
            errs.append(np.arccos(np.clip((ray_h * ray_o).sum(axis=1), -1.0, 1.0)))
            Hs.append(H)
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


#: Boards calibrate_images asks for before it tries: two fix a pinhole camera with zero skew
#: (Zhang 2000, sec. 3.1) but leave nothing to check it with.
_MIN_BOARDS = 3


def calibrate_images(images: Any, board: Any, *, model: str = "brown-conrady", fix: tuple[str, ...] | None = None,
                     free: tuple[str, ...] | None = None, robust_loss: str | None = None,
                     reject_sigma: float | None = 5.0, progress: Any = None) -> CalibrationResult:
    """Detect the board in each image and calibrate from the corners found.

    Parameters
    ----------
    images : sequence of arrays or paths
        Images as arrays (grey, RGB, 8 or 16 bit) or files :func:`camkit.io.read_image` reads;
        all of the same size.
    board : Checkerboard
    model, fix, free, robust_loss, reject_sigma
        As for :func:`calibrate`.
    progress : callable(done, total) or None
        Called after each image is detected.

    Returns
    -------
    CalibrationResult
        With ``detections`` (one per image, in input order); images where no board was found
        are in ``rejected_views`` with the detector's reason.
    """
    if not isinstance(board, Checkerboard):
        raise ParameterError(f"board: expected a Checkerboard, got {type(board).__name__}")
    if isinstance(images, np.ndarray | str | os.PathLike) or not hasattr(images, "__len__"):
        raise ShapeError("images: expected a sequence (list) of images or paths, one per view, got "
                         f"{type(images).__name__}")
    if len(images) == 0:
        raise EstimationError("images: no images given; calibration needs 3 or more views of the board")
    detections, size = [], None
    for k, item in enumerate(images):
        img = read_image(item) if isinstance(item, str | os.PathLike) else item
        if not isinstance(img, np.ndarray):
            raise ShapeError(f"images[{k}]: expected an image array or a path, got {type(item).__name__}")
        if size is None:
            size = img.shape[:2]
        elif img.shape[:2] != size:
            raise ShapeError(f"images[{k}]: expected the size of the first image, {size[1]}x{size[0]}, "
                             f"got {img.shape[1]}x{img.shape[0]}; one calibration is for one camera mode")
        detections.append(detect_corners(img, board))
        if progress is not None:
            progress(k + 1, len(images))
    found = [d for d in detections if d.found]
    if len(found) < _MIN_BOARDS:
        raise EstimationError(
            f"images: the board was found in {len(found)} of {len(images)} images; calibration needs it in at "
            f"least {_MIN_BOARDS} (better 10 or more), each showing the board tilted a different way. Check the "
            f"board size (inner corners {board.inner_cols}x{board.inner_rows}, not squares), and photograph the "
            "whole board, in focus, filling a good part of the image", detections=tuple(detections))
    obj = board.object_points()
    try:
        result = calibrate([obj] * len(detections), [d.corners for d in detections], width=size[1],
                           height=size[0], model=model, fix=fix, free=free, robust_loss=robust_loss,
                           reject_sigma=reject_sigma)
    except EstimationError as exc:
        raise EstimationError(f"{exc} (the board was found in {len(found)} of {len(images)} images)",
                              detections=tuple(detections)) from None
    reasons = {i: r for i, r in result.rejected_views}
    rejected_views = [(i, reasons[i] if d.found else f"board not found: {d.message}")
                      for i, d in enumerate(detections) if i in reasons]
    return replace(result, rejected_views=rejected_views, detections=detections)
