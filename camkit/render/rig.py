"""A camera rig seeing a target: poses for the instants, and each camera's image with the exact
truth (every corner's pixel in every camera)."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from camkit._repr import summary_repr
from camkit._validate import as_positive_int
from camkit.errors import ParameterError
from camkit.geometry.pose import Pose
from camkit.lens.base import CameraModel
from camkit.render.dataset import plan_views
from camkit.render.effects import Effects, render_view
from camkit.target import Target

__all__ = ["RigInstant", "simulate_rig"]


@dataclass(frozen=True, slots=True, eq=False)
class RigInstant:
    """What a rig saw at one instant.

    Attributes
    ----------
    rig_from_target : Pose
    corners_px : list of ndarray, (N, 2)
        Per camera, every target point's true pixel (NaN where it is outside the image or
        behind the camera).
    images : list of ndarray or None
        Per camera, the rendered image (None when rendering was not asked for).
    """

    rig_from_target: Pose
    corners_px: list[np.ndarray]
    images: list[np.ndarray] | None

    def __repr__(self) -> str:
        return summary_repr(self)


def simulate_rig(cameras: Sequence[CameraModel], cam_from_rig: Sequence[Pose], target: Target, instants: int, *,
                 seed: int = 0, render: bool = True, effects: Effects | None = None,
                 tilt_deg: tuple[float, float] = (10.0, 50.0),
                 fill: tuple[float, float] = (0.35, 0.6)) -> list[RigInstant]:
    """Instants of a rig seeing ``target``: the rig's poses are planned for the first camera
    (:func:`~camkit.render.plan_views`: board centres spread over its image, tilted by
    ``tilt_deg``, filling ``fill`` of its width, every corner inside it), and each camera
    sees the target from ``cam_from_rig @ rig_from_target`` (the others may see part of it, or
    none). With ``render``, each camera's image is rendered (:func:`~camkit.render.render_view`
    with ``effects``; seeded, so the same ``seed`` gives the same images)."""
    cams = list(cameras)
    poses = list(cam_from_rig)
    if len(cams) < 1 or len(cams) != len(poses):
        raise ParameterError(f"cameras, cam_from_rig: expected one pose per camera, got {len(cams)} cameras and "
                             f"{len(poses)} poses")
    for k, (c, p) in enumerate(zip(cams, poses, strict=True)):
        if not isinstance(c, CameraModel):
            raise ParameterError(f"cameras[{k}]: expected a camkit camera model, got {type(c).__name__}")
        if not isinstance(p, Pose):
            raise ParameterError(f"cam_from_rig[{k}]: expected a Pose, got {type(p).__name__}")
    if not isinstance(target, Target):
        raise ParameterError(f"target: expected a camkit target (e.g. a Checkerboard), got {type(target).__name__}")
    n = as_positive_int(instants, "instants")
    rng = np.random.default_rng(seed)
    first = plan_views(cams[0], target, n, rng, tilt_deg=tilt_deg, fill=fill)
    obj = target.object_points()
    out = []
    for k, cam0_from_target in enumerate(first):
        rig_from_target = poses[0].inverse() @ cam0_from_target
        corners, images = [], []
        for c, (cam, pose) in enumerate(zip(cams, poses, strict=True)):
            cam_from_target = pose @ rig_from_target
            px = cam.project(cam_from_target.apply(obj))
            inside = ((px[:, 0] >= 0) & (px[:, 0] <= cam.width - 1) & (px[:, 1] >= 0)
                      & (px[:, 1] <= cam.height - 1))
            px[~inside] = np.nan
            corners.append(px)
            if render:
                img, _ = render_view(cam, cam_from_target, target, effects,
                                     rng=np.random.default_rng([seed, k, c]))
                images.append(img)
        out.append(RigInstant(rig_from_target=rig_from_target, corners_px=corners, images=images if render else None))
    return out
