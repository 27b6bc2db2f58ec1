"""Calibration of a camera rig: N cameras rigidly mounted together, observing a target at the
same instants; stereo is the two-camera case.

Unknowns: every camera's free intrinsics and its pose in the rig (``cam_from_rig``; camera
``reference`` defines the rig frame and sits at its origin) form the solver's global block;
the rig's pose at each instant (``rig_from_target``) is a local block. A corner seen by camera
``c`` at instant ``t`` gives the residual ``project_c(cam_from_rig_c @ rig_from_target_t @ X)
- observed``, so each observation depends on the global block and one local block: the arrow
shape that :func:`camkit.calib.refine.solve` eliminates by the Schur complement (the same
structure Kalibr and mrcal solve; mrcal's documentation, "Formulation").

Start: each camera calibrated alone (or its intrinsics given, then a PnP per instant), each
camera's pose relative to a camera it shares instants with from the median of those instants'
relative poses, chained from the reference through the cameras' shared instants.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from camkit._kernels import calib as calib_kernels
from camkit._repr import summary_repr
from camkit._validate import as_positive_int, check_choice
from camkit.calib.calibrate import CalibrationResult, calibrate, held_parameters
from camkit.calib.homography import dlt_homographies
from camkit.calib.refine import Linearization, LMOptions, solve
from camkit.calib.views import pose_jacobian, reject_outliers
from camkit.calib.zhang import poses_from_homographies
from camkit.errors import EstimationError, ParameterError, ShapeError
from camkit.geometry.pose import Pose
from camkit.geometry.rotation import matrix_from_rvec
from camkit.lens.base import CameraModel
from camkit.target import Detection, Target

__all__ = ["CameraRig", "RigResult", "calibrate_rig"]


@dataclass(frozen=True, slots=True, eq=False)
class CameraRig:
    """Cameras rigidly mounted together: what a rig file holds and what rectification and
    triangulation need.

    Attributes
    ----------
    names : tuple of str
    models : tuple of CameraModel
    cam_from_rig : tuple of Pose
        Each camera's pose in the rig frame.
    """

    names: tuple[str, ...]
    models: tuple[CameraModel, ...]
    cam_from_rig: tuple[Pose, ...]

    def __post_init__(self) -> None:
        n = len(self.names)
        if n < 1 or len(self.models) != n or len(self.cam_from_rig) != n:
            raise ParameterError(f"names, models, cam_from_rig: expected one of each per camera, got {n}, "
                                 f"{len(self.models)} and {len(self.cam_from_rig)}")
        if len(set(self.names)) != n:
            raise ParameterError(f"names: expected different names, got {list(self.names)}")
        for k, (m, p) in enumerate(zip(self.models, self.cam_from_rig, strict=True)):
            if not isinstance(m, CameraModel):
                raise ParameterError(f"models[{k}]: expected a camkit camera model, got {type(m).__name__}")
            if not isinstance(p, Pose):
                raise ParameterError(f"cam_from_rig[{k}]: expected a Pose, got {type(p).__name__}")

    def index(self, camera: int | str) -> int:
        """The index of a camera given by index or name."""
        if isinstance(camera, str):
            if camera not in self.names:
                raise ParameterError(f"camera: expected one of {list(self.names)}, got {camera!r}")
            return self.names.index(camera)
        if isinstance(camera, bool) or not isinstance(camera, int | np.integer) or not 0 <= camera < len(self.names):
            raise ParameterError(f"camera: expected a name or an index in [0, {len(self.names)}), got {camera!r}")
        return int(camera)

    def relative_pose(self, a: int | str, b: int | str) -> Pose:
        """``cam_a_from_cam_b``: maps points in camera ``b``'s frame into camera ``a``'s (for a
        stereo pair, ``relative_pose("left", "right")`` is ``left_from_right``)."""
        return self.cam_from_rig[self.index(a)] @ self.cam_from_rig[self.index(b)].inverse()


@dataclass(frozen=True, slots=True, eq=False)
class RigResult:
    """What a rig calibration found, and how well it is known.

    Attributes
    ----------
    names : tuple of str
        The cameras' names, in input order.
    reference : int
        The camera at the rig's origin.
    cameras : tuple of CalibrationResult
        Per camera what a single-camera calibration gives: its model, ``cam_from_target`` per
        instant it saw (``view_indices`` are the instants), residuals, RMS, the covariance and
        standard deviations of its free intrinsics (the marginal of the joint fit: the other
        cameras and every pose eliminated).
    cam_from_rig : tuple of Pose
        Each camera's pose in the rig (identity for the reference).
    rig_from_target : list of Pose or None
        The rig's pose at each instant (None where no camera saw the target).
    rotation_sigma_deg, translation_sigma_m : ndarray, (n_cameras, 3)
        One-sigma of each ``cam_from_rig``: of the small rotation ``w`` in
        ``R <- exp([w]x) R`` (degrees, about the camera's axes) and of ``t`` (metres, or the
        target's unit); zero for the reference.
    baseline_m, baseline_sigma_m : ndarray, (n_cameras,)
        Distance of each camera's centre from the reference's, and its one-sigma.
    rms_px : float
        ``sqrt(mean(dx^2 + dy^2))`` over every corner used, all cameras.
    camera_rms_px : ndarray, (n_cameras,)
    instant_rms_px : ndarray, (n_instants,)
        NaN where no corner was used.
    covariance : ndarray, (G, G)
        Of every free parameter (``param_names``), scaled by the residual variance.
    param_names : tuple of str
        ``"<camera>.<parameter>"`` for the intrinsics, ``"<camera>.rx"`` ... ``"<camera>.tz"``
        for the poses (``rx, ry, rz`` the rotation ``w`` above, radians).
    rejected : list of (camera, instant, corner, reason)
        Corners left out as outliers.
    converged : bool
    iterations : int
    cost : float
    message : str
    """

    names: tuple[str, ...]
    reference: int
    cameras: tuple[CalibrationResult, ...]
    cam_from_rig: tuple[Pose, ...]
    rig_from_target: list[Pose | None]
    rotation_sigma_deg: np.ndarray
    translation_sigma_m: np.ndarray
    baseline_m: np.ndarray
    baseline_sigma_m: np.ndarray
    rms_px: float
    camera_rms_px: np.ndarray
    instant_rms_px: np.ndarray
    covariance: np.ndarray
    param_names: tuple[str, ...]
    rejected: list[tuple[int, int, int, str]] = field(default_factory=list)
    converged: bool = False
    iterations: int = 0
    cost: float = float("nan")
    message: str = ""

    def __repr__(self) -> str:
        return summary_repr(self)

    @property
    def models(self) -> tuple[CameraModel, ...]:
        return tuple(c.model for c in self.cameras)

    @property
    def rig(self) -> CameraRig:
        """The cameras and their poses, without the fit's statistics (what a rig file holds)."""
        return CameraRig(self.names, self.models, self.cam_from_rig)

    def index(self, camera: int | str) -> int:
        """The index of a camera given by index or name."""
        return self.rig.index(camera)

    def relative_pose(self, a: int | str, b: int | str) -> Pose:
        """``cam_a_from_cam_b`` (see :meth:`CameraRig.relative_pose`)."""
        return self.rig.relative_pose(a, b)

    def block(self, camera: int | str) -> tuple[list[int], list[int]]:
        """Indices into ``param_names`` of a camera's free intrinsics and of its pose (empty
        for the reference)."""
        name = self.names[self.index(camera)]
        intr, pose = [], []
        for k, p in enumerate(self.param_names):
            cam, _, par = p.rpartition(".")
            if cam == name:
                (pose if par in _POSE_NAMES else intr).append(k)
        return intr, pose

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready: the cameras (model, RMS, parameter sigmas), their poses in the rig
        (rotation vector, translation, their sigmas), the baselines and the fit's summary."""
        cams = []
        for k, name in enumerate(self.names):
            c = self.cameras[k]
            p = self.cam_from_rig[k]
            cams.append({
                "name": name, "model": c.model.to_dict(), "rms_px": _num(self.camera_rms_px[k]),
                "stddev": {n: _num(v) for n, v in c.stddev.items()},
                "cam_from_rig": {"rvec": [float(v) for v in p.rvec], "t_m": [float(v) for v in p.t]},
                "rotation_sigma_deg": [float(v) for v in self.rotation_sigma_deg[k]],
                "translation_sigma_m": [float(v) for v in self.translation_sigma_m[k]],
                "baseline_m": float(self.baseline_m[k]), "baseline_sigma_m": _num(self.baseline_sigma_m[k]),
                "instants": [int(i) for i in c.view_indices],
            })
        return {"format": "camkit-rig", "version": RIG_FORMAT_VERSION, "reference": self.names[self.reference],
                "cameras": cams, "rms_px": _num(self.rms_px),
                "instant_rms_px": [_num(v) for v in self.instant_rms_px],
                "converged": bool(self.converged), "iterations": int(self.iterations), "message": self.message,
                "rejected_corners": [{"camera": self.names[c], "instant": int(t), "corner": int(i), "reason": r}
                                     for c, t, i, r in self.rejected],
                "rms_definition": "sqrt(mean over corners of dx^2 + dy^2), every camera's corners"}


#: Version of the rig results layout (``RigResult.to_dict``).
RIG_FORMAT_VERSION = 1
_POSE_NAMES = ("rx", "ry", "rz", "tx", "ty", "tz")


def _num(x: float) -> float | None:
    return None if not np.isfinite(x) else float(x)


@dataclass(frozen=True, slots=True, eq=False)
class _RigState:
    params: tuple[np.ndarray, ...]
    Rc: np.ndarray
    tc: np.ndarray
    Rs: np.ndarray
    ts: np.ndarray


class _RigProblem:
    """Reprojection residuals of every camera's corners in use, over the cameras' free
    intrinsics and poses (global) and the rig's pose per instant (local)."""

    local_name = "rig pose"
    local_size = 6

    def __init__(self, classes: list[type[CameraModel]], sizes: list[tuple[int, int]], names: list[str],
                 free: list[list[int]], reference: int, blocks: list[tuple[int, int, np.ndarray, np.ndarray]],
                 n_groups: int, given: list[CameraModel | None] | None = None) -> None:
        self.classes, self.sizes, self.free, self.reference = classes, sizes, free, reference
        self.n_groups = n_groups
        self.blocks = blocks  # (camera, group, object points in use, pixels in use)
        # A camera given with all its intrinsics held projects through that model as it is
        # (its valid radius searched once, over its whole image, and kept with it).
        self._held: dict[int, tuple[float, CameraModel]] = {
            c: (np.inf, m) for c, m in enumerate(given or []) if m is not None and not free[c]}
        gn: list[str] = []
        self.intr_off, self.pose_off = [], []
        for c, cls in enumerate(classes):
            self.intr_off.append(len(gn))
            gn += [f"{names[c]}.{cls.param_names[i]}" for i in free[c]]
        for c in range(len(classes)):
            self.pose_off.append(len(gn) if c != reference else -1)
            if c != reference:
                gn += [f"{names[c]}.{p}" for p in _POSE_NAMES]
        self.global_names = tuple(gn)
        self.per_cam = []
        for c in range(len(classes)):
            mine = [b for b in blocks if b[0] == c]
            if not mine:
                self.per_cam.append(None)
                continue
            obj = np.ascontiguousarray(np.concatenate([b[2] for b in mine]), dtype=np.float64)
            img = np.concatenate([b[3] for b in mine])
            grp = np.repeat(np.array([b[1] for b in mine], dtype=np.int64), [len(b[2]) for b in mine])
            self.per_cam.append((obj, img, grp))
        used = [d for d in self.per_cam if d is not None]
        self.n_obs = sum(len(d[0]) for d in used)
        self.group = np.concatenate([d[2] for d in used]) if used else np.zeros(0, dtype=np.int64)
        # Observations are stacked camera by camera, each camera's blocks in their order: the
        # blocks must come camera by camera (reject_outliers and the result walk them in order).
        cams = [b[0] for b in blocks]
        if cams != sorted(cams):
            raise ValueError("_RigProblem: blocks must be ordered camera by camera")

    def model(self, state: _RigState, c: int) -> CameraModel:
        w, h = self.sizes[c]
        return self.classes[c].from_params(state.params[c], width=w, height=h)

    def _pointed(self, state: _RigState, c: int, Xc: np.ndarray) -> CameraModel:
        """Camera c's model for projecting ``Xc`` (:meth:`CameraModel.for_points`). A camera
        whose intrinsics are all held keeps one model: the one it was given, or one searched
        for its valid radius again only where the points reach farther than before (within
        that reach the projections are the same; the solver calls this a few times per
        iteration)."""
        if self.free[c]:
            return self.model(state, c).for_points(Xc)
        held = self._held.get(c)
        if held is not None and held[0] == np.inf:  # the model given: nothing to measure
            return held[1]
        with np.errstate(divide="ignore", invalid="ignore"):
            r = np.hypot(Xc[:, 0], Xc[:, 1]) / Xc[:, 2]
        reach = float(r[(Xc[:, 2] > 0) & np.isfinite(r)].max(initial=0.0))
        if held is None or reach > held[0]:
            # Searched a quarter farther than the points reach: the poses' steps move them.
            wider = Xc * np.array([1.25, 1.25, 1.0])
            held = (1.25 * reach, self.model(state, c).for_points(wider))
            self._held[c] = held
        return held[1]

    def linearize(self, state: _RigState) -> Linearization:
        G = len(self.global_names)
        n = self.n_obs
        res, Jg, Jl = np.empty((n, 2)), np.zeros((n, 2, G)), np.empty((n, 2, 6))
        lo = 0
        for c, data in enumerate(self.per_cam):
            if data is None:
                continue
            obj, img, g = data
            hi = lo + len(obj)
            RX, Xr = calib_kernels.rotate_views(state.Rs, state.ts, obj, g)
            Rc = state.Rc[c]
            XrRc = Xr @ Rc.T
            Xc = XrRc + state.tc[c]
            uv, dp, dk = self._pointed(state, c, Xc).project_with_jacobian(Xc)
            o = self.intr_off[c]
            if self.free[c]:
                Jg[lo:hi, :, o:o + len(self.free[c])] = dk[:, :, self.free[c]]
            if self.pose_off[c] >= 0:
                Jg[lo:hi, :, self.pose_off[c]:self.pose_off[c] + 6] = pose_jacobian(dp, XrRc)
            np.subtract(uv, img, out=res[lo:hi])
            # d pixel / d rig point = dp Rc (as (2N, 3) @ (3, 3): numpy's stacked matmul is slower)
            Jl[lo:hi] = pose_jacobian((dp.reshape(-1, 3) @ Rc).reshape(dp.shape), RX)
            lo = hi
        return Linearization(res, Jg, Jl, self.group)

    def retract(self, state: _RigState, d_global: np.ndarray, d_local: np.ndarray) -> _RigState:
        params = []
        for c, p in enumerate(state.params):
            p = p.copy()
            o = self.intr_off[c]
            p[self.free[c]] += d_global[o:o + len(self.free[c])]
            params.append(p)
        Rc, tc = state.Rc.copy(), state.tc.copy()
        for c in range(len(params)):
            o = self.pose_off[c]
            if o >= 0:
                Rc[c] = matrix_from_rvec(d_global[o:o + 3]) @ Rc[c]
                tc[c] = tc[c] + d_global[o + 3:o + 6]
        return _RigState(tuple(params), Rc, tc, matrix_from_rvec(d_local[:, :3]) @ state.Rs,
                         state.ts + d_local[:, 3:])


def _rotation_medoid(Rs: list[np.ndarray]) -> np.ndarray:
    """The rotation of ``Rs`` with the smallest summed angle to the others (a robust centre)."""
    A = np.array(Rs)
    tr = np.einsum("aij,bij->ab", A, A)
    ang = np.arccos(np.clip((tr - 1.0) / 2.0, -1.0, 1.0))
    return A[int(np.argmin(ang.sum(axis=1)))]


def _as_list(x: Any, n: int, name: str) -> list[Any]:
    if isinstance(x, list | tuple):
        if len(x) != n:
            raise ParameterError(f"{name}: expected one entry per camera ({n}), got {len(x)}")
        return list(x)
    return [x] * n


def _observations(views: Any, targets: Any,
                  names: list[str]) -> tuple[list[list[np.ndarray | None]], list[Target], list[np.ndarray]]:
    """Per camera and instant the (N, 2) pixels (NaN rows: not seen) or None; the target per
    instant; and its object points per instant (computed once a target)."""
    n_t = len(views[0]) if isinstance(views[0], list | tuple) else 0
    for c, v in enumerate(views):
        if not isinstance(v, list | tuple):
            raise ShapeError(f"views[{c}] ({names[c]}): expected a list with one detection per instant, got "
                             f"{type(v).__name__}")
        if len(v) != n_t:
            raise ShapeError(f"views[{c}] ({names[c]}): expected {n_t} instants, as views[0] ({names[0]}) has, "
                             f"got {len(v)}; the cameras' images must be paired instant by instant (None where a "
                             "camera did not see the target)")
    if isinstance(targets, Target):
        tgts = [targets] * n_t
    elif isinstance(targets, list | tuple) and all(isinstance(t, Target) for t in targets):
        if len(targets) != n_t:
            raise ParameterError(f"targets: expected one target, or one per instant ({n_t}), got {len(targets)}")
        tgts = list(targets)
    else:
        raise ParameterError(f"targets: expected a camkit target (or one per instant), got {type(targets).__name__}")
    points: dict[int, np.ndarray] = {}
    for g in tgts:
        if id(g) not in points:
            points[id(g)] = g.object_points()
    obj_of = [points[id(g)] for g in tgts]
    obs: list[list[np.ndarray | None]] = []
    for c, v in enumerate(views):
        row: list[np.ndarray | None] = []
        for t, d in enumerate(v):
            n_pts = len(obj_of[t])
            if d is None:
                row.append(None)
                continue
            if isinstance(d, Detection):
                px = np.asarray(d.corners, dtype=np.float64) if d.found else None
            else:
                try:
                    px = np.asarray(d, dtype=np.float64)
                except (TypeError, ValueError):
                    raise ShapeError(f"views[{c}][{t}] ({names[c]}, instant {t}): expected a Detection, an (N, 2) "
                                     f"array of pixels or None, got {type(d).__name__}") from None
            if px is not None and px.shape != (n_pts, 2):
                raise ShapeError(f"views[{c}][{t}] ({names[c]}, instant {t}): expected ({n_pts}, 2) pixels, one row "
                                 f"per target point (NaN where not seen), got shape {px.shape}")
            row.append(px)
        obs.append(row)
    return obs, tgts, obj_of


def calibrate_rig(views: Sequence[Sequence[Any]], targets: Target | Sequence[Target], *,
                  sizes: Any, models: str | Sequence[str] = "brown-conrady", reference: int = 0,
                  names: Sequence[str] | None = None, intrinsics: Sequence[CameraModel | None] | None = None,
                  fix: tuple[str, ...] | None = None, free: tuple[str, ...] | None = None,
                  robust_loss: str | None = None, reject_sigma: float | None = 5.0,
                  max_iterations: int = 200) -> RigResult:
    """Calibrate N cameras that observe a target at the same instants, as one problem.

    Parameters
    ----------
    views : list (one per camera) of lists (one per instant)
        What each camera saw at each instant: a :class:`~camkit.target.Detection`, an (N, 2)
        array of pixels in the order of the target's points (NaN rows where not seen), or None
        where the camera did not see the target. Every camera has the same number of instants.
    targets : Target, or one per instant
    sizes : (width, height), or one per camera
        The cameras' image sizes.
    models : registry name, or one per camera
    reference : int
        The camera at the rig's origin (``cam_from_rig`` identity).
    names : camera names (``cam0``, ``cam1``, ... by default)
    intrinsics : one CameraModel or None per camera
        A camera given here keeps these intrinsics (from an earlier single-camera calibration);
        its model and size come from it.
    fix, free : parameters held or freed, for every camera estimated (as :func:`calibrate`)
    robust_loss, reject_sigma, max_iterations : as :func:`calibrate`

    Returns
    -------
    RigResult

    Raises
    ------
    EstimationError
        A camera that sees the target at too few instants to be calibrated, cameras that never
        share an instant with the reference (directly or through other cameras), in words
        naming them.
    """
    if not isinstance(views, list | tuple) or len(views) < 2:
        got = f"{len(views)} cameras" if isinstance(views, list | tuple) else type(views).__name__
        raise ShapeError(f"views: expected a list with one list of detections per camera, for 2 or more cameras, "
                         f"got {got}")
    n_c = len(views)
    names = [f"cam{c}" for c in range(n_c)] if names is None else [str(n) for n in names]
    if len(names) != n_c or len(set(names)) != n_c:
        raise ParameterError(f"names: expected {n_c} different names, one per camera, got {names}")
    if isinstance(reference, bool) or not isinstance(reference, int | np.integer) or not 0 <= reference < n_c:
        raise ParameterError(f"reference: expected a camera index in [0, {n_c}), got {reference!r}")
    reference = int(reference)
    obs, tgts, obj_of = _observations(views, targets, names)
    n_t = len(tgts)
    given = _as_list(intrinsics, n_c, "intrinsics") if intrinsics is not None else [None] * n_c
    for c, m in enumerate(given):
        if m is not None and not isinstance(m, CameraModel):
            raise ParameterError(f"intrinsics[{c}] ({names[c]}): expected a camkit camera model or None, got "
                                 f"{type(m).__name__}")
    model_names = _as_list(models, n_c, "models")
    size_list = _as_list(sizes, n_c, "sizes") if not (isinstance(sizes, list | tuple) and len(sizes) == 2
                                                     and all(isinstance(s, int | np.integer) for s in sizes)) \
        else [tuple(sizes)] * n_c
    sz: list[tuple[int, int]] = []
    for c, s in enumerate(size_list):
        if given[c] is not None:
            sz.append((given[c].width, given[c].height))
            continue
        if not isinstance(s, list | tuple) or len(s) != 2:
            raise ParameterError(f"sizes[{c}] ({names[c]}): expected (width, height), got {s!r}")
        sz.append((as_positive_int(s[0], f"sizes[{c}] width"), as_positive_int(s[1], f"sizes[{c}] height")))
    if robust_loss is not None:
        check_choice(robust_loss, ("huber", "cauchy"), "robust_loss")

    # Which (camera, instant) pairs can be used: 4 or more corners seen.
    seen = np.zeros((n_c, n_t), dtype=bool)
    for c in range(n_c):
        for t in range(n_t):
            px = obs[c][t]
            seen[c, t] = px is not None and int(np.isfinite(px).all(axis=1).sum()) >= 4
    for c in range(n_c):
        if not seen[c].any():
            raise EstimationError(f"camera {names[c]!r}: the target was not seen (4 or more corners) at any of the "
                                  f"{n_t} instants; check its images or leave it out")

    # Each camera alone: its intrinsics (unless given) and its pose at each instant it saw.
    classes, start_models, cam_poses = [], [], []
    for c in range(n_c):
        ts_c = np.flatnonzero(seen[c])
        objs = [obj_of[t] for t in ts_c]
        imgs = [obs[c][t] for t in ts_c]
        poses: dict[int, Pose] = {}
        if given[c] is not None:
            # The poses' start from each view's homography onto the normalised image plane
            # (Zhang's decomposition, all views at once); the joint fit refines them.
            m = given[c]
            all_rays = np.split(m.unproject(np.concatenate(imgs)), np.cumsum([len(p) for p in imgs])[:-1])
            usable = [np.isfinite(rays).all(axis=1) & (rays[:, 2] > 1e-6) for rays in all_rays]
            found = dlt_homographies([o[ok, :2] for o, ok in zip(objs, usable, strict=True)],
                                     [rays[ok, :2] / rays[ok, 2:] for rays, ok in zip(all_rays, usable, strict=True)])
            ts_ok = [int(t) for t, H in zip(ts_c, found, strict=True) if H is not None]
            Hs = [H for H in found if H is not None]
            poses = dict(zip(ts_ok, poses_from_homographies(np.eye(3), Hs), strict=True))
        else:
            try:
                single = calibrate(objs, imgs, width=sz[c][0], height=sz[c][1], model=model_names[c], fix=fix,
                                   free=free, robust_loss=robust_loss, reject_sigma=reject_sigma,
                                   max_iterations=max_iterations)
            except EstimationError as exc:
                raise EstimationError(f"camera {names[c]!r} alone ({len(ts_c)} instants with the target): {exc}") \
                    from None
            m = single.model
            for k, pose in zip(single.view_indices, single.poses, strict=True):
                poses[int(ts_c[k])] = pose
        classes.append(type(m))
        start_models.append(m)
        cam_poses.append(poses)

    # Each camera's pose relative to the reference, through the cameras' shared instants
    # (breadth first from the reference).
    cam_from_ref: dict[int, Pose] = {reference: Pose.identity()}
    frontier = [reference]
    while frontier:
        nxt = []
        for p in frontier:
            for c in range(n_c):
                if c in cam_from_ref:
                    continue
                shared = sorted(set(cam_poses[c]) & set(cam_poses[p]))
                if not shared:
                    continue
                # cam_c_from_cam_p at each shared instant: R_c R_p^T, t_c - R_c R_p^T t_p.
                Rc = np.array([cam_poses[c][t].R for t in shared])
                Rp = np.array([cam_poses[p][t].R for t in shared])
                Rrel = Rc @ Rp.transpose(0, 2, 1)
                trel = np.array([cam_poses[c][t].t for t in shared]) - np.einsum(
                    "nij,nj->ni", Rrel, np.array([cam_poses[p][t].t for t in shared]))
                cam_from_ref[c] = Pose(_rotation_medoid(list(Rrel)), np.median(trel, axis=0)) @ cam_from_ref[p]
                nxt.append(c)
        frontier = nxt
    lonely = [names[c] for c in range(n_c) if c not in cam_from_ref]
    if lonely:
        raise EstimationError(f"cameras {lonely}: they never see the target at an instant shared with camera "
                              f"{names[reference]!r} or with a camera linked to it, so their place in the rig is not "
                              "determined; photograph the target so that it is seen by them and another camera at once")

    # The rig's pose at each instant: from the first camera that has a pose there.
    groups = [t for t in range(n_t) if any(t in cam_poses[c] for c in range(n_c))]
    g_of = {t: k for k, t in enumerate(groups)}
    Rs, ts = np.empty((len(groups), 3, 3)), np.empty((len(groups), 3))
    for k, t in enumerate(groups):
        c = next(c for c in range(n_c) if t in cam_poses[c])
        # rig_from_target = cam_from_ref^-1 @ cam_from_target: R_c^T R, R_c^T (t - t_c).
        Rc, tc, p = cam_from_ref[c].R, cam_from_ref[c].t, cam_poses[c][t]
        Rs[k], ts[k] = Rc.T @ p.R, Rc.T @ (p.t - tc)

    free_idx = []
    for c in range(n_c):
        if given[c] is not None:
            free_idx.append([])
            continue
        held = set(classes[c].param_indices(held_parameters(model_names[c], fix, free)))
        free_idx.append([i for i in range(len(classes[c].param_names)) if i not in held])
    keys = [(c, t) for c in range(n_c) for t in groups if t in cam_poses[c]]
    masks = [np.isfinite(obs[c][t]).all(axis=1) for c, t in keys]
    state = _RigState(tuple(m.params() for m in start_models), np.array([cam_from_ref[c].R for c in range(n_c)]),
                      np.array([cam_from_ref[c].t for c in range(n_c)]), Rs, ts)
    rejected: list[tuple[int, int, int, str]] = []
    tolerances = (1e-6, 1e-10) if reject_sigma is not None else (1e-10,)
    iterations = 0
    for rnd, tol in enumerate(tolerances):
        final = rnd == len(tolerances) - 1
        blocks = [(c, g_of[t], obj_of[t][m], obs[c][t][m]) for (c, t), m in zip(keys, masks, strict=True)]
        problem = _RigProblem(classes, sz, names, free_idx, reference, blocks, len(groups), given)
        report = solve(problem, state, LMOptions(max_iterations=max_iterations, tolerance=tol,
                                                 robust_loss=robust_loss, covariance=final))
        iterations += report.iterations
        state = report.state
        if final:
            break
        for k, i, why in reject_outliers(report.residuals, masks, list(range(len(keys))), reject_sigma):
            rejected.append((keys[k][0], keys[k][1], i, why))
    return _result(problem, report, state, keys, masks, obs, obj_of, names, reference, groups, n_t, rejected,
                   iterations)


def _result(problem: _RigProblem, report: Any, state: _RigState, keys: list[tuple[int, int]],
            masks: list[np.ndarray], obs: list[list[np.ndarray | None]], obj_of: list[np.ndarray], names: list[str],
            reference: int, groups: list[int], n_t: int, rejected: list[tuple[int, int, int, str]],
            iterations: int) -> RigResult:
    n_c = len(names)
    res = report.residuals
    dof = max(res.size - report.n_params, 1)
    sigma2 = float((res**2).sum() / dof)
    cov = report.covariance * sigma2
    rig_from_target: list[Pose | None] = [None] * n_t
    for k, t in enumerate(groups):
        rig_from_target[t] = Pose._unchecked(state.Rs[k], state.ts[k])
    cam_from_rig = tuple(Pose._unchecked(state.Rc[c], state.tc[c]) for c in range(n_c))
    # Residuals per (camera, instant), back in the blocks' order.
    counts = [int(m.sum()) for m in masks]
    split = np.split(res, np.cumsum(counts)[:-1])
    sq_c, n_c_used = np.zeros(n_c), np.zeros(n_c)
    sq_t, n_t_used = np.zeros(n_t), np.zeros(n_t)
    per_cam: list[dict[int, np.ndarray]] = [{} for _ in range(n_c)]
    block_rms: dict[tuple[int, int], float] = {}
    used_c: list[list[np.ndarray]] = [[] for _ in range(n_c)]
    for (c, t), m, r in zip(keys, masks, split, strict=True):
        full = np.full((len(m), 2), np.nan)
        full[m] = r
        per_cam[c][t] = full
        used_c[c].append(r)
        s = float((r**2).sum())
        block_rms[(c, t)] = float(np.sqrt(s / len(r))) if len(r) else float("nan")
        sq_c[c] += s
        n_c_used[c] += len(r)
        sq_t[t] += s
        n_t_used[t] += len(r)
    cameras = []
    k_of = {t: k for k, t in enumerate(groups)}
    for c in range(n_c):
        model = problem.model(state, c)
        inst = sorted(per_cam[c])
        # cam_from_target = cam_from_rig @ rig_from_target (exact rotations: no re-projection).
        ks = [k_of[t] for t in inst]
        Rct = state.Rc[c] @ state.Rs[ks]
        tct = state.ts[ks] @ state.Rc[c].T + state.tc[c]
        poses = [Pose._unchecked(Rct[j], tct[j]) for j in range(len(inst))]
        resid = [per_cam[c][t] for t in inst]
        R = np.concatenate(used_c[c]) if used_c[c] else np.zeros((0, 2))
        R = R[np.isfinite(R).all(axis=1)]
        o = problem.intr_off[c]
        idx = list(range(o, o + len(problem.free[c])))
        fnames = tuple(problem.classes[c].param_names[i] for i in problem.free[c])
        ccov = cov[np.ix_(idx, idx)]
        view_rms = np.array([block_rms[(c, t)] for t in inst])
        cameras.append(CalibrationResult(
            model=model, poses=poses, rms_px=float(np.sqrt((R**2).sum(axis=1).mean())),
            std_px=(float(R[:, 0].std()), float(R[:, 1].std())), view_rms_px=view_rms, residuals=resid,
            free_params=fnames, covariance=ccov, stddev={n: float(np.sqrt(ccov[j, j])) for j, n in enumerate(fnames)},
            rejected=[(t, i, why) for cc, t, i, why in rejected if cc == c], view_indices=tuple(inst),
            rejected_views=[(t, "the target was not seen there (4 or more corners)") for t in range(n_t)
                            if t not in per_cam[c]],
            object_points=list(obj_of),
            image_points=[obs[c][t] if obs[c][t] is not None else np.full((len(obj_of[t]), 2), np.nan)
                          for t in range(n_t)],
            converged=report.converged, iterations=iterations, cost=report.cost, message=report.message))
    rot_sig = np.zeros((n_c, 3))
    tr_sig = np.zeros((n_c, 3))
    base = np.linalg.norm(state.tc, axis=1)  # |-R^T t| = |t|: the centre's distance from the reference's
    base_sig = np.zeros(n_c)
    for c in range(n_c):
        o = problem.pose_off[c]
        if o < 0:
            continue
        d = np.sqrt(np.maximum(np.diag(cov)[o:o + 6], 0.0))
        rot_sig[c], tr_sig[c] = np.degrees(d[:3]), d[3:]
        # The centre is -R^T t; its distance to the reference's (the origin) is |t|.
        t = state.tc[c]
        u = t / max(float(np.linalg.norm(t)), 1e-300)
        base_sig[c] = float(np.sqrt(max(u @ cov[o + 3:o + 6, o + 3:o + 6] @ u, 0.0)))
    all_sq = (res**2).sum(axis=1)
    with np.errstate(invalid="ignore", divide="ignore"):
        inst_rms = np.where(n_t_used > 0, np.sqrt(sq_t / np.maximum(n_t_used, 1)), np.nan)
    return RigResult(
        names=tuple(names), reference=reference, cameras=tuple(cameras), cam_from_rig=cam_from_rig,
        rig_from_target=rig_from_target, rotation_sigma_deg=rot_sig, translation_sigma_m=tr_sig, baseline_m=base,
        baseline_sigma_m=base_sig, rms_px=float(np.sqrt(all_sq.mean())),
        camera_rms_px=np.sqrt(sq_c / np.maximum(n_c_used, 1)), instant_rms_px=inst_rms, covariance=cov,
        param_names=problem.global_names, rejected=rejected, converged=report.converged, iterations=iterations,
        cost=report.cost, message=report.message)

