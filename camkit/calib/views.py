"""The single-camera calibration problem for :func:`camkit.calib.refine.solve`: the camera's
free parameters (the global block) and one pose per view (the local blocks).

Pose updates: ``R <- exp([w]x) R``, ``t <- t + dt`` (a local parametrisation of the rotation).
All views are evaluated at once: stacked points, rotations as arrays, one projection with the
lens model's analytic Jacobians."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from camkit._kernels import calib as calib_kernels
from camkit._validate import as_points
from camkit.calib.refine import Linearization
from camkit.errors import ParameterError, ShapeError
from camkit.geometry.pose import Pose
from camkit.geometry.rotation import matrix_from_rvec
from camkit.lens.base import CameraModel

__all__ = ["ViewsProblem", "ViewsState", "pose_jacobian"]


@dataclass(frozen=True, slots=True, eq=False)
class ViewsState:
    """A point of the search: the model's full parameter vector and every view's pose."""

    params: np.ndarray
    Rs: np.ndarray
    ts: np.ndarray

    def poses(self) -> list[Pose]:
        return [Pose._unchecked(R, t) for R, t in zip(self.Rs, self.ts, strict=True)]


def pose_jacobian(dp: np.ndarray, RX: np.ndarray) -> np.ndarray:
    """d pixel / d (w, dt), (N, 2, 6), for ``R <- exp([w]x) R, t <- t + dt``: ``[dp @ -[RX]x, dp]``
    from ``dp`` (N, 2, 3), d pixel / d camera point, and ``RX`` (N, 3), the rotated point."""
    out = np.empty((dp.shape[0], 2, 6))
    calib_kernels.pose_jacobian(np.ascontiguousarray(dp, dtype=np.float64),
                                np.ascontiguousarray(RX, dtype=np.float64), out)
    return out


class ViewsProblem:
    """Reprojection residuals ``project(R_v X + t_v) - observed`` of the points in use (``mask``)
    of every view, over the parameters ``free`` (indices into ``cls.param_names``) and the poses."""

    local_name = "pose"
    local_size = 6

    def __init__(self, cls: type[CameraModel], width: int, height: int, objs: list[np.ndarray],
                 imgs: list[np.ndarray], mask: list[np.ndarray], free: list[int]) -> None:
        self.cls, self.width, self.height, self.free = cls, width, height, list(free)
        self.global_names = tuple(cls.param_names[i] for i in free)
        self.n_groups = len(objs)
        self.obj = np.ascontiguousarray(np.concatenate([o[m] for o, m in zip(objs, mask, strict=True)]),
                                        dtype=np.float64)
        self.img = np.concatenate([p[m] for p, m in zip(imgs, mask, strict=True)])
        self.view = np.repeat(np.arange(len(mask), dtype=np.int64), [int(m.sum()) for m in mask])

    def start(self, model: CameraModel, poses: list[Pose]) -> ViewsState:
        return ViewsState(model.params(), np.array([p.R for p in poses]), np.array([p.t for p in poses]))

    def model(self, state: ViewsState) -> CameraModel:
        """A fresh model at ``state`` (its valid region searched in full, as a model to keep)."""
        return self.cls.from_params(state.params, width=self.width, height=self.height)

    def linearize(self, state: ViewsState) -> Linearization:
        RX, Xc = calib_kernels.rotate_views(state.Rs, state.ts, self.obj, self.view)
        c = self.model(state).for_points(Xc)
        uv, dp, dk = c.project_with_jacobian(Xc)
        return Linearization(uv - self.img, dk[:, :, self.free], pose_jacobian(dp, RX), self.view)

    def retract(self, state: ViewsState, d_global: np.ndarray, d_local: np.ndarray) -> ViewsState:
        p = state.params.copy()
        p[self.free] += d_global
        # R' = exp([w]x) R, t' = t + dt: consistent with d X / d w = -[R X_o]x above.
        return ViewsState(p, matrix_from_rvec(d_local[:, :3]) @ state.Rs, state.ts + d_local[:, 3:])


def _unstack(x: Any) -> Any:
    """A stacked (V, N, k) array as the list of its views (as OpenCV takes them); else ``x``."""
    return list(x) if isinstance(x, np.ndarray) and x.ndim == 3 else x


def _kind(x: Any) -> str:
    return f"an array of shape {x.shape}" if isinstance(x, np.ndarray) else type(x).__name__


def as_views(object_points: Any, image_points: Any) -> tuple[list[np.ndarray], list[np.ndarray]]:
    """The views as lists of (N, 3) planar object points and (N, 2) pixels (NaN rows: not
    seen), checked. Views with the same number of points may also come stacked, as (V, N, 3)
    and (V, N, 2) arrays."""
    object_points, image_points = _unstack(object_points), _unstack(image_points)
    if not isinstance(object_points, list | tuple) or not isinstance(image_points, list | tuple):
        raise ShapeError("object_points, image_points: expected lists with one array per view, or (V, N, 3) and "
                         f"(V, N, 2) arrays, got {_kind(object_points)} and {_kind(image_points)}")
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


def reject_outliers(residuals: np.ndarray, mask: list[np.ndarray], views: list[int],
                    reject_sigma: float) -> list[tuple[int, int, str]]:
    """Points whose residual norm exceeds ``reject_sigma`` robust standard deviations (the MAD
    of the 2-D residual norms, per axis), taken out of ``mask`` (changed in place) and listed as
    ``(view, index, reason)``. ``residuals`` (N, 2) are the solver's, stacked view by view over
    the points in use; ``views[k]`` is the input index of the k-th view."""
    res = np.hypot(residuals[:, 0], residuals[:, 1])
    sigma = 1.4826 * np.median(res) / 0.8326  # MAD of the 2-D residual norm -> per-axis sigma
    limit = reject_sigma * max(sigma, 1e-6) * np.sqrt(2)
    rejected: list[tuple[int, int, str]] = []
    start = 0
    for k, i in enumerate(views):
        used = np.flatnonzero(mask[k])
        r = res[start:start + len(used)]
        start += len(used)
        for j, rj in zip(used[r > limit], r[r > limit], strict=True):
            rejected.append((i, int(j), f"residual {rj:.2f} px > {reject_sigma:g} robust sigma ({limit:.2f} px)"))
        mask[k][used[r > limit]] = False
    return rejected
