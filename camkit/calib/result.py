"""The result of a calibration: what was found, how well it is known, and its dictionary form
(the results file, ``camkit calibrate --json``)."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from camkit._kernels import calib as calib_kernels
from camkit._repr import summary_repr
from camkit.calib.refine import RefineReport
from camkit.errors import ParameterError
from camkit.geometry.pose import Pose
from camkit.lens.base import CameraModel

__all__ = ["RESULTS_FORMAT_VERSION", "CalibrationResult", "assemble_result", "stacked_points"]

#: Version of the results file's layout.
RESULTS_FORMAT_VERSION = 1


def _num(x: float) -> float | None:
    """JSON has no NaN: a value that does not exist is None."""
    return None if not math.isfinite(x) else float(x)


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

    def __repr__(self) -> str:
        return summary_repr(self)

    def view_ypr_deg(self) -> np.ndarray:
        """Yaw, pitch, roll (degrees) of the camera relative to the board, per view (n, 3)."""
        return np.degrees(np.array([p.inverse().ypr() for p in self.poses]))

    def to_dict(self, image_names: Sequence[str] | None = None) -> dict[str, Any]:
        """``{"model": {type, width, height, parameters by name}, "rms_px", "std_px": [x, y],
        "views": [{"image", "found", "n_corners", "rms_px"}], "stddev": {parameter: sigma}}``,
        plus the format version, convergence, rejected corners and views, and per view the
        pose (``cam_from_target`` as a rotation vector and translation, metres) and the
        camera's yaw/pitch/roll relative to the board (degrees). JSON-ready: a value that does
        not exist is None.

        ``views`` has one entry per input view (or image): ``found`` is false and ``rms_px``
        None for a view that was left out."""
        dets = self.detections
        n_inputs = len(dets) if dets is not None else max(
            (*self.view_indices, *(i for i, _ in self.rejected_views)), default=-1) + 1
        if image_names is not None and len(image_names) != n_inputs:
            raise ParameterError(f"image_names: expected {n_inputs} names, one per input view, got {len(image_names)}")
        names = list(image_names) if image_names is not None else [f"view {i}" for i in range(n_inputs)]
        pos = {v: k for k, v in enumerate(self.view_indices)}
        ypr = self.view_ypr_deg()
        reasons = dict(self.rejected_views)
        views = []
        for i in range(n_inputs):
            entry: dict[str, Any] = {"image": names[i]}
            if i in pos:
                k = pos[i]
                seen = ~(self.residuals[k] != self.residuals[k]).any(axis=1)  # corners used (not NaN)
                pose = self.poses[k]
                entry.update(found=True, n_corners=int(seen.sum()), rms_px=_num(float(self.view_rms_px[k])),
                             rvec=[float(v) for v in pose.rvec], t_m=[float(v) for v in pose.t],
                             camera_ypr_deg=[float(v) for v in ypr[k]])
            else:
                n = dets[i].n_found if dets is not None else int(np.isfinite(self.image_points[i]).all(axis=1).sum())
                entry.update(found=False, n_corners=int(n), rms_px=None, reason=reasons.get(i, ""))
            views.append(entry)
        return {
            "format": "camkit-calibration", "version": RESULTS_FORMAT_VERSION,
            "model": self.model.to_dict(),
            "rms_px": _num(self.rms_px), "std_px": [_num(self.std_px[0]), _num(self.std_px[1])],
            "views": views,
            "stddev": {k: _num(v) for k, v in self.stddev.items()},
            "converged": bool(self.converged), "iterations": int(self.iterations), "message": self.message,
            "rejected_corners": [{"view": int(v), "corner": int(c), "reason": r} for v, c, r in self.rejected],
            "rms_definition": "sqrt(mean over corners of dx^2 + dy^2), as OpenCV's calibrateCamera",
        }


def stacked_points(objs: list[np.ndarray], poses: list[Pose]) -> np.ndarray:
    """Every view's target points in its camera frame, stacked view by view (one kernel call)."""
    view = np.repeat(np.arange(len(objs), dtype=np.int64), [len(o) for o in objs])
    Rs = np.array([pose.R for pose in poses])
    ts = np.array([pose.t for pose in poses])
    return calib_kernels.rotate_views(Rs, ts, np.ascontiguousarray(np.concatenate(objs), dtype=np.float64), view)[1]


