"""The image-formation simulator: planar targets seen through any camera model."""

from camkit.render.dataset import camera_to_dict, default_camera, plan_views, simulate_dataset
from camkit.render.effects import Defocus, Effects, Exposure, Motion, render_view
from camkit.render.rig import RigInstant, simulate_rig
from camkit.render.target import RenderTruth, render_checkerboard, render_target, render_texture

__all__ = [
    "Defocus",
    "Effects",
    "Exposure",
    "Motion",
    "RenderTruth",
    "RigInstant",
    "camera_to_dict",
    "default_camera",
    "plan_views",
    "render_checkerboard",
    "render_target",
    "render_texture",
    "render_view",
    "simulate_dataset",
    "simulate_rig",
]
