"""Camera calibration, the orchestration: views in, a result out.

The layers it calls, each usable alone: a closed-form start (:mod:`camkit.calib.start`,
chosen by the lens model), the least-squares problem of one camera and its views
(:mod:`camkit.calib.views`) solved by the one sparse Levenberg-Marquardt
(:mod:`camkit.calib.refine`), and the result (:mod:`camkit.calib.result`)."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import replace
from typing import Any

import numpy as np

from camkit._validate import as_positive_float, as_positive_int, check_choice, check_same_size
from camkit.calib.refine import LMOptions, solve
from camkit.calib.result import CalibrationResult, assemble_result
from camkit.calib.start import centred_start, closed_form_start, linear_distortion_start
from camkit.calib.views import ViewsProblem, as_views, reject_outliers
from camkit.errors import EstimationError, ParameterError, ShapeError
from camkit.lens.base import get_model
from camkit.target import Detection, Target

__all__ = ["DEFAULT_FIX", "CalibrationResult", "calibrate", "calibrate_detections", "calibrate_images",
           "default_fix", "held_parameters"]

#: Held at their start values by default for Brown-Conrady (``BrownConrady.default_fixed``):
#: skew, and the terms beyond k1, k2, p1, p2, k3 (OpenCV's default 5-coefficient model).
DEFAULT_FIX = ("skew", "k4", "k5", "k6", "s1", "s2", "s3", "s4")


def default_fix(model: str) -> tuple[str, ...]:
    """The parameters ``calibrate`` holds unless freed: the model's ``default_fixed``
    (:data:`DEFAULT_FIX` for Brown-Conrady, skew alone for the others; Kannala-Brandt fits
    k1..k4, as OpenCV's fisheye module does)."""
    return tuple(get_model(model).default_fixed)


def held_parameters(model: str, fix: Any = (), free: Any = ()) -> tuple[str, ...]:
    """The parameters calibration holds: the model's defaults, plus ``fix``, less ``free``
    (:meth:`CameraModel.held_parameters`).

    Examples
    --------
    >>> held_parameters("brown-conrady", fix=("k3",), free=("k4",))
    ('skew', 'k3', 'k5', 'k6', 's1', 's2', 's3', 's4')
    """
    return get_model(model).held_parameters(fix, free)


def calibrate(object_points: Any, image_points: Any, *, width: int, height: int, model: str = "brown-conrady",
              fix: tuple[str, ...] | None = None, free: tuple[str, ...] | None = None,
              robust_loss: str | None = None, robust_scale_px: float = 1.0,
              reject_sigma: float | None = 5.0, max_iterations: int = 200) -> CalibrationResult:
    """Calibrate a camera from views of a planar target.

    Layers: the closed-form start the model asks for (:meth:`CameraModel.start_projection`):
    a homography per view (normalised DLT) and Zhang's closed form for K and the poses, or,
    for a fisheye, the equidistant projection ``r = f theta`` (J. Kannala and S. Brandt, IEEE
    TPAMI 28(8), 2006, sec. 3.2: its initialisation), f chosen as the one under which every
    view's corners lie on a plane; the model's linear distortion terms by least squares
    (Zhang 2000, sec. 3.3), fewer of them where all would fold a view's points back. Then the
    sparse Levenberg-Marquardt
    (:func:`camkit.calib.refine.solve`) over the free model parameters and every pose
    (rotations updated multiplicatively), with the lens models' analytic Jacobians. The
    model's default held parameters (:func:`default_fix`), plus those named in ``fix``, less
    those named in ``free`` (names or groups such as ``"tangential"``; see
    :func:`held_parameters`), keep their start value (0 for distortion). ``robust_loss``
    ("huber" or "cauchy", scale ``robust_scale_px``) reweights residuals; corners whose
    residual exceeds ``reject_sigma`` robust standard deviations are rejected with the reason
    recorded, and the fit repeated once. Where the fit from Zhang's start cannot start, ends
    with an RMS over a pixel (strong distortion bends the homographies, and the closed form
    can put the principal point far off) or leaves its focal length unsure (a standard
    deviation over 1 % of it: views that determine f weakly give the cost more than one
    minimum), it is tried again from the principal point at the image's centre
    (:func:`~camkit.calib.start.centred_start`, OpenCV's start) and the lower cost kept. A fit
    that leaves the focal length unsure by more than a tenth of it is refused, in words: views
    whose boards all face one way (normals within 5 degrees of each other under Zhang's start:
    Zhang 2000, sec. 3.3) are fitted and judged so, not refused on the angle alone, since boards
    tilted about one axis still determine f where the tilt is large.

    Parameters
    ----------
    object_points : list of (N_i, 3) arrays, Z = 0, or one (V, N, 3) array
    image_points : list of (N_i, 2) arrays, or one (V, N, 2) array; NaN rows for corners not seen
    width, height : int
    model : registry name

    Returns
    -------
    CalibrationResult

    Raises
    ------
    EstimationError
        Too few views or points, or views that cannot determine the camera (a focal length
        unsure by over 10 %); the message names the cause and what to do.
    """
    objs, imgs = as_views(object_points, image_points)
    w = as_positive_int(width, "width")
    h = as_positive_int(height, "height")
    cls = get_model(model)
    held = held_parameters(model, fix, free)
    if robust_loss is not None:
        check_choice(robust_loss, ("huber", "cauchy"), "robust_loss")
    scale = as_positive_float(robust_scale_px, "robust_scale_px")
    fixed = set(cls.param_indices(held)) if held else set()
    free_idx = [i for i in range(len(cls.param_names)) if i not in fixed]
    free_names = {cls.param_names[i] for i in free_idx}
    # Views with 4 or more points not on one line start the fit; the others are listed.
    keep, rejected_views = [], []
    for i, (o, p) in enumerate(zip(objs, imgs, strict=True)):
        seen = np.isfinite(p).all(axis=1)
        n = int(seen.sum())
        reason = (f"only {n} corners (4 needed)" if n < 4
                  else f"the {n} corners seen lie on one line" if _collinear(o[seen, :2]) else None)
        if reason:
            rejected_views.append((i, reason))
        keep.append(reason is None)
    if sum(keep) < (2 if "skew" not in free_names else 3):
        raise EstimationError(f"views: only {sum(keep)} views have 4 or more corners; calibration needs at least "
                              "3 (2 with skew held at 0) views of the board in different orientations")
    views = [i for i, k in enumerate(keep) if k]
    K, start_poses = closed_form_start(cls, [objs[i] for i in views], [imgs[i] for i in views], w, h,
                                       zero_skew="skew" not in free_names)
    # Zhang 2000 sec. 3.3: with every board normal parallel the focal length is not determined;
    # with lens distortion the linear system is not exactly singular, so the geometry raises the
    # doubt (_MIN_SPREAD_DEG) and the fit's own uncertainty settles it (_MAX_F_SHARE).
    spread = _spread(start_poses)
    parallel = spread < _MIN_SPREAD_DEG
    if parallel and not {"fx", "fy"} <= free_names:
        raise _unsure_error(spread, None)
    if "skew" not in free_names:
        K[0, 1] = 0.0
    vobjs, vimgs = [objs[i] for i in views], [imgs[i] for i in views]

    def fit(K: np.ndarray, start_poses: list) -> tuple:
        """(model, poses, masks, report, iterations, rejected) of the fit from the start ``K``,
        ``start_poses``."""
        cam = linear_distortion_start(cls.initial_guess(K, width=w, height=h), vobjs, vimgs, start_poses,
                                      free_names)
        poses = list(start_poses)
        mask = [np.isfinite(imgs[i]).all(axis=1) for i in views]
        rejected: list[tuple[int, int, str]] = []
        # With outlier rejection: a first fit to 1e-6 relative cost decrease is enough to tell
        # the outliers; the final fit, without them, goes to 1e-10.
        tolerances = (1e-6, 1e-10) if reject_sigma is not None else (1e-10,)
        total_iterations = 0
        for rnd, tol in enumerate(tolerances):
            final = rnd == len(tolerances) - 1
            problem = ViewsProblem(cls, w, h, vobjs, vimgs, mask, free_idx)
            n_params = len(free_idx) + 6 * len(views)
            if n_params > 2 * len(problem.obj):
                raise EstimationError(f"points: {len(problem.obj)} corners cannot determine {n_params} unknowns; "
                                      "use more views or more corners per view")
            report = solve(problem, problem.start(cam, poses),
                           LMOptions(max_iterations=max_iterations, tolerance=tol, robust_loss=robust_loss,
                                     robust_scale=scale, covariance=final))
            total_iterations += report.iterations
            # A fresh model: the solver's trial models know their valid region only as far as the data.
            cam, poses = problem.model(report.state), report.state.poses()
            if final:
                break
            rejected += reject_outliers(report.residuals, mask, views, reject_sigma)
        return cam, poses, mask, report, total_iterations, rejected

    try:
        best = fit(K, start_poses)
        failed = None
    except EstimationError as e:
        best, failed = None, e
    # A fit that ends far from the corners (an RMS over _RETRY_RMS_PX), cannot start or leaves
    # its focal length unsure (_RETRY_F_SHARE) is tried again from the principal point at the
    # image's centre (centred_start), and the lower RMS kept (the two may reject different
    # corners as outliers).
    if cls.start_projection() == "perspective" and (best is None or not _rms(best[3]) <= _RETRY_RMS_PX
                                                    or _weak_focal(best[0], best[3], free_names)):
        try:
            other = fit(*centred_start(vobjs, vimgs, w, h, "skew" not in free_names))
        except EstimationError:
            other = None
        if other is not None and (best is None or _rms(other[3]) < _rms(best[3])):
            best = other
    share = None if best is None else _focal_share(best[0], best[3], free_names, _NOISE_FLOOR_PX)
    if parallel and (share is None or not share <= _MAX_F_SHARE):
        raise _unsure_error(spread, share)
    if best is None:
        raise failed
    if not share <= _MAX_F_SHARE:
        raise _unsure_error(None, share)
    cam, poses, mask, report, total_iterations, rejected = best
    all_poses: list = [None] * len(objs)
    for k, i in enumerate(views):
        all_poses[i] = poses[k]
    return assemble_result(cam, objs, imgs, all_poses, views, mask, report.global_names, report, total_iterations,
                           rejected, rejected_views)


#: ``calibrate`` fits again from :func:`~camkit.calib.start.centred_start` where the fit from
#: Zhang's start ends with an RMS over this (px) or cannot start: on the real plantcv_wide set
#: (a 5.5 MP wide-angle lens, the board filling the frame) Zhang's start put the principal
#: point 630 px from the centre, and the fit from it ended at 34 px RMS; from the centre, at
#: 7.6 px (OpenCV's calibrateCamera: 13.0 px on its own corners).
_RETRY_RMS_PX = 1.0


#: ... and where the fit leaves its focal length unsure: a standard deviation over this share of
#: it (from the fit's covariance and residual variance). Where the views determine f weakly
#: the cost has more than one minimum: on OpenCV's four ChArUco tutorial photos (boards within
#: 6 degrees of one orientation) the fit from Zhang's start ended at fx 612.7 +- 43 px, 0.1932 px
#: RMS, and from the centre at OpenCV's own minimum, fx 457.3 +- 15.8 px, 0.1878 px RMS.
#: Well-determined sets (Bouguet's 20 views: 0.06 %) fit once.
_RETRY_F_SHARE = 0.01


#: Views whose board normals all lie within this angle (degrees) of each other, under Zhang's
#: start, may not determine the focal length (Zhang 2000, sec. 3.3: parallel boards give no
#: more constraints than one); the fit's uncertainty decides (:data:`_MAX_F_SHARE`).
_MIN_SPREAD_DEG = 5.0


#: A fit that leaves the focal length with a standard deviation over this share of it is
#: refused: a focal length unsure by a tenth is no calibration (OpenCV's calibrateCamera returns
#: such fits without a word). On the real sets the share is 0.02-0.4 % (Bouguet's 20 views, the
#: six real_boards sets) and 2.3 % on OpenCV's five ChArUco tutorial photos, whose boards are
#: tilted 20-28 degrees about one axis (normals within 4-6 degrees of each other, so the spread
#: alone would refuse them); boards square to the camera leave f unsure by hundreds of percent.
_MAX_F_SHARE = 0.10


#: ... with the residuals' standard deviation taken as at least this (px, per coordinate):
#: exact corners would otherwise give any fit, determined or not, a standard deviation of 0.
#: No detector locates corners better (camkit's noise-free rendered median error: 0.005 px).
_NOISE_FLOOR_PX = 0.01


def _unsure_error(spread: float | None, share: float | None) -> EstimationError:
    """The refusal of views that leave the focal length unsure: ``spread`` the angle (degrees)
    within which every board's normal lies, where under :data:`_MIN_SPREAD_DEG`; ``share`` the
    fit's focal-length standard deviation over the focal length, where there was a fit."""
    # A share that is not finite: the fit's normal equations are singular (boards square to the
    # camera, exact corners), f has no standard deviation at all.
    unsure = "" if share is None else (
        f"the fit leaves it unsure by {100 * share:.0f} %" if np.isfinite(share)
        else "the fit leaves it wholly undetermined")
    if spread is not None:
        cause = (f"every board is within {spread:.1f} degrees of the same orientation; the focal length cannot be "
                 "determined" + (f" ({unsure})" if unsure else ""))
    else:
        cause = f"the views do not determine the focal length ({unsure}, over {100 * _MAX_F_SHARE:.0f} %)"
    return EstimationError(f"views: {cause}. Tilt the board differently between photos (10-50 degrees, about "
                           "different axes), in more photos, the board filling more of the image")


def _focal_share(cam: Any, report: Any, free_names: set[str], floor_px: float = 0.0) -> float:
    """The larger of fx's and fy's standard deviation over their value, from the fit ``cam`` (its
    solver's ``report``): the covariance scaled by the residuals' variance, their standard
    deviation taken as at least ``floor_px``; 0 where neither is free, NaN where the fit has no
    covariance (a variance below zero, as a singular fit's rounding leaves, counts as none)."""
    r = np.asarray(report.residuals, dtype=np.float64)
    r = r[np.isfinite(r).all(axis=1)]
    sigma2 = max(float((r**2).sum() / max(r.size - report.n_params, 1)), floor_px**2)
    names = list(report.global_names)
    free = [f for f in ("fx", "fy") if f in free_names and f in names]
    var = [float(report.covariance[names.index(f), names.index(f)]) * sigma2 for f in free]
    shares = [float(np.sqrt(v)) / abs(float(getattr(cam, f))) if v >= 0 else float("nan")
              for v, f in zip(var, free, strict=True)]
    return max(shares, default=0.0) if np.isfinite(shares).all() else float("nan")


def _weak_focal(cam: Any, report: Any, free_names: set[str]) -> bool:
    """Whether the fit ``cam`` (its solver's ``report``) leaves its focal length unsure (see
    :data:`_RETRY_F_SHARE`); not where the fit has no covariance."""
    return bool(_focal_share(cam, report, free_names) > _RETRY_F_SHARE)


def _rms(report) -> float:
    """The RMS (px, OpenCV's: over corners) of a fit's residuals ``(N, 2)``, over the corners it
    could project; infinite where it projects none."""
    r = np.asarray(report.residuals, dtype=np.float64)
    ok = np.isfinite(r).all(axis=1)
    return float(np.sqrt(np.sum(r[ok] ** 2) / ok.sum())) if ok.any() else float("inf")


def _spread(poses: list) -> float:
    """The largest angle (degrees) between two of the ``poses``' board normals."""
    normals = np.array([p.R[:, 2] for p in poses])
    return float(np.degrees(np.arccos(np.clip(np.abs(normals @ normals.T), -1, 1))).max())


def _collinear(xy: np.ndarray) -> bool:
    s = np.linalg.svd(xy - xy.mean(axis=0), compute_uv=False)
    return bool(s[1] <= 1e-6 * s[0])


#: Boards calibrate_images asks for before it tries: two fix a pinhole camera with zero skew
#: (Zhang 2000, sec. 3.1) but leave nothing to check it with.
_MIN_BOARDS = 3


def calibrate_images(images: Any, board: Any, *, model: str = "brown-conrady", fix: tuple[str, ...] | None = None,
                     free: tuple[str, ...] | None = None, robust_loss: str | None = None,
                     reject_sigma: float | None = 5.0, progress: Any = None) -> CalibrationResult:
    """Detect the target in each image and calibrate from the points found.

    Parameters
    ----------
    images : sequence of arrays
        Images (grey, RGB, 8 or 16 bit), all of the same size. Files are read by
        :func:`camkit.pipeline.calibrate_files` (or :func:`camkit.io.read_image`).
    board : Target
        A Checkerboard, or any registered target.
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
    target = _as_target(board)
    if isinstance(images, np.ndarray | str) or not hasattr(images, "__len__"):
        raise ShapeError("images: expected a sequence (list) of image arrays, one per view, got "
                         f"{type(images).__name__}")
    if len(images) == 0:
        raise EstimationError("images: no images given; calibration needs 3 or more views of the board")
    detections, size = [], None
    for k, img in enumerate(images):
        if not isinstance(img, np.ndarray):
            raise ShapeError(f"images[{k}]: expected an image array, got {type(img).__name__} (files: "
                             "camkit.pipeline.calibrate_files, or camkit.io.read_image first)")
        size = check_same_size(size, img, f"images[{k}]")
        detections.append(target.detect(img))
        if progress is not None:
            progress(k + 1, len(images))
    return calibrate_detections(detections, target, width=size[1], height=size[0], model=model, fix=fix, free=free,
                                robust_loss=robust_loss, reject_sigma=reject_sigma)


def _other_size(detections: Sequence[Detection], target: Target) -> str:
    """": N of the M images without the board show a whole board of AxB ..." where at least two
    detections, and half of those that failed, saw the same whole board of another size
    (:attr:`Detection.board_seen`: a miscounted board); else ""."""
    from collections import Counter

    missed = [d for d in detections if not d.found]
    seen = Counter(d.board_seen for d in missed if d.board_seen is not None)
    if not seen:
        return ""
    (size, n), = seen.most_common(1)
    if n < max(2, (len(missed) + 1) // 2):
        return ""
    return f": {n} of the {len(missed)} images without it show a whole board of {target.seen_note(size)}"


def _as_target(board: Any) -> Target:
    if not isinstance(board, Target):
        raise ParameterError(f"board: expected a camkit target (e.g. a Checkerboard), got {type(board).__name__}")
    return board


def calibrate_detections(detections: Sequence[Detection], board: Target, *, width: int, height: int,
                         model: str = "brown-conrady", fix: tuple[str, ...] | None = None,
                         free: tuple[str, ...] | None = None, robust_loss: str | None = None,
                         reject_sigma: float | None = 5.0) -> CalibrationResult:
    """Calibrate from the target's detections in images of ``width x height`` pixels (one per
    image, in input order; :meth:`Target.detect`). Asks for the target in at least 3 images
    and says in words how many it was found in; the result carries ``detections``, and images
    where it was not found are in ``rejected_views`` with the detector's reason. Other
    arguments as :func:`calibrate`."""
    target = _as_target(board)
    detections = list(detections)
    if not detections or not all(isinstance(d, Detection) for d in detections):
        raise ParameterError("detections: expected a non-empty list of Detection (one per image)")
    found = [d for d in detections if d.found]
    if len(found) < _MIN_BOARDS:
        raise EstimationError(
            f"images: the board was found in {len(found)} of {len(detections)} images; calibration needs it in at "
            f"least {_MIN_BOARDS} (better 10 or more), each showing the board tilted a different way. Check the "
            f"{target.size_note()}{_other_size(detections, target)}, and photograph the whole board, in focus, "
            "filling a good part of the image", detections=tuple(detections))
    obj = target.object_points()
    try:
        result = calibrate([obj] * len(detections), [d.corners for d in detections], width=width,
                           height=height, model=model, fix=fix, free=free, robust_loss=robust_loss,
                           reject_sigma=reject_sigma)
    except EstimationError as exc:
        raise EstimationError(f"{exc} (the board was found in {len(found)} of {len(detections)} images)",
                              detections=tuple(detections)) from None
    reasons = {i: r for i, r in result.rejected_views}
    rejected_views = [(i, reasons[i] if d.found else f"board not found: {d.message}")
                      for i, d in enumerate(detections) if i in reasons]
    message = result.message
    other = _other_size(detections, target)
    if other:  # a board of the size given found in some images, a whole one of another in more
        message += f"; check the {target.size_note()}{other}"
    return replace(result, rejected_views=rejected_views, detections=detections, message=message)