#: A fit whose RMS is over this (px) says in its message that the model does not fit: corners
#: of a lens model that fits leave 0.1-0.3 px on real photos (Bouguet's set 0.15, the six
#: real_boards sets 0.10-0.22 with the right model; a car camera's JPEGs 0.88, OpenCV's fit of
#: its own corners 0.86); a fisheye lens under brown-conrady leaves 10.4 px, and plantcv_wide's
#: large board, not flat, 7.6 px (views 1.8-23 px; OpenCV's fit of its own corners 13.0 px).
_POOR_FIT_RMS_PX = 2.0


def assemble_result(cam: CameraModel, objs: list[np.ndarray], imgs: list[np.ndarray], poses: list[Pose | None],
                    views: list[int], mask: list[np.ndarray], free_names: tuple[str, ...], report: RefineReport,
                    iterations: int, rejected: list[tuple[int, int, str]],
                    rejected_views: list[tuple[int, str]]) -> CalibrationResult:
    """The result of a fit: every view's residuals from one projection of all the points, the
    RMS as OpenCV defines it, and the covariance of the free parameters scaled by the residual
    variance (``report.covariance`` is for unit noise)."""
    counts = [len(objs[i]) for i in views]
    view = np.repeat(np.arange(len(views), dtype=np.int64), counts)
    Xc = stacked_points([objs[i] for i in views], [poses[i] for i in views])
    used = np.concatenate(mask)
    res = cam.project(Xc) - np.concatenate([imgs[i] for i in views])
    # A corner the fitted model cannot project (beyond the radius where its distortion folds
    # back) has no residual: it is listed as rejected with that reason, and the message says
    # the model does not fit these views, rather than an RMS of NaN.
    lost = used & ~np.isfinite(res).all(axis=1)
    message = report.message
    if lost.any():
        first = np.concatenate([[0], np.cumsum(counts)[:-1]])
        rejected = rejected + [(views[int(view[j])], int(j - first[view[j]]),
                                "the fitted lens model does not reach this point (its distortion folds back "
                                "before this radius)") for j in np.flatnonzero(lost)]
        used = used & ~lost
        message = (f"{message}; {int(lost.sum())} corners lie beyond the radius where the fitted distortion folds "
                   f"back: the model does not fit these views (try another lens model, or check the views)")
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
    rms = float(np.sqrt((R**2).sum(axis=1).mean()))
    if not lost.any() and rms > _POOR_FIT_RMS_PX:
        message = (f"{message}; an RMS of {rms:.1f} px is far more than corners' noise (0.1-0.5 px where the lens "
                   "model fits): the model does not fit these views (for a fisheye lens, try kannala-brandt), the "
                   "board is not flat, or some detections are wrong")
    dof = max(R.size - report.n_params, 1)
    sigma2 = float((R**2).sum() / dof)
    cov = report.covariance * sigma2
    names = free_names
    return CalibrationResult(
        model=cam, poses=[poses[i] for i in views], rms_px=rms,
        std_px=(float(R[:, 0].std()), float(R[:, 1].std())), view_rms_px=view_rms[views],
        residuals=[residuals[i] for i in views], free_params=names, covariance=cov,
        stddev={n: float(np.sqrt(cov[j, j])) for j, n in enumerate(names)}, rejected=rejected,
        view_indices=tuple(views), rejected_views=rejected_views, object_points=objs, image_points=imgs,
        converged=report.converged, iterations=iterations, cost=report.cost, message=message)
